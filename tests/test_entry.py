"""spq._entry, the per-call queries' entry points in C: the same answers and errors as the Python
ones they wrap (each C entry's ``__wrapped__``), on every kind, on threads, without leaking.

The oracle for the values is the Python path (the kernel compiled by numba's dispatcher, against the
C path's cfunc copy of it) and, for the polytopes, the exact Minkowski reference."""

import contextlib
import os
import pickle
import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import spq
import spq.query as sq
from harness.references.minkowski import reference_distance
from tests.test_gjk import hull, pose, random_pose


@pytest.fixture(scope="module", autouse=True)
def compiled():
    """The C entries, built in place by the README's editable install: under CI their absence fails
    (the tests would only ever see the Python path), elsewhere it skips."""
    if sq._entry is None:
        if os.environ.get("CI"):
            pytest.fail("spq._entry is not built: install with pip install -e . (a C compiler is needed)")
        pytest.skip("spq._entry is not built (pip install -e . builds it)")


PYTHON_PLAIN = spq.distance.__wrapped__ if sq._entry is not None else spq.distance


def shapes():
    rng = np.random.default_rng(3)
    pts = rng.normal(size=(30, 3)) * 0.15
    return {"box": spq.Box(0.05, 0.1, 0.15), "sphere": spq.Sphere(0.1), "capsule": spq.Capsule(0.05, 0.15),
            "pch": spq.Polyhedron.from_points(pts), "stp": spq.STPBV.from_points(pts, 0.02, 1.0),
            "cse": spq.Superellipsoid(0.1, 0.08, 0.05, 0.5, 0.7)}


def test_the_entries_are_compiled_and_keep_the_python_ones_signatures():
    import inspect

    assert type(spq.distance).__module__ == "spq._entry" and type(spq.Pair.distance).__module__ == "spq._entry"
    for entry in (spq.distance, spq.Pair.distance, spq.Pair.cold_distance):
        assert inspect.signature(entry) == inspect.signature(entry.__wrapped__)
        assert entry.__doc__ == entry.__wrapped__.__doc__ and entry.__doc__
    assert pickle.loads(pickle.dumps(spq.distance)) is spq.distance
    pair = spq.Pair(spq.Sphere(0.1), spq.Sphere(0.1))
    bound = pair.distance  # a method bound to its pair, as a function's
    assert bound.__self__ is pair and bound(np.eye(4), pose(t=(1, 0, 0))).distance == pytest.approx(0.8)


def test_c_and_python_entries_agree_bit_for_bit_on_every_kind():
    """Every kind against every kind, unsigned and signed: the plain call, a Pair's cold call and a
    Pair along a path, each through C and through Python, give the same result arrays bit for bit;
    on the polytopes, the bounds hold the exact reference's distance."""
    rng = np.random.default_rng(12)
    pa = np.stack([random_pose(rng, 0.0) for _ in range(5)])
    pb = np.stack([random_pose(rng, 0.25) for _ in range(5)])
    kinds = shapes()
    for a_name, A in kinds.items():
        for b_name, B in kinds.items():
            for signed in (False, True):
                c_pair, py_pair = spq.Pair(A, B, signed=signed), spq.Pair(A, B, signed=signed)
                for i in range(len(pa)):
                    where = (a_name, b_name, signed, i)
                    c = spq.distance(A, B, pa[i], pb[i], signed=signed)
                    py = PYTHON_PLAIN(A, B, pa[i], pb[i], signed=signed)
                    assert type(c) is type(py) and type(c.distance) is float, where
                    assert c.distance == py.distance and np.array_equal(c._out, py._out, equal_nan=True), where
                    cold = c_pair.cold_distance(pa[i], pb[i])
                    assert np.array_equal(cold._out, py._out, equal_nan=True), where
                    step = c_pair.distance(pa[i], pb[i])
                    py_step = type(py_pair).distance.__wrapped__(py_pair, pa[i], pb[i])
                    assert np.array_equal(step._out, py_step._out, equal_nan=True), where
                    if a_name == b_name == "pch":
                        exact = reference_distance(A, B, pa[i], pb[i]).signed_distance
                        value = exact if signed else max(exact, 0.0)
                        assert c.lower_bound - 1e-9 <= value <= c.upper_bound + 1e-9, where


