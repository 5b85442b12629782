"""spq.kernels.jit: inline="hot" kernels are inlined into hot entry points and called from the others;
spq.kernels.indexing: an unsigned index compiles without numba's wrap of negative indices; numba's
inliner, sped up by spq.kernels.jit, compiles the same code as numba's own."""

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

from spq.kernels.indexing import at
from spq.kernels.jit import kernel


# cache off: a kernel loaded from numba's cache has no LLVM text to inspect
@kernel(inline="hot", cache=False)
def _scaled(x):
    return 2.0 * x


@kernel(hot=True, cache=False)
def _hot_entry(x):
    return _scaled(x) + 1.0


@kernel(cache=False)
def _plain_entry(x):
    return _scaled(x) + 1.0


def _refers_to_scaled(dispatcher) -> bool:
    (llvm,) = dispatcher.inspect_llvm().values()
    return re.search(r"@\"?_ZN[^\s(]*7_scaled", llvm) is not None


def test_a_hot_kernel_is_inlined_only_into_hot_entry_points():
    assert _hot_entry(3.0) == _plain_entry(3.0) == 7.0
    assert not _refers_to_scaled(_hot_entry)
    assert _refers_to_scaled(_plain_entry)


@kernel(cache=False)
def _read_signed(a, i):
    return a[3 * i + 1]


@kernel(cache=False)
def _read_unsigned(a, i):
    return a[at(3 * i + 1)]


def _negative_index_tests(dispatcher) -> int:
    """Signed comparisons of an int64 with 0 in the compiled LLVM: numba's wrap of a negative index is
    one (index < 0 selects the array's length to add), on any target."""
    (llvm,) = dispatcher.inspect_llvm().values()
    return len(re.findall(r"icmp slt i64 [^,]+, 0\b", llvm))


def test_an_unsigned_index_reads_the_same_element_without_the_negative_index_wrap():
    a = np.arange(30.0) * 1.5
    for i in (0, 4, 9):
        assert _read_unsigned(a, i) == _read_signed(a, i) == a[3 * i + 1]
    assert _negative_index_tests(_read_signed) > 0  # the control: a signed index is wrapped
    assert _negative_index_tests(_read_unsigned) == 0


# ------------------------------------------------------------------------- the compiled cache

_KERNEL_A = '''from pkg.kernels.jit import kernel


@kernel(inline="always")
def value():
    return {value}
'''
_KERNEL_B = '''from pkg.kernels.jit import kernel
from pkg.kernels.a import value


@kernel
def twice():
    return 2.0 * value()
'''
_RUN = "from pkg.kernels.b import twice; print(twice(), sum(twice.stats.cache_hits.values()))"


def _stamp_runs(tmp_path, first_import: str = "") -> list[tuple[float, int]]:
    """b (inlining a) run in fresh processes, a edited in between: (result, cache hits) of each run.
    first_import: a statement run before b's import (another package's kernels)."""
    import shutil

    import spq.kernels.jit as jit

    for name in ("pkg", "other"):
        kernels = tmp_path / name / "kernels"
        kernels.mkdir(parents=True)
        (tmp_path / name / "__init__.py").write_text("")
        (kernels / "__init__.py").write_text("")
        shutil.copy(Path(jit.__file__), kernels / "jit.py")
    kernels = tmp_path / "pkg" / "kernels"
    (kernels / "b.py").write_text(_KERNEL_B)

    def run(value: float) -> tuple[float, int]:
        (kernels / "a.py").write_text(_KERNEL_A.format(value=value))
        out = subprocess.run([sys.executable, "-c", first_import + _RUN], cwd=tmp_path, capture_output=True,
                             text=True, check=True).stdout.split()
        return float(out[0]), int(out[1])

    return [run(1.0), run(1.0), run(5.0), run(5.0)]


