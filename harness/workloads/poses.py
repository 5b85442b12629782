"""Seeded pose suites: uniformly random rotations and distance-controlled buckets (NOTES section 8).

Poses are 4x4 homogeneous matrices (local -> world, metres); batches are (N, 4, 4). Rotations are
drawn uniformly on SO(3) with ``scipy.spatial.transform.Rotation.random`` (never Euler angles), and
every random draw comes from ``np.random.default_rng(seed)``, so a suite is a pure function of its
arguments.

Body size. For a pair (A, B) the suite's length scale is

    L = (r_A + r_B) / 2,

where ``r = Polyhedron.bounding_radius()`` is the radius of the smallest ball centred at the body's
local origin that contains it. Bucket targets are multiples of L (``BUCKETS``), e.g. 'close-1e-3'
asks for a distance of 1e-3 L.

Construction of one sample (``bucket_suite``): random rotations for A and B; A's origin uniform in
[-L, L]^3; B's origin at distance 1.05 (r_A + r_B) from A's in a uniformly random direction (so the
bounding balls, hence the bodies, are disjoint). The exact closest points then come from
:class:`harness.references.minkowski.MinkowskiReference`, and B is translated along the separation normal n by
``target - d``. For separated targets the exact distance is then the target (the Minkowski
difference lies in the half-space n.x <= -d, touching its boundary at the closest point); for
overlapping targets B is pushed |target| past contact along n and the reference gives the true
penetration depth, which is stored (it can be smaller than |target|). The reference is queried
again at the final pose (reusing the hull through its ``offset`` argument) and its answer is what
the suite stores. A draw whose answer misses its bucket (an overlapping target that does not
overlap, which happens when the contact is at a sharp vertex, or a separated target off by more
than ``SUITE_TOL``) is discarded and redrawn.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from harness.references.minkowski import TOUCH_TOL, MinkowskiReference
from spq.shapes.polyhedron import Polyhedron

BUCKETS: dict[str, float] = {
    "distant-5": 5.0,
    "distant-2.5": 2.5,
    "distant-1": 1.0,
    "distant-0.5": 0.5,
    "close-1e-1": 1e-1,
    "close-1e-2": 1e-2,
    "close-1e-3": 1e-3,
    "close-1e-4": 1e-4,
    "touching": 0.0,
    "overlap-1e-4": -1e-4,
    "overlap-1e-3": -1e-3,
    "overlap-1e-2": -1e-2,
    "overlap-1e-1": -1e-1,
}
"""Bucket name -> target signed distance in units of the body size L (see module docstring)."""

SUITE_TOL_REL = 1e-12  # separated targets: accept |d_ref - target| <= SUITE_TOL_REL * target ...
SUITE_TOL_ABS_L = 4e-15  # ... + SUITE_TOL_ABS_L * L (a few ulps of the body size; seen: <= 4e-16 L)
START_GAP = 1.05  # B's origin starts at START_GAP * (r_A + r_B) from A's
MAX_ATTEMPTS = 100  # redraws allowed per sample before giving up


def pose_matrix(rotation, translation) -> np.ndarray:
    """4x4 (or (N, 4, 4)) homogeneous matrices from rotation matrices (3x3 / (N, 3, 3)) and
    translations ((3,) / (N, 3), metres)."""
    rot = np.asarray(rotation, dtype=np.float64)
    t = np.asarray(translation, dtype=np.float64)
    if rot.shape[-2:] != (3, 3) or t.shape[-1:] != (3,) or rot.shape[:-2] != t.shape[:-1]:
        raise ValueError(f"rotation (..., 3, 3) and translation (..., 3) must match; got {rot.shape} and {t.shape}")
    out = np.zeros(rot.shape[:-2] + (4, 4))
    out[..., :3, :3] = rot
    out[..., :3, 3] = t
    out[..., 3, 3] = 1.0
    return out


def random_rotations(n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 3, 3) rotation matrices drawn uniformly on SO(3) from ``rng``."""
    return Rotation.random(n, random_state=rng).as_matrix().reshape(n, 3, 3)


