"""What a report records about the run: versions, machine, seeds, tolerances, time."""

from __future__ import annotations

import datetime as _dt
import os
import platform
from importlib import metadata
from pathlib import Path


def _version(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "not installed"


PACKAGES = ("spq", "numpy", "scipy", "numba", "python-fcl", "coal", "pybullet", "trimesh", "pandas")


def _cpu_model(cpuinfo: Path) -> str:
    """The first 'model name' of a /proc/cpuinfo-style file; platform.processor() where there is none
    (it is empty on Linux, hence the file)."""
    try:
        for line in cpuinfo.read_text().splitlines():
            key, _, value = line.partition(":")
            if key.strip() == "model name" and value.strip():
                return value.strip()
    except OSError:
        pass
    return platform.processor()


def _caches(cpu_dir: Path) -> str:
    """The data and unified caches of one CPU's sysfs folder, smallest level first: 'L1d 32K, L2 1024K'."""
    caches = []
    for index in sorted(cpu_dir.glob("cache/index*")):
        try:
            level, kind, size = ((index / name).read_text().strip() for name in ("level", "type", "size"))
        except OSError:
            continue
        if kind != "Instruction":
            caches.append((int(level), f"L{level}{'d' if kind == 'Data' else ''} {size}"))
    return ", ".join(text for _, text in sorted(caches))


def describe_cpu(cpuinfo: Path = Path("/proc/cpuinfo"), cpu_dir: Path = Path("/sys/devices/system/cpu/cpu0")) -> str:
    """The processor a run measured on: its model name, the CPU that LLVM (so numba) compiles for, and
    its caches, e.g. 'AMD EPYC (LLVM: znver4; L1d 32K, L2 1024K, L3 32768K)'. Speed ratios between
    engines and between spq's own pairs move with it, so reports record it beside the versions."""
    try:
        from llvmlite import binding

        llvm = binding.get_host_cpu_name()
    except Exception:  # llvmlite missing or unable to tell: the rest still says something
        llvm = "unknown"
    details = "; ".join(part for part in (f"LLVM: {llvm}", _caches(cpu_dir)) if part)
    return f"{_cpu_model(cpuinfo) or 'unknown CPU'} ({details})"


def run_metadata(**extra) -> dict:
    """Versions of the packages measured, machine, and the caller's settings (seed, tolerances...)."""
    return {
        "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "python": platform.python_version(),
        "machine": f"{platform.machine()} {describe_cpu()}, {os.cpu_count()} cpus",
        "platform": platform.platform(),
        "versions": {p: _version(p) for p in PACKAGES},
        **extra,
    }
