"""`spq bench robot`: whole-body self-distance of a robot, per configuration, against coal and python-fcl.

Three measurements on one robot scene (JVRC-1 by default, every non-adjacent pair of its bodies),
after checking spq's forward kinematics against pybullet's on the first random configurations:

- spq's all-pairs time per configuration for each bounding-volume policy, cold on random
  configurations and with per-pair warm starts along a smooth trajectory, with and without
  bounding-sphere pruning (all pairs is the headline). Each figure is timed in blocks of
  ``TIMING_BLOCK`` consecutive configurations: every run goes through all configurations in order,
  one compiled call per block (warm starts carry across blocks, as in one call), and each block
  keeps its fastest of ``repeats`` runs; the figure is their sum over the number of configurations.
  A slow spell of a shared machine then has to span every run of a block to count, where a best of
  whole runs kept it whenever it lasted one run (measured: 0.47 to 0.70 ms for the same code). The
  table goes through all its rows ``passes`` times and each row keeps its least time, since a spell
  can outlast the runs of one row (coherent auto, JVRC-1: 0.140 and 0.225 ms in two single-pass
  runs of the same code; one row's runs take about half a second).
- coal and python-fcl on the same PCH pairs at the same random configurations, from Python (one call
  per pair), with forward kinematics done beforehand and not timed (which favours them), each pair's
  loop the fastest of ``repeats``; their distances are compared with spq's PCH distances.
- continuity along the trajectory: the distance gradient (w.r.t. the joints) of the closest pair, for
  ``auto`` (an STP-BV on one side of every pair) and ``pch`` (PCH-PCH). The steps with the largest
  gradient change (where the closest pair stays the same: when it changes, the minimum's gradient
  jumps for any bounding volume) are bisected: a jump keeps its size down to a 1/1024 sub-step, a
  continuous change shrinks with it. PCH-PCH gradients jump where the witness points jump across a
  face or an edge (parallel features); with an STP-BV on one side they cannot.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from harness.suites.bench.timing import best_time, blocked_times
from harness.workloads.robot_poses import random_configurations, smooth_trajectory
from spq.kernels.gjk import FAILED, OUT_DISTANCE, OUT_ITERATIONS, OUT_SIZE, OUT_STATUS, OVERLAPPING, SEPARATED
from spq.scene import Scene

JUMP_CANDIDATES = 20  # the steps with the largest relative gradient change, tested by bisection
BISECTIONS = 10  # halvings of a candidate step: a jump keeps its size, a continuous change shrinks ~1000x
JUMP_RESIDUAL = 0.25  # a candidate whose change stays over this fraction of itself after bisection is a jump
CONTINUITY_ZOOM = 10  # the continuity track samples the trajectory this many times finer (steps of ~0.01 rad)
MOVING_PAIR_M = 1e-3  # m: pairs whose distance varies less along the trajectory are left out (nearly rigid)
POLICIES = ("auto", "pch", "stp-both")
TARGET_COLD_MS, TARGET_COHERENT_MS = 0.5, 0.25  # issue 6's targets for auto, JVRC-1 (drawn on the chart)
FK_CONFIGURATIONS = 100  # random configurations whose link poses are checked against pybullet
TIMING_BLOCK = 50  # configurations per timed call (about 25 ms cold): see best_run


@dataclass
class RobotBenchConfig:
    robot: str = "jvrc1"
    configurations: int = 1000
    steps: int = 1000
    seed: int = 0
    policies: tuple[str, ...] = POLICIES
    prune: float = 0.05  # m: bounding-sphere pruning threshold of the "pruned" rows
    repeats: int = 3
    passes: int = 2  # times the scene table goes through all its rows; each row keeps its least time
    engines: list[str] = field(default_factory=lambda: ["coal", "fcl"])
    engine_configurations: int | None = None  # configurations the engines run (None: all)
    r: float = 0.005
    R: float = 2.0
    skip: list[tuple[str, str]] = field(default_factory=list)
    workers: int = 1  # > 1: the cold rows also on this many threads (spq.workers), beside one thread's


def load_scene(config: RobotBenchConfig, policy: str, scene_class=Scene) -> Scene:
    """config.robot's scene under ``policy``; scene_class: another version's Scene (a same-process A/B)."""
    from datasets.robots import robot_files

    files = robot_files(config.robot)
    return scene_class.from_urdf(files.urdf, convex_dir=files.convex_dir, mesh_root=files.mesh_root,
                                 policy=policy, r=config.r, R=config.R, skip=config.skip)


def result_array(configurations: int, pairs: int, size: int = OUT_SIZE) -> np.ndarray:
    """A zeroed (configurations, pairs, size) result array whose pages are written here, not in a
    timed call: np.zeros maps fresh pages lazily, and a first run into them paid the page faults
    (JVRC-1, 1000 configurations, 63 MB: pch 0.22 -> 0.33 ms per configuration in a single run).
    size: the result row's length (OUT_SIZE; another version's in a same-process A/B)."""
    out = np.empty((configurations, pairs, size))
    out.fill(0.0)
    return out


def best_run(scene: Scene, qs: np.ndarray, coherent: bool, prune: float | None, repeats: int,
             block: int = TIMING_BLOCK, workers: int = 1):
    """(seconds, raw results) over qs: the sum, over blocks of ``block`` consecutive configurations,
    of each block's fastest of ``repeats`` runs. Every run starts from reset warm starts and goes
    through all of qs in order, one compiled call per block, so a block's warm starts are the ones
    a single call would have.

    The calls write into one result array, allocated and touched before the timing, as a control
    loop would: a fresh array's page faults are the allocator's cost, not the queries'. workers: threads
    per call (spq.workers; a coherent run stays on one)."""
    if repeats < 1 or block < 1:
        raise ValueError(f"repeats and block must be >= 1, got {repeats} and {block}")
    scene.reset()
    scene.distances_many(qs[:2], coherent=coherent, prune=prune)  # compile / load the kernels
    out = result_array(len(qs), len(scene.pairs))
    run = lambda q, o: scene.distances_many(q, coherent=coherent, prune=prune, out=o, workers=workers)  # noqa: E731
    # one job: no other evicts its data, and an untimed call would advance the warm starts
    seconds, _ = blocked_times({"run": (run, qs, out)}, repeats, block, before_round=scene.reset, warm=False)["run"]
    return seconds, out


def signed_rows(scenes: dict, qs: np.ndarray, repeats: int, block: int = TIMING_BLOCK) -> pd.DataFrame:
    """Per policy, every pair cold over qs, unsigned and signed=True timed in turn within each round
    (so the ratio between them is fair on a shared machine), with the deepest pair per configuration
    (the least signed distance) and the failures of the signed run."""
    rows = []
    for policy, scene in scenes.items():
        outs = {signed: result_array(len(qs), len(scene.pairs)) for signed in (False, True)}
        for signed in outs:
            scene.distances_many(qs[:2], signed=signed)  # compile / load the kernels
        jobs = {signed: (lambda q, o, signed=signed, scene=scene: scene.distances_many(q, signed=signed, out=o),
                         qs, out) for signed, out in outs.items()}
        seconds = {signed: timed[0] for signed, timed in blocked_times(jobs, repeats, block).items()}
        signed_out = outs[True]
        deepest = signed_out[:, :, OUT_DISTANCE].min(axis=1)
        status = signed_out[:, :, OUT_STATUS]
        unsigned_ms, signed_ms = (1e3 * seconds[s] / len(qs) for s in (False, True))
        rows.append({"policy": policy, "configurations": len(qs), "pairs": len(scene.pairs),
                     "unsigned_ms_per_config": unsigned_ms, "signed_ms_per_config": signed_ms,
                     "signed_over_unsigned": signed_ms / unsigned_ms,
                     "configs_with_overlap": int((deepest < 0).sum()),
                     "mean_overlapping_pairs": float((status == OVERLAPPING).sum(axis=1).mean()),
                     "median_deepest_overlap_m": float(np.median(-deepest[deepest < 0])) if (deepest < 0).any()
                     else 0.0,
                     "max_depth_m": float(max(0.0, -deepest.min())),
                     "signed_failed": int((status == 3).sum())})
    return pd.DataFrame(rows)


def summary_row(scene: Scene, policy: str, source: str, coherent: bool, prune, seconds: float,
                out: np.ndarray) -> dict:
    n, npairs = out.shape[0], out.shape[1]
    status = out[:, :, OUT_STATUS]
    dist = np.where(status == OVERLAPPING, 0.0, out[:, :, OUT_DISTANCE])
    per_config_min = dist.min(axis=1)
    separated_min = np.where(status == SEPARATED, dist, np.inf).min(axis=1)
    computed = status >= 0
    kinds = scene.kind_counts()
    return {
        "policy": policy, "pairs_by_bv": " ".join(f"{k} {v}" for k, v in kinds.items()),
        "configurations": source, "mode": "coherent" if coherent else "cold",
        "pruning_m": prune if prune else 0.0, "pairs": npairs,
        "ms_per_config": 1e3 * seconds / n, "pairs_per_s": n * npairs / seconds,
        "pairs_computed_pct": 100.0 * computed.mean(),
        "mean_iterations": float(out[:, :, OUT_ITERATIONS][computed].mean()),
        "median_min_distance_m": float(np.median(per_config_min)),
        "median_min_separated_m": float(np.median(separated_min)),
        "configs_with_overlap": int((status == OVERLAPPING).any(axis=1).sum()),
        "mean_overlapping_pairs": float((status == OVERLAPPING).sum(axis=1).mean()),
        "failed": int((status == 3).sum()),
    }


def scene_table(config: RobotBenchConfig, randoms: np.ndarray, trajectory: np.ndarray, progress: bool):
    """spq rows for every policy x (random cold, trajectory coherent) x (all pairs, pruned); also
    returns the scenes and the cold PCH and auto results on ``randoms`` for the engines and figures.
    config.workers > 1 adds the cold rows on that many threads (mode "cold N workers")."""
    from tqdm import tqdm

    if config.passes < 1:
        raise ValueError(f"passes must be at least 1, got {config.passes}")
    rows, scenes, results = {}, {}, {}
    jobs = [(p, src, coh, pr, 1) for p in config.policies for src, coh in (("random", False), ("trajectory", True))
            for pr in (None, config.prune)]
    if config.workers > 1:
        jobs += [(p, "random", False, pr, config.workers) for p in config.policies for pr in (None, config.prune)]
    bar = tqdm(total=len(jobs) * config.passes, desc="bench robot", unit="run", disable=not progress)
    for _ in range(config.passes):
        for job in jobs:
            policy, source, coherent, prune, workers = job
            if policy not in scenes:
                scenes[policy] = load_scene(config, policy)
            scene = scenes[policy]
            qs = randoms if source == "random" else trajectory
            seconds, out = best_run(scene, qs, coherent, prune, config.repeats, workers=workers)
            bar.update(1)
            if job in rows and seconds >= rows[job][0]:
                continue  # (a later pass gives the same results: each run starts from reset warm starts)
            row = summary_row(scene, policy, source, coherent, prune, seconds, out)
            if workers > 1:
                row["mode"] = f"cold {workers} workers"
            rows[job] = (seconds, row)
            if source == "random" and prune is None and workers == 1:
                results[policy] = out
    bar.close()
    return pd.DataFrame([row for _, row in rows.values()]), scenes, results


def engine_table(config: RobotBenchConfig, scene: Scene, qs: np.ndarray, spq_out: np.ndarray, spq_seconds: float,
                 progress: bool) -> pd.DataFrame:
    """coal and fcl over every pair of the scene (their PCHs) at qs, one Python call per query, against
    spq's PCH results; spq_seconds: spq's cold time for the same configurations. Each pair's loop over
    qs is the fastest of config.repeats."""
    from tqdm import tqdm

    from harness.engines import available_engines

    poses = np.array([scene.body_poses(q) for q in qs])  # (n, nbodies, 4, 4): not timed
    status = spq_out[:, :, OUT_STATUS]
    separated = status == SEPARATED
    n, npairs = spq_out.shape[0], spq_out.shape[1]
    rows = [{"engine": "spq (pch, batched)", "ms_per_config": 1e3 * spq_seconds / n,
             "pairs_per_s": n * npairs / spq_seconds, "max_abs_diff_vs_spq_m": 0.0, "results_off_by_over_0.1mm": 0,
             "speedup_of_spq_auto": np.nan}]
    for name, engine in available_engines(config.engines).items():
        distances = np.empty((n, npairs))
        seconds = 0.0
        for p, (a, b) in enumerate(tqdm(scene.pairs, desc=name, unit="pair", disable=not progress)):
            prepared = engine.prepare(scene.bodies[a].hull, scene.bodies[b].hull)
            pa = np.ascontiguousarray(poses[:, a])
            pb = np.ascontiguousarray(poses[:, b])
            prepared.distance_loop(pa[:2], pb[:2])
            loop_seconds, distances[:, p] = best_time(lambda: prepared.distance_loop(pa, pb), config.repeats)
            seconds += loop_seconds
            prepared.close()
        diff = np.abs(distances - spq_out[:, :, OUT_DISTANCE])[separated]
        rows.append({"engine": name, "ms_per_config": 1e3 * seconds / n, "pairs_per_s": n * npairs / seconds,
                     "max_abs_diff_vs_spq_m": float(diff.max()) if diff.size else np.nan,
                     "results_off_by_over_0.1mm": int((diff > 1e-4).sum()), "speedup_of_spq_auto": np.nan})
        engine.close()
    return pd.DataFrame(rows)


def cold_beside_pinocchio(scenes: dict, peers: dict, qs: np.ndarray, q_pin, repeats: int,
                          block: int = TIMING_BLOCK) -> tuple[dict, dict]:
    """({name: seconds}, {policy: cold results (N, npairs, OUT_SIZE)}): each spq scene's cold run over
    qs and each pinocchio peer's computeDistances loop over q_pin (the same configurations in
    pinocchio's order), timed side by side in blocks of configurations (timing.blocked_times)."""
    jobs = {variant: (peer.run, np.asarray(q_pin)) for variant, peer in peers.items()}
    outs = {}
    for policy, scene in scenes.items():
        scene.distances_many(qs[:2], coherent=False)  # compile / load the kernels
        outs[policy] = result_array(len(qs), len(scene.pairs))
        jobs[policy] = (lambda q, o, scene=scene: scene.distances_many(q, coherent=False, out=o), qs, outs[policy])
    return {name: timed[0] for name, timed in blocked_times(jobs, repeats, block).items()}, outs


