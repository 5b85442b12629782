"""Joint-space pose sources for robot scenes: seeded random configurations and smooth trajectories,
and configurations read from a CSV file.

The seeded sources draw from ``np.random.default_rng(seed)`` only, so a source is a pure function of
its arguments. Joint values are radians (revolute) or metres (prismatic), always within the model's
limits.
"""

from __future__ import annotations

from pathlib import Path

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


def read_configurations(model, path) -> np.ndarray:
    """(n, ndof) configurations from a CSV file: a header row of joint names (``model.joint_names``,
    in any order), then one configuration per row, radians or metres.

    ValueError for a missing or unknown joint column, a repeated column, a row of the wrong length, a
    value that is not a number, no rows at all, or a value outside the joint limits (naming the row
    and joint)."""
    import csv

    path = Path(path)
    with path.open(newline="") as fh:
        rows = [row for row in csv.reader(fh) if any(cell.strip() for cell in row)]
    if not rows:
        raise ValueError(f"{path}: empty; expected a header of joint names {list(model.joint_names)}")
    header = [name.strip() for name in rows[0]]
    repeated = sorted({name for name in header if header.count(name) > 1})
    missing = [name for name in model.joint_names if name not in header]
    unknown = [name for name in header if name not in model.joint_names]
    if repeated or missing or unknown:
        problems = [f"{what} {names}" for what, names in (("missing joint columns", missing),
                    ("unknown columns", unknown), ("repeated columns", repeated)) if names]
        raise ValueError(f"{path}: {'; '.join(problems)}; the header must name each joint of robot "
                         f"{model.name!r} once: {list(model.joint_names)}")
    if len(rows) < 2:
        raise ValueError(f"{path}: no configurations after the header")
    order = [header.index(name) for name in model.joint_names]
    qs = np.empty((len(rows) - 1, len(order)))
    for n, row in enumerate(rows[1:]):
        if len(row) != len(header):
            raise ValueError(f"{path}: configuration {n} has {len(row)} values; the header has {len(header)}")
        try:
            qs[n] = [float(row[k]) for k in order]
        except ValueError as exc:
            raise ValueError(f"{path}: configuration {n}: {exc}") from None
    try:
        return model.check_configurations(qs)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
