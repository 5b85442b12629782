"""Robot self-distance scenes (spq.Scene): bodies and pairs, distances, bounds, warm starts, pruning,
joint-space gradients, bad input.

Oracles (never spq itself):

- the URDF files, parsed here with ElementTree, for the bodies and the pairs a scene must query;
- coal's GJK (gjk_tolerance 1e-10) between the same convex hulls at ``scene.body_poses(q)`` for
  every PCH distance, plus the hulls' own plane equations for witness points;
- containment for the ``auto`` policy: an STP-BV with small radius r contains its hull grown by r,
  so its distance to a hull is at most max(0, d_PCH - r);
- a cold query for warm-started ones; an unpruned query (and coal) for pruned runs;
- central finite differences of the pair distances in q for ``distance_gradient``.

JVRC-1 needs the shared datasets (fail under CI, skip otherwise); the KUKA iiwa and the Franka
Panda come with pybullet_data.
"""

from __future__ import annotations

import itertools
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import spq
from datasets.robots import ROBOTS
from harness.workloads.robot_poses import smooth_trajectory
from spq.kernels.gjk import OUT_DISTANCE, OUT_SIZE
from spq.scene import Scene
from tests.conftest import require_shared_datasets

DIST_TOL = 1e-8  # m: spq against coal, and witness points on their hulls
COAL_GJK_TOL = 1e-10  # m: coal's gjk_tolerance, well below DIST_TOL
BOUND_SLACK = 1e-9  # m: the auto-policy bound d_auto <= max(0, d_PCH - r)
COHERENT_TOL = 1e-9  # m: warm-started against cold distances
N_CONFIGURATIONS = 100
CONFIG_SEED = 20240607
TRAJECTORY_STEPS = 200
TRAJECTORY_SEED = 11
PRUNE = 0.05  # m: pruning threshold
# Gradients: GJK's distances stop improving near 1e-12 m even at tol 1e-13 (the floor of double
# arithmetic on these hulls), so a central difference with step h carries noise ~1e-12 / h. With
# h = 1e-6 that is ~5e-7, as large as 1e-5 of a typical gradient; h = 1e-5 (truncation ~h^2 d''' ~
# 1e-9) brings it to ~5e-8, under the absolute term below.
FD_STEP = 1e-5  # rad or m
GRAD_RTOL = 1e-5  # of the pair's largest |FD component|
GRAD_ATOL = 1e-7  # FD noise floor (see above)
TIGHT = dict(tol=1e-13, rel_tol=1e-13)
N_GRADIENT_CONFIGURATIONS = 3

JVRC1_BODIES = 35
ARM_BODIES = {"kuka_iiwa": 8, "panda": 11}  # panda_link8 and panda_grasptarget carry no geometry


# ---------------------------------------------------------------- independent oracles


def urdf_bodies(path: Path) -> tuple[list[tuple[str, str]], dict[str, str]]:
    """From the URDF text alone: the bodies as (body name, link name), one per collision geometry of
    each link (visual geometries when a link has no collision), named as spq names them (the link,
    suffixed #k when a link has several); and each child link's parent link."""
    root = ET.parse(path).getroot()
    parent_of = {j.find("child").get("link"): j.find("parent").get("link") for j in root.findall("joint")}
    bodies = []
    for link in root.findall("link"):
        name = link.get("name")
        geoms = [e for e in link.findall("collision") if e.find("geometry") is not None]
        geoms = geoms or [e for e in link.findall("visual") if e.find("geometry") is not None]
        bodies += [(name if len(geoms) == 1 else f"{name}#{k}", name) for k in range(len(geoms))]
    return bodies, parent_of


def urdf_adjacent_links(path: Path) -> set[frozenset]:
    """{link, nearest ancestor link that carries a body}: links joined by a joint, once links
    without geometry (JVRC-1's R_HIP_P_S between PELVIS_S and R_HIP_R_S, sensor frames) are
    collapsed."""
    bodies, parent_of = urdf_bodies(path)
    with_body = {link for _, link in bodies}
    out = set()
    for link in with_body:
        a = parent_of.get(link)
        while a is not None and a not in with_body:
            a = parent_of.get(a)
        if a is not None:
            out.add(frozenset((link, a)))
    return out


