"""spq ab: copies of the package at two revisions side by side, and how the suite times and compares them.

A whole A/B compiles the kernels twice (minutes), so these tests check its parts: the copies (renamed
imports, importable beside spq, reused, at a git revision), the row comparison and the alternating order
of the timed calls."""

import subprocess
from pathlib import Path

import numpy as np
import pytest

from harness.suites import ab
from harness.suites.ab import packages
from harness.suites.bench.timing import blocked_times

REPO = Path(__file__).resolve().parents[1]


def test_rename_imports_turns_every_import_of_spq_to_the_copy():
    source = ("from spq.kernels.jit import kernel\nimport spq.query\nfrom spq import Pair\n"
              "x = spq.kernels.gjk.OUT_SIZE\nfrom spqr import y\nname = 'spq'\n")
    out = packages.rename_imports(source, "spq_abc")
    assert out == ("from spq_abc.kernels.jit import kernel\nimport spq_abc.query\nfrom spq_abc import Pair\n"
                   "x = spq_abc.kernels.gjk.OUT_SIZE\nfrom spqr import y\nname = 'spq'\n")


def test_a_copy_of_the_working_tree_imports_beside_spq_and_is_reused(tmp_path):
    import spq

    name, resolved, folder = packages.prepare(REPO, packages.WORKING_TREE, tmp_path)
    assert resolved == packages.WORKING_TREE and name.startswith("spq_")
    copied = list((folder / name).rglob("*.py"))
    assert len(copied) == len(list((REPO / "spq").rglob("*.py")))
    for path in copied:
        text = path.read_text()
        assert "from spq." not in text and "import spq." not in text and "from spq import" not in text, path
    module = packages.load(name, folder)
    assert module.Pair is not spq.Pair and module.Pair.__module__.startswith(name + ".")
    assert packages.prepare(REPO, packages.WORKING_TREE, tmp_path) == (name, resolved, folder)


def test_a_copy_at_a_revision_is_that_commit_and_a_bad_revision_is_refused(tmp_path):
    head = subprocess.run(["git", "-C", str(REPO), "rev-parse", "HEAD"], capture_output=True, text=True)
    if head.returncode != 0:
        pytest.skip("not a git checkout")
    name, resolved, folder = packages.prepare(REPO, "HEAD", tmp_path)
    assert resolved == head.stdout.strip()
    assert (folder / name / "kernels" / "gjk.py").is_file()
    with pytest.raises(ValueError, match="no-such-revision"):
        packages.prepare(REPO, "no-such-revision", tmp_path)


def test_rows_differing_counts_rows_not_equal_bit_for_bit():
    a = np.array([[1.0, np.nan], [2.0, 3.0], [0.0, 1.0]])
    b = np.array([[1.0, np.nan], [2.0, np.nextafter(3.0, 4.0)], [-0.0, 1.0]])
    assert ab.rows_differing(a, a) == 0
    assert ab.rows_differing(a, b) == 1  # -0.0 == 0.0; the second row differs by an ulp


def test_blocked_times_alternates_which_version_runs_first():
    calls = []

    def job(key):
        return lambda a: calls.append((key, int(a[0])))

    poses = np.arange(4)
    blocked_times({"old": (job("old"), poses), "new": (job("new"), poses)}, 2, block=2, alternate=True)
    order = [("old", 0), ("new", 0), ("new", 2), ("old", 2),  # round 0: blocks 0, 1
             ("new", 0), ("old", 0), ("old", 2), ("new", 2)]  # round 1
    assert calls == [call for call in order for _ in range(2)]  # each timed call after an untimed one


def test_the_suite_refuses_unknown_pairs_and_empty_sizes():
    with pytest.raises(ValueError, match="pairs must be some of"):
        ab.run(ab.Config(pairs=["CSE-BOX"]))
    with pytest.raises(ValueError, match="five numbers"):
        ab.run(ab.Config(pairs=["CSE-CSE"], cse="0.1,0.1"))
    with pytest.raises(ValueError, match="repeats must be at least 1"):
        ab.run(ab.Config(repeats=0))


def test_result_rows_are_the_public_fields_in_order():
    from types import SimpleNamespace

    n = 3
    rng = np.random.default_rng(0)
    batch = SimpleNamespace(distance=rng.normal(size=n), point_a=rng.normal(size=(n, 3)),
                            point_b=rng.normal(size=(n, 3)), normal=rng.normal(size=(n, 3)),
                            lower_bound=rng.normal(size=n), upper_bound=rng.normal(size=n),
                            iterations=np.array([4, 5, 6]), status_code=np.array([0, 2, 3], dtype=np.int8))
    rows = ab.result_rows(batch)
    assert rows.shape == (n, 14)
    assert np.array_equal(rows[:, 0], batch.distance) and np.array_equal(rows[:, 7:10], batch.normal)
    assert list(rows[:, ab.STATUS_COLUMN]) == [0.0, 2.0, 3.0] and list(rows[:, 12]) == [4.0, 5.0, 6.0]


def _stub_version(out_size, out_distance=0):
    from types import SimpleNamespace

    return SimpleNamespace(kernels=SimpleNamespace(gjk=SimpleNamespace(OUT_SIZE=out_size, OUT_DISTANCE=out_distance)))


