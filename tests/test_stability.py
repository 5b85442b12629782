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