def random_poses(n: int, seed: int, translation_range: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """Independent random poses for throughput benchmarks.

    Returns ``(poses_a, poses_b)``, each (n, 4, 4): uniform rotations, translations uniform in
    ``[-translation_range, translation_range]^3`` metres. No control over distance or overlap.
    """
    n = _as_count(n, "n")
    if not np.isfinite(translation_range) or translation_range < 0:
        raise ValueError(f"translation_range must be finite and >= 0 (metres); got {translation_range}")
    rng = np.random.default_rng(seed)
    rot = random_rotations(2 * n, rng)
    t = rng.uniform(-translation_range, translation_range, size=(2 * n, 3))
    poses = pose_matrix(rot, t)
    return poses[:n].copy(), poses[n:].copy()


def body_size(a: Polyhedron, b: Polyhedron) -> float:
    """The suite's length scale L = (r_A + r_B) / 2 in metres (bounding radii about local origins)."""
    return 0.5 * (a.bounding_radius() + b.bounding_radius())


@dataclass(eq=False)
class PoseSuite:
    """A distance-controlled set of N pose pairs with their exact reference answers.

    bucket : (N,) str, bucket name per sample (keys of ``BUCKETS``).
    pose_a, pose_b : (N, 4, 4) float64, local -> world.
    target : (N,) float64, requested signed distance in metres (``BUCKETS[bucket] * scale``).
    ref_distance : (N,) exact distance (m, 0 when overlapping).
    ref_signed : (N,) exact signed distance (m): distance, or -penetration depth.
    ref_point_a, ref_point_b : (N, 3) exact witness points (world, m).
    ref_normal : (N, 3) unit normal from A to B (direction of least penetration when overlapping).
    ref_status : (N,) str, 'separated' | 'touching' | 'overlapping'.
    seed : int; pair_name : str; scale : float, the body size L in metres.
    """

    bucket: np.ndarray
    pose_a: np.ndarray
    pose_b: np.ndarray
    target: np.ndarray
    ref_distance: np.ndarray
    ref_signed: np.ndarray
    ref_point_a: np.ndarray
    ref_point_b: np.ndarray
    ref_status: np.ndarray
    seed: int
    pair_name: str
    scale: float = float("nan")
    ref_normal: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __len__(self) -> int:
        return len(self.bucket)

    @property
    def separated(self) -> np.ndarray:
        """(N,) bool: samples whose reference status is 'separated'."""
        return self.ref_status == "separated"

    @property
    def overlapping(self) -> np.ndarray:
        """(N,) bool: samples whose reference status is 'overlapping'."""
        return self.ref_status == "overlapping"

    def select(self, mask) -> "PoseSuite":
        """Sub-suite of the samples where ``mask`` ((N,) bool or index array) holds."""
        idx = np.arange(len(self))[mask]
        arrays = {k: getattr(self, k)[idx] for k in _ARRAY_FIELDS}
        return PoseSuite(**arrays, seed=self.seed, pair_name=self.pair_name, scale=self.scale)

    def bucket_of(self, name: str) -> "PoseSuite":
        """Sub-suite of one bucket."""
        if name not in set(self.bucket.tolist()):
            raise ValueError(f"bucket {name!r} not in this suite; it has {sorted(set(self.bucket.tolist()))}")
        return self.select(self.bucket == name)

    def save(self, path) -> None:
        """Write the suite to an ``.npz`` file."""
        arrays = {k: getattr(self, k) for k in _ARRAY_FIELDS}
        np.savez_compressed(path, seed=self.seed, pair_name=self.pair_name, scale=self.scale, **arrays)

    @classmethod
    def load(cls, path) -> "PoseSuite":
        """Read a suite written by :meth:`save`."""
        path = Path(path)
        if not path.is_file():
            raise ValueError(f"pose suite file not found: {path}")
        with np.load(path, allow_pickle=False) as z:
            missing = [k for k in _ARRAY_FIELDS if k not in z]
            if missing:
                raise ValueError(f"{path} is not a saved PoseSuite: missing {missing}")
            arrays = {k: z[k] for k in _ARRAY_FIELDS}
            return cls(**arrays, seed=int(z["seed"]), pair_name=str(z["pair_name"]), scale=float(z["scale"]))


_ARRAY_FIELDS = (
    "bucket",
    "pose_a",
    "pose_b",
    "target",
    "ref_distance",
    "ref_signed",
    "ref_point_a",
    "ref_point_b",
    "ref_status",
    "ref_normal",
)


def _as_count(n, name: str) -> int:
    if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ValueError(f"{name} must be an integer >= 0; got {n!r}")
    return int(n)


def _accepts(target: float, scale: float, res) -> bool:
    if target > 0.0:
        tol = SUITE_TOL_REL * target + SUITE_TOL_ABS_L * scale
        return res.status == "separated" and abs(res.distance - target) <= tol
    if target == 0.0:
        return res.status == "touching"
    return res.status == "overlapping"


def _unit(rng: np.random.Generator) -> np.ndarray:
    while True:
        v = rng.normal(size=3)
        n = np.linalg.norm(v)
        if n > 1e-6:
            return v / n


def bucket_suite(
    a: Polyhedron,
    b: Polyhedron,
    n_per_bucket: int,
    seed: int,
    buckets=None,
    progress: bool = False,
    pair_name: str | None = None,
) -> PoseSuite:
    """Distance-controlled pose suite for the pair (A, B) (construction in the module docstring).

    Parameters
    ----------
    a, b : Polyhedron
    n_per_bucket : int >= 0, samples per bucket.
    seed : int, seed of ``np.random.default_rng``; equal arguments give identical suites.
    buckets : None (all of ``BUCKETS``), a list of names from ``BUCKETS``, or a dict name -> target
        in units of L.
    progress : True for a tqdm progress bar of its own, or an existing bar (anything with
        ``update(n)``) to advance by one per sample, e.g. one bar over several suites.
    pair_name : label stored in the suite; defaults to the bodies' ``name`` attributes (set by
        ``datasets.load_object``) or their reprs.

    Samples are ordered bucket by bucket in the order of ``buckets``.
    """
    for name, body in (("a", a), ("b", b)):
        if not isinstance(body, Polyhedron):
            raise ValueError(f"{name} must be a spq Polyhedron; got {type(body).__name__}")
    n_per_bucket = _as_count(n_per_bucket, "n_per_bucket")
    if buckets is None:
        chosen = dict(BUCKETS)
    elif isinstance(buckets, dict):
        chosen = {str(k): float(v) for k, v in buckets.items()}
    else:
        unknown = [k for k in buckets if k not in BUCKETS]
        if unknown:
            raise ValueError(f"unknown bucket(s) {unknown}; known: {list(BUCKETS)}")
        chosen = {k: BUCKETS[k] for k in buckets}
    if not all(np.isfinite(v) for v in chosen.values()):
        raise ValueError(f"bucket targets must be finite; got {chosen}")
    if pair_name is None:
        pair_name = f"{getattr(a, 'name', repr(a))}|{getattr(b, 'name', repr(b))}"

    rng = np.random.default_rng(seed)
    r_a, r_b = a.bounding_radius(), b.bounding_radius()
    scale = 0.5 * (r_a + r_b)
    n = n_per_bucket * len(chosen)
    out = {
        "bucket": np.empty(n, dtype=object),
        "pose_a": np.empty((n, 4, 4)),
        "pose_b": np.empty((n, 4, 4)),
        "target": np.empty(n),
        "ref_distance": np.empty(n),
        "ref_signed": np.empty(n),
        "ref_point_a": np.empty((n, 3)),
        "ref_point_b": np.empty((n, 3)),
        "ref_normal": np.empty((n, 3)),
        "ref_status": np.empty(n, dtype=object),
    }
    own_bar = not hasattr(progress, "update")
    bar = None if own_bar else progress
    if own_bar and progress and n:
        from tqdm.auto import tqdm

        bar = tqdm(total=n, desc=f"pose suite {pair_name}", unit="pose")
    k = 0
    try:
        for bname, rel in chosen.items():
            target = rel * scale
            for _ in range(n_per_bucket):
                for _attempt in range(MAX_ATTEMPTS):
                    rot = random_rotations(2, rng)
                    t_a = rng.uniform(-scale, scale, size=3)
                    t_b = t_a + START_GAP * (r_a + r_b) * _unit(rng)
                    pose_a, pose_b = pose_matrix(rot[0], t_a), pose_matrix(rot[1], t_b)
                    ref = MinkowskiReference(a, b, pose_a, pose_b)
                    start = ref.query()
                    if start.status != "separated":  # cannot happen with disjoint bounding balls
                        continue
                    offset = (target - start.distance) * start.normal
                    res = ref.query(offset)
                    if _accepts(target, scale, res):
                        break
                else:
                    raise RuntimeError(
                        f"bucket {bname!r} (target {target:.3g} m): no acceptable pose in {MAX_ATTEMPTS} draws"
                    )
                pose_b = pose_b.copy()
                pose_b[:3, 3] = t_b + offset
                out["bucket"][k] = bname
                out["pose_a"][k] = pose_a
                out["pose_b"][k] = pose_b
                out["target"][k] = target
                out["ref_distance"][k] = res.distance
                out["ref_signed"][k] = res.signed_distance
                out["ref_point_a"][k] = res.point_a
                out["ref_point_b"][k] = res.point_b
                out["ref_normal"][k] = res.normal
                out["ref_status"][k] = res.status
                k += 1
                if bar is not None:
                    bar.update(1)
    finally:
        if bar is not None and own_bar:
            bar.close()
    out["bucket"] = out["bucket"].astype(str) if n else np.empty(0, dtype="<U1")
    out["ref_status"] = out["ref_status"].astype(str) if n else np.empty(0, dtype="<U1")
    return PoseSuite(**out, seed=int(seed), pair_name=pair_name, scale=float(scale))


__all__ = [
    "BUCKETS",
    "TOUCH_TOL",
    "PoseSuite",
    "body_size",
    "bucket_suite",
    "pose_matrix",
    "random_poses",
    "random_rotations",
]