def urdf_pairs(path: Path, skip_adjacent: bool) -> set[frozenset]:
    """The body pairs a scene must query, as sets of two body names."""
    bodies, _ = urdf_bodies(path)
    adjacent = urdf_adjacent_links(path)
    out = set()
    for (na, la), (nb, lb) in itertools.combinations(bodies, 2):
        if skip_adjacent and (la == lb or frozenset((la, lb)) in adjacent):
            continue
        out.add(frozenset((na, nb)))
    return out


class CoalScene:
    """coal.Convex objects for every body of a scene (built once, through the harness's
    convex_from_mesh) and a coal.ComputeDistance per queried pair."""

    def __init__(self, scene: Scene):
        import coal

        from harness.engines.coal_engine import convex_from_mesh

        self.scene = scene
        # ComputeDistance keeps raw pointers to the geometries: keep them alive with it
        self.geoms = [convex_from_mesh(b.hull.vertices, b.hull.faces) for b in scene.bodies]
        self.compute = [coal.ComputeDistance(self.geoms[a], self.geoms[b]) for a, b in scene.pairs]
        self.request = coal.DistanceRequest()
        self.request.enable_signed_distance = True
        self.request.gjk_tolerance = COAL_GJK_TOL
        self._result = coal.DistanceResult()
        self._tfs = [coal.Transform3s() for _ in scene.bodies]

    def distances(self, q) -> np.ndarray:
        """(npairs,) coal's signed distance (m; negative = penetration) at configuration q."""
        for tf, pose in zip(self._tfs, self.scene.body_poses(q)):
            tf.setRotation(pose[:3, :3])
            tf.setTranslation(pose[:3, 3])
        out = np.empty(len(self.compute))
        for k, ((a, b), compute) in enumerate(zip(self.scene.pairs, self.compute)):
            self._result.clear()
            out[k] = compute(self._tfs[a], self._tfs[b], self.request, self._result)
        return out


def check_against_coal(scene: Scene, q, result, coal_d: np.ndarray, where: str) -> dict:
    """Distances, statuses and witness points of one PCH result against coal's distances at q;
    returns the worst errors seen."""
    expected = np.maximum(coal_d, 0.0)
    err = np.abs(result.distance - expected)
    k = int(np.argmax(err))
    assert err[k] <= DIST_TOL, (where, scene.pair_names[k], result.distance[k], coal_d[k], q.tolist())
    overlapping = result.status == "overlapping"
    assert (coal_d[overlapping] <= DIST_TOL).all(), (where, np.flatnonzero(overlapping & (coal_d > DIST_TOL)))
    assert overlapping[coal_d < -DIST_TOL].all(), (where, np.flatnonzero(~overlapping & (coal_d < -DIST_TOL)))
    assert set(result.status) <= {"separated", "touching", "overlapping"}, (where, set(result.status))
    assert (result.distance[overlapping] == 0.0).all()

    # witness points: |pA - pB| = d, each on its hull's boundary (hull frame, qhull planes)
    sep = np.flatnonzero(result.status == "separated")
    pa, pb = result.point_a[sep], result.point_b[sep]
    gap = np.linalg.norm(pb - pa, axis=1)
    gap_err = np.abs(gap - result.distance[sep])
    assert gap_err.max(initial=0.0) <= DIST_TOL, (where, scene.pair_names[sep[np.argmax(gap_err)]])
    normal_err = np.abs(result.normal[sep] - (pb - pa) / gap[:, None]).max(initial=0.0)
    assert normal_err <= 1e-9, (where, normal_err)
    poses = scene.body_poses(q)
    worst_surface = 0.0
    for side, points in ((0, pa), (1, pb)):
        owners = scene.pairs[sep, side]
        for body in np.unique(owners):
            mine = owners == body
            pose = poses[body]
            local = (points[mine] - pose[:3, 3]) @ pose[:3, :3]  # world -> hull frame
            s = np.abs(scene.bodies[body].hull.signed_distance_to_surface(local))
            k = sep[mine][np.argmax(s)]
            assert s.max() <= DIST_TOL, (where, scene.pair_names[k], "AB"[side], s.max())
            worst_surface = max(worst_surface, float(s.max()))
    return {"distance": float(err.max()), "gap": float(gap_err.max(initial=0.0)), "surface": worst_surface,
            "separated": len(sep), "overlapping": int(overlapping.sum())}


