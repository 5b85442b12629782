"""spq profile: numba's kernels named for perf (checked against numba's own records of each function's name
and LLVM's address for it), hot spots counted as brute force counts them, and the command end to end."""

from __future__ import annotations

import shutil
from pathlib import Path

import numba
import numpy as np
import pandas as pd
import pytest

from harness.cli import main
from harness.suites.profile import area, jit_symbols
from harness.suites.profile.sampling import paranoid_level


def _fresh_kernel():
    """A kernel compiled in this process (not from numba's cache), inside a function so its name holds <locals>."""
    def scaled_sum(x, k):
        total = 0.0
        for v in x:
            total += k * v
        return total

    return numba.njit(scaled_sum)


def test_readable_is_the_kernels_python_qualified_name():
    kernel = _fresh_kernel()
    kernel(np.ones(3), 2.0)
    fndesc = next(iter(kernel.overloads.values())).fndesc
    expected = f"{kernel.py_func.__module__}.{kernel.py_func.__qualname__}"
    assert "<locals>" in expected
    assert jit_symbols.readable(fndesc.mangled_name) == expected
    assert jit_symbols.readable("cfunc." + fndesc.mangled_name) == expected + " [cfunc]"
    assert jit_symbols.readable("__ieee754_log_fma") == "__ieee754_log_fma"


@pytest.mark.skipif(shutil.which("readelf") is None, reason="readelf (binutils) is not on PATH")
def test_every_kernel_compiled_after_install_is_placed_where_llvm_put_it():
    jit_symbols.install()
    kernel = _fresh_kernel()
    assert kernel(np.arange(4.0), 0.5) == 3.0
    overload = next(iter(kernel.overloads.values()))
    # LLVM's own answer for the function's address, which jit_symbols does not ask for this function
    address = overload.library.get_pointer_to_function(overload.fndesc.llvm_func_name)
    placed = {s.name: s for s in jit_symbols.symbols()}
    symbol = placed[overload.fndesc.mangled_name]
    assert symbol.address == address and symbol.size > 0
    path, named = jit_symbols.write_perf_map()
    lines = path.read_text().splitlines()
    assert len(lines) == named and f"{address:x} {symbol.size:x} {symbol.name}" in lines


def test_hot_spots_count_the_samples_as_brute_force_does():
    placed = [jit_symbols.Symbol(1000, 100, "_ZN3spq7kernels3gjk7descendB2v1E", 0, 16),
              jit_symbols.Symbol(2000, 50, "_ZN3spq7kernels3epa7epa_runB2v1E", 1, 0)]
    rng = np.random.default_rng(3)
    addresses = rng.choice([1005, 1005, 1099, 1100, 2000, 2049, 2050, 999, 5000], size=400).astype(np.uint64)
    spots = jit_symbols.hot_spots(addresses, placed, top=10)
    inside = {1005: ("spq.kernels.gjk.descend", 5), 1099: ("spq.kernels.gjk.descend", 99),
              2000: ("spq.kernels.epa.epa_run", 0), 2049: ("spq.kernels.epa.epa_run", 49)}
    expected = {inside[a]: np.count_nonzero(addresses == a) / len(addresses) for a in inside}
    got = {(r.function, r.offset): r.share for r in spots.itertuples()}
    assert got == pytest.approx(expected)
    assert list(spots.share) == sorted(spots.share, reverse=True)
    assert spots.loc[spots.function == "spq.kernels.gjk.descend", "object_offset"].eq(16).all()


def test_areas_group_kernels_by_module_and_libraries_by_name():
    assert area("spq.kernels.gjk.descend", "perf-12.map") == "spq.kernels.gjk"
    assert area("spq.kernels.gjk.descend [cpython]", "[JIT] tid 12") == "spq.kernels.gjk"
    assert area("0x00007f35619240f6", "[JIT] tid 12") == "JIT (unnamed)"
    assert area("__ieee754_exp_fma", "libm.so.6") == "libm"
    assert area("_PyEval_EvalFrameDefault", "python3.11") == "Python interpreter"
    assert area("array_subscript", "_multiarray_umath.cpython-311-x86_64-linux-gnu.so") == "numpy"


def _perf_usable() -> bool:
    level = paranoid_level()
    return all(shutil.which(t) for t in ("perf", "readelf")) and level is not None and level <= 2