def test_plain_calls_over_more_shape_pairs_than_the_cache_holds_answer_as_batched_queries():
    """spq.distance over twice PLAIN_PAIRS shape pairs in turn (every kind against every kind, two
    copies of each shape), so that every call packs a new Pair and takes its machine code from the
    cache shared by all pairs (query._machine_code): through C and through Python, each result array
    is the batched query's (kb.query_batch through numba's own dispatch), bit for bit; between the
    polytopes, the bounds hold the exact reference's distance."""
    rng = np.random.default_rng(5)
    kinds = list(shapes().items()) + list(shapes().items())
    pairs = [(a, b) for a in kinds for b in kinds]
    assert len(pairs) >= 2 * sq.PLAIN_PAIRS
    for k in range(3 * len(pairs)):
        (a_name, A), (b_name, B) = pairs[k % len(pairs)]
        pa, pb, signed = random_pose(rng, 0.0), random_pose(rng, 0.2), bool(k % 2)
        batched = spq.distances(A, B, pa, pb, signed=signed)._rows[0]
        for call in (spq.distance, PYTHON_PLAIN):
            result = call(A, B, pa, pb, signed=signed)
            assert np.array_equal(result._out, batched, equal_nan=True), (k, call)
        if a_name == b_name == "pch":
            exact = reference_distance(A, B, pa, pb).signed_distance
            value = exact if signed else max(exact, 0.0)
            assert result.lower_bound - 1e-9 <= value <= result.upper_bound + 1e-9, k


def test_c_entries_take_the_python_path_and_its_errors_for_anything_else():
    """Keywords, positional options, poses of other types and layouts, bad values and bad calls:
    what the C entries do not take themselves they hand to Python, so answers and error messages
    are the Python entries'."""
    a, b = hull(41), hull(42)
    pb = pose(t=(0.3, 0.05, 0.0))
    readonly = pb.copy()
    readonly.flags.writeable = False
    swapped = pb.astype(">f8")
    calls = [
        lambda f: f(a, b, np.eye(4), pb),
        lambda f: f(a, b, np.eye(4), pb, 1e-10, 1e-10, 128, True),
        lambda f: f(a, b, np.eye(4), pb, signed=True, tol=1e-6),
        lambda f: f(a, b, pose_a=np.eye(4), pose_b=pb),
        lambda f: f(a, b, np.eye(4), pb.tolist()),
        lambda f: f(a, b, np.asfortranarray(pb), np.eye(4)),
        lambda f: f(a, b, np.eye(4), readonly),
        lambda f: f(a, b, np.eye(4), swapped),
        lambda f: f(a, b, np.eye(4), pb.astype(np.float32)),
        lambda f: f(a, b, np.eye(4), np.eye(4)[None]),
        lambda f: f(a, b, np.eye(4), np.full((4, 4), np.nan)),
        lambda f: f(a, b, np.diag([2.0, 1, 1, 1]), pb),
        lambda f: f(a, b, np.eye(4), pb, tol=-1),
        lambda f: f(a, b, np.eye(4), pb, signed=1),
        lambda f: f(a, b, np.eye(4), pb, colour="red"),
        lambda f: f(a, b, np.eye(4), pb, 1e-10, tol=1e-10),
        lambda f: f(a, b, np.eye(4)),
        lambda f: f(a, a, b, pb),  # a shape for pose_a, the last pair's B: not spq 0.1's order (B is a shape)
        lambda f: f(a, np.eye(4), b, pb),  # spq 0.1's order: a warning, then the answer
    ]
    for k, call in enumerate(calls):
        for _ in range(2):  # the first call packs the pair; the second may take the C path
            outcomes = []
            for f in (spq.distance, PYTHON_PLAIN):
                try:
                    with pytest.warns(DeprecationWarning) if k == len(calls) - 1 and not sq._OLD_ORDER["warned"] \
                            else contextlib.nullcontext():
                        r = call(f)
                    outcomes.append(("result", r._out))
                except (ValueError, TypeError) as e:
                    outcomes.append((type(e), str(e)))
            (kind_c, c), (kind_py, py) = outcomes
            assert kind_c == kind_py, k
            assert np.array_equal(c, py, equal_nan=True) if kind_c == "result" else c == py, k
    for method in ("distance", "cold_distance"):  # a pair for each path: Pair.distance keeps a warm start
        python = getattr(spq.Pair, method).__wrapped__
        c_pair, py_pair = spq.Pair(a, b), spq.Pair(a, b)
        for args, kwargs in (((np.eye(4), pb), {}), ((np.eye(4),), {"pose_b": pb}), ((np.eye(4), np.eye(3)), {}),
                             ((np.eye(4),), {}), ((np.eye(4), pb), {})):
            outcomes = []
            for f in (getattr(c_pair, method), lambda *x, **y: python(py_pair, *x, **y)):
                try:
                    outcomes.append(("result", f(*args, **kwargs)._out))
                except (ValueError, TypeError) as e:
                    outcomes.append((type(e), str(e).replace(".__wrapped__", "")))
            (kind_c, c), (kind_py, py) = outcomes
            assert kind_c == kind_py, (method, args, kwargs)
            if kind_c == "result":
                assert np.array_equal(c, py, equal_nan=True)