# ---------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def jvrc1():
    require_shared_datasets()
    return ROBOTS["jvrc1"]


@pytest.fixture(scope="module")
def jvrc1_pch(jvrc1) -> Scene:
    return Scene.from_urdf(jvrc1.urdf, convex_dir=jvrc1.convex_dir, policy="pch")


@pytest.fixture(scope="module")
def jvrc1_auto(jvrc1) -> Scene:
    return Scene.from_urdf(jvrc1.urdf, convex_dir=jvrc1.convex_dir, policy="auto")


@pytest.fixture(scope="module")
def jvrc1_configurations(jvrc1_pch) -> np.ndarray:
    rng = np.random.default_rng(CONFIG_SEED)
    return np.array([jvrc1_pch.random_configuration(rng) for _ in range(N_CONFIGURATIONS)])


@pytest.fixture(scope="module")
def jvrc1_coal(jvrc1_pch, jvrc1_configurations) -> np.ndarray:
    """(N_CONFIGURATIONS, npairs) coal's signed distances of the JVRC-1 hull pairs."""
    pytest.importorskip("coal")
    oracle = CoalScene(jvrc1_pch)
    return np.array([oracle.distances(q) for q in jvrc1_configurations])


@pytest.fixture(scope="module")
def jvrc1_trajectory(jvrc1_pch) -> np.ndarray:
    return smooth_trajectory(jvrc1_pch.model, TRAJECTORY_STEPS, TRAJECTORY_SEED)


@pytest.fixture(scope="module", params=["kuka_iiwa", "panda"])
def arm(request) -> tuple[str, Scene]:
    files = ROBOTS[request.param]
    return request.param, Scene.from_urdf(files.urdf, mesh_root=files.mesh_root, policy="pch")


# ---------------------------------------------------------------- 1. bodies and pairs


def test_jvrc1_has_35_bodies_and_561_pairs_595_without_adjacency_skipping(jvrc1, jvrc1_pch):
    bodies, _ = urdf_bodies(jvrc1.urdf)
    assert len(bodies) == JVRC1_BODIES == len(jvrc1_pch.bodies)
    assert sorted(jvrc1_pch.body_names) == sorted(name for name, _ in bodies)
    for body in jvrc1_pch.bodies:  # each body rides on its own link, named after the mesh's hull file
        assert jvrc1_pch.model.link_names[body.link] == body.name
        assert Path(body.source).parent == Path(jvrc1.convex_dir) and body.source.endswith("-ch.txt")

    # the bodies form a tree once body-less links are collapsed: every body but the root one
    # (PELVIS_S) has exactly one adjacent ancestor, so adjacency skipping drops 34 pairs
    adjacent = urdf_adjacent_links(jvrc1.urdf)
    assert len(adjacent) == JVRC1_BODIES - 1
    assert frozenset(("R_HIP_R_S", "PELVIS_S")) in adjacent  # across the body-less R_HIP_P_S
    expected = urdf_pairs(jvrc1.urdf, skip_adjacent=True)
    assert len(expected) == JVRC1_BODIES * (JVRC1_BODIES - 1) // 2 - (JVRC1_BODIES - 1) == 561
    assert len(jvrc1_pch.pairs) == 561
    assert {frozenset(p) for p in jvrc1_pch.pair_names} == expected
    assert (jvrc1_pch.pairs[:, 0] < jvrc1_pch.pairs[:, 1]).all()

    every = Scene.from_urdf(jvrc1.urdf, convex_dir=jvrc1.convex_dir, policy="pch", skip_adjacent=False)
    assert len(every.pairs) == 595 == JVRC1_BODIES * (JVRC1_BODIES - 1) // 2
    assert {frozenset(p) for p in every.pair_names} == urdf_pairs(jvrc1.urdf, skip_adjacent=False)

    # explicit skips come off the list, in either order
    skipped = Scene.from_urdf(jvrc1.urdf, convex_dir=jvrc1.convex_dir, policy="pch",
                              skip=[("L_KNEE_S", "R_KNEE_S"), ("NECK_P_S", "PELVIS_S")])
    assert {frozenset(p) for p in skipped.pair_names} == expected - {frozenset(("L_KNEE_S", "R_KNEE_S")),
                                                                     frozenset(("NECK_P_S", "PELVIS_S"))}


