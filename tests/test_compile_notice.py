"""The line spq writes while numba compiles its kernels (spq.compile_notice), in fresh processes with
an empty numba cache: said when compiling, not when the cache has the kernel, silenced by the env."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from spq.compile_notice import NOTICE_AFTER, CompileNotice, _delay_from_env

REPO = Path(__file__).resolve().parent.parent
# a small kernel called straight from Python, and a user's own njit function that is not spq's
PROGRAM = """
import numpy as np
from numba import njit
import spq
from spq.kernels.gjk import _triple

@njit
def users_own(x):
    return x + 1.0

users_own(1.0)
W = np.eye(4)[:, :3].copy()
print("triple", _triple(W, 0, 1, 2))
"""


def _run(cache: Path, **env) -> subprocess.CompletedProcess:
    full = {k: v for k, v in os.environ.items() if k not in ("NUMBA_DISABLE_JIT", "SPQ_COMPILE_NOTICE")}
    full.update(NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(REPO), **env)
    return subprocess.run([sys.executable, "-c", PROGRAM], env=full, capture_output=True, text=True, timeout=600)


def test_the_notice_names_the_kernel_compiled_and_is_silent_once_it_is_cached(tmp_path):
    first = _run(tmp_path, SPQ_COMPILE_NOTICE="0.001")  # announced after 1 ms: this kernel compiles in less than 2 s
    assert first.returncode == 0, first.stderr
    assert "triple 1.0" in first.stdout
    lines = [line for line in first.stderr.splitlines() if line.startswith("spq:")]
    assert lines[0].startswith("spq: numba is compiling _triple for its first use"), first.stderr
    assert lines[1].startswith("spq: _triple compiled in "), first.stderr
    assert len(lines) == 2 and "users_own" not in first.stderr  # a user's own function: nothing said
    again = _run(tmp_path, SPQ_COMPILE_NOTICE="0.001")
    assert again.returncode == 0 and "triple 1.0" in again.stdout
    assert "spq:" not in again.stderr  # from numba's cache: nothing to say


def test_the_notice_is_silenced_by_the_environment(tmp_path):
    run = _run(tmp_path, SPQ_COMPILE_NOTICE="0")
    assert run.returncode == 0 and "triple 1.0" in run.stdout
    assert "spq:" not in run.stderr


def _event(module: str, name: str):
    """A numba compile event's shape, for a function of that module and name."""
    fn = SimpleNamespace(__module__=module, __qualname__=name)
    return SimpleNamespace(data={"dispatcher": SimpleNamespace(py_func=fn)})


def test_a_nested_compile_is_one_line_and_other_functions_are_not_reported():
    class Stream:
        text = ""

        def write(self, s):
            self.text += s

        def flush(self):
            pass

    stream = Stream()
    notice = CompileNotice(stream, 0)  # announced at once
    notice.on_start(_event("users.module", "mine"))  # not spq's: ignored, and so is its end
    notice.on_end(_event("users.module", "mine"))
    assert stream.text == ""
    notice.on_start(_event("spq.kernels.batch", "query_batch"))
    notice.on_start(_event("spq.kernels.gjk", "descend"))  # a callee compiled inside it
    notice.on_end(_event("spq.kernels.gjk", "descend"))
    assert stream.text.count("\n") == 1
    notice.on_end(_event("spq.kernels.batch", "query_batch"))
    lines = stream.text.splitlines()
    assert len(lines) == 2 and "query_batch" in lines[0] and lines[1].startswith("spq: query_batch compiled in ")


def test_a_compile_shorter_than_the_delay_is_not_announced():
    lines = []
    stream = SimpleNamespace(write=lines.append, flush=lambda: None)
    notice = CompileNotice(stream, 60.0)
    ev = _event("spq.kernels.batch", "query_batch")
    notice.on_start(ev)
    notice.on_end(ev)
    assert lines == [] and notice.timer is None and notice.depth == 0


def test_the_delay_is_read_from_the_environment(monkeypatch):
    monkeypatch.delenv("SPQ_COMPILE_NOTICE", raising=False)
    assert _delay_from_env() == NOTICE_AFTER
    for off in ("0", "off", " OFF "):
        monkeypatch.setenv("SPQ_COMPILE_NOTICE", off)
        assert _delay_from_env() is None
    monkeypatch.setenv("SPQ_COMPILE_NOTICE", "5")
    assert _delay_from_env() == 5.0
    for bad in ("soon", "-1", "nan", "inf"):
        monkeypatch.setenv("SPQ_COMPILE_NOTICE", bad)
        with pytest.raises(ValueError, match="SPQ_COMPILE_NOTICE"):
            _delay_from_env()