def test_a_cached_kernel_is_compiled_anew_when_a_kernel_it_inlines_changes(tmp_path):
    # numba stamps b's cache with b.py alone: without spq.kernels.jit's digest of every kernel file,
    # editing a.py (inlined into b) left b's old machine code running from the cache
    # compiled and cached; from the cache; a.py changed: compiled anew, not the stale 2.0; from the cache
    assert _stamp_runs(tmp_path) == [(2.0, 0), (2.0, 1), (10.0, 0), (10.0, 1)]


def test_a_second_copy_of_the_kernels_in_one_process_keeps_its_own_stamp(tmp_path):
    # a same-process A/B imports an older copy of spq first: its stamp was the only one installed, and
    # this copy's kernels fell back to numba's per-file stamps (stale after an edit of a.py alone)
    assert _stamp_runs(tmp_path, "import other.kernels.jit; ") == [(2.0, 0), (2.0, 1), (10.0, 0), (10.0, 1)]


@kernel(cache=False)
def _by_kind(kind, x):
    return x + kind


@kernel(cache=False)
def _calls_with_constants(x):
    return _by_kind(0, x) + _by_kind(1, x) + _by_kind(2, x)


def test_a_kernel_called_with_constants_is_compiled_once_for_their_plain_type():
    """numba's default compiles a callee once per literal value it is called with (three copies of
    _by_kind here, each with everything it calls); the project's decorator compiles one."""
    assert _calls_with_constants(1.0) == 6.0
    assert len(_by_kind.signatures) == 1, _by_kind.signatures


def test_no_kernel_takes_more_than_twelve_parameters():
    """A kernel's shapes, pose, tolerances and scratch travel as tuples (spq.kernels' docstring), so a
    signature stays readable; the oracle is the source, parsed."""
    import ast
    from pathlib import Path

    import spq.kernels

    folder = Path(spq.kernels.__file__).parent
    long = []
    for path in sorted(folder.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef) and len(node.args.args) > 12:
                long.append(f"{path.name}:{node.name} ({len(node.args.args)})")
    assert not long, long
    assert len(list(folder.glob("*.py"))) > 20  # not vacuous: the kernels were found


_INLINE_PROBE = r'''
import collections, sys, numpy as np
from spq.kernels.jit import kernel
from spq.kernels.kinematics import _compose_rigid
from numba.core.inline_closurecall import InlineWorker

built = collections.Counter()  # the inlined functions' IR builds, by name
_run_untyped_passes = InlineWorker.run_untyped_passes


def counted(self, func, *args, **kwargs):
    built[func.__name__] += 1
    return _run_untyped_passes(self, func, *args, **kwargs)


InlineWorker.run_untyped_passes = counted

@kernel(inline="always", cache=False)
def _leg(a, i, s):
    t = 0.0
    for k in range(i):
        if a[k] > s:
            t += a[k] * s
        else:
            t -= a[k]
    return t

@kernel(inline="always", cache=False)
def _both(a, i):
    return _leg(a, i, 0.5) + _leg(a, i // 2, 0.25) * _leg(a, i, 0.75)

@kernel(cache=False)
def _probe(a):
    total = 0.0
    for i in range(a.shape[0]):
        total += _both(a, i) - _both(a, i // 3)
    return total

def _reference(a):  # the same sums in plain Python floats: an oracle apart from either compile
    def leg(i, s):
        t = 0.0
        for k in range(i):
            t = t + float(a[k]) * s if a[k] > s else t - float(a[k])
        return t
    both = lambda i: leg(i, 0.5) + leg(i // 2, 0.25) * leg(i, 0.75)
    total = 0.0
    for i in range(len(a)):
        total += both(i) - both(i // 3)
    return total

@kernel(cache=False)
def _chain(Ts, tmp, out):  # a kernel of spq.kernels (inline="always") at two call sites
    _compose_rigid(Ts[0], Ts[1], tmp)
    _compose_rigid(tmp, Ts[2], out)
    return out[0, 3] + out[1, 3] + out[2, 3]

a = np.random.default_rng(0).random(40)
Ts = np.array([np.eye(4)] * 3)
for k in range(3):
    q = np.linalg.qr(np.random.default_rng(k).normal(size=(3, 3)))[0]
    Ts[k, :3, :3], Ts[k, :3, 3] = q, np.random.default_rng(k + 3).normal(size=3)
chained = np.empty((4, 4))
_chain(Ts, np.empty((4, 4)), chained)
assert np.allclose(chained, Ts[0] @ Ts[1] @ Ts[2], rtol=0.0, atol=1e-14)
assert abs(_probe(a) - _reference(a)) <= 1e-12 * abs(_reference(a)), (_probe(a), _reference(a))
print(getattr(InlineWorker.inline_function, "_spq_shared_scope", False), built["_compose_rigid"], built["_leg"])
print(repr(_probe(a)))
(llvm,) = _probe.inspect_llvm().values()
(chain_llvm,) = _chain.inspect_llvm().values()
print(llvm + chain_llvm)
'''