# ---------------------------------------------------------------- 2. PCH distances against coal


@pytest.mark.engines
def test_jvrc1_pch_distances_and_witness_points_match_coal(jvrc1_pch, jvrc1_configurations, jvrc1_coal):
    assert jvrc1_pch.kind_counts() == {"pch-pch": 561}
    separated = overlapping = 0
    for n, (q, coal_d) in enumerate(zip(jvrc1_configurations, jvrc1_coal)):
        result = jvrc1_pch.distances(q, coherent=False)
        stats = check_against_coal(jvrc1_pch, q, result, coal_d, f"configuration {n}")
        separated += stats["separated"]
        overlapping += stats["overlapping"]
    # random humanoid poses: mostly separated pairs, some interpenetrating limbs
    assert separated > 0.9 * N_CONFIGURATIONS * 561 and overlapping > 0


# ---------------------------------------------------------------- 3. the auto policy


def test_jvrc1_auto_puts_the_stp_bv_on_the_side_with_fewer_stp_features(jvrc1_auto):
    assert all(b.policy == "auto" and b.stp is not None and b.stp_features > 0 for b in jvrc1_auto.bodies)
    assert all(b.stp_features == b.stp.n_small + b.stp.n_big + b.stp.n_tori for b in jvrc1_auto.bodies)
    for (a, b), sides in zip(jvrc1_auto.pairs, jvrc1_auto.pair_kinds):
        fa, fb = jvrc1_auto.bodies[a].stp_features, jvrc1_auto.bodies[b].stp_features
        assert sides == (("stp", "pch") if fa <= fb else ("pch", "stp")), (jvrc1_auto.bodies[a].name, fa, fb)
    counts = jvrc1_auto.kind_counts()
    assert sum(counts.values()) == len(jvrc1_auto.pairs) == 561
    assert counts == {"stp-pch": 561}


def test_jvrc1_auto_stores_shared_hulls_once_and_each_pair_matches_a_lone_query(jvrc1_auto, jvrc1_configurations):
    """A body whose STP-BV's underlying hull is its PCH keeps one copy (the packing check reads every
    slot's data back); the scene's pair distances equal lone spq.distance queries of the same shapes."""
    slots = {(i, bv) for pair, kinds in zip(jvrc1_auto.pairs, jvrc1_auto.pair_kinds) for i, bv in zip(pair, kinds)}
    # the scene's pools hold the sparse cube maps (Scene's packing): count those
    own = sum(len(Scene._volume(jvrc1_auto.bodies[i], bv)[0].kernel_data(dense=False).idata) for i, bv in slots)
    assert len(jvrc1_auto._ipool) < own - 10_000  # some hulls are stored once
    q = jvrc1_configurations[0]
    result = jvrc1_auto.distances(q, coherent=False)
    poses = jvrc1_auto.body_poses(q)
    for k in range(0, len(jvrc1_auto.pairs), 7):
        (a, b), (sa, sb) = jvrc1_auto.pairs[k], jvrc1_auto.pair_kinds[k]
        A, B = (Scene._volume(jvrc1_auto.bodies[i], bv)[0] for i, bv in ((a, sa), (b, sb)))
        lone = spq.distance(A, B, poses[a], poses[b])
        assert abs(lone.distance - result.distance[k]) <= 1e-9, (jvrc1_auto.pair_names[k], lone.distance)


@pytest.mark.engines
def test_jvrc1_auto_distances_are_at_most_the_pch_distance_less_r(jvrc1_auto, jvrc1_configurations, jvrc1_coal):
    """An STP-BV contains its hull grown by r, so d_auto <= max(0, d_PCH - r) (d_PCH from coal)."""
    r = jvrc1_auto.r
    below = 0
    for n, (q, coal_d) in enumerate(zip(jvrc1_configurations, jvrc1_coal)):
        result = jvrc1_auto.distances(q, coherent=False)
        assert not result.pruned.any()
        bound = np.maximum(0.0, coal_d - r)
        excess = result.distance - bound
        k = int(np.argmax(excess))
        assert excess[k] <= BOUND_SLACK, (n, jvrc1_auto.pair_names[k], result.distance[k], coal_d[k], q.tolist())
        assert (result.distance >= 0.0).all()
        assert ((result.status == "overlapping") == (result.distance == 0.0)).all()
        below += int((excess < -1e-6).sum())
    assert below > 0  # the STP-BVs bulge beyond the r-grown hulls: the bound is not an identity


