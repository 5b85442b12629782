"""Shrinking a wrong or failed spq query to a small reproducer: fewer points, rounder numbers, a simpler
pose, each step kept only if the query still goes wrong (or fails) the same way.

The predicate re-judges the single query against the reference (harness.suites.fuzz.judge with every query
referenced), so a shrunk case is wrong by the same independent measure as the original. Steps, repeated
until none helps or the budget of predicate calls runs out:

1. points: delete chunks of a cloud's points (halves, quarters, ... single points), as delta debugging;
2. the pose pair expressed relative to A (A at the identity), which changes rounding only;
3. numbers: every coordinate, radius, semi-axis, exponent and translation rounded to the fewest
   significant digits that keep the failure, one field at a time; rotations through their quaternion.

A case on which spq raised is shrunk in its poses only, and must raise the same exception with the
same message.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

DEFAULT_BUDGET = 150  # predicate calls (each a reference or oracle call: 1 ms .. 1 s)


def case_of(bad) -> dict:
    """A reproducer dict from a judge.Bad (or a dict of its fields)."""
    d = bad.as_dict() if hasattr(bad, "as_dict") else dict(bad)
    return {k: copy.deepcopy(d[k]) for k in ("family", "a", "b", "pose_a", "pose_b", "mode", "verdict", "detail")}


def still_bad(case: dict, plant=None) -> bool:
    """True when spq's answer to the case's single query is judged as the case's verdict (wrong, failed,
    or raised with the same exception and message) again; a case the oracle cannot build is not bad."""
    from harness.suites.fuzz.judge import judge_case

    try:
        pa, pb = np.asarray(case["pose_a"], float)[None], np.asarray(case["pose_b"], float)[None]
        result = judge_case(case["family"], case["a"], case["b"], pa, pb, np.random.default_rng(0), {}, sample=1.0,
                            plant=plant, modes=(case["mode"],))
    except (ValueError, RuntimeError):
        return False
    return any(b.mode == case["mode"] and b.verdict == case["verdict"]
               and (b.verdict != "raised" or b.detail == case["detail"]) for b in result.bad)


def points_count(case: dict) -> int:
    return sum(len(case[s].get("points", [])) for s in ("a", "b"))


def shrink(case: dict, budget: int = DEFAULT_BUDGET, plant=None) -> dict:
    """The smallest variant of ``case`` found within ``budget`` predicate calls (module docstring)."""
    calls = [0]

    def ok(candidate) -> bool:
        if calls[0] >= budget:
            return False
        calls[0] += 1
        return still_bad(candidate, plant)

    case = copy.deepcopy(case)
    if not ok(case):
        raise ValueError("the case is not wrong or failed to begin with; nothing to shrink")
    # a case that raised keeps its shapes as drawn: a smaller or rounder shape may be refused for a
    # reason of its own (too few points, a flat cloud) that the same message would not tell apart
    shapes_too = case["verdict"] != "raised"
    changed = True
    while changed and calls[0] < budget:
        changed = False
        if shapes_too:
            for side in ("a", "b"):
                changed |= _drop_points(case, side, ok)
        changed |= _relative_pose(case, ok)
        changed |= _round_numbers(case, ok, shapes_too)
    case["shrink_calls"] = calls[0]
    return case


def _drop_points(case, side, ok) -> bool:
    pts = case[side].get("points")
    if pts is None:
        return False
    minimum = 4 if case[side]["kind"] == "pch" else 1
    changed = False
    chunk = max(1, len(pts) // 2)
    while chunk >= 1:
        i = 0
        while i < len(case[side]["points"]):
            pts = case[side]["points"]
            if len(pts) - chunk < minimum:
                break
            trial = copy.deepcopy(case)
            trial[side]["points"] = pts[:i] + pts[i + chunk:]
            if ok(trial):
                case[side]["points"] = trial[side]["points"]
                changed = True
            else:
                i += chunk
        chunk //= 2
    return changed


def _relative_pose(case, ok) -> bool:
    pa = np.asarray(case["pose_a"], float)
    if np.array_equal(pa, np.eye(4)):
        return False
    trial = copy.deepcopy(case)
    trial["pose_a"] = np.eye(4).tolist()
    trial["pose_b"] = (np.linalg.inv(pa) @ np.asarray(case["pose_b"], float)).tolist()
    if ok(trial):
        case.update(trial)
        return True
    return False


def _round(x, digits: int):
    x = np.asarray(x, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        mag = np.where(x == 0, 0, np.floor(np.log10(np.abs(np.where(x == 0, 1, x)))))
    scale = 10.0 ** (digits - 1 - mag)
    return np.round(x * scale) / scale


def _fields(case, shapes: bool = True):
    """(getter, setter) pairs over the case's numbers, one field (an array or a scalar) at a time: the
    shapes' (unless ``shapes`` is False) and the poses'."""
    out = []
    for side in ("a", "b") if shapes else ():
        for key, value in case[side].items():
            if key == "kind":
                continue
            out.append((lambda c, s=side, k=key: c[s][k], lambda c, v, s=side, k=key: c[s].__setitem__(k, v)))
    for key in ("pose_a", "pose_b"):
        out.append((lambda c, k=key: np.asarray(c[k], float)[:3, 3].tolist(),
                    lambda c, v, k=key: _set_translation(c, k, v)))
        out.append((lambda c, k=key: Rotation.from_matrix(np.asarray(c[k], float)[:3, :3]).as_quat().tolist(),
                    lambda c, v, k=key: _set_rotation(c, k, v)))
    return out


def _set_translation(case, key, v):
    p = np.asarray(case[key], float)
    p[:3, 3] = v
    case[key] = p.tolist()


def _set_rotation(case, key, quat):
    p = np.asarray(case[key], float)
    q = np.asarray(quat, float)
    if not np.isfinite(q).all() or np.linalg.norm(q) == 0:
        raise ValueError("degenerate quaternion")
    p[:3, :3] = Rotation.from_quat(q / np.linalg.norm(q)).as_matrix()
    case[key] = p.tolist()


def _round_numbers(case, ok, shapes: bool = True) -> bool:
    changed = False
    for get, put in _fields(case, shapes):
        value = get(case)
        for digits in range(1, 16):
            rounded = _round(value, digits)
            if np.array_equal(rounded, np.asarray(value, float)):
                break
            trial = copy.deepcopy(case)
            try:
                put(trial, rounded.tolist() if rounded.ndim else float(rounded))
            except ValueError:
                continue
            if ok(trial):
                case.clear()
                case.update(trial)
                changed = True
                break
    return changed


def save(case: dict, folder, name: str | None = None) -> Path:
    """Write the reproducer as JSON under ``folder`` (name: family-mode-verdict-N by default)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    if name is None:
        stem = f"{case['family']}-{case['mode']}-{case['verdict']}"
        k = 1
        while (folder / f"{stem}-{k}.json").exists():
            k += 1
        name = f"{stem}-{k}.json"
    path = folder / name
    path.write_text(json.dumps(case, indent=1) + "\n")
    return path
