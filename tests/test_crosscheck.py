"""A small cross-check: spq against the exact reference and coal on real links, every bucket."""

import numpy as np
import pytest

from datasets import load_object
from harness.suites.crosscheck import scoring as cc


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


@pytest.mark.engines
def test_depth_is_scored_against_the_reference_and_an_engine_without_depth_is_listed(monkeypatch):
    from harness import engines as engines_mod
    from harness.engines import register_engine

    # the two test engines stay in this test (a later report would list them as engines of its own)
    monkeypatch.setattr(engines_mod, "ENGINE_FACTORIES", dict(engines_mod.ENGINE_FACTORIES))
    from harness.engines.coal_engine import CoalEngine

    class OffByAMillimetre(CoalEngine):
        """coal with every signed distance made 1 mm deeper: a wrong depth the scores must show."""

        def prepare(self, a, b):
            pair = super().prepare(a, b)
            inner = pair.query_many

            def query_many(pa, pb):
                r = inner(pa, pb)
                r.raw_distance = r.raw_distance - 1e-3
                return r

            pair.query_many = query_many
            return pair

    class NoDepth(CoalEngine):
        gives_depth = False

    register_engine("coal-deeper", lambda: OffByAMillimetre(name="coal-deeper"), replace=True)
    register_engine("coal-nodepth", lambda: NoDepth(name="coal-nodepth"), replace=True)
    config = cc.CrosscheckConfig(objects=["kuka_link_4"], per_bucket=5, seed=4,
                                 engines=["spq", "coal-deeper", "coal-nodepth"],
                                 buckets=["close-1e-2", "touching", "overlap-1e-3", "overlap-1e-1"])
    table = cc.run(config, load_object, progress=False)
    depth = cc.depth_summary(table)
    spq_rows = depth[depth.engine == "spq"]
    assert set(spq_rows.bucket) == {"touching", "overlap-1e-3", "overlap-1e-1"}  # separated buckets not scored
    assert spq_rows.max_abs_depth_error.max() <= 1e-9 and (spq_rows.certificate_holds_pct == 100).all()
    assert (spq_rows.sign_errors == 0).all() and spq_rows.max_witness_off_surface.max() <= 1e-9
    deeper = depth[depth.engine == "coal-deeper"]
    assert np.allclose(deeper.median_abs_depth_error, 1e-3, atol=1e-6)
    assert list(depth[depth.engine == "coal-nodepth"].depth) == ["no depth"]
    worst = cc.depth_worst_cases(table, k=2)
    assert set(worst.engine) == {"spq", "coal-deeper"}