def test_sweep_rows_differing_compares_whole_rows_or_only_distances_across_layouts():
    a = np.zeros((2, 3, 4))
    b = a.copy()
    b[1, 2, 3] = 1.0  # one pair's row differs outside its distance
    assert ab.sweep_rows_differing([_stub_version(4), _stub_version(4)], [a, b]) == 1
    c = np.zeros((2, 3, 5))  # a version with a longer result row: its distances alone are compared
    c[0, 0, 0] = 0.5
    assert ab.sweep_rows_differing([_stub_version(4), _stub_version(5)], [b, c]) == 1


@pytest.mark.parametrize("coherent", [False, True])
def test_sweep_row_times_both_scenes_on_the_same_configurations_and_counts_what_differs(coherent):
    class StubScene:
        """distances_many writes each pair's row from the configuration; ``bias`` moves one pair."""

        def __init__(self, bias):
            self.pairs = [(0, 1), (0, 2), (1, 2)]
            self.bias = bias
            self.seen = []
            self.resets = 0

        def reset(self):
            self.resets += 1

        def distances_many(self, qs, coherent=False, out=None):
            assert coherent is want
            out = np.empty((len(qs), len(self.pairs), 4)) if out is None else out
            out[:] = qs.sum(axis=1)[:, None, None]
            out[:, 2, 0] += self.bias
            self.seen.append(np.array(qs))
            return out

    want = coherent
    qs = np.arange(20.0).reshape(10, 2)
    old, new = StubScene(0.0), StubScene(1.0)
    config = ab.Config(repeats=2, robot_block=4)
    row = ab.sweep_row([_stub_version(4), _stub_version(4)], [old, new], qs, "bot pch", config, None, coherent=coherent)
    assert row["pair"] == "bot pch (3 pairs)" and row["queries"] == 30
    assert row["mode"] == ("coherent sweep" if coherent else "cold sweep")
    assert old.resets == new.resets == 1  # each version's warm starts forgotten before its first call
    assert row["rows_differing"] == 10  # the third pair of every configuration
    assert row["old_s"] > 0 and row["new_s"] > 0
    timed = [q for q in old.seen if len(q) != 2]  # (the first call, on two configurations, compiles)
    # every block twice in a row (an untimed call, then the timed one), all configurations in each of two rounds
    assert all(np.array_equal(warm, once) for warm, once in zip(timed[::2], timed[1::2]))
    once = np.concatenate(timed[1::2])
    assert np.array_equal(once, np.concatenate([qs, qs]))


def test_the_suite_refuses_a_bad_robot_set_up_before_copying_anything():
    with pytest.raises(ValueError, match="unknown robot"):
        ab.run(ab.Config(robot="no-such-robot"))
    with pytest.raises(ValueError, match="policies must be some of"):
        ab.run(ab.Config(robot="jvrc1", policies=["hull"]))
    with pytest.raises(ValueError, match="configs must be at least 1"):
        ab.run(ab.Config(robot="jvrc1", configs=0))
    with pytest.raises(ValueError, match="none only with a robot"):
        ab.run(ab.Config(pairs=[]))


def test_outside_bounds_counts_rows_where_the_two_versions_cannot_both_be_right():
    rows = np.zeros((4, 14))
    rows[:, 0], rows[:, ab.LOWER_COLUMN], rows[:, ab.UPPER_COLUMN] = 1.0, 1.0 - 1e-9, 1.0 + 1e-9
    other = rows.copy()
    other[1, 0] = 1.0 + 5e-10  # moved, but inside the first version's bounds, and they inside its own
    other[2, 0], other[2, ab.LOWER_COLUMN], other[2, ab.UPPER_COLUMN] = 1.1, 1.1, 1.1  # beyond them
    other[3, ab.LOWER_COLUMN] = other[3, ab.UPPER_COLUMN] = 1.0 + 5e-9  # its bounds exclude the first's distance
    assert ab.outside_bounds(rows, rows) == 0
    assert ab.outside_bounds(rows, other) == 2 and ab.outside_bounds(other, rows) == 2


def test_cse_pairs_are_placed_as_table1_places_them():
    import spq
    from datasets import load_object

    link = load_object("kuka_link_4")
    pairs = ab._pairs(spq, "kuka_link_4", ["CSE-STP", "CSE-CSE"], False, 0.005, 2.0, "fit")
    cse, offset = spq.Superellipsoid.fit(link.vertices)
    pair, offset_a, offset_b = pairs["CSE-STP"]
    assert isinstance(pair.A, spq.Superellipsoid) and isinstance(pair.B, spq.STPBV)
    assert np.array_equal(offset_a, offset) and np.array_equal(offset_b, np.eye(4))
    assert (pair.A.a, pair.A.e1) == (cse.a, cse.e1)
    pair, offset_a, offset_b = ab._pairs(spq, "kuka_link_4", ["CSE-CSE"], True, 0.005, 2.0, "0.07,0.12,0.09,0.3,0.3")["CSE-CSE"]
    centre = 0.5 * (link.vertices.min(axis=0) + link.vertices.max(axis=0))
    assert np.allclose(offset_a[:3, 3], centre) and np.array_equal(offset_a, offset_b)
    assert (pair.A.a, pair.A.b, pair.A.c, pair.A.e1, pair.A.e2) == (0.07, 0.12, 0.09, 0.3, 0.3) and pair.signed
