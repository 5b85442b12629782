"""A line on stderr while numba compiles spq's kernels, which on a fresh install takes minutes.

The first call of a query, a batch or a scene compiles the kernels it reaches (numba, ``cache=True``);
later runs load them from numba's cache within seconds. Without a word, that first call looks hung.
numba triggers its ``numba:compile`` event only when a function is not in its cache, so a listener on
that event says when an spq entry point starts compiling and how long it took. Kernels compiled
inside another's compile (its callees) are part of that one line. ``SPQ_COMPILE_NOTICE=0`` silences it.
"""

from __future__ import annotations

import os
import sys
import time

ENV = "SPQ_COMPILE_NOTICE"


def _spq_function(ev) -> str | None:
    """The qualified name of the spq function a compile event is for, or None for anyone else's."""
    dispatcher = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
    function = getattr(dispatcher, "py_func", None)
    module = getattr(function, "__module__", "") or ""
    return function.__qualname__ if module == "spq" or module.startswith("spq.") else None


def _listener_class():
    from numba.core import event

    class CompileNotice(event.Listener):
        """Writes a line to ``stream`` (default: sys.stderr at the time) when an spq function starts
        compiling outside any other compile, and one when it is done."""

        def __init__(self, stream=None):
            self.stream = stream
            self.depth = 0  # nested compile events inside the spq compile being reported
            self.name = ""
            self.start = 0.0

        def _write(self, text: str) -> None:
            stream = self.stream or sys.stderr
            stream.write(text + "\n")
            stream.flush()

        def on_start(self, ev):
            if self.depth == 0:
                name = _spq_function(ev)
                if name is None:
                    return
                self.name, self.start = name, time.perf_counter()
                self._write(f"spq: numba is compiling {name} for its first use (minutes on a fresh install; "
                            "numba's cache keeps it for later runs)")
            self.depth += 1

        def on_end(self, ev):
            if self.depth == 0:
                return
            self.depth -= 1
            if self.depth == 0:
                self._write(f"spq: {self.name} compiled in {time.perf_counter() - self.start:.0f} s")

    return CompileNotice


_INSTALLED: list = []


def install(stream=None):
    """Register the notice with numba's event system, once per process; returns the listener, or None
    when ``SPQ_COMPILE_NOTICE=0`` or numba has no event system."""
    if os.environ.get(ENV, "1") == "0":
        return None
    if _INSTALLED:
        return _INSTALLED[0]
    try:
        from numba.core import event
        listener = _listener_class()(stream)
        event.register("numba:compile", listener)
    except (ImportError, AttributeError):  # a numba without the event API: no notice, nothing else lost
        return None
    _INSTALLED.append(listener)
    return listener