def _canonical_llvm(text: str) -> str:
    """LLVM IR with each function's local names (values, labels) renamed in order of appearance, and
    numba's compile counters and runs of spaces collapsed: two modules equal here are the same code
    under other names. (An inlined kernel's variables are named after its IR's build, which
    spq.kernels.jit makes once per kernel and numba once per call site, so numbered temporaries and
    labels differ between the two.)"""

    def one_function(part: str) -> str:
        names = {}

        def name(s):
            return names.setdefault(s, f"v{len(names)}")

        part = re.sub(r'(?m)^("[^"]*"|[-a-zA-Z$._0-9]+):', lambda m: name(m.group(1)) + ":", part)
        return re.sub(r'%("[^"]*"|[-a-zA-Z$._0-9]+)', lambda m: "%" + name(m.group(1)), part)

    text = re.sub(r"B\d+v\d+(?=[BE])", "Bv", text)  # numba's compile counter in mangled names ("B3v10")
    return re.sub(r" +", " ", "".join(one_function(p) for p in re.split(r"(?m)^(?=define )", text)))


def test_canonical_llvm_tells_renamed_code_from_changed_code():
    a = "define i64 @f(i64 %x) {\nB12:\n  %.5 = add i64 %x, 1\n  br label %B12\n}"
    renamed = a.replace(".5", ".77").replace("B12", "B3")
    assert _canonical_llvm(a) == _canonical_llvm(renamed)
    assert _canonical_llvm(a) != _canonical_llvm(a.replace("add i64 %x, 1", "add i64 %x, 2"))
    assert _canonical_llvm(a) != _canonical_llvm(a.replace("%.5 = add i64 %x", "%.5 = add i64 %.5"))


def test_inlining_with_shared_scopes_compiles_the_same_code_as_numbas_own_copies(tmp_path):
    """spq.kernels.jit's inliner (IR built once per kernel, copied in linear time): the same LLVM IR
    but for local names, and the same result as numba's own (SPQ_NUMBA_INLINE_COPY=stock), each in
    a fresh process, and that result the plain-Python sum's."""
    script = tmp_path / "probe.py"
    script.write_text(_INLINE_PROBE)
    root = str(Path(__file__).resolve().parent.parent)
    runs = {}
    for mode in ("shared", "stock"):
        env = {**os.environ, "PYTHONPATH": root, "SPQ_NUMBA_INLINE_COPY": mode}
        env.pop("NUMBA_DISABLE_JIT", None)
        done = subprocess.run([sys.executable, str(script)], env=env, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr
        runs[mode] = done.stdout.split("\n", 2)
    # the copy was (not) taken over; a kernel's IR built once for its two call sites, not twice (numba's
    # way), and another module's inlined function built at each of its six sites either way
    assert runs["shared"][0] == "True 1 6" and runs["stock"][0] == "False 2 6"
    assert runs["shared"][1] == runs["stock"][1]
    assert re.search(r"@\"?_ZN[^\s(]*4_leg", runs["shared"][2]) is None  # inlined, not called
    assert "fadd double" in runs["shared"][2]
    assert _canonical_llvm(runs["shared"][2]) == _canonical_llvm(runs["stock"][2])
