"""Names for numba's machine code, so that a sampling profiler can tell one kernel from another.

numba compiles each kernel into an object file that LLVM's engine loads at an address of its own
choosing; ``perf`` sees samples there as bare addresses. This module keeps each object's bytes as numba
hands them to LLVM (compiled now, or loaded from numba's on-disk cache), reads their function symbols with
``readelf``, finds where the engine put them, and writes the map ``perf report`` reads for such code
(``/tmp/perf-<pid>.map``: start, size and name per line).

It wraps two class methods of numba's ``CPUCodeLibrary`` (numba.core.codegen), the engine's object-cache
hooks, and hands the wrapped ones to the engine: it must be installed before the first call of a kernel whose
code is to be named. It reaches into
numba's internals, so a numba whose internals differ is told plainly rather than profiled wrong.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from harness.suites.profile.sampling import ProfilerUnavailable

_objects: list[bytes] = []
_installed = False


@dataclass(frozen=True)
class Symbol:
    address: int
    size: int
    name: str  # the linker's (mangled) name
    object_index: int  # which captured object holds it
    offset: int  # its offset in that object's section


def install() -> None:
    """Keep every object numba's engine takes from now on (idempotent)."""
    global _installed
    if _installed:
        return
    from numba.core import codegen

    library = getattr(codegen, "CPUCodeLibrary", None)
    hooks = ("_object_getbuffer_hook", "_object_compiled_hook")
    if library is None or not all(hasattr(library, h) for h in hooks):
        import numba

        raise ProfilerUnavailable(f"numba {numba.__version__} has no CPUCodeLibrary object-cache hooks "
                           f"({', '.join(hooks)}): kernels cannot be named for the profiler")
    get_buffer = library._object_getbuffer_hook.__func__
    compiled = library._object_compiled_hook.__func__

    def keep(buffer) -> None:
        if buffer:
            _objects.append(bytes(buffer))

    def get_buffer_kept(cls, ll_module):  # an object numba loads (its cache, or a library already built)
        buffer = get_buffer(cls, ll_module)
        keep(buffer)
        return buffer

    def compiled_kept(cls, ll_module, buffer):  # an object LLVM has just compiled
        compiled(cls, ll_module, buffer)
        keep(buffer)

    library._object_getbuffer_hook = classmethod(get_buffer_kept)
    library._object_compiled_hook = classmethod(compiled_kept)
    from numba.core.registry import cpu_target

    # the engine took the hooks when numba's code generator was made (at the first compile or cache load,
    # which importing spq may already have done): hand it the wrapped ones
    cpu_target.target_context.codegen()._engine.set_object_cache(library._object_compiled_hook,
                                                                   library._object_getbuffer_hook)
    _installed = True


def require_tools() -> None:
    """Raise ProfilerUnavailable unless readelf (which names the kernels) is on PATH."""
    _require("readelf")


def _require(tool: str) -> str:
    path = shutil.which(tool)
    if path is None:
        raise ProfilerUnavailable(f"{tool} is not on PATH; the profile needs it (binutils: apt-get install binutils)")
    return path


def _functions(data: bytes) -> list[tuple[int, int, str, str, str]]:
    """(offset, size, binding, section index, name) of an object's FUNC symbols."""
    with tempfile.NamedTemporaryFile(suffix=".o", delete=False) as fh:
        fh.write(data)
        path = fh.name
    try:
        text = subprocess.run([_require("readelf"), "-sW", path], capture_output=True, text=True, check=True).stdout
    finally:
        os.unlink(path)
    rows = []
    for line in text.splitlines():
        parts = line.split()
        if len(parts) == 8 and parts[3] == "FUNC" and parts[6].isdigit():
            rows.append((int(parts[1], 16), int(parts[2]), parts[4], parts[6], parts[7]))
    return rows


def symbols() -> list[Symbol]:
    """Every function of the objects kept so far, placed where the engine loaded it. An object is placed
    through one of its global functions; its other functions in the same section follow at their offsets
    (LLVM's engine loads a section whole)."""
    from numba.core.registry import cpu_target

    engine = cpu_target.target_context.codegen()._engine._ee
    found: dict[int, Symbol] = {}
    for index, data in enumerate(_objects):
        functions = _functions(data)
        base = None
        for offset, _, binding, section, name in functions:
            if binding == "GLOBAL":
                address = engine.get_function_address(name)
                if address:
                    base = (section, address - offset)
                    break
        if base is None:
            continue  # an object the engine has not loaded (or has replaced)
        for offset, size, _, section, name in functions:
            if section == base[0] and size > 0:
                address = base[1] + offset
                found.setdefault(address, Symbol(address, size, name, index, offset))
    return sorted(found.values(), key=lambda s: s.address)


def write_perf_map(pid: int | None = None) -> tuple[Path, int]:
    """Write /tmp/perf-<pid>.map for the objects kept so far; (its path, the functions it names)."""
    pid = os.getpid() if pid is None else pid
    path = Path(f"/tmp/perf-{pid}.map")
    placed = symbols()
    path.write_text("".join(f"{s.address:x} {s.size:x} {s.name}\n" for s in placed))
    return path, len(placed)