STP_MESH_REL_TOLERANCE = 1e-3  # pinocchio's STP-BV meshes for auto's volumes, times each one's bounding radius
ON_AUTO_VOLUMES = " on auto's volumes"  # the suffix of a pinocchio variant given auto's STP sides as meshes


def pinocchio_table(config: RobotBenchConfig, scenes: dict, qs: np.ndarray, spq_out: np.ndarray) -> pd.DataFrame:
    """pinocchio.computeDistances (one C++ call per configuration over every pair, forward kinematics
    included, coal.Convex hulls on the same links) in each of its coal GJK variants, timed beside
    spq's cold pch and auto runs in blocks of configurations (timing.blocked_times), and its
    distances against spq's PCH results (spq_out, cold at qs): separated pairs' largest difference,
    and overlap verdicts that disagree outside a 1e-6 m band. An empty table's single row says why
    pinocchio did not run.

    With an auto scene, each variant also runs the same job as spq's auto ("<variant> on auto's
    volumes"): each pair's STP side as that body's certified STP-BV mesh (pinocchio_peer.stp_mesh_shapes,
    STP_MESH_REL_TOLERANCE), compared with spq's auto results; the meshes lie inside the STP-BVs, so on
    separated pairs an exact answer lies 0 to stp_mesh_error_m (the largest mesh's certified error)
    above spq's (diff_min_m, diff_max_m: pinocchio less spq)."""
    from datasets.robots import robot_files
    from harness.engines import pinocchio_peer as pp

    try:
        version = pp.version()
    except ImportError as exc:
        return pd.DataFrame([{"engine": "pinocchio", "status": f"not run: {exc}"}])
    urdf = robot_files(config.robot).urdf
    peers = {variant: pp.build(scenes["pch"], urdf, variant) for variant in pp.VARIANTS}
    mesh_errors = {}
    if "auto" in scenes:  # the same job as spq's auto: the STP sides as the STP-BVs' meshes
        auto = scenes["auto"]
        if not np.array_equal(np.asarray(auto.pairs), np.asarray(scenes["pch"].pairs)):
            raise ValueError("the auto and pch scenes of the pinocchio table must have the same pairs")
        shapes, mesh_errors = pp.stp_mesh_shapes(auto, STP_MESH_REL_TOLERANCE)
        peers.update({f"{variant}{ON_AUTO_VOLUMES}": pp.build(auto, urdf, variant, stp_shapes=shapes)
                      for variant in pp.VARIANTS})
    q_pin = np.array([peers["default"].configuration(q) for q in qs])
    spq_sides = {p: scenes[p] for p in ("pch", "auto") if p in scenes}
    best, outs = cold_beside_pinocchio(spq_sides, peers, qs, q_pin, config.repeats)
    rows = []
    for variant, peer in peers.items():
        on_auto = variant.endswith(ON_AUTO_VOLUMES)
        reference = outs["auto"] if on_auto else spq_out  # spq's cold results on the same volumes
        spq_d = reference[:, :, OUT_DISTANCE]
        separated = reference[:, :, OUT_STATUS] == SEPARATED
        d = np.array([peer.distances(q) for q in q_pin])
        diff = (d - spq_d)[separated]
        band = 1e-6
        disagree = ((spq_d < -band) & (d > band)) | ((spq_d > band) & (d < -band))
        ms = 1e3 * best[variant] / len(qs)
        rows.append({"engine": f"pinocchio ({variant})", "status": "ran", "version": version,
                     "ms_per_config": ms, "spq_pch_ms": 1e3 * best.get("pch", np.nan) / len(qs),
                     "spq_auto_ms": 1e3 * best.get("auto", np.nan) / len(qs),
                     "spq_pch_speedup": np.nan if on_auto else best[variant] / best.get("pch", np.nan),
                     "spq_auto_speedup": best[variant] / best.get("auto", np.nan),
                     "max_abs_diff_vs_spq_m": float(np.abs(diff).max()) if diff.size else np.nan,
                     "diff_min_m": float(diff.min()) if diff.size else np.nan,
                     "diff_max_m": float(diff.max()) if diff.size else np.nan,
                     "stp_mesh_error_m": max(mesh_errors.values()) if on_auto and mesh_errors else np.nan,
                     "overlap_disagreements": int(disagree.sum()), "pairs": len(peer.geometry.collisionPairs),
                     "configurations": len(qs)})
    return pd.DataFrame(rows)


