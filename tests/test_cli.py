"""The spq command line on small inputs: each command runs and writes its tables."""

from __future__ import annotations

import pandas as pd

from harness.cli import main


def test_bench_pch_writes_rates_and_the_ratio_to_coal(tmp_path):
    assert main(["bench", "pch", "--poses", "300", "--repeats", "1", "--quiet", "--engines", "spq", "coal",
                 "--out", str(tmp_path)]) == 0
    table = pd.read_csv(tmp_path / "bench_pch.csv")
    assert set(table.engine) == {"spq", "coal"}
    assert set(table[table.engine == "spq"]["mode"]) == {"batched", "per-call", "batched signed", "per-call signed"}
    assert set(table.poses) == {"all", "overlapping"}
    assert (table.queries_per_s > 0).all()
    assert (table.loc[table.engine == "coal", "ratio_to_coal_pch"] == 1.0).all()
    # the overlapping subset: every engine finds every pose overlapping, and spq signed gives depths
    sub = table[table.poses == "overlapping"]
    assert (sub.overlapping == sub.queries).all() and (sub.queries > 0).all()


def test_bench_stp_runs_stp_pairs_beside_pch(tmp_path):
    assert main(["bench", "stp", "--poses", "300", "--repeats", "1", "--quiet", "--engines", "spq", "coal",
                 "--out", str(tmp_path)]) == 0
    table = pd.read_csv(tmp_path / "bench_stp.csv")
    assert {"PCH-PCH", "STP-PCH", "STP-STP"} <= set(table.pair)
    assert set(table[table.pair != "PCH-PCH"].engine) == {"spq"}


def test_bench_table1_writes_the_lower_triangle_with_the_paper_beside(tmp_path):
    assert main(["bench", "table1", "--poses", "300", "--repeats", "1", "--quiet", "--out", str(tmp_path)]) == 0
    table = pd.read_csv(tmp_path / "table1.csv")
    assert len(table) == 6 and (table.failed == 0).all()
    volumes = pd.read_csv(tmp_path / "table1_volumes.csv")
    ratio = dict(zip(volumes.BV, volumes.volume_ratio_to_pch))
    assert ratio["PCH"] == 1.0 and ratio["STP"] > 1.0 and ratio["CSE"] > 1.0
    text = (tmp_path / "table1.md").read_text()
    assert "795,123" in text and "coal PCH-PCH in the same run" in text and "STP-STP takes" in text


def test_bench_support_writes_the_scaling_chart(tmp_path):
    assert main(["bench-support", "--object", "kuka_link_4", "--R-values", "0.3", "2.0", "--directions", "500",
                 "--repeats", "1", "--quiet", "--out", str(tmp_path)]) == 0
    table = pd.read_csv(tmp_path / "support_scaling.csv")
    assert set(table.method) == {"naive", "march", "hull"} and len(table) == 2 * 3 * 2
    assert (tmp_path / "support_scaling.png").stat().st_size > 10_000


def test_unknown_object_is_a_clear_error(tmp_path, capsys):
    assert main(["bench", "pch", "--object", "no_such_link", "--poses", "10", "--quiet", "--out", str(tmp_path)]) == 2
    assert "neither a known object nor an existing file" in capsys.readouterr().err


def test_bench_pch_with_workers_adds_the_threaded_batched_rows(tmp_path):
    assert main(["bench", "pch", "--poses", "300", "--repeats", "1", "--quiet", "--engines", "spq", "--workers", "2",
                 "--out", str(tmp_path)]) == 0
    table = pd.read_csv(tmp_path / "bench_pch.csv")
    modes = set(table["mode"])
    assert {"batched", "batched 2 workers", "batched signed 2 workers"} <= modes


def test_bad_workers_are_a_clear_error(tmp_path, capsys):
    assert main(["crosscheck", "--workers", "0", "--per-bucket", "1", "--agreement-poses", "0", "--engines", "spq",
                 "--quiet", "--out", str(tmp_path)]) == 2
    assert "workers must be an integer from 1 to" in capsys.readouterr().err
