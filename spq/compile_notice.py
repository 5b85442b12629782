"""A line on stderr while numba compiles spq's kernels, which on a fresh install takes minutes.

The first call of a query, a batch or a scene compiles the kernels it reaches (numba, ``cache=True``);
later runs load them from numba's cache within seconds. Without a word, that first call looks hung.
numba triggers its ``numba:compile`` event only when a function is not in its cache, so a listener on
that event says, once a compile of an spq entry point has run for a couple of seconds, what it is
compiling, and then how long it took. Kernels compiled inside another's compile (its callees) are
part of that one line. ``SPQ_COMPILE_NOTICE``: ``0`` (or ``off``) silences it; a number of seconds
sets how long a compile runs before it is announced (default :data:`NOTICE_AFTER`).
"""

from __future__ import annotations

import os
import sys
import threading
import time

from numba.core import event

ENV = "SPQ_COMPILE_NOTICE"
NOTICE_AFTER = 2.0  # seconds: shorter compiles (small kernels, a cache a little stale) pass unannounced


def _spq_function(ev) -> str | None:
    """The qualified name of the spq function a compile event is for, or None for anyone else's."""
    dispatcher = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
    function = getattr(dispatcher, "py_func", None)
    module = getattr(function, "__module__", "") or ""
    return function.__qualname__ if module == "spq" or module.startswith("spq.") else None


class CompileNotice(event.Listener):
    """Writes a line to ``stream`` (default: sys.stderr at the time) once an spq function compiled
    outside any other compile has taken ``after`` seconds (at once if ``after`` <= 0), and a line when
    it is done if the first was written. numba compiles under one global lock, so the events come one
    at a time; the lock here is between them and the timer's thread."""

    def __init__(self, stream=None, after: float = NOTICE_AFTER):
        self.stream = stream
        self.after = float(after)
        self.depth = 0  # compile events open inside the spq compile being reported, itself included
        self.name = ""
        self.start = 0.0
        self.told = False
        self.timer = None
        self.lock = threading.Lock()

    def _write(self, text: str) -> None:
        stream = self.stream or sys.stderr
        stream.write(text + "\n")
        stream.flush()

    def _tell(self, name: str) -> None:
        with self.lock:
            if self.depth > 0 and self.name == name and not self.told:
                self.told = True
                self._write(f"spq: numba is compiling {name} for its first use (minutes on a fresh install; "
                            "numba's cache keeps it for later runs)")

    def on_start(self, ev):
        if self.depth > 0:
            self.depth += 1
            return
        name = _spq_function(ev)
        if name is None:
            return
        with self.lock:
            self.name, self.start, self.told, self.depth = name, time.perf_counter(), False, 1
        if self.after <= 0:
            self._tell(name)
        else:
            self.timer = threading.Timer(self.after, self._tell, args=(name,))
            self.timer.daemon = True
            self.timer.start()

    def on_end(self, ev):
        if self.depth != 1:
            self.depth = max(self.depth - 1, 0)
            return
        if self.timer is not None:
            self.timer.cancel()
            self.timer = None
        with self.lock:
            self.depth = 0
            if self.told:
                self._write(f"spq: {self.name} compiled in {time.perf_counter() - self.start:.0f} s")


def _delay_from_env() -> float | None:
    """Seconds before a compile is announced, from SPQ_COMPILE_NOTICE; None: silenced."""
    text = os.environ.get(ENV, "").strip().lower()
    if text == "":
        return NOTICE_AFTER
    if text in ("0", "off", "no", "false"):
        return None
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0 < value < float("inf"):
        raise ValueError(f"{ENV} must be 0 or off (silenced) or a number of seconds > 0; got {text!r}")
    return value


_INSTALLED: list = []


def install(stream=None):
    """Register the notice with numba's event system, once per process; returns the listener, or None
    when SPQ_COMPILE_NOTICE silences it."""
    after = _delay_from_env()
    if after is None:
        return None
    if not _INSTALLED:
        _INSTALLED.append(CompileNotice(stream, after))
        event.register("numba:compile", _INSTALLED[0])
    return _INSTALLED[0]
