"""What a control step costs, measured side by side in one process on the same configurations.

The configurations are a controller run's own (spq-auto on one task, so the pairs near contact are the
ones a controller meets), replayed in order: each mode starts from reset warm starts and goes through
all of them, modes taking turns within each round, and each mode's fastest round counts (the machine is
shared: the rounds' spread is reported beside). Modes, per step:

- ``distances``: ``scene.distances(q, prune=di, signed=True)`` (coherent), the controller's query alone;
- ``distances+jacobians``: the same with ``jacobian=True`` (every queried pair's row ∂d/∂q);
- ``all pairs cold`` / ``all pairs cold + jacobians``: every pair, cold, no pruning
  (``distances_many(..., jacobian=...)`` over all the configurations in one call), the worst case;
- ``step spq-<policy>``: a whole control step: spq's damper rows (distances and Jacobians), the task
  Jacobians and objective, the joint-limit bounds and the QP (proxqp through qpsolvers, warm-started);
- ``step pin-damper``: the same step fed by pinocchio + coal (``computeDistances``: forward kinematics
  and every pair's coal distance in C++, then frame Jacobians at the witness points of the pairs within
  d_i), the same task part and QP, pinocchio's coal requests in their fastest variant.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np


@dataclass
class StepTiming:
    robot: str
    table: object  # pandas DataFrame: mode, ms per step (best round), spread, ratio
    steps: int
    rounds: int
    note: str


def _timed(fn, qs) -> float:
    """Mean seconds per configuration: fn's own figure where it returns one (a control step), else the
    wall time of the calls."""
    start = time.perf_counter()
    own = 0.0
    for k, q in enumerate(qs):
        seconds = fn(k, q)
        own += seconds if isinstance(seconds, float) else 0.0
    return (own if own > 0.0 else time.perf_counter() - start) / len(qs)


def _step_fn(controller, task, qs):
    """A whole control step at the k-th configuration (as Controller.run's loop body, without the log)."""
    from harness.suites.control.controller import joint_bounds

    p = controller.params
    q0 = np.asarray(task.q0, float)
    start_points = task.hand_points(controller.scene, q0)
    links0 = controller.scene.link_poses(q0)
    R_ref = np.array([links0[link][:3, :3] for link, _ in task.hands])
    state = {"qdot": np.zeros(controller.n)}

    def step(k, q) -> float:
        """Seconds of the step: the source's own timing of its rows (distances, Jacobians: not the
        witness points' body frames that only the measures use), then the task part and the QP."""
        rows, seconds = controller.source.rows(q)
        start = time.perf_counter()
        refs, vels = task.reference(k * p.dt, start_points)
        P, c = controller.objective(q, task.hands, refs, vels, q0, R_ref)
        lb, ub, _ = joint_bounds(q, controller.lower, controller.upper, controller.vmax, p, controller.frozen)
        h = p.xi * (rows.distance - p.ds) / (p.di - p.ds)
        state["qdot"], _ = controller.solve(P, c, -rows.jacobian, h, lb, ub, state["qdot"])
        return seconds + time.perf_counter() - start

    return step


def _fastest_pin_variant(source) -> str:
    """Set pinocchio's coal requests to their fastest GJK variant on this run (harness.engines.pinocchio_peer)."""
    import coal

    from harness.engines.pinocchio_peer import VARIANTS

    best, name = np.inf, "default"
    q = source.pm.to_pin(source.pm.q_template)
    for variant, (gjk, guess) in VARIANTS.items():
        for request in source.pm.gdata.distanceRequests:
            request.gjk_variant = getattr(coal.GJKVariant, gjk)
            request.gjk_initial_guess = getattr(coal.GJKInitialGuess, guess)
        import pinocchio as pin

        start = time.perf_counter()
        for _ in range(200):
            pin.computeDistances(source.pm.model, source.pm.data, source.pm.geometry, source.pm.gdata, q)
        seconds = time.perf_counter() - start
        if seconds < best:
            best, name = seconds, variant
    gjk, guess = VARIANTS[name]
    for request in source.pm.gdata.distanceRequests:
        request.gjk_variant = getattr(coal.GJKVariant, gjk)
        request.gjk_initial_guess = getattr(coal.GJKInitialGuess, guess)
    return name


def step_timing(robot: str = "jvrc1", steps: int = 400, rounds: int = 5, seed: int = 0, params=None,
                policies=("auto", "pch", "stp"), progress: bool = False) -> StepTiming:
    """Time per control step (ms) of each mode (module docstring) on ``robot``'s first task."""
    import pandas as pd
    from tqdm import tqdm

    from harness.suites.control.controller import ControlParams, Controller, SpqSource
    from harness.suites.control.peers import PinocchioSource
    from harness.suites.control.scenes import robot_scenes
    from harness.suites.control.tasks import frozen_mask, make_tasks, setup

    if steps < 2 or rounds < 1:
        raise ValueError(f"steps must be >= 2 and rounds >= 1; got {steps} and {rounds}")
    params = params or ControlParams()
    policies = tuple(dict.fromkeys(("auto", *policies)))
    scenes = robot_scenes(robot, policies=list(dict.fromkeys(("pch", *policies))))
    model = scenes.base.model
    frozen = frozen_mask(model, setup(robot))
    task = make_tasks(scenes.base, robot, 1, seed)[0]
    auto = scenes.by_policy["auto"]
    run = Controller(auto, SpqSource(auto, params), params, frozen).run(task, steps)
    qs = np.ascontiguousarray(run.q[:-1])

    modes = {}
    for policy in policies:
        scene = scenes.by_policy[policy]
        modes[f"distances spq-{policy}"] = (scene, lambda k, q, s=scene: s.distances(
            q, prune=params.di, signed=True))
        modes[f"distances+jacobians spq-{policy}"] = (scene, lambda k, q, s=scene: s.distances(
            q, prune=params.di, signed=True, jacobian=True))
    cold_out = np.empty((len(qs), len(auto.pairs), 14))
    cold_jac = np.empty((len(qs), len(auto.pairs), auto.nv))
    modes["all pairs cold spq-auto"] = (auto, "cold", False)
    modes["all pairs cold + jacobians spq-auto"] = (auto, "cold", True)
    for policy in policies:
        scene = scenes.by_policy[policy]
        ctrl = Controller(scene, SpqSource(scene, params), params, frozen)
        modes[f"step spq-{policy}"] = (scene, _step_fn(ctrl, task, qs))
    pin_source = PinocchioSource(scenes.base, scenes.urdf, task.q0, frozen, task.hands, params)
    variant = _fastest_pin_variant(pin_source)
    pin_ctrl = Controller(scenes.base, pin_source, params, frozen)
    modes["step pin-damper"] = (None, _step_fn(pin_ctrl, task, qs))

    times = {name: [] for name in modes}
    with tqdm(total=rounds * len(modes), desc="step timing", unit="mode", disable=not progress) as bar:
        for _ in range(rounds):
            for name, mode in modes.items():
                scene = mode[0]
                if scene is not None:
                    scene.reset()
                if len(mode) == 3:  # one compiled call over all the configurations
                    start = time.perf_counter()
                    scene.distances_many(qs, coherent=False, out=cold_out, jacobian=mode[2], jac_out=cold_jac) \
                        if mode[2] else scene.distances_many(qs, coherent=False, out=cold_out)
                    times[name].append((time.perf_counter() - start) / len(qs))
                else:
                    times[name].append(_timed(mode[1], qs))
                bar.update()
    best = {name: min(t) for name, t in times.items()}
    rows = []
    for name, t in times.items():
        ref = None
        if name.startswith("distances+jacobians"):
            ref = best[name.replace("distances+jacobians", "distances")]
        elif name == "all pairs cold + jacobians spq-auto":
            ref = best["all pairs cold spq-auto"]
        elif name.startswith("step spq-"):
            ref = best["step pin-damper"]
        rows.append({"mode": name, "ms_per_step": round(best[name] * 1e3, 4),
                     "rounds_spread": round((np.median(t) - min(t)) / min(t), 3),
                     "ratio": round(best[name] / ref, 3) if ref and name.startswith(("distances", "all")) else
                     (round(ref / best[name], 2) if ref else None),
                     "ratio_means": ("time / time without Jacobians" if name.startswith(("distances+", "all pairs cold +"))
                                     else "pin-damper step / this step" if name.startswith("step spq-") else "")})
    note = (f"{robot}: {len(auto.pairs)} pairs ({scenes.pairs_note}), {int((~frozen).sum())} active joints; "
            f"{len(qs)} configurations of an spq-auto run of task {task.name} (dt {params.dt} s, di {params.di} m, "
            f"ds {params.ds} m, xi {params.xi}); {rounds} rounds, modes in turn, fastest round counts; pinocchio's "
            f"coal requests in their fastest variant here ({variant}).")
    return StepTiming(robot, pd.DataFrame(rows), len(qs), rounds, note)