def test_old_argument_order_once_warned_takes_the_fast_paths(monkeypatch):
    """spq 0.1's order, distance(A, pose_a, B, pose_b): after its one DeprecationWarning, every later call
    answers bit for bit as the new order does, through the C entry (which neither Python path then runs)
    and through Python's entry (which hands it to the fast path in the new order) alike, signed or not; with
    the warning's flag reset, the next such call warns again, the C entry waiting for Python's warning."""
    import warnings

    a, b = hull(45), spq.STPBV.from_points(hull(46).vertices, 0.01, 2.0)
    poses = [random_pose(np.random.default_rng(k), 0.8) for k in range(8)]
    monkeypatch.setitem(sq._OLD_ORDER, "warned", False)
    for signed in (False, True):
        results = [spq.distance(a, b, np.eye(4), p, signed=signed) for p in poses]
        assert {r.status for r in results} == {"separated", "overlapping"}
        new = [(r.distance, r._out.copy()) for r in results]
        with pytest.warns(DeprecationWarning) if not sq._OLD_ORDER["warned"] else contextlib.nullcontext():
            spq.distance(a, np.eye(4), b, poses[0], signed=signed)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            python = [(r.distance, r._out.copy()) for r in (PYTHON_PLAIN(a, np.eye(4), b, p, signed=signed) for p in poses)]
            spq.distance(a, b, np.eye(4), poses[0], signed=signed)  # the C entry's last pair, again
            calls = {"slow": 0, "python": 0}
            with monkeypatch.context() as m:  # the slow path packs a pair, Python's fast path allocates the result
                m.setattr(sq, "_plain_pair", lambda *x: calls.__setitem__("slow", calls["slow"] + 1))
                m.setattr(sq, "_empty", lambda n: calls.__setitem__("python", calls["python"] + 1))
                c = [(r.distance, r._out.copy()) for r in (spq.distance(a, np.eye(4), b, p, signed=signed) for p in poses)]
            assert calls == {"slow": 0, "python": 0}
        for got in (python, c):
            for (d, out), (d_new, out_new) in zip(got, new):
                assert d == d_new and np.array_equal(out, out_new, equal_nan=True)
    monkeypatch.setitem(sq._OLD_ORDER, "warned", False)
    with pytest.warns(DeprecationWarning):
        spq.distance(a, np.eye(4), b, poses[1], signed=True)