def gradient_track(scene: Scene, trajectory: np.ndarray, pairs: np.ndarray, signed: bool = False) -> dict:
    """Along the trajectory (coherent), the closest of ``pairs`` at each step, its distance and its
    distance gradient (steps, ndof) w.r.t. the joint values (signed: overlaps as minus their depth)."""
    scene.reset()
    steps = len(trajectory)
    closest = np.empty(steps, dtype=int)
    dmin = np.empty(steps)
    grads = np.empty((steps, scene.model.ndof))
    for k, q in enumerate(trajectory):
        result = scene.distances(q, coherent=True, signed=signed)
        i = pairs[np.argmin(result.distance[pairs])]
        closest[k], dmin[k] = i, result.distance[i]
        grads[k] = scene.distance_gradient(q, result, int(i))
    return {"closest": closest, "distance": dmin, "gradient": grads}


def pair_gradient(scene: Scene, q: np.ndarray, pair: int, signed: bool = False) -> np.ndarray:
    """Distance gradient (ndof,) of one pair at q, from a cold query."""
    return scene.distance_gradient(q, scene.distances(q, coherent=False, signed=signed), pair)


def bisect_change(scene: Scene, q0: np.ndarray, q1: np.ndarray, pair: int, levels: int = BISECTIONS,
                  signed: bool = False) -> float:
    """The part of the gradient change between q0 and q1 left in a 2^-levels sub-interval, after
    following the larger half's change at each level: near 1 for a jump, near 2^-levels for a
    continuous gradient."""
    g0, g1 = pair_gradient(scene, q0, pair, signed), pair_gradient(scene, q1, pair, signed)
    total = np.linalg.norm(g1 - g0)
    if total == 0.0:
        return 0.0
    for _ in range(levels):
        qm = 0.5 * (q0 + q1)
        gm = pair_gradient(scene, qm, pair, signed)
        if np.linalg.norm(gm - g0) >= np.linalg.norm(g1 - gm):
            q1, g1 = qm, gm
        else:
            q0, g0 = qm, gm
    return float(np.linalg.norm(g1 - g0) / total)