# ---------------------------------------------------------------- 4. warm starts


@pytest.mark.parametrize("policy", ["auto", "pch"])
def test_coherent_distances_along_a_trajectory_equal_cold_ones(policy, jvrc1_auto, jvrc1_pch, jvrc1_trajectory):
    scene = {"auto": jvrc1_auto, "pch": jvrc1_pch}[policy]
    scene.reset()
    warm = [scene.distances(q, coherent=True) for q in jvrc1_trajectory]
    cold = [scene.distances(q, coherent=False) for q in jvrc1_trajectory]
    worst = max(np.abs(w.distance - c.distance).max() for w, c in zip(warm, cold))
    assert worst <= COHERENT_TOL, worst
    for step, (w, c) in enumerate(zip(warm, cold)):
        assert (w.status == c.status).all(), step
    # the warm starts were taken: fewer GJK iterations in all
    assert sum(w.iterations.sum() for w in warm) < sum(c.iterations.sum() for c in cold)
    # one compiled call over the whole trajectory gives the same warm-started results
    scene.reset()
    many = scene.distances_many(jvrc1_trajectory, coherent=True)
    np.testing.assert_allclose(many[:, :, OUT_DISTANCE], np.array([w.distance for w in warm]), rtol=0,
                               atol=COHERENT_TOL)
    # and into a caller's array, which it returns, with the same results
    scene.reset()
    buffer = np.full_like(many, np.nan)
    assert scene.distances_many(jvrc1_trajectory, coherent=True, out=buffer) is buffer
    np.testing.assert_array_equal(buffer, many)
    scene.reset()


# ---------------------------------------------------------------- 5. pruning


@pytest.mark.engines
def test_pruned_pairs_are_farther_than_the_threshold_and_the_rest_unchanged(jvrc1_pch, jvrc1_configurations,
                                                                           jvrc1_coal):
    pruned_total = kept_total = 0
    for n, (q, coal_d) in enumerate(zip(jvrc1_configurations, jvrc1_coal)):
        full = jvrc1_pch.distances(q, coherent=False)
        pruned = jvrc1_pch.distances(q, coherent=False, prune=PRUNE)
        p = pruned.pruned
        assert ((pruned.status == "pruned") == p).all()
        # bounding spheres: a lower bound on the true distance, above the threshold
        assert (coal_d[p] > PRUNE).all(), (n, [jvrc1_pch.pair_names[k] for k in np.flatnonzero(p & (coal_d <= PRUNE))])
        assert (pruned.lower_bound[p] > PRUNE).all()
        assert (pruned.lower_bound[p] <= coal_d[p] + 1e-12).all()
        assert np.isinf(pruned.distance[p]).all()
        assert not p[coal_d <= PRUNE].any()
        np.testing.assert_array_equal(pruned.distance[~p], full.distance[~p])
        assert (pruned.status[~p] == full.status[~p]).all()
        pruned_total += int(p.sum())
        kept_total += int((~p).sum())
    assert pruned_total > 0 and kept_total > 0, (pruned_total, kept_total)


@pytest.mark.engines
def test_a_result_keeps_its_values_after_later_calls(jvrc1_pch, jvrc1_configurations, jvrc1_coal):
    """A SceneDistances' points and normals are views into its sweep's rows: a later call (or a
    batch from distances_many) must not write into them. Each result is checked against coal's
    distance at its own configuration after every call has run."""
    results = [jvrc1_pch.distances(q, coherent=False) for q in jvrc1_configurations[:3]]
    kept = [(r.point_a.copy(), r.point_b.copy(), r.normal.copy(), r.status.copy()) for r in results]
    jvrc1_pch.distances_many(jvrc1_configurations[3:6])
    jvrc1_pch.distances(jvrc1_configurations[6], coherent=False)
    for r, (pa, pb, n, status), coal_d in zip(results, kept, jvrc1_coal):
        np.testing.assert_array_equal(r.point_a, pa)
        np.testing.assert_array_equal(r.point_b, pb)
        np.testing.assert_array_equal(r.normal, n)
        assert (r.status == status).all()
        sep = r.status == "separated"
        assert sep.sum() > 100, int(sep.sum())  # coal judges most pairs of each kept result
        np.testing.assert_allclose(np.linalg.norm(r.point_b[sep] - r.point_a[sep], axis=1), coal_d[sep], atol=1e-6)


