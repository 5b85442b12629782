"""spq tradeoff / rtradeoff: tiny runs through the command line and the harness functions."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from harness.cli import main
from harness.suites.tradeoff import sweeps as tr


def test_pareto_front():
    speed = np.array([10.0, 5.0, 20.0, 20.0, 1.0])
    error = np.array([1e-3, 1e-6, 1e-2, 1e-1, np.inf])
    assert tr.pareto_front(speed, error).tolist() == [True, True, True, False, False]


def test_tradeoff_quick(tmp_path):
    pytest.importorskip("coal")
    out = tmp_path / "t"
    # tiny: 3 separated buckets x 4 poses; spq at two tolerances, coal at one, no pybullet/fcl
    config = tr.quick_tradeoff_config(per_bucket=4, buckets=("distant-1", "close-1e-1", "close-1e-3"),
                                      spq_tols=(1e-3, 1e-10), coal_tols=(1e-8,), others=(), repeats=1)
    from datasets import load_object

    table, suite = tr.run_tradeoff(config, load_object)
    assert len(suite) == 12 and np.all(suite.ref_distance > 0)
    spq_b = table[(table.engine == "spq") & (table["mode"] == "batched")].set_index("tolerance")
    assert spq_b.loc[1e-10, "max_abs_error"] < spq_b.loc[1e-3, "max_abs_error"]
    assert spq_b.loc[1e-10, "max_abs_error"] < 1e-9
    assert (table.queries_per_s > 0).all() and table.pareto_max.any()
    tr.plot_tradeoff(table, out.with_suffix(".png"))
    assert out.with_suffix(".png").stat().st_size > 0


def test_tradeoff_cli_quick(tmp_path):
    pytest.importorskip("coal")
    pytest.importorskip("fcl")
    pytest.importorskip("pybullet")
    assert main(["tradeoff", "--quick", "--per-bucket", "2", "--repeats", "1", "--out", str(tmp_path),
                 "--quiet"]) == 0
    for name in ("tradeoff.csv", "tradeoff.md", "tradeoff.png"):
        assert (tmp_path / name).stat().st_size > 0
    table = pd.read_csv(tmp_path / "tradeoff.csv")
    assert {"spq", "coal", "fcl", "bullet", "bullet-margin"} <= set(table.engine)
    s = table[(table.engine == "spq") & (table["mode"] == "batched")].set_index("tolerance")
    assert s.loc[1e-10, "max_abs_error"] < s.loc[1e-3, "max_abs_error"]


def test_rtradeoff_cli_quick(tmp_path):
    assert main(["rtradeoff", "--quick", "--out", str(tmp_path), "--quiet"]) == 0
    for name in ("rtradeoff.csv", "rtradeoff.md", "rtradeoff.png"):
        assert (tmp_path / name).stat().st_size > 0
    table = pd.read_csv(tmp_path / "rtradeoff.csv").sort_values("R")
    assert len(table) >= 3
    features, excess = table.features.to_numpy(), table.volume_excess.to_numpy()
    assert np.all(np.diff(features) >= 0) and features[-1] > features[0], features.tolist()
    assert np.all(np.diff(excess) <= 0) and excess[-1] < excess[0], excess.tolist()
    assert table.recommended.sum() == 1
    assert "Recommendation" in (tmp_path / "rtradeoff.md").read_text()