def gradient_jumps(scene: Scene, trajectory: np.ndarray, track: dict, signed: bool = False) -> dict:
    """Jump statistics of a gradient track. Steps where the closest pair changes are counted apart.
    Among the others, the JUMP_CANDIDATES largest relative changes (|change| / |gradient|) are bisected
    (:func:`bisect_change`); a jump is one whose change stays over JUMP_RESIDUAL of itself."""
    g = track["gradient"]
    change = np.linalg.norm(np.diff(g, axis=0), axis=1)
    norm = np.linalg.norm(g, axis=1)
    relative = change / np.maximum(np.maximum(norm[1:], norm[:-1]), 1e-12)
    switch = track["closest"][1:] != track["closest"][:-1]
    same = np.flatnonzero(~switch)
    candidates = same[np.argsort(-relative[same])[:JUMP_CANDIDATES]]
    residual = np.array([bisect_change(scene, trajectory[k], trajectory[k + 1], int(track["closest"][k]),
                                       signed=signed) for k in candidates])
    jumps = np.sort(candidates[residual > JUMP_RESIDUAL]) if len(candidates) else candidates
    return {"closest_pair_switches": int(switch.sum()),
            "median_relative_change": float(np.median(relative[same])) if same.size else np.nan,
            "max_relative_change_same_pair": float(relative[same].max()) if same.size else np.nan,
            "largest_residual_after_bisection": float(residual.max()) if residual.size else np.nan,
            "gradient_jumps_same_pair": int(len(jumps)), "jump_steps": jumps + 1, "change": relative,
            "switch": switch}