def test_pruning_with_warm_starts_along_a_trajectory_keeps_exact_distances(jvrc1_auto, jvrc1_trajectory):
    """A pair that is pruned for a while and comes back must not reuse a stale warm start wrongly."""
    jvrc1_auto.reset()
    flips = 0
    previous = None
    for step, q in enumerate(jvrc1_trajectory):
        cold = jvrc1_auto.distances(q, coherent=False)
        warm = jvrc1_auto.distances(q, coherent=True, prune=PRUNE)
        p = warm.pruned
        assert (cold.distance[p] > PRUNE).all(), step
        assert (warm.lower_bound[p] <= cold.distance[p] + 1e-12).all(), step
        np.testing.assert_allclose(warm.distance[~p], cold.distance[~p], rtol=0, atol=COHERENT_TOL)
        if previous is not None:
            flips += int((previous & ~p).sum())
        previous = p
    jvrc1_auto.reset()
    assert flips > 0  # some pairs were pruned, then queried again


# ---------------------------------------------------------------- 6. joint-space gradients


def fd_gradients(scene: Scene, q: np.ndarray, h: float = FD_STEP) -> np.ndarray:
    """(npairs, ndof) central differences of every pair's distance in each joint value."""
    out = np.empty((len(scene.pairs), len(q)))
    for j in range(len(q)):
        e = np.zeros_like(q)
        e[j] = h
        out[:, j] = (scene.distances(q + e, coherent=False).distance
                     - scene.distances(q - e, coherent=False).distance) / (2.0 * h)
    return out


def check_gradients(scene: Scene, seed: int) -> dict:
    """distance_gradient of every separated pair against central differences, at a few
    configurations (kept FD_STEP away from the limits); returns how many gradients were checked and
    which degrees of freedom they exercised."""
    m = scene.model
    rng = np.random.default_rng(seed)
    checked, dofs_seen = 0, set()
    for c in range(N_GRADIENT_CONFIGURATIONS):
        q = np.clip(scene.random_configuration(rng), m.lower + 2 * FD_STEP, m.upper - 2 * FD_STEP)
        result = scene.distances(q, coherent=False)
        fd = fd_gradients(scene, q)
        for k in np.flatnonzero(result.status == "separated"):
            g = scene.distance_gradient(q, result, k)
            scale = np.abs(fd[k]).max()
            err = np.abs(g - fd[k])
            assert (err <= GRAD_RTOL * scale + GRAD_ATOL).all(), (
                c, scene.pair_names[k], result.distance[k], g.tolist(), fd[k].tolist())
            dofs_seen |= set(np.flatnonzero(np.abs(fd[k]) > 1e-3).tolist())
            checked += 1
        for k in np.flatnonzero(result.status == "overlapping"):
            assert np.isnan(scene.distance_gradient(q, result, k)).all()
    return {"checked": checked, "dofs": dofs_seen}


@pytest.fixture(scope="module")
def jvrc1_auto_tight(jvrc1) -> Scene:
    return Scene.from_urdf(jvrc1.urdf, convex_dir=jvrc1.convex_dir, policy="auto", **TIGHT)


