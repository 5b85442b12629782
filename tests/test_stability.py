"""spq stability on tiny settings: the tables and the heat map are written and spq never returns a wrong
number; the generated cases are a pure function of (seed, index), the full run holds at least 10^4 of
them, and a deliberately wrong engine is judged wrong against the exact reference and the fuzz oracle."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from harness.cli import main


def test_stability_quick_writes_tables_and_spq_is_never_wrong(tmp_path):
    assert main(["stability", "--quick", "--quiet", "--out", str(tmp_path)]) == 0
    for name in ("stability.csv", "stability.md", "stability_summary.csv", "stability_summary.md"):
        assert (tmp_path / name).stat().st_size > 0
    table = pd.read_csv(tmp_path / "stability.csv")
    assert {"touching", "overlap_shallow", "overlap_deep", "scale", "far_from_origin", "flat_needle",
            "near_parallel", "fcl_box_gap_3"} <= set(table.family)
    spq_rows = table[table.engine == "spq"]
    assert len(spq_rows) > 50
    assert not (spq_rows.verdict == "wrong").any(), spq_rows[spq_rows.verdict == "wrong"].to_string()
    summary = pd.read_csv(tmp_path / "stability_summary.csv")
    assert int(summary.loc[summary.engine == "spq", "wrong"].iloc[0]) == 0
    assert "### near_parallel" in (tmp_path / "stability_summary.md").read_text()
    pen = {"pen_shallow", "pen_containment", "pen_parallel", "pen_scale", "pen_far_from_origin",
           "pen_degenerate_simplex", "pen_long_face"}
    assert pen <= set(table.family)
    for engine, rows in table[table.family.isin(pen)].groupby("engine"):  # every engine ran every family
        assert set(rows.family) == pen, engine
    spq_depth = spq_rows[spq_rows.depth_verdict.notna() & (spq_rows.depth_verdict != "")]
    assert len(spq_depth) > 30 and not (spq_depth.depth_verdict == "wrong").any()
    assert (spq_depth.depth_abs_error.dropna() <= spq_depth.allowed_depth_error.dropna()).all()
    assert (tmp_path / "stability_depth_worst.csv").stat().st_size > 0
    # the generated cases: one per fuzz family, judged and drawn into the heat map
    from harness.suites.fuzz.families import FAMILIES

    generated = pd.read_csv(tmp_path / "stability_generated_detail.csv.gz")
    assert set(generated.family) == set(FAMILIES)
    gen_spq = generated[generated.engine == "spq"]
    assert len(gen_spq) == generated.case_index.nunique() >= len(FAMILIES)
    assert not gen_spq.verdict.isin(["wrong", "no_reference"]).any(), gen_spq.to_string()
    assert set(generated.reference) <= {"exact", "bracket", "oracle", "dense oracle"}
    assert (generated[generated.engine != "spq"].reference == "exact").all()  # the peers: polytope pairs only
    png = (tmp_path / "stability_heatmap.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    text = (tmp_path / "stability_summary.md").read_text()
    assert "stability_heatmap.png" in text and "A case is one shape pair at one pose" in text
    summary_n = int(summary.loc[summary.engine == "spq", "n"].iloc[0])
    assert summary_n == len(spq_rows) + len(gen_spq)  # the summary counts both kinds of case


def test_depth_verdicts():
    from harness.suites.stability.hard_cases import depth_verdict

    assert depth_verdict("spq", True, "overlapping", -0.1, -0.1, 1.0)[0] == "ok"
    assert depth_verdict("spq", True, "overlapping", -0.1 + 1e-6, -0.1, 1.0)[0] == "wrong"
    assert depth_verdict("spq", True, "separated", 1e-6, -1e-6, 1.0)[0] == "wrong"  # the wrong side of contact
    assert depth_verdict("spq", True, "failed", float("nan"), -0.1, 1.0)[0] == "failed"
    assert depth_verdict("spq", False, "overlapping", 0.0, -0.1, 1.0)[0] == "no depth"


def test_generated_case_is_a_pure_function_of_seed_and_index():
    from harness.suites.stability import hard_cases as st

    k = 3 * st.POSES_PER_DRAW + 7
    later = st.generated_case(0, k)
    st.generated_case(0, 5)  # other draws in between change nothing
    again = st.generated_case(0, k)
    for key in ("family", "regime"):
        assert later[key] == again[key]
    assert later["a"] == again["a"] and later["b"] == again["b"]
    assert np.array_equal(later["pose_a"], again["pose_a"]) and np.array_equal(later["pose_b"], again["pose_b"])
    family, a, b, pa, pb, _ = st.generated_draw(0, 3)  # case k is pose k % P of draw k // P
    assert family == later["family"] and a == later["a"] and np.array_equal(pa[7], later["pose_a"])
    other = st.generated_case(1, k)  # another seed, another case
    assert other["a"] != later["a"] or not np.array_equal(other["pose_a"], later["pose_a"])
    with pytest.raises(ValueError, match="case index"):
        st.generated_case(0, -1)


def test_full_config_has_at_least_1e4_cases_over_every_family():
    from harness.suites.fuzz.families import FAMILIES
    from harness.suites.stability import hard_cases as st

    config = st.StabilityConfig()
    indices = st.generated_indices(config)
    assert len(indices) >= 10_000 and len(set(indices)) == len(indices)
    draws = st.generated_tasks(config)
    assert sum(len(picks) for _, _, picks in draws) == len(indices)
    per_family = pd.Series([st.GENERATED_SCHEDULE[j % len(st.GENERATED_SCHEDULE)] for _, j, _ in draws]).value_counts()
    assert set(per_family.index) == set(FAMILIES) and per_family.min() >= 5
    quick = st.generated_indices(st.StabilityConfig(quick=True))
    assert {st.GENERATED_SCHEDULE[k // st.POSES_PER_DRAW] for k in quick} == set(FAMILIES)
    assert st.generated_indices(st.StabilityConfig(generated=False)) == []
    with pytest.raises(ValueError, match="generated_cases"):
        st.StabilityConfig(generated_cases=-1)


class _Shifted:
    """An engine that answers spq's signed distance plus ``shift`` metres: a deliberately wrong engine."""

    name, tolerance, gives_depth = "shifted", 1e-6, True

    def __init__(self, shift: float):
        self.shift = shift

    def prepare(self, a, b):
        from harness.engines.spq_engine import SpqEngine

        inner, shift = SpqEngine(signed=True).prepare(a, b), self.shift

        class Pair:
            def __enter__(self):
                return self

            def __exit__(self, *exc):
                return None

            def query_many(self, poses_a, poses_b):
                r = inner.query_many(poses_a, poses_b)
                r.raw_distance = r.raw_distance + shift
                r.distance = np.maximum(r.raw_distance, 0.0)
                return r

        return Pair()


