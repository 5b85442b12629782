"""Throughput benchmarks: queries per second of every engine on the same object and poses, one run.

Each engine runs its leanest per-query Python loop (``PreparedPair.distance_loop``); spq also runs its
batched compiled call (one per block of poses) and the plain ``spq.distance`` call in a loop. The
poses are cut into blocks, every engine runs block 1, then block 2, and so on, ``repeats`` rounds; an
engine's time is the sum over the blocks of its least time on each (harness.suites.bench.timing), and
every rate is divided by coal's PCH-PCH rate from the same run.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from harness.engines import available_engines
from harness.suites.bench.timing import BLOCK, blocked_calls, blocked_times
from harness.workloads.poses import random_poses

BASELINE = ("PCH-PCH", "coal")
# The peers that also run on the STP-BV's own meshes: the two fastest on PCH-PCH (fcl and bullet run 2 to 5
# times slower than coal there, and a mesh of thousands of vertices only widens that).
MESH_ENGINES = ("coal", "mujoco")
# Hausdorff tolerances of those meshes, times the STP-BV's bounding radius: spq's default mesh
# (STPBV.to_mesh) and one ten times finer.
MESH_REL_TOLERANCES = (1e-3, 1e-4)
MESH_MODE = "per-call on STP-BV mesh"  # the mode of a peer's row on the meshes: "<MESH_MODE> <tolerance> m"


@dataclass
class BenchConfig:
    object_name: str
    poses: int = 20000
    seed: int = 0
    translation_range: float = 0.3  # m: translations uniform in [-range, range]^3
    repeats: int = 3  # rounds: each block of poses timed this many times, its least time kept
    block: int = BLOCK  # poses per block (harness.suites.bench.timing.blocked_times)
    engines: list[str] | None = None
    r: float = 0.005  # STP-BV radii (m), for the STP pairs
    R: float = 2.0
    pairs: list[str] = field(default_factory=lambda: ["PCH-PCH"])
    mesh_rel_tolerances: tuple = MESH_REL_TOLERANCES  # () leaves the peers off the STP-BV's meshes
    workers: int = 1  # > 1: spq's batched rows also on this many threads (spq.workers), beside one thread's


def timing_modes(pair) -> list[tuple[str, object]]:
    """(mode, distances function) pairs to time: the batch where the engine has one (spq), and the
    leanest per-call loop."""
    modes = [("per-call", pair.distance_loop)]
    if hasattr(pair, "distance_batch"):
        modes.insert(0, ("batched", pair.distance_batch))
    return modes


def _shapes(config: BenchConfig, load_object) -> dict:
    from spq.shapes.stpbv import STPBV

    pch = load_object(config.object_name)
    shapes = {"PCH": pch}
    if any("STP" in p for p in config.pairs):
        shapes["STP"] = STPBV.from_points(pch.vertices, config.r, config.R)
    return shapes


def _signed_modes(shape_a, shape_b) -> list[tuple[str, object]]:
    """spq's signed timing modes (overlaps get their penetration depth), as timing_modes."""
    import spq

    pair = spq.Pair(shape_a, shape_b, signed=True)

    def per_call(poses_a, poses_b):
        query = pair.distance
        return np.array([query(pa, pb).distance for pa, pb in zip(poses_a, poses_b)])

    def batched(poses_a, poses_b):
        return spq.distances(shape_a, shape_b, poses_a, poses_b, signed=True).distance

    return [("batched signed", batched), ("per-call signed", per_call)]


def _plain_call_modes(shape_a, shape_b, tol: float, rel_tol: float) -> list[tuple[str, object]]:
    """The call a newcomer writes first, ``spq.distance(A, B, pose_a, pose_b)`` in a Python loop (a Pair
    made per call), unsigned and signed, as timing_modes: its own rows beside the prepared Pair's
    ("per-call")."""
    import spq

    def plain(signed: bool):
        def run(poses_a, poses_b):
            distance = spq.distance
            return np.array([distance(shape_a, shape_b, pa, pb, tol=tol, rel_tol=rel_tol, signed=signed).distance
                             for pa, pb in zip(poses_a, poses_b)])
        return run

    return [("plain call", plain(False)), ("plain call signed", plain(True))]


def _threaded_modes(shape_a, shape_b, tol: float, rel_tol: float, workers: int) -> list[tuple[str, object]]:
    """spq's batched modes, unsigned and signed, on ``workers`` threads (their results equal the
    one-thread batches' bit for bit), as timing_modes."""
    import spq

    def batched(signed: bool):
        def run(poses_a, poses_b):
            return spq.distances(shape_a, shape_b, poses_a, poses_b, tol=tol, rel_tol=rel_tol, signed=signed,
                                 workers=workers).distance
        return run

    return [(f"batched {workers} workers", batched(False)), (f"batched signed {workers} workers", batched(True))]