def test_jvrc1_distance_gradients_match_finite_differences_with_mimic_joints(jvrc1_auto_tight):
    scene = jvrc1_auto_tight
    m = scene.model
    assert m.ndof == 34
    seen = check_gradients(scene, seed=5)
    assert seen["checked"] > 0.9 * N_GRADIENT_CONFIGURATIONS * len(scene.pairs)
    assert seen["dofs"] == set(range(m.ndof))  # every joint moved some pair's distance
    # the thumb dof drives six finger links with multipliers 1, 3, -1, -3, -1, -3: check one
    # pair per finger link directly, in a pose where each is clear of the pelvis
    thumb = m.joint_names.index("R_UTHUMB")
    rng = np.random.default_rng(8)
    q = np.clip(scene.random_configuration(rng), m.lower + 2 * FD_STEP, m.upper - 2 * FD_STEP)
    result = scene.distances(q, coherent=False)
    fd = fd_gradients(scene, q)
    for finger, multiplier in [("R_UTHUMB_S", 1), ("R_LTHUMB_S", 3), ("R_UINDEX_S", -1), ("R_LINDEX_S", -3),
                               ("R_ULITTLE_S", -1), ("R_LLITTLE_S", -3)]:
        assert m.q_multiplier[m.link_index(finger)] == multiplier and m.q_index[m.link_index(finger)] == thumb
        k = scene.pair_names.index(("PELVIS_S", finger))
        assert result.status[k] == "separated", (finger, result.distance[k])
        g = scene.distance_gradient(q, result, k)
        assert abs(fd[k, thumb]) > 1e-4, (finger, fd[k, thumb])
        np.testing.assert_allclose(g, fd[k], rtol=0, atol=GRAD_RTOL * np.abs(fd[k]).max() + GRAD_ATOL)


def test_panda_distance_gradients_match_finite_differences_with_prismatic_fingers():
    files = ROBOTS["panda"]
    scene = Scene.from_urdf(files.urdf, mesh_root=files.mesh_root, policy="auto", **TIGHT)
    fingers = scene.model.joint_names.index("panda_finger_joint1")
    seen = check_gradients(scene, seed=3)
    assert seen["checked"] > 0.9 * N_GRADIENT_CONFIGURATIONS * len(scene.pairs)
    assert fingers in seen["dofs"]  # a prismatic joint (both fingers, one mimicking the other)
    assert seen["dofs"] == set(range(scene.model.ndof))


def test_gradient_of_a_pruned_pair_is_nan(jvrc1_auto, jvrc1_configurations):
    q = jvrc1_configurations[0]
    result = jvrc1_auto.distances(q, coherent=False, prune=PRUNE)
    k = int(np.flatnonzero(result.pruned)[0])
    assert np.isnan(jvrc1_auto.distance_gradient(q, result, k)).all()


# ---------------------------------------------------------------- 7. KUKA iiwa and Franka Panda


@pytest.mark.engines
def test_arm_scenes_load_with_their_bodies_and_match_coal(arm):
    name, scene = arm
    files = ROBOTS[name]
    bodies, _ = urdf_bodies(files.urdf)
    assert len(scene.bodies) == ARM_BODIES[name] == len(bodies)
    assert sorted(scene.body_names) == sorted(n for n, _ in bodies)
    expected = urdf_pairs(files.urdf, skip_adjacent=True)
    assert len(scene.pairs) == {"kuka_iiwa": 21, "panda": 45}[name] == len(expected)
    assert {frozenset(p) for p in scene.pair_names} == expected
    for body in scene.bodies:  # hulls come from the collision meshes shipped with pybullet
        assert Path(body.source).is_file() and Path(body.source).suffix in {".stl", ".obj"}

    oracle = CoalScene(scene)
    rng = np.random.default_rng(CONFIG_SEED)
    for n in range(20):
        q = scene.random_configuration(rng)
        check_against_coal(scene, q, scene.distances(q, coherent=False), oracle.distances(q), f"{name} {n}")


def test_arm_hulls_are_the_hulls_of_their_meshes(arm):
    """Every mesh vertex inside the body's hull (to 1e-9 m) and every hull vertex a mesh vertex."""
    import trimesh

    _, scene = arm
    for body in scene.bodies:
        mesh = trimesh.load(body.source, force="mesh")
        points = np.asarray(mesh.vertices, dtype=np.float64)
        assert body.hull.signed_distance_to_surface(points).max() <= 1e-9, body.name
        d = np.abs(body.hull.vertices[:, None, :] - points[None, :, :]).max(axis=2).min(axis=1)
        assert d.max() <= 1e-12, body.name


# ---------------------------------------------------------------- 8. bad input

TINY_URDF = """<robot name="tiny">
  <link name="base"><collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision></link>
  <link name="arm"><collision><origin xyz="0 0 0.25"/>
    <geometry><box size="0.05 0.05 0.4"/></geometry></collision></link>
  <link name="tip"><collision><geometry>{tip}</geometry></collision></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="arm"/><origin xyz="0 0 0.05"/>
    <axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5" effort="1" velocity="1"/></joint>
  <joint name="elbow" type="revolute"><parent link="arm"/><child link="tip"/><origin xyz="0 0 0.45"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
</robot>
"""
TIP_SPHERE = '<sphere radius="0.04"/>'