def test_a_wrong_peer_is_judged_wrong_against_the_exact_reference():
    from harness.engines import available_engines
    from harness.suites.stability import hard_cases as st

    j = st.GENERATED_SCHEDULE.index("hull-random")
    rows = pd.DataFrame(st.draw_rows(0, j, (0, 1, 2, 3), {**available_engines(["spq"]), "shifted": _Shifted(1e-3)}))
    assert (rows.reference == "exact").all()
    assert (rows[rows.engine == "spq"].verdict == "ok").all()
    liar = rows[rows.engine == "shifted"]
    assert len(liar) == 4 and (liar.verdict == "wrong").all(), liar.to_string()
    assert (liar.abs_error.where(liar.ref_signed > 0) - 1e-3).abs().max() < 1e-9  # the shift, measured


@pytest.mark.parametrize("shift", [-1e-3, 1e-3])
def test_a_wrong_spq_is_judged_wrong_against_the_fuzz_oracle(monkeypatch, shift):
    """spq's answers on a non-polytope pair (separated poses) shifted by 1 mm: below the oracle's lower
    bound of the signed distance, or above the distance of two points of the bodies (the support points
    along the oracle's or spq's normal), so 'wrong', not merely disputed, whichever way it was settled."""
    from harness.engines import available_engines
    from harness.suites.fuzz import judge
    from harness.suites.stability import hard_cases as st
    from spq.kernels.gjk import OUT_DISTANCE

    true_outputs = judge.spq_outputs

    def shifted(*args, **kwargs):
        out = true_outputs(*args, **kwargs)
        for o in out.values():
            o[:, OUT_DISTANCE] += shift
        return out

    j = st.GENERATED_SCHEDULE.index("stp-min-R")
    honest = pd.DataFrame(st.draw_rows(0, j, (0, 1, 2), available_engines(["spq"])))
    assert (honest.verdict == "ok").all() and (honest.ref_signed > 0).all(), honest.to_string()
    monkeypatch.setattr(judge, "spq_outputs", shifted)
    rows = pd.DataFrame(st.draw_rows(0, j, (0, 1, 2), available_engines(["spq"])))
    assert set(rows.reference) <= {"bracket", "oracle", "dense oracle"}
    assert (rows.verdict == "wrong").all(), rows.to_string()
