"""Seeded joint-space pose sources for robot scenes: random configurations and smooth trajectories.

Both draw from ``np.random.default_rng(seed)`` only, so a source is a pure function of its
arguments. Joint values are radians (revolute) or metres (prismatic), always within the model's
limits.
"""

from __future__ import annotations

import numpy as np

TRAJECTORY_FILL = 0.9  # fraction of each joint's half-range the trajectory sweeps
TRAJECTORY_CYCLES = (0.5, 2.0)  # full sine periods of each joint over the whole trajectory


def random_configurations(model, n: int, seed: int) -> np.ndarray:
    """(n, ndof) configurations drawn uniformly within the joint limits."""
    rng = np.random.default_rng(seed)
    return np.array([model.random_configuration(rng) for _ in range(int(n))]).reshape(int(n), -1)


def smooth_trajectory(model, steps: int, seed: int) -> np.ndarray:
    """(steps, ndof) joint values along a smooth (C-infinity) trajectory within the limits.

    Joint j follows mid_j + 0.9 half_j sin(2 pi c_j s + phi_j), s in [0, 1], with c_j uniform in
    TRAJECTORY_CYCLES and phi_j uniform in [0, 2 pi): every joint moves, the step between two
    configurations is small (about 2 pi c half / steps), and no limit is touched."""
    steps = int(steps)
    if steps < 2:
        raise ValueError(f"a trajectory needs at least 2 steps; got {steps}")
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(model.lower, dtype=float), np.asarray(model.upper, dtype=float)
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    cycles = rng.uniform(*TRAJECTORY_CYCLES, size=len(lo))
    phase = rng.uniform(0.0, 2.0 * np.pi, size=len(lo))
    s = np.linspace(0.0, 1.0, steps)[:, None]
    return mid + TRAJECTORY_FILL * half * np.sin(2.0 * np.pi * cycles * s + phase)