def continuity_table(scenes: dict, trajectory: np.ndarray, policies=("auto", "pch")) -> tuple[pd.DataFrame, dict]:
    """Gradient tracks along the trajectory for each policy: of the closest pair at each step, and of
    one fixed pair (the one most often closest for PCH-PCH). Pairs considered: separated at every step
    for every policy (an overlapping pair has no gradient) and moving (their distance varies by more
    than MOVING_PAIR_M; pairs whose relative pose is fixed have zero gradient)."""
    outs = {p: scenes[p].distances_many(trajectory, coherent=False) for p in policies}
    keep = np.all([(o[:, :, OUT_STATUS] == SEPARATED).all(axis=0) for o in outs.values()], axis=0)
    keep &= np.all([np.ptp(o[:, :, OUT_DISTANCE], axis=0) > MOVING_PAIR_M for o in outs.values()], axis=0)
    pairs = np.flatnonzero(keep)
    tracks, rows = {}, []
    for p in policies:
        tracks[p] = gradient_track(scenes[p], trajectory, pairs)
    counts = np.bincount(tracks[policies[-1]]["closest"], minlength=len(keep))
    fixed = int(np.argmax(counts))
    names = scenes[policies[0]].pair_names[fixed]
    for p in policies:
        tracks[p].update(gradient_jumps(scenes[p], trajectory, tracks[p]))
        tracks[p]["fixed"] = gradient_track(scenes[p], trajectory, np.array([fixed]))
        tracks[p]["fixed"].update(gradient_jumps(scenes[p], trajectory, tracks[p]["fixed"]))
        tracks[p]["fixed"]["name"] = f"{names[0]} - {names[1]}"
        for what, tr in (("closest pair", tracks[p]), (f"{names[0]} - {names[1]}", tracks[p]["fixed"])):
            rows.append({"policy": p, "track": what, "pairs_tracked": len(pairs) if what == "closest pair" else 1,
                         "steps": len(trajectory),
                         **{k: v for k, v in tr.items() if k in ("closest_pair_switches", "median_relative_change",
                                                                 "max_relative_change_same_pair",
                                                                 "largest_residual_after_bisection",
                                                                 "gradient_jumps_same_pair")}})
    return pd.DataFrame(rows), tracks


