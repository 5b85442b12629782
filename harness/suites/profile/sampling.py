"""``perf`` driven from inside the process it samples: record this process while a job runs, then read the
samples by function (numba's kernels named through harness.suites.profile.jit_symbols' map)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pandas as pd

class ProfilerUnavailable(RuntimeError):
    """perf, binutils or numba's hooks are missing or not allowed here: the profile cannot run (the message says
    which, and what to install or set)."""


SEPARATOR = "|"  # perf report's field separator: absent from numba's, libm's and CPython's symbol names


def perf_path() -> str:
    path = shutil.which("perf")
    if path is None:
        raise ProfilerUnavailable("perf is not on PATH: the profile samples with Linux perf (apt-get install "
                           "linux-perf, or linux-tools-$(uname -r))")
    return path


def paranoid_level() -> int | None:
    try:
        return int(Path("/proc/sys/kernel/perf_event_paranoid").read_text())
    except (OSError, ValueError):
        return None


class Recording:
    """``with Recording(path, frequency): job()`` samples this process (all its threads) while the block runs."""

    def __init__(self, path: Path, frequency: int):
        self.path, self.frequency = Path(path), frequency
        self._process = None

    def __enter__(self):
        self.path.parent.mkdir(parents=True, exist_ok=True)
        cmd = [perf_path(), "record", "-F", str(self.frequency), "-p", str(os.getpid()), "-o", str(self.path), "-q"]
        self._process = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        time.sleep(0.5)  # perf attaches to the threads before the job starts
        if self._process.poll() is not None:
            raise ProfilerUnavailable(f"perf record failed ({' '.join(cmd)}): {self._process.stderr.read().strip()} "
                               f"(kernel.perf_event_paranoid = {paranoid_level()}; sampling another process's "
                               "threads needs 2 or less, or CAP_PERFMON)")
        return self

    def __exit__(self, *exc):
        self._process.send_signal(signal.SIGINT)
        try:
            _, err = self._process.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            self._process.kill()
            raise ProfilerUnavailable("perf record did not stop within 60 s of SIGINT") from None
        if self._process.returncode not in (0, -signal.SIGINT, 130) or not self.path.exists():
            raise ProfilerUnavailable(f"perf record exited with {self._process.returncode}: {err.strip()}")
        return False


def samples_by_symbol(path: Path, tid: int) -> tuple[pd.DataFrame, int]:
    """The samples of thread ``tid`` in recording ``path`` by (shared object, symbol): a table with columns
    share (of that thread's samples), object, symbol; and the thread's sample count. Run while the
    process's perf map is in /tmp (perf names JIT code from it at report time). The shares come from perf's
    sample counts, not its percentages (which, filtered by thread, need not sum to 100)."""
    cmd = [perf_path(), "report", "-i", str(path), "--tid", str(tid), "--stdio", "--no-children", "--sort", "dso,sym",
           "-F", "sample,dso,sym", "-q", "-t", SEPARATOR]
    text = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    rows = []
    for line in text.splitlines():
        fields = [f.strip() for f in line.split(SEPARATOR)]
        if len(fields) < 3 or not fields[0].isdigit():
            continue
        symbol = fields[2]
        if symbol.startswith("[") and "] " in symbol:  # "[.] name": perf's mark for user code
            symbol = symbol.split("] ", 1)[1]
        rows.append({"samples": int(fields[0]), "object": fields[1], "symbol": symbol})
    table = pd.DataFrame(rows, columns=["samples", "object", "symbol"])
    count = int(table.samples.sum())
    table.insert(0, "share", table.samples / max(count, 1))
    return table.drop(columns="samples"), count


def sample_addresses(path: Path, tid: int) -> np.ndarray:
    """The instruction address of each of thread ``tid``'s samples in recording ``path`` (uint64)."""
    text = subprocess.run([perf_path(), "script", "-i", str(path), "--tid", str(tid), "-F", "ip"],
                          capture_output=True, text=True, check=True).stdout
    return np.array([int(line, 16) for line in text.split()], dtype=np.uint64)
