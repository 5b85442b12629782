"""A small cross-check: spq against the exact reference and coal on real links, every bucket."""

import numpy as np
import pytest

from datasets import load_object
from harness import crosscheck as cc


@pytest.fixture(scope="module")
def table():
    config = cc.CrosscheckConfig(objects=["kuka_link_4", "panda_link_5", "random_hull_50"], per_bucket=6,
                                 seed=3, engines=["spq", "coal"])
    return cc.run(config, load_object, progress=False)


@pytest.mark.engines
def test_spq_matches_the_reference_in_every_bucket(table):
    spq_rows = table[table.engine == "spq"]
    assert set(spq_rows.bucket) == set(cc.BUCKETS)
    assert spq_rows.abs_error.max() <= 1e-9
    sep = spq_rows.ref_signed > cc.AMBIGUOUS_BAND
    assert spq_rows.witness_gap_error[sep].max() <= 1e-12
    assert spq_rows.witness_off_surface[sep].max() <= 1e-9
    assert (spq_rows.verdict == "ok").all()


@pytest.mark.engines
def test_coal_agrees_with_the_reference_within_its_tolerance(table):
    coal_rows = table[table.engine == "coal"]
    assert coal_rows.abs_error[coal_rows.ref_signed > cc.AMBIGUOUS_BAND].max() <= 1e-6
    assert (coal_rows.verdict != "failed").all()


def test_summary_has_one_row_per_engine_and_bucket(table):
    summary = cc.summarize(table)
    assert len(summary) == 2 * len(cc.BUCKETS)
    assert (summary.n == 6).all()
    worst = cc.worst_cases(table, k=3)
    assert set(worst.engine) == {"spq", "coal"} and len(worst) == 6


def test_status_verdicts_use_the_ambiguous_band():
    ref = np.array([1e-3, 1e-3, -1e-3, -1e-3, 1e-12, -1e-12, 1.0])
    status = np.array(["overlapping", "separated", "separated", "overlapping", "overlapping", "separated", "failed"])
    assert list(cc.status_verdict(ref, status)) == [
        "false_overlap", "ok", "missed_overlap", "ok", "ok", "ok", "failed"]


@pytest.mark.engines
def test_spq_and_coal_agree_on_random_poses():
    table = cc.agreement(["kuka_link_4", "panda_hand"], 4000, seed=1, load_object=load_object, progress=False)
    assert table.results.sum() == 8000
    assert (table.status_disagreements == 0).all() and (table.spq_failed == 0).all()
    assert table.max_abs_difference.max() <= cc.AGREEMENT_TOL