def stp_meshes(stp, rel_tolerances) -> list[tuple[float, object]]:
    """(tolerance in m, trimesh) for each relative tolerance: the STP-BV's certified mesh
    (:meth:`spq.shapes.stpbv.STPBV.to_mesh`: every vertex on the true surface, the mesh inside the
    STP-BV, their Hausdorff distance at most the tolerance). What a user of an engine without STP-BVs
    gives it for the same smooth volume."""
    radius = stp.bounding_radius()
    return [(rel * radius, stp.to_mesh(rel * radius)) for rel in rel_tolerances]


def _mesh_modes(pair_types, shapes: dict, engines: dict, rel_tolerances) -> tuple[list, dict]:
    """The peers (MESH_ENGINES) on the STP-BV's meshes: ([(pair type, engine name, mode, prepared pair)],
    {mode: (mesh vertices, certified Hausdorff bound in m)}). An STP side is the mesh, a PCH side the hull."""
    stp_pairs = [p for p in pair_types if "STP" in p]
    peers = [name for name in MESH_ENGINES if name in engines]
    if not (stp_pairs and peers and rel_tolerances):
        return [], {}
    runs, info = [], {}
    for tolerance, mesh in stp_meshes(shapes["STP"], rel_tolerances):
        mode = f"{MESH_MODE} {tolerance:.1e} m"
        info[mode] = (len(mesh.vertices), float(mesh.metadata["max_error"]))
        for pair_type in stp_pairs:
            a, b = (mesh if kind == "STP" else shapes[kind] for kind in pair_type.split("-"))
            runs += [(pair_type, name, mode, engines[name].prepare(a, b)) for name in peers]
    return runs, info


def throughput(config: BenchConfig, load_object, progress: bool = True) -> pd.DataFrame:
    """Queries per second per pair type, engine and mode on two copies of one object, with the
    ratio to coal's PCH-PCH rate. External engines run PCH-PCH, and (MESH_ENGINES) the STP pairs on the
    STP-BV's meshes, as they have no STP-BV.
    config.workers > 1 adds spq's batched modes on that many threads.

    coal always runs with signed distance on (its EPA on overlaps); spq runs unsigned (overlaps get
    distance 0) and, in the modes named "signed", with signed=True. Every job runs on all poses
    (``poses`` = "all") and again on the overlapping ones alone ("overlapping": those coal's result
    calls overlapping), where a signed engine pays for its depth on every query; ratios are to coal's
    PCH-PCH rate on the same poses.

    The peers have no STP-BV; with config.mesh_rel_tolerances they also run STP-PCH and STP-STP on the
    STP-BV's certified meshes (stp_meshes), in the same blocks: rows "<MESH_MODE> <tolerance> m", with
    the mesh's vertices and certified error, and the least and largest of their signed distance less
    spq's (the exact STP-BV's) on the same poses."""
    from tqdm import tqdm

    from spq.workers import check_workers

    workers = check_workers(config.workers)
    shapes = _shapes(config, load_object)
    poses_a, poses_b = random_poses(config.poses, config.seed, config.translation_range)
    engines = available_engines(config.engines)
    if "spq" in engines:  # the plain rows are spq unsigned; _signed_modes adds the signed ones
        from harness.engines.spq_engine import SpqEngine

        engines["spq"] = SpqEngine(signed=False)
    runs = [(p, name) for p in config.pairs for name in engines if p == "PCH-PCH" or name == "spq"]
    prepared, modes = [], {}
    try:
        for pair_type, name in runs:
            a_kind, b_kind = pair_type.split("-")
            pair = engines[name].prepare(shapes[a_kind], shapes[b_kind])
            prepared.append(pair)
            extra = []
            if name == "spq":
                extra = _signed_modes(shapes[a_kind], shapes[b_kind]) + _plain_call_modes(
                    shapes[a_kind], shapes[b_kind], engines[name].tolerance, engines[name].rel_tol)
            if name == "spq" and workers > 1:
                extra += _threaded_modes(shapes[a_kind], shapes[b_kind], engines[name].tolerance, engines[name].rel_tol,
                                         workers)
            for mode, fn in timing_modes(pair) + extra:
                fn(poses_a[:8], poses_b[:8])  # compile and warm
                modes[(pair_type, name, mode)] = fn
        mesh_runs, mesh_info = _mesh_modes(config.pairs, shapes, engines, config.mesh_rel_tolerances)
        for pair_type, name, mode, pair in mesh_runs:
            prepared.append(pair)
            pair.distance_loop(poses_a[:8], poses_b[:8])
            modes[(pair_type, name, mode)] = pair.distance_loop
        overlapping = _overlapping(modes, poses_a, poses_b)
        subsets = {"all": (poses_a, poses_b)}
        if overlapping.any():
            subsets["overlapping"] = (poses_a[overlapping], poses_b[overlapping])
        jobs = {key + (subset,): (fn, pa, pb) for subset, (pa, pb) in subsets.items() for key, fn in modes.items()}
        with tqdm(total=blocked_calls(jobs, config.repeats, config.block), desc="bench", unit="run",
                  disable=not progress) as bar:
            timed = blocked_times(jobs, config.repeats, config.block, progress=bar)
    finally:
        for pair in prepared:
            pair.close()
        for engine in engines.values():
            engine.close()
    rows = [{"pair": pair_type, "engine": name, "mode": mode, "poses": subset, "queries": len(subsets[subset][0]),
             "seconds": seconds, "queries_per_s": len(subsets[subset][0]) / seconds,
             "overlapping": int(np.sum(np.concatenate(blocks) <= 0.0))}
            for (pair_type, name, mode, subset), (seconds, blocks) in timed.items()]
    table = pd.DataFrame(rows)
    table["ratio_to_coal_pch"] = np.nan
    for subset in subsets:
        here = table.poses == subset
        base = table.loc[here & (table.pair == BASELINE[0]) & (table.engine == BASELINE[1]), "queries_per_s"]
        if len(base):
            table.loc[here, "ratio_to_coal_pch"] = table.loc[here, "queries_per_s"] / base.iloc[0]
    table.insert(0, "object", config.object_name)
    table["features"] = table.pair.map(lambda p: "+".join(str(_feature_count(shapes[k])) for k in p.split("-")))
    _add_mesh_columns(table, timed, mesh_info, shapes)
    table["seed"] = config.seed
    return table


