"""A quick continuity run: polyhedral witness points jump, STP-BV ones stay Lipschitz, gradients match FD."""

from __future__ import annotations

import numpy as np
import pytest

from harness.suites.continuity import witness_continuity as ct

R = 2.0


@pytest.fixture(scope="module")
def table():
    from datasets import load_object

    config = ct.quick_config(engines=(), pairs=[("PCH", "PCH"), ("STP", "PCH"), ("STP", "STP")],
                             trajectories=("parallel_faces", "random_path"), R=R)
    tab, paths = ct.run(config, load_object)
    assert set(paths) == {("PCH-PCH", "spq"), ("STP-PCH", "spq"), ("STP-STP", "spq")}
    return tab


def _ratios(table, trajectory, pair):
    g = table[(table.trajectory == trajectory) & (table.pair == pair) & (table.engine == "spq")].sort_values("step_s")
    return g.witness_lipschitz.to_numpy()  # smallest step first


def test_all_separated(table):
    assert (table.not_separated == 0).all()
    assert (table.min_distance_m > 0.005).all()


def test_polyhedra_jump_on_parallel_faces(table):
    r = _ratios(table, "parallel_faces", "PCH-PCH")
    assert r[0] > 10 * r[-1], r


@pytest.mark.parametrize("pair", ["STP-PCH", "STP-STP"])
def test_stp_bounded_on_parallel_faces(table, pair):
    r = _ratios(table, "parallel_faces", pair)  # m/rad: steps 5e-6, 5e-4, 5e-2 rad
    assert r[0] < 1.5 * r[1], r
    assert r[0] < 2.0 * R, r


@pytest.mark.parametrize("pair", ["STP-PCH", "STP-STP"])
def test_stp_bounded_on_random_path(table, pair):
    r = _ratios(table, "random_path", pair)
    assert r[0] < 1.5 * r[1], r


@pytest.mark.parametrize("pair", ["STP-PCH", "STP-STP"])
def test_gradient_matches_fd(table, pair):
    g = table[(table.pair == pair) & (table.engine == "spq")]
    assert (g.grad_rel_error < 1e-6).all(), g[["trajectory", "grad_abs_error", "grad_rel_error"]]


def test_engines_optional_pch_rows():
    from datasets import load_object

    pytest.importorskip("coal")
    config = ct.quick_config(engines=("coal",), pairs=[("PCH", "PCH")], trajectories=("parallel_faces",),
                             steps=(1e-1, 1e-4), grid=21, gradient_samples=3)
    tab, _ = ct.run(config, load_object)
    coal = tab[tab.engine == "coal"].sort_values("step_s")
    assert len(coal) == 2 and np.isnan(coal.grad_rel_error).all()
    assert coal.witness_lipschitz.iloc[0] > 10 * coal.witness_lipschitz.iloc[1]



def _contact_rows(a, b):
    from datasets import load_object
    from harness.suites.continuity import contact_continuity as cc

    config = cc.ContactConfig(paths=2, grid=101, seed=1)
    bodies = cc.build_bodies(config, load_object)
    for k in range(config.paths):
        path = cc.ContactPath(bodies[a], bodies[b], config, 100 + k)
        yield cc.measure(path, config)


def test_pch_signed_distance_passes_contact_without_a_step():
    # the signed distance is 1-Lipschitz in B's translation (and the rotation here is slow), so a
    # sign change bisected 40 times leaves a difference far below 1e-9 m
    for row, curve in _contact_rows("PCH", "PCH"):
        assert row["crossings"] == 2 and row["failed"] == 0, row
        assert row["max_crossing_jump_m"] < 1e-9
        assert row["min_signed_m"] < -1e-3 and curve["distance"][0] > 0 and curve["distance"][-1] > 0


def test_stp_gradient_does_not_jump_through_contact():
    for row, _ in _contact_rows("STP", "PCH"):
        assert row["crossings"] == 2 and row["gradient_jumps"] - row["gradient_jumps_deeper_than_r"] == 0, row


def test_stp_signed_distance_passes_contact_without_a_step():
    for row, _ in _contact_rows("STP", "PCH"):
        assert row["failed"] == 0 and row["max_crossing_jump_m"] < 1e-9, row
