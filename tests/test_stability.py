"""spq stability on tiny settings: the tables are written and spq never returns a wrong number."""

from __future__ import annotations

import pandas as pd

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


def test_depth_verdicts():
    from harness.stability import depth_verdict

    assert depth_verdict("spq", True, "overlapping", -0.1, -0.1, 1.0)[0] == "ok"
    assert depth_verdict("spq", True, "overlapping", -0.1 + 1e-6, -0.1, 1.0)[0] == "wrong"
    assert depth_verdict("spq", True, "separated", 1e-6, -1e-6, 1.0)[0] == "wrong"  # the wrong side of contact
    assert depth_verdict("spq", True, "failed", float("nan"), -0.1, 1.0)[0] == "failed"
    assert depth_verdict("spq", False, "overlapping", 0.0, -0.1, 1.0)[0] == "no depth"