def dump_objects(folder: Path) -> list[Path]:
    """Write the kept objects as folder/<index>.o (for ``objdump -d``); their paths."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for index, data in enumerate(_objects):
        path = folder / f"{index}.o"
        path.write_bytes(data)
        paths.append(path)
    return paths


# numba escapes characters outside [A-Za-z0-9_] as _xx (hex), but leaves "_" itself alone, so only the
# escapes a qualified name can hold (<locals>, <lambda>) are read back
_ESCAPES = {"_3c": "<", "_3e": ">"}
_ESCAPE = re.compile("|".join(_ESCAPES))


def readable(name: str) -> str:
    """numba's mangled name as its Python qualified name: ``_ZN3spq7kernels3gjk7descendB3v12...`` ->
    ``spq.kernels.gjk.descend``; numba's wrappers (cpython., cfunc.) say so in brackets. Other names
    are returned as they are."""
    wrapper = ""
    if name.startswith("cfunc."):
        name, wrapper = name[len("cfunc."):], " [cfunc]"
    if not name.startswith("_ZN"):
        return name + wrapper
    parts, i = [], 3
    while i < len(name) and name[i].isdigit():
        j = i
        while name[j].isdigit():
            j += 1
        length = int(name[i:j])
        parts.append(name[j:j + length])
        i = j + length
    if parts and parts[0] == "cpython":
        parts, wrapper = parts[1:], " [cpython]"
    text = ".".join(_ESCAPE.sub(lambda m: _ESCAPES[m.group(0)], p) for p in parts)
    return (text or name) + wrapper


def hot_spots(addresses: np.ndarray, placed: list[Symbol], top: int) -> pd.DataFrame:
    """The ``top`` instructions of the named kernels that most samples fell on: function, offset in it, share of
    all samples given, and the symbol and object they sit in (for disassembly)."""
    starts = np.array([s.address for s in placed], dtype=np.uint64)
    columns = ["function", "offset", "share", "symbol", "object_index", "object_offset"]
    if not len(starts) or not len(addresses):
        return pd.DataFrame(columns=columns)
    at = np.searchsorted(starts, addresses, side="right") - 1
    inside = at >= 0
    inside[inside] &= addresses[inside] < starts[at[inside]] + np.array([placed[i].size for i in at[inside]],
                                                                        dtype=np.uint64)
    unique, counts = np.unique(addresses[inside], return_counts=True)
    order = np.argsort(counts, kind="stable")[::-1][:top]
    rows = []
    for address, count in zip(unique[order], counts[order]):
        s = placed[int(np.searchsorted(starts, address, side="right") - 1)]
        rows.append({"function": readable(s.name), "offset": int(address) - s.address, "share": count / len(addresses),
                     "symbol": s.name, "object_index": s.object_index, "object_offset": s.offset})
    return pd.DataFrame(rows, columns=columns)


_TARGET = re.compile(r"<[^<>+]*(\+0x[0-9a-f]+)?>")  # a jump's target: its mangled name left out


def disassembly(object_file: Path, symbol: str) -> dict[int, str]:
    """One function's instructions as objdump reads them from its object: {offset in the object's section:
    instruction}, in address order; empty where objdump is missing or does not know the symbol."""
    if shutil.which("objdump") is None:
        return {}
    out = subprocess.run(["objdump", "-d", "--no-show-raw-insn", f"--disassemble={symbol}", str(object_file)],
                         capture_output=True, text=True).stdout
    lines = {}
    for line in out.splitlines():
        head, _, rest = line.partition(":\t")
        if rest and head.strip():
            try:
                lines[int(head.strip(), 16)] = _TARGET.sub(r"<\1>", " ".join(rest.split()))
            except ValueError:
                pass
    return lines


def instructions(objects: list[Path], spots: pd.DataFrame) -> list[str]:
    """Each hot spot's instruction as objdump reads it from its object (the sampled address is often the
    instruction after the one that stalled: perf's skid); "" where objdump is missing or says nothing."""
    listings: dict[tuple[int, str], dict[int, str]] = {}
    text = []
    for spot in spots.itertuples():
        key = (spot.object_index, spot.symbol)
        if key not in listings:
            listings[key] = disassembly(objects[spot.object_index], spot.symbol)
        text.append(listings[key].get(spot.object_offset + spot.offset, ""))
    return text


def annotated(addresses: np.ndarray, symbol: Symbol, object_file: Path, top: int, context: int = 4) -> list[str]:
    """Lines "percent  offset  instruction" of one function around its ``top`` most sampled instructions
    (``context`` instructions before each, one after), percent of all samples given; "..." between runs."""
    inside = addresses[(addresses >= symbol.address) & (addresses < symbol.address + symbol.size)]
    offsets, counts = np.unique((inside - np.uint64(symbol.address)).astype(np.int64), return_counts=True)
    count = dict(zip(offsets.tolist(), counts.tolist()))
    listing = [(at - symbol.offset, text) for at, text in disassembly(object_file, symbol.name).items()]
    where = {offset: i for i, (offset, _) in enumerate(listing)}
    shown = set()
    for offset in sorted(count, key=count.get, reverse=True)[:top]:
        if offset in where:
            i = where[offset]
            shown.update(range(max(0, i - context), min(len(listing), i + 2)))
    lines, previous = [], None
    for i in sorted(shown):
        if previous is not None and i != previous + 1:
            lines.append("   ...")
        offset, text = listing[i]
        lines.append(f"{100 * count.get(offset, 0) / max(len(addresses), 1):6.2f}  {offset:6x}  {text}")
        previous = i
    return lines
