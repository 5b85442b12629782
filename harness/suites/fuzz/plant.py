"""Planted bugs: a deliberately broken spq answer, to show that the campaign finds and shrinks such a bug.

``early-stop``: the GJK stops once its gap is within 1e-2 relative (instead of spq's 1e-10) and reports
its bounds as closed (lower bound = upper bound = the distance it stopped at), the behaviour of a
search that quits an iteration or more too early yet claims convergence. On a round body it returns a
distance slightly too large with a certificate that excludes the true one.

``refuse-cse``: packing a superellipsoid raises a ValueError, as the inner polytope of a flat diamond
once did (docs/notes/speed-45.md, stop 78): the campaign must record such a case as 'raised' and go on.
"""

from __future__ import annotations

EARLY_STOP_REL = 1e-2


def planted(name: str | None):
    """None, or a function (spec A, spec B, poses_a, poses_b) -> {mode: output rows} (an spq answering
    wrong, or raising)."""
    if name is None:
        return None
    if name not in PLANTS:
        raise ValueError(f"unknown planted bug {name!r}; choose from {list(PLANTS)}")
    return PLANTS[name]


def _early_stop(a: dict, b: dict, poses_a, poses_b):
    from harness.suites.fuzz.judge import spq_outputs
    from harness.suites.fuzz.oracle import spq_shape
    from spq.kernels.gjk import OUT_LOWER, OUT_UPPER

    out = spq_outputs(spq_shape(a), spq_shape(b), poses_a, poses_b, rel_tol=EARLY_STOP_REL)
    for rows in out.values():
        rows[:, OUT_LOWER] = rows[:, OUT_UPPER]
    return out


def _refuse_cse(a: dict, b: dict, poses_a, poses_b):
    from harness.suites.fuzz.judge import spq_outputs
    from harness.suites.fuzz.oracle import spq_shape

    if "cse" in (a["kind"], b["kind"]):
        raise ValueError("planted: a superellipsoid's inner polytope is refused")
    return spq_outputs(spq_shape(a), spq_shape(b), poses_a, poses_b)


PLANTS = {"early-stop": _early_stop, "refuse-cse": _refuse_cse}