def contact_track(scenes: dict, trajectory: np.ndarray, r: float, policies=("auto", "pch")) -> tuple[list, dict]:
    """Per policy, the signed-distance track of the pair that enters and leaves contact most often
    along the trajectory, among the pairs that never fail and, with an STP-BV on a side, are never
    deeper than its small radius r (down to which its penetration depth is C1; deeper, the nearest
    boundary point of the Minkowski difference may switch for any bodies): (table rows, tracks per
    policy); a policy whose pairs never cross contact has neither."""
    rows, tracks = [], {}
    for p in policies:
        out = scenes[p].distances_many(trajectory, coherent=False, signed=True)
        sd = out[:, :, OUT_DISTANCE]
        ok = (out[:, :, OUT_STATUS] != FAILED).all(axis=0)
        if p != "pch":
            ok &= sd.min(axis=0) > -r
        crossings = np.where(ok, (np.diff(np.sign(sd), axis=0) != 0).sum(axis=0), 0)
        if crossings.max() == 0:
            continue
        pair = int(np.argmax(crossings))
        names = scenes[p].pair_names[pair]
        tr = gradient_track(scenes[p], trajectory, np.array([pair]), signed=True)
        tr.update(gradient_jumps(scenes[p], trajectory, tr, signed=True))
        tr["name"] = f"{names[0]} - {names[1]}"
        tracks[p] = tr
        in_contact = tr["distance"] < 0.0
        rows.append({"policy": p, "track": f"through contact: {tr['name']}", "pairs_tracked": 1,
                     "steps": len(trajectory), "contact_crossings": int((in_contact[1:] != in_contact[:-1]).sum()),
                     "deepest_m": float(tr["distance"].min()),
                     **{k: v for k, v in tr.items() if k in ("closest_pair_switches", "median_relative_change",
                                                             "max_relative_change_same_pair",
                                                             "largest_residual_after_bisection",
                                                             "gradient_jumps_same_pair")}})
    return rows, tracks


def plot_distance_matrix(scene: Scene, q: np.ndarray, path: Path, policy: str) -> None:
    """Heat map of every pair's distance at one posture; skipped pairs blank, overlaps black."""
    from harness.report.charts import pyplot, save_figure

    plt = pyplot()
    result = scene.distances(q, coherent=False)
    nb = len(scene.bodies)
    matrix = np.full((nb, nb), np.nan)
    for (a, b), d, s in zip(scene.pairs, result.distance, result.status):
        matrix[a, b] = matrix[b, a] = 0.0 if s == "overlapping" else d
    fig, ax = plt.subplots(figsize=(9, 8))
    cmap = plt.get_cmap("viridis").with_extremes(bad="white")
    image = ax.imshow(matrix, cmap=cmap, vmin=0.0, interpolation="nearest")
    overl = np.argwhere(matrix == 0.0)
    ax.scatter(overl[:, 1], overl[:, 0], marker="s", s=30, color="black", label="overlapping")
    names = scene.body_names
    ax.set_xticks(range(nb), names, rotation=90, fontsize=6)
    ax.set_yticks(range(nb), names, fontsize=6)
    fig.colorbar(image, ax=ax, label="distance (m)")
    if len(overl):
        ax.legend(loc="upper right", fontsize=7)
    save_figure(fig, path, f"{scene.model.name}: pair distances at one random posture ({policy}; blank = skipped)")


