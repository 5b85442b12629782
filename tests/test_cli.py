"""The spq command line on small inputs: each command runs and writes its tables."""

from __future__ import annotations

import pandas as pd

from harness.cli import main


def test_bench_pch_writes_rates_and_the_ratio_to_coal(tmp_path):
    assert main(["bench", "pch", "--poses", "300", "--repeats", "1", "--quiet", "--engines", "spq", "coal",
                 "--out", str(tmp_path)]) == 0
    table = pd.read_csv(tmp_path / "bench_pch.csv")
    assert set(table.engine) == {"spq", "coal"}
    assert set(table[table.engine == "spq"]["mode"]) == {"batched", "per-call", "batched signed", "per-call signed",
                                                          "plain call", "plain call signed"}
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
    on_meshes = table["mode"].str.startswith("per-call on STP-BV mesh")
    assert set(table[(table.pair != "PCH-PCH") & ~on_meshes].engine) == {"spq"}
    # coal on the STP-BV's certified meshes (inside the STP-BV, within mesh_error_m of it), an external
    # oracle for spq's exact signed distances: at or above them, by at most 1 (STP-PCH) or 2 (STP-STP) times
    # the mesh's error, beside coal's own GJK/EPA tolerance
    meshes = pd.read_csv(tmp_path / "bench_stp_meshes.csv")
    assert len(meshes) == 2 * 2 * 2 and set(meshes.engine) == {"coal"}  # 2 pairs x 2 meshes x 2 pose sets
    sides = meshes.pair.map({"STP-PCH": 1, "STP-STP": 2})
    assert (meshes.diff_min_m >= -1e-6).all()
    assert (meshes.diff_max_m <= sides * meshes.mesh_error_m + 1e-6).all()
    assert (meshes.spq_batched_signed_speedup > 0).all() and (meshes.queries_per_s > 0).all()


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


def test_bench_table1_cse_option_reaches_the_table(tmp_path):
    import pytest

    from harness.suites.table1 import CSE_PRESETS, cse_spec
    from spq import Superellipsoid

    assert main(["bench", "table1", "--cse", "boxy", "--poses", "200", "--repeats", "1", "--quiet",
                 "--out", str(tmp_path)]) == 0
    boxy = Superellipsoid(*CSE_PRESETS["boxy"])
    volumes = pd.read_csv(tmp_path / "table1_volumes.csv")
    assert volumes.loc[volumes.BV == "CSE", "volume_m3"].iloc[0] == pytest.approx(boxy.volume(), rel=1e-12)
    text = (tmp_path / "table1.md").read_text()
    assert "'boxy'" in text and f"e1 = {boxy.e1:.4g}, e2 = {boxy.e2:.4g}" in text
    given = "0.05,0.11,0.08,0.3,0.7"
    assert main(["bench", "table1", "--cse", given, "--poses", "200", "--repeats", "1", "--quiet",
                 "--out", str(tmp_path)]) == 0
    text = (tmp_path / "table1.md").read_text()
    assert "'custom'" in text and "a = 0.05 m, b = 0.11 m, c = 0.08 m, e1 = 0.3, e2 = 0.7" in text
    assert cse_spec(given) == ("custom", (0.05, 0.11, 0.08, 0.3, 0.7))
    assert cse_spec("fit") == ("fit", None)


def test_bench_table1_rejects_a_bad_cse(capsys):
    import pytest

    from harness.suites.table1 import cse_spec

    for bad, message in [("0.1,0.1,0.1,0.5", "five numbers"), ("0.1,0.1,0.1,0.5,2.5", "e2 must be in (0, 2]"),
                         ("0.1,-1,0.1,0.5,0.5", "b must be finite and > 0"), ("cube", "five numbers"),
                         ("0.1,0.1,x,0.5,0.5", "c must be a number")]:
        with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
            cse_spec(bad)
        with pytest.raises(SystemExit):
            main(["bench", "table1", "--cse", bad, "--poses", "10", "--quiet"])
        assert message in capsys.readouterr().err