@pytest.mark.skipif(not _perf_usable(), reason="perf or readelf missing, or kernel.perf_event_paranoid > 2")
def test_profile_names_the_kernels_that_hold_a_batched_jobs_samples(tmp_path):
    # in a process of its own, as the command runs: kernels a process loaded before the profiler started
    # (this test process's earlier tests) keep no object code to be named from
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-m", "harness.cli", "profile", "PCH-PCH", "--unsigned", "--poses", "2000",
                           "--seconds", "1", "--quiet", "--out", str(tmp_path)], cwd=Path(__file__).parents[1],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    areas = pd.read_csv(tmp_path / "profile_areas.csv")
    share = dict(zip(areas.area, areas.percent))
    assert sum(share.values()) == pytest.approx(100.0, abs=0.5)
    # a cold batched PCH-PCH query is the GJK descent over the hulls' supports, all in compiled code
    assert share.get("spq.kernels.gjk", 0.0) > 30.0
    assert share.get("JIT (unnamed)", 0.0) < 5.0 and share.get("Python interpreter", 0.0) < 5.0
    spots = pd.read_csv(tmp_path / "profile_hot_spots.csv")
    assert len(spots) > 0 and spots.function.str.startswith("spq.kernels.").all()
    symbols = pd.read_csv(tmp_path / "profile_symbols.csv")
    assert symbols.object_file.map(lambda f: Path(f).exists()).all()


def test_profile_rejects_a_bad_pair_and_mode(capsys):
    assert main(["profile", "PCH-XYZ", "--quiet"]) == 2
    assert "pair must be two of ['PCH', 'STP', 'CSE']" in capsys.readouterr().err
    assert main(["profile", "--seconds", "0.1", "--quiet"]) == 2
    assert "seconds must lie in [0.5, 3600]" in capsys.readouterr().err


@pytest.mark.skipif(shutil.which("readelf") is None or shutil.which("objdump") is None,
                    reason="binutils (readelf, objdump) are not on PATH")
def test_annotated_lines_give_each_sampled_instruction_its_share(tmp_path):
    jit_symbols.install()
    kernel = _fresh_kernel()
    kernel(np.arange(4.0), 0.5)
    overload = next(iter(kernel.overloads.values()))
    placed = [s for s in jit_symbols.symbols() if s.name == overload.fndesc.mangled_name]
    assert len(placed) == 1
    symbol = placed[0]
    objects = jit_symbols.dump_objects(tmp_path)
    listing = jit_symbols.disassembly(objects[symbol.object_index], symbol.name)
    offsets = [at - symbol.offset for at in listing]
    assert offsets[0] == 0 and len(offsets) > 3 and all(0 <= o < symbol.size for o in offsets)
    second = offsets[1]
    addresses = np.array([symbol.address] * 3 + [symbol.address + second, 1], dtype=np.uint64)
    lines = jit_symbols.annotated(addresses, symbol, objects[symbol.object_index], top=2, context=0)
    first_line, second_line = lines[0].split(), lines[1].split()
    assert first_line[:2] == ["60.00", "0"] and second_line[:2] == ["20.00", f"{second:x}"]
    assert " ".join(first_line[2:]) == listing[symbol.offset]


@pytest.mark.parametrize("coherent", [False, True])
def test_a_robots_job_sweeps_random_configurations_cold_or_the_benchs_trajectory_coherently(coherent, monkeypatch):
    from harness.suites import profile
    from harness.workloads.robot_poses import random_configurations, smooth_trajectory

    calls = []

    class StubScene:
        model = object()
        pairs = [(0, 1), (0, 2)]

        def distances_many(self, qs, coherent=False, signed=False, out=None):
            calls.append((qs, coherent, signed, out.shape))

    monkeypatch.setattr("harness.suites.robot.robot_bench.load_scene", lambda config, policy: StubScene())
    want = {}

    def poses(kind):
        def make(model, n, seed):
            want[kind] = np.full((n, 3), float(seed))
            return want[kind]
        return make

    monkeypatch.setattr("harness.workloads.robot_poses.random_configurations", poses("random"))
    monkeypatch.setattr("harness.workloads.robot_poses.smooth_trajectory", poses("trajectory"))
    job, queries, what = profile._robot_job(profile.Config(robot="jvrc1", coherent=coherent, configs=7, seed=3))
    job()
    (qs, got_coherent, signed, shape), = calls
    assert got_coherent is coherent and signed is True and shape[:2] == (7, 2) and queries == 14
    assert qs is want["trajectory" if coherent else "random"]
    assert ("coherent all-pairs sweep" in what and "7-step smooth trajectory" in what) if coherent else \
        ("cold all-pairs sweep" in what and "7 random configurations" in what)