def plot_trajectory(tracks: dict, path: Path, contact: dict | None = None) -> None:
    """Closest-pair distance and gradient norm, then one fixed pair's gradient norm and its change per
    step, per policy; below, on its own trajectory, a pair's signed distance through contact and its
    gradient norm (contact_track), when one was found."""
    from harness.report.charts import pyplot, save_figure

    plt = pyplot()
    if contact:
        fig, all_axes = plt.subplots(6, 1, figsize=(9, 15))
        axes, below = list(all_axes[:4]), list(all_axes[4:])
        for ax in axes[1:]:
            ax.sharex(axes[0])
        below[1].sharex(below[0])
    else:
        fig, axes = plt.subplots(4, 1, figsize=(9, 11), sharex=True)
    colours = {"auto": "tab:blue", "pch": "tab:red", "stp-both": "tab:green"}
    labels = {"auto": "auto (STP-BV on one side)", "pch": "PCH-PCH"}
    for p, tr in tracks.items():
        steps = np.arange(len(tr["distance"]))
        colour, label = colours.get(p), labels.get(p, p)
        axes[0].plot(steps, tr["distance"], color=colour, lw=1, label=label)
        axes[1].plot(steps, np.linalg.norm(tr["gradient"], axis=1), color=colour, lw=1, label=label)
        fixed = tr["fixed"]
        axes[2].plot(steps, np.linalg.norm(fixed["gradient"], axis=1), color=colour, lw=1, label=label)
        axes[3].semilogy(steps[1:], np.maximum(fixed["change"], 1e-6), color=colour, lw=0.8, label=label)
        # jumps confirmed by bisection
        jumps = fixed["jump_steps"]
        axes[3].scatter(jumps, np.maximum(fixed["change"][jumps - 1], 1e-6), color=colour, s=14, marker="x")
    first = next(iter(tracks.values()))
    for k in np.flatnonzero(first["switch"]) + 1:
        axes[1].axvline(k, color="0.85", lw=0.5, zorder=0)
    axes[0].set_ylabel("min distance (m)")
    axes[1].set_ylabel("|gradient| of the min\n(m/rad; grey: pair changes)")
    axes[2].set_ylabel(f"|gradient| (m/rad)\n{first['fixed']['name']}")
    axes[3].set_ylabel("|gradient change| per step\n(x: jumps)")
    axes[3].set_xlabel("trajectory step")
    axes[0].legend(fontsize=8)
    if contact:
        for p, tr in contact.items():
            steps = np.arange(len(tr["distance"]))
            colour, label = colours.get(p), labels.get(p, p)
            below[0].plot(steps, tr["distance"], color=colour, lw=1, label=f"{label}: {tr['name']}")
            below[1].plot(steps, np.linalg.norm(tr["gradient"], axis=1), color=colour, lw=1, label=label)
            jumps = tr["jump_steps"]
            below[1].scatter(jumps, np.linalg.norm(tr["gradient"][jumps], axis=1), color=colour, s=14, marker="x")
        below[0].axhline(0.0, color="k", lw=0.6)
        below[0].set_ylabel("signed distance (m)\nof a pair through contact")
        below[1].set_ylabel("|gradient| (m/rad)\n(x: jumps)")
        below[1].set_xlabel("step of the coarser trajectory (through contact)")
        below[0].legend(fontsize=8)
    save_figure(fig, path, "Minimum distance and its gradient along a smooth trajectory")