def test_c_entries_hold_no_references_they_should_not():
    """Many calls leave the reference counts of the shapes, the poses, the options and the result
    type where they were, and a result holds only its own array."""
    a, b = hull(43), hull(44)
    pa, pb = np.eye(4), pose(t=(0.3, 0.05, 0.0))
    tol = 1e-7
    pair = spq.Pair(a, b, signed=True)
    spq.distance(a, b, pa, pb, tol=tol)
    pair.distance(pa, pb)
    watched = (a, b, pa, pb, tol, pair, pair._entry, sq.DistanceResult)
    before = [sys.getrefcount(x) for x in watched]
    for _ in range(2000):
        spq.distance(a, b, pa, pb, tol=tol)
        pair.distance(pa, pb)
        pair.cold_distance(pa, pb)
    kept, python = spq.distance(a, b, pa, pb, tol=tol), PYTHON_PLAIN(a, b, pa, pb, tol=tol)
    assert sys.getrefcount(kept) == sys.getrefcount(python) == 2  # the name, and getrefcount's argument
    for field in ("_out", "point_a", "point_b", "normal", "status", "iterations", "lower_bound", "upper_bound"):
        value = getattr(kept, field)
        assert sys.getrefcount(value) == 2 or isinstance(value, (str, int)), field  # a new object, held here only
    del kept, python, value
    assert [sys.getrefcount(x) for x in watched] == before


def test_freed_results_reused_by_later_calls_leave_held_results_as_they_were():
    """spq._entry keeps up to 16 freed results for the next calls: a result still held is never one
    of them, and a reused one carries nothing of its last query. Held results, with freed ones reused
    in between (and rejected poses, which free theirs at once), match the Python path's answers on
    their own poses field for field."""
    a, b = hull(45), hull(46)
    rng = np.random.default_rng(7)
    poses = [random_pose(rng, 0.4) for _ in range(120)]
    held, expected = [], []
    for i, pb in enumerate(poses):
        result = spq.distance(a, b, np.eye(4), pb, signed=i % 2 == 0)
        if i % 3 == 0:  # every third kept, the others freed at once into the kept pool
            held.append(result)
            expected.append(PYTHON_PLAIN(a, b, np.eye(4), pb, signed=i % 2 == 0))
        if i % 10 == 0:
            with pytest.raises(ValueError):
                spq.distance(a, b, np.eye(4), np.full((4, 4), np.nan))
    assert len({id(r) for r in held}) == len(held)
    for got, want in zip(held, expected):
        assert got.distance == want.distance
        np.testing.assert_array_equal(got._out, want._out)
        assert (got.status, got.iterations) == (want.status, want.iterations)


def test_c_entries_on_threads_answer_as_one_thread():
    """Four threads, each on its own pairs and poses at once (each thread has its own last pair; the
    work array is shared, as a query holds the GIL): every answer equals the same call's on the
    Python path, made afterwards on one thread."""
    kinds = list(shapes().values())
    rng = np.random.default_rng(13)
    pa = np.stack([random_pose(rng, 0.0) for _ in range(40)])
    pb = np.stack([random_pose(rng, 0.25) for _ in range(40)])

    def run(k):
        A, B = kinds[k], kinds[(k + 2) % len(kinds)]
        pair = spq.Pair(A, B, signed=bool(k % 2))
        return [(spq.distance(A, B, x, y, signed=bool(k % 2))._out, pair.cold_distance(x, y)._out)
                for _ in range(5) for x, y in zip(pa, pb)]

    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(run, range(4)))
    for k, results in enumerate(got):
        A, B = kinds[k], kinds[(k + 2) % len(kinds)]
        for i, (plain, cold) in enumerate(results):
            want = PYTHON_PLAIN(A, B, pa[i % 40], pb[i % 40], signed=bool(k % 2))._out
            assert np.array_equal(plain, want, equal_nan=True) and np.array_equal(cold, want, equal_nan=True), (k, i)