@pytest.fixture
def tiny(tmp_path) -> Path:
    path = tmp_path / "tiny.urdf"
    path.write_text(TINY_URDF.format(tip=TIP_SPHERE))
    return path


def test_a_mesh_without_a_hull_file_or_mesh_file_raises(tmp_path):
    path = tmp_path / "meshy.urdf"
    path.write_text(TINY_URDF.format(tip='<mesh filename="package://tiny/meshes/claw.dae"/>'))
    empty = tmp_path / "convex"
    empty.mkdir()
    with pytest.raises(ValueError, match=r"link 'tip' names mesh 'package://tiny/meshes/claw.dae' but .*claw-ch\.txt "
                                         r"does not exist"):
        Scene.from_urdf(path, convex_dir=empty)
    with pytest.raises(ValueError, match=r"link 'tip' names mesh .*claw.dae.*, not found at .*give mesh_root"):
        Scene.from_urdf(path)
    path.write_text(TINY_URDF.format(tip='<mesh filename="meshes/claw.stl"/>'))
    with pytest.raises(ValueError, match=r"not found at .*meshes/claw\.stl"):
        Scene.from_urdf(path)


def test_bad_configurations_raise_naming_the_joint(tiny):
    scene = Scene.from_urdf(tiny, policy="pch")
    assert len(scene.bodies) == 3 and scene.pair_names == [("base", "tip")]
    q = np.array([0.3, -0.4])
    result = scene.distances(q)
    for bad, message in [
        ([0.3], r"shape \(2,\)"),
        ([0.3, -0.4, 0.0], r"shape \(2,\)"),
        ([np.nan, -0.4], "'shoulder'.*must be finite"),
        ([0.3, np.inf], "'elbow'.*must be finite"),
        ([0.3, 2.5], r"value 2\.5 of joint 'elbow' is outside its limits \[-2\.0, 2\.0\]"),
        ([-1.6, 0.0], "'shoulder' is outside its limits"),
    ]:
        with pytest.raises(ValueError, match=message):
            scene.distances(bad)
        with pytest.raises(ValueError, match=message):
            scene.distance_gradient(bad, result, 0)
    with pytest.raises(ValueError, match="configurations 1: value 2.5 of joint 'elbow'"):
        scene.distances_many([q, [0.3, 2.5]])
    shape = (1, len(scene.pairs), OUT_SIZE)
    strided = np.zeros(shape[:2] + (2 * OUT_SIZE,))[:, :, ::2]
    for out in (np.zeros((2,) + shape[1:]), np.zeros(shape, dtype=np.float32), strided, [[[0.0] * OUT_SIZE]]):
        with pytest.raises(ValueError, match=r"out must be a writeable C-contiguous float64 array of shape \(1, "):
            scene.distances_many([q], out=out)


def test_bad_policies_and_prune_raise(tiny):
    with pytest.raises(ValueError, match=r"unknown scene policy 'convex'; choose one of \['pch', 'stp', 'cse', "
                                         r"'auto', 'stp-both'\]"):
        Scene.from_urdf(tiny, policy="convex")
    with pytest.raises(ValueError, match=r"unknown policy 'sphere'; choose one of \['pch', 'stp', 'cse', 'auto'\]"):
        Scene.from_urdf(tiny, policies={"arm": "sphere"})
    with pytest.raises(ValueError, match="unknown policy 'stp-both'"):  # scene-wide only
        Scene.from_urdf(tiny, policies={"arm": "stp-both"})
    with pytest.raises(ValueError, match=r"policies name unknown bodies \['hand'\]"):
        Scene.from_urdf(tiny, policies={"hand": "pch"})
    scene = Scene.from_urdf(tiny, policy="pch", policies={"tip": "stp"})
    assert scene.pair_kinds == [("pch", "stp")]
    q = np.zeros(2)
    for prune in (-0.1, np.nan, np.inf):
        with pytest.raises(ValueError, match="prune must be None or a finite distance >= 0"):
            scene.distances(q, prune=prune)
        with pytest.raises(ValueError, match="prune must be None or a finite distance >= 0"):
            scene.distances_many([q], prune=prune)