def plot_engines(table: pd.DataFrame, engines: pd.DataFrame, path: Path) -> None:
    """Side by side: ms per configuration of spq (each policy, cold and coherent) and the engines."""
    from harness.report.charts import pyplot, save_figure

    plt = pyplot()
    full = table[table.pruning_m == 0.0]
    labels = [f"spq {r.policy}\n{r.mode}" for r in full.itertuples()]
    values = list(full.ms_per_config)
    colours = ["tab:blue" if r.mode == "cold" else "tab:cyan" for r in full.itertuples()]
    for r in engines.itertuples():
        if r.engine.startswith("spq"):
            continue
        labels.append(f"{r.engine}\nPCH, cold")
        values.append(r.ms_per_config)
        colours.append("tab:gray")
    fig, ax = plt.subplots(figsize=(10, 4.5))
    ax.bar(range(len(values)), values, color=colours)
    ax.set_yscale("log")
    ax.yaxis.set_major_locator(plt.matplotlib.ticker.LogLocator(subs=(1.0, 2.0, 5.0)))
    ax.yaxis.set_major_formatter(plt.matplotlib.ticker.FormatStrFormatter("%g"))
    ax.yaxis.set_minor_formatter(plt.matplotlib.ticker.NullFormatter())
    for target, style in ((TARGET_COLD_MS, "--"), (TARGET_COHERENT_MS, ":")):
        ax.axhline(target, color="0.3", lw=0.8, ls=style)
        ax.text(len(values) - 0.5, target, f"target {target:g} ms", ha="right", va="bottom", fontsize=7)
    ax.set_xticks(range(len(values)), labels, fontsize=7)
    ax.set_ylabel("ms per configuration (all pairs)")
    for i, v in enumerate(values):
        ax.text(i, v, f"{v:.2g}", ha="center", va="bottom", fontsize=7)
    save_figure(fig, path, "All pairs per configuration: spq policies against coal and python-fcl (PCH pairs)")


def run(config: RobotBenchConfig, progress: bool = True) -> dict:
    """Every table of the robot benchmark, the scene's size, and under "figures" its charts as
    (file name, draw(path)) pairs: a figure is drawn only when its caller writes it."""
    from datasets.robots import robot_files
    from harness.references.pybullet_kinematics import fk_errors

    base = load_scene(config, "pch")
    randoms = random_configurations(base.model, config.configurations, config.seed)
    checked = randoms[:FK_CONFIGURATIONS]
    position, rotation = fk_errors(robot_files(config.robot).urdf, base.model, checked, strip_geometry=True)
    kinematics = pd.DataFrame([{"robot": base.model.name, "links": base.model.nlinks, "dof": base.model.ndof,
                                "configurations": len(checked), "max_position_error_m": position,
                                "max_rotation_entry_error": rotation}])
    trajectory = smooth_trajectory(base.model, config.steps, config.seed)
    table, scenes, results = scene_table(config, randoms, trajectory, progress)
    pch = scenes.get("pch") or base
    m = config.engine_configurations or config.configurations
    pch_rows = table[(table.policy == "pch") & (table.configurations == "random") & (table.pruning_m == 0.0)]
    pch_seconds = float(pch_rows.ms_per_config.iloc[0]) * 1e-3 * m if len(pch_rows) else np.nan
    pch_out = results["pch"] if "pch" in results else best_run(pch, randoms, False, None, 1)[1]
    engines = engine_table(config, pch, randoms[:m], pch_out[:m], pch_seconds, progress)
    auto_rows = table[(table.policy == "auto") & (table.configurations == "random") & (table.pruning_m == 0.0)]
    if len(auto_rows):
        engines["speedup_of_spq_auto"] = engines.ms_per_config / float(auto_rows.ms_per_config.iloc[0])
        engines.loc[engines.engine.str.startswith("spq"), "speedup_of_spq_auto"] = np.nan
    scenes.setdefault("pch", pch)
    if "auto" not in scenes:
        scenes["auto"] = load_scene(config, "auto")
    signed = signed_rows({p: scenes[p] for p in config.policies if p in scenes}, randoms, config.repeats)
    pinocchio = pinocchio_table(config, scenes, randoms[:m], pch_out[:m])
    # the continuity track: the first 1/CONTINUITY_ZOOM of a trajectory sampled CONTINUITY_ZOOM times finer
    fine = smooth_trajectory(base.model, config.steps * CONTINUITY_ZOOM, config.seed)[:config.steps]
    continuity, tracks = continuity_table(scenes, fine)
    contact_rows, contact = contact_track(scenes, trajectory, config.r)
    continuity = pd.concat([continuity, pd.DataFrame(contact_rows)], ignore_index=True)
    auto, posture = scenes["auto"], randoms[0]
    figures = [("robot_distance_matrix.png", lambda path: plot_distance_matrix(auto, posture, path, "auto")),
               ("robot_trajectory.png", lambda path: plot_trajectory(tracks, path, contact)),
               ("robot_engines.png", lambda path: plot_engines(table, engines, path))]
    return {"scene": table, "engines": engines, "continuity": continuity, "kinematics": kinematics, "signed": signed,
            "pinocchio": pinocchio, "bodies": len(base.bodies), "pairs": len(base.pairs), "robot": base.model.name,
            "figures": figures}