def test_entry_refuses_arrays_it_cannot_take():
    state = np.zeros(8)
    with pytest.raises(ValueError, match="float64"):
        sq._entry.Entry(1, state, np.zeros(4, dtype=np.float32), state)
    with pytest.raises(ValueError, match="writeable"):
        readonly = np.zeros(8)
        readonly.flags.writeable = False
        sq._entry.Entry(1, readonly, state, state)
    with pytest.raises(ValueError, match="address"):
        sq._entry.Entry(0, state, state, state)
    with pytest.raises(ValueError, match="Entry"):
        sq._entry.remember((1, 2, 3))


def test_the_results_fields_read_in_c_are_the_python_ones():
    """spq.DistanceResult (made by spq._entry.result_type) holds the result vector and reads its fields
    in C; the Python fields (spq.query._ResultFields, used without the extension) on the same vector
    give the same values and types. Fields are copies, results pickle, and _out takes only a vector
    of its size."""
    class PythonResult(sq._ResultFields):
        __slots__ = ()

    a, b = hull(45), hull(46)
    rng = np.random.default_rng(14)
    for signed in (False, True):
        for _ in range(20):
            r = spq.distance(a, b, random_pose(rng, 0.0), random_pose(rng, 0.2), signed=signed)
            py = PythonResult()
            py._out, py.distance = r._out, r.distance
            for field in ("distance", "point_a", "point_b", "normal", "status", "iterations", "lower_bound",
                          "upper_bound", "_out"):
                c_value, py_value = getattr(r, field), getattr(py, field)
                assert type(c_value) is type(py_value), field
                assert c_value == py_value if isinstance(c_value, str) else \
                    np.array_equal(c_value, py_value, equal_nan=True), field
                if isinstance(c_value, np.ndarray):
                    assert c_value.dtype == np.float64 and c_value.shape == py_value.shape, field
            back = pickle.loads(pickle.dumps(r))
            assert type(back) is spq.DistanceResult and np.array_equal(back._out, r._out, equal_nan=True)
            assert back.distance == r.distance and repr(back) == repr(r)
    r.point_a[:] = 7.0  # a copy: the result keeps its value
    assert not np.any(r.point_a == 7.0)
    with pytest.raises(ValueError, match="1-D array of"):
        r._out = np.zeros(3)
    with pytest.raises(AttributeError):
        r.status = "separated"


def test_without_the_extension_spq_answers_the_same_in_python():
    """Where spq._entry could not be built, spq.query imports without it: the plain call, Pair's
    methods and DistanceResult are the Python ones, with the same answers bit for bit (here, in a
    process where importing the extension fails)."""
    import json
    import subprocess
    import textwrap

    a, b = hull(47), hull(48)
    rng = np.random.default_rng(15)
    pa, pb = random_pose(rng, 0.0), random_pose(rng, 0.2)
    want = [spq.distance(a, b, pa, pb, signed=s)._out for s in (False, True)]
    script = textwrap.dedent(f"""
        import sys
        sys.modules["spq._entry"] = None  # import spq._entry raises ImportError
        import json
        import numpy as np, spq, spq.query as sq
        from tests.test_gjk import hull
        assert sq._entry is None and type(spq.distance).__name__ == "function"
        assert spq.DistanceResult.__mro__[1] is sq._ResultFields
        pa, pb = np.array({pa.tolist()}), np.array({pb.tolist()})
        for s in (False, True):
            r = spq.distance(hull(47), hull(48), pa, pb, signed=s)
            r = spq.distance(hull(47), hull(48), pa, pb, signed=s)
            print(json.dumps(r._out.tolist()), r.status, type(r.distance).__name__)
    """)
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600,
                         cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    assert run.returncode == 0, run.stderr
    lines = run.stdout.strip().splitlines()
    for line, out in zip(lines, want):
        values, status, kind = line.rsplit(" ", 2)
        assert np.array_equal(np.array(json.loads(values), dtype=float), out, equal_nan=True)
        assert kind == "float" and status in spq.STATUS_NAMES
    assert len(lines) == 2