def _add_mesh_columns(table: pd.DataFrame, timed: dict, mesh_info: dict, shapes: dict) -> None:
    """On the peers' rows on the STP-BV's meshes: features with the mesh's vertices for its STP side,
    mesh_error_m (the mesh's certified Hausdorff bound), and the least and largest peer - spq over the
    row's poses (diff_min_m, diff_max_m), against spq's batched signed answers on the same pair and
    poses. The meshes lie inside the STP-BVs, so a peer exact on them reads 0 to 1 (STP-PCH) or 2
    (STP-STP) times mesh_error_m above spq; outside that range is the peer's own error."""
    table["mesh_error_m"] = np.nan
    table["diff_min_m"] = np.nan
    table["diff_max_m"] = np.nan
    for i, row in table.iterrows():
        if row["mode"] not in mesh_info:
            continue
        vertices, error = mesh_info[row["mode"]]
        table.at[i, "features"] = "+".join(str(vertices) if k == "STP" else str(_feature_count(shapes[k]))
                                           for k in row.pair.split("-"))
        table.at[i, "mesh_error_m"] = error
        exact = timed.get((row.pair, "spq", "batched signed", row.poses))
        if exact is not None:
            diff = np.concatenate(timed[(row.pair, row.engine, row["mode"], row.poses)][1]) - np.concatenate(exact[1])
            table.at[i, "diff_min_m"], table.at[i, "diff_max_m"] = float(diff.min()), float(diff.max())


def mesh_summary(table: pd.DataFrame) -> pd.DataFrame:
    """One row per peer on an STP-BV mesh (pair, poses, engine, mode): its rate beside spq's signed rates
    on the exact STP-BV, and spq's speed-up over it (spq's rate / the peer's), batched and per call."""
    mesh_rows = table[table["mode"].str.startswith(MESH_MODE)]
    rows = []
    for _, r in mesh_rows.iterrows():
        spq_rate = {m: table.loc[(table.pair == r.pair) & (table.poses == r.poses) & (table.engine == "spq")
                                 & (table["mode"] == m), "queries_per_s"] for m in ("batched signed", "per-call signed")}
        rate = {m: float(v.iloc[0]) if len(v) else np.nan for m, v in spq_rate.items()}
        rows.append({"pair": r.pair, "poses": r.poses, "engine": r.engine, "mode": r["mode"], "features": r.features,
                     "mesh_error_m": r.mesh_error_m, "queries_per_s": r.queries_per_s,
                     "spq_batched_signed_speedup": rate["batched signed"] / r.queries_per_s,
                     "spq_per_call_signed_speedup": rate["per-call signed"] / r.queries_per_s,
                     "diff_min_m": r.diff_min_m, "diff_max_m": r.diff_max_m})
    return pd.DataFrame(rows)


def _overlapping(modes: dict, poses_a: np.ndarray, poses_b: np.ndarray) -> np.ndarray:
    """(N,) bool: the poses the baseline engine (coal, else spq) finds overlapping on PCH-PCH."""
    for engine in (BASELINE[1], "spq"):
        for (pair_type, name, _), fn in modes.items():
            if pair_type == BASELINE[0] and name == engine:
                return np.asarray(fn(poses_a, poses_b)) <= 0.0
    return np.zeros(len(poses_a), dtype=bool)


def _feature_count(shape) -> int:
    return getattr(shape, "n_patches", None) or len(shape.vertices)
