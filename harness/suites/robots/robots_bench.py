"""`spq bench robots`: the field's robots (every robot of example-robot-data), one row each.

Each robot is loaded by datasets.example_robots (collision meshes as convex hulls, boxes, spheres
and capsules as spq's exact shapes, cylinders as circumscribing 64-gon prisms, adjacent links
skipped, the root fixed) and measured as `spq bench robot` measures one robot, on fewer
configurations:

- spq's all-pairs time per configuration for the ``pch`` and ``auto`` policies, cold on random
  configurations and warm-started along a smooth trajectory (robot_bench.best_run: blocks of
  configurations, each block's best of the repeats);
- pinocchio.computeDistances on the same bodies (coal.Convex hulls, coal's exact Sphere, Box and
  Capsule for the primitives) and pairs: coal's GJK variants race on the first configurations, and
  the fastest is timed beside spq's cold runs in blocks of configurations
  (robot_bench.cold_beside_pinocchio), its distances compared with spq's PCH;
- coal from Python (tolerance 1e-8 m, signed distance on) on the same pairs at the first
  configurations: its largest difference from spq's PCH distances on pairs spq finds separated;
- gradient jumps of the closest pair along a smooth trajectory for pch and auto
  (robot_bench.gradient_track and gradient_jumps: the largest changes bisected ten times);
- the pairs left once the robot's shipped SRDF (datasets.example_robots.robot_srdf, MoveIt's
  ``disable_collisions``) is applied on top of the adjacent-link rule, beside the pairs measured
  (which do not use it); a robot without an SRDF says so.

A robot that does not load is a row with status 'failed' and the reason; one without pairs to
query (a single link, every body on adjacent links) or without a movable joint is a row that says so.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from harness.suites.robot import robot_bench as rb
from harness.workloads.robot_poses import random_configurations, smooth_trajectory
from spq.kernels.gjk import OUT_DISTANCE, OUT_STATUS, OVERLAPPING, SEPARATED

POLICIES = ("pch", "auto")
QUICK_ROBOTS = ("double_pendulum_simple", "ur5_robot", "panda", "allegro_right_hand", "a1", "solo12")
OVERLAP_BAND_M = 1e-6  # m: an overlap verdict disagrees only when the other side is beyond this band
COAL_TOLERANCE = 1e-8  # m: coal's gjk_tolerance, as the coal engine adapter sets it
PROBE_CONFIGURATIONS = 25  # pinocchio's GJK variants race on these first; only the fastest is timed against spq
STATUS_RAN, STATUS_FAILED, STATUS_NO_PAIRS, STATUS_NO_JOINTS = "ran", "failed", "no pairs", "no joints"
COLUMNS = ["robot", "status", "reason", "links", "dof", "bodies", "meshes", "boxes", "spheres", "capsules",
           "cylinders", "hull_vertices", "pairs", "srdf", "srdf_disabled", "pairs_srdf", "load_s", "pch_cold_ms",
           "auto_cold_ms", "pch_coherent_ms",
           "auto_coherent_ms", "pinocchio_ms", "pinocchio_variant", "pinocchio_over_pch", "pinocchio_over_auto",
           "pinocchio_max_diff_m", "pinocchio_overlap_disagreements", "coal_max_diff_m", "coal_overlap_disagreements",
           "overlapping_pct", "pch_jumps", "auto_jumps", "jump_pairs", "seconds"]


@dataclass
class ShapeCache:
    """What robots sharing meshes share within a run: hulls (Scene.from_model's hull_cache) and the
    STP-BVs built on them (id(hull) -> (hull, STPBV), the hull kept so that its id stays its own)."""

    hulls: dict = field(default_factory=dict)
    stps: dict = field(default_factory=dict)


def _reason(exc: BaseException) -> str:
    """An exception as one short line, with the installed package's folder left out of paths."""
    from datasets.example_robots import package_root

    message = str(exc)
    if "message:" in message:  # coal's C++ errors: file, function and line, then the message
        message = message.rsplit("message:", 1)[1].strip()
    if "Too many neighbors" in message:
        message += " (coal.Convex refuses a hull vertex with 255 or more neighbours)"
    text = f"{type(exc).__name__}: {message}"
    try:
        text = text.replace(str(package_root()) + "/", "")
    except ValueError:
        pass
    return " ".join(text.split())


SRDF_NONE = "none shipped"


def srdf_counts(name: str, scene) -> dict:
    """{'srdf': the robot's shipped SRDF file name (or SRDF_NONE, or why it was not read),
    'srdf_disabled': its disable_collisions link pairs, 'pairs_srdf': the scene's pairs that the SRDF
    does not disable (NaN without one)}. SRDF links the URDF lacks are passed over, as pinocchio does."""
    from datasets.example_robots import robot_srdf
    from spq.collision_pairs import skip_pairs
    from spq.io.srdf import read_srdf

    path = robot_srdf(name)
    if path is None:
        return {"srdf": SRDF_NONE, "srdf_disabled": np.nan, "pairs_srdf": np.nan}
    try:
        disabled = read_srdf(path)
    except ValueError as exc:
        return {"srdf": f"{path.name}: {_reason(exc)}", "srdf_disabled": np.nan, "pairs_srdf": np.nan}
    skip = {frozenset(p) for p in skip_pairs(scene.bodies, disabled, link_names=scene.model.link_names,
                                             unknown="ignore")}
    left = sum(frozenset(p) not in skip for p in scene.pair_names)
    return {"srdf": path.name, "srdf_disabled": len(disabled), "pairs_srdf": left}


def derive_scene(scene, policy: str, cache: ShapeCache):
    """scene.with_policy(policy), reusing the STP-BVs built for the same hull objects before."""
    for b in scene.bodies:
        hit = cache.stps.get(id(b.hull))
        if b.stp is None and hit is not None and hit[0] is b.hull:
            b.stp = hit[1]
    out = scene.with_policy(policy)
    for b in out.bodies:
        if b.stp is not None:
            cache.stps.setdefault(id(b.hull), (b.hull, b.stp))
    return out


def geometry_counts(model) -> dict:
    """How many bodies of each kind the model's link geometry makes (meshes, boxes, ...)."""
    counts = {"meshes": 0, "boxes": 0, "spheres": 0, "capsules": 0, "cylinders": 0}
    for geoms in model.link_geometry:
        for g in geoms:
            kind = getattr(g, "kind", None)
            counts["meshes" if kind is None else kind + ("es" if kind == "box" else "s")] += 1
    return counts


def fastest_variant(peers: dict, q_pin: list) -> str:
    """The pinocchio variant fastest on the first PROBE_CONFIGURATIONS configurations (best of two runs
    each): timing every variant in every round cost more than all of spq's runs together."""
    probe = q_pin[:PROBE_CONFIGURATIONS]
    return min(peers, key=lambda v: peers[v].seconds(probe, 2))


def peer_agreement(peer, q_pin: list, spq_out: np.ndarray) -> tuple[float, int]:
    """(largest |pinocchio - spq| over pairs spq finds separated (m), overlap verdicts that disagree
    outside OVERLAP_BAND_M) at the configurations q_pin, against spq's PCH results spq_out."""
    theirs = np.array([peer.distances(q) for q in q_pin]).reshape(spq_out.shape[:2])
    return _agreement(theirs, spq_out)


def _agreement(theirs: np.ndarray, spq_out: np.ndarray) -> tuple[float, int]:
    mine = spq_out[:, :, OUT_DISTANCE]
    status = spq_out[:, :, OUT_STATUS]
    diff = np.abs(theirs - mine)[status == SEPARATED]
    band = OVERLAP_BAND_M
    disagree = ((status == OVERLAPPING) & (theirs > band)) | ((status == SEPARATED) & (mine > band) & (theirs < -band))
    return (float(diff.max()) if diff.size else np.nan), int(disagree.sum())


def coal_agreement(scene, qs: np.ndarray, spq_out: np.ndarray) -> tuple[float, int]:
    """coal (one Python call per pair and configuration, the bodies as pinocchio_peer.coal_geometry
    makes them) on every pair at qs, against spq's PCH results there: as :func:`peer_agreement`."""
    import coal

    from harness.engines.coal_engine import CoalPair
    from harness.engines.pinocchio_peer import coal_geometry

    request = coal.DistanceRequest()
    request.enable_signed_distance = True
    request.gjk_tolerance = COAL_TOLERANCE
    geometry = [coal_geometry(b) for b in scene.bodies]
    poses = np.array([scene.body_poses(q) for q in qs])  # (n, bodies, 4, 4)
    theirs = np.empty(spq_out.shape[:2])
    for p, (a, b) in enumerate(scene.pairs):
        pair = CoalPair(geometry[a], geometry[b], request)
        theirs[:, p] = pair.distance_loop(np.ascontiguousarray(poses[:, a]), np.ascontiguousarray(poses[:, b]))
    return _agreement(theirs, spq_out)


def gradient_jumps(scenes: dict, trajectory: np.ndarray) -> dict:
    """Per policy, gradient jumps of the closest pair along the trajectory (robot_bench's track and
    bisection), over the pairs separated at every step for every policy and moving by more than
    robot_bench.MOVING_PAIR_M; {'pairs': how many such pairs, policy: jumps}."""
    outs = {p: s.distances_many(trajectory, coherent=False) for p, s in scenes.items()}
    keep = np.all([(o[:, :, OUT_STATUS] == SEPARATED).all(axis=0) for o in outs.values()], axis=0)
    keep &= np.all([np.ptp(o[:, :, OUT_DISTANCE], axis=0) > rb.MOVING_PAIR_M for o in outs.values()], axis=0)
    pairs = np.flatnonzero(keep)
    result = {"pairs": len(pairs)}
    for policy, scene in scenes.items():
        if len(pairs) == 0:
            result[policy] = np.nan
            continue
        track = rb.gradient_track(scene, trajectory, pairs)
        result[policy] = rb.gradient_jumps(scene, trajectory, track)["gradient_jumps_same_pair"]
    return result


def measure_robot(name: str, config, cache: ShapeCache) -> dict:
    """One row of the robots table (COLUMNS) for robot ``name``: see the module docstring."""
    from datasets.example_robots import load_scene

    row = {c: np.nan for c in COLUMNS}
    row.update(robot=name, status=STATUS_RAN, reason="", pinocchio_variant="")
    notes = []
    t0 = time.perf_counter()
    try:
        pch = load_scene(name, "pch", hull_cache=cache.hulls, r=config.r, R=config.R)
    except Exception as exc:  # a robot that does not load is a row with the reason, never dropped
        row["load_s"] = row["seconds"] = time.perf_counter() - t0
        row.update(status=STATUS_FAILED, reason=_reason(exc))
        return row
    model = pch.model
    row.update(links=model.nlinks, dof=model.ndof, bodies=len(pch.bodies), pairs=len(pch.pairs),
               hull_vertices=sum(len(b.hull.vertices) for b in pch.bodies if b.shape is None),
               **geometry_counts(model), **srdf_counts(name, pch))
    scenes = {"pch": pch}
    try:
        scenes["auto"] = derive_scene(pch, "auto", cache)
    except Exception as exc:
        notes.append(f"auto not built: {_reason(exc)}")
    row["load_s"] = row["seconds"] = time.perf_counter() - t0
    if len(pch.pairs) == 0:
        row.update(status=STATUS_NO_PAIRS, reason=f"{len(pch.bodies)} bodies, no pair to query (bodies on one "
                                                   "link or on adjacent links are skipped)")
        return row
    if model.ndof == 0:
        row.update(status=STATUS_NO_JOINTS, reason="no movable joint: every distance is constant")
        return row
    try:
        _measure(name, config, scenes, row, notes)
    except Exception as exc:  # one robot's surprise must not end a run over all of them
        notes.append(f"measuring stopped: {_reason(exc)}")
        row["status"] = STATUS_FAILED
    row["reason"] = "; ".join(notes)
    row["seconds"] = time.perf_counter() - t0
    return row


def _measure(name: str, config, scenes: dict, row: dict, notes: list) -> None:
    """The timings, agreements and gradient jumps of one loaded robot into ``row``; what did not run
    into ``notes``."""
    from datasets.example_robots import robot_urdf

    pch = scenes["pch"]
    model = pch.model
    qs = random_configurations(model, config.configs, config.seed)
    peers = {}
    try:
        from harness.engines import pinocchio_peer as pp

        peers = {v: pp.build(pch, robot_urdf(name), v) for v in config.pin_variants}
        q_pin = [peers[config.pin_variants[0]].configuration(q) for q in qs]
    except Exception as exc:
        notes.append(f"pinocchio not run: {_reason(exc)}")
        peers, q_pin = {}, []
    if peers:
        fastest = fastest_variant(peers, q_pin)
        peers = {fastest: peers[fastest]}
    best, outs = rb.cold_beside_pinocchio(scenes, peers, qs, q_pin, config.repeats)
    ms = {k: 1e3 * v / len(qs) for k, v in best.items()}
    row.update(pch_cold_ms=ms["pch"], auto_cold_ms=ms.get("auto", np.nan))
    status = outs["pch"][:, :, OUT_STATUS]
    row["overlapping_pct"] = 100.0 * float((status == OVERLAPPING).mean())
    if peers:
        row.update(pinocchio_ms=ms[fastest], pinocchio_variant=fastest, pinocchio_over_pch=best[fastest] / best["pch"],
                   pinocchio_over_auto=best[fastest] / best["auto"] if "auto" in best else np.nan)
        row["pinocchio_max_diff_m"], row["pinocchio_overlap_disagreements"] = peer_agreement(
            peers[fastest], q_pin, outs["pch"])
    m = min(config.engine_configs, len(qs))
    try:
        row["coal_max_diff_m"], row["coal_overlap_disagreements"] = coal_agreement(pch, qs[:m], outs["pch"][:m])
    except Exception as exc:  # coal refuses some hulls (a vertex with 255 neighbours or more): say so, go on
        notes.append(f"coal not run: {_reason(exc)}")

    trajectory = smooth_trajectory(model, config.steps, config.seed)
    for policy, scene in scenes.items():
        row[f"{policy}_coherent_ms"] = 1e3 * rb.best_run(scene, trajectory, True, None, config.repeats)[0] / len(trajectory)
    # the gradient track: the first 1/CONTINUITY_ZOOM of a trajectory sampled CONTINUITY_ZOOM times finer
    fine = smooth_trajectory(model, config.steps * rb.CONTINUITY_ZOOM, config.seed)[:config.steps]
    jumps = gradient_jumps(scenes, fine)
    row.update(pch_jumps=jumps["pch"], auto_jumps=jumps.get("auto", np.nan), jump_pairs=jumps["pairs"])
    if jumps["pairs"] == 0:
        notes.append("no pair separated and moving along the whole gradient track")


def plot_time_against_pairs(table: pd.DataFrame, path: Path) -> None:
    """ms per configuration (log) against pairs (log), one point per robot and method."""
    from harness.report.charts import pyplot, save_figure

    plt = pyplot()
    ran = table[table.status == STATUS_RAN]
    fig, ax = plt.subplots(figsize=(9, 6))
    series = [("pch_cold_ms", "spq pch, cold", "tab:red", "o"), ("auto_cold_ms", "spq auto, cold", "tab:blue", "o"),
              ("pch_coherent_ms", "spq pch, coherent", "tab:red", "x"),
              ("auto_coherent_ms", "spq auto, coherent", "tab:blue", "x"),
              ("pinocchio_ms", "pinocchio.computeDistances (fastest variant), cold", "0.3", "s")]
    for column, label, colour, marker in series:
        points = ran[np.isfinite(ran[column].astype(float))]
        filled = marker != "o" or "cold" not in label
        ax.scatter(points.pairs, points[column], label=label, color=colour, marker=marker, s=22,
                   alpha=0.8, facecolors=colour if filled else "none")
    if len(ran):
        largest = ran.sort_values("pairs").tail(2)
        for r in largest.itertuples():
            ax.annotate(r.robot, (r.pairs, r.pch_cold_ms), fontsize=7, xytext=(3, -10), textcoords="offset points")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("pairs queried per configuration (log)")
    ax.set_ylabel("ms per configuration, all pairs (log)")
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    ax.legend(fontsize=8)
    save_figure(fig, path, f"example-robot-data: all-pairs time against pair count ({len(ran)} robots)")


def run(config, progress: bool = False) -> dict:
    """The robots table (one row per robot, COLUMNS) and its chart as (file name, draw(path))."""
    from tqdm import tqdm

    from datasets.example_robots import robot_names

    names = list(config.robots) if config.robots else (list(QUICK_ROBOTS) if config.quick else robot_names())
    known = robot_names()
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ValueError(f"unknown robots {unknown}; known: {', '.join(known)}")
    cache = ShapeCache()
    rows = [measure_robot(name, config, cache) for name in tqdm(names, desc="bench robots", unit="robot",
                                                                 disable=not progress)]
    table = pd.DataFrame(rows, columns=COLUMNS)
    return {"table": table,
            "figures": [("robots_time_vs_pairs.png", lambda path: plot_time_against_pairs(table, path))]}
