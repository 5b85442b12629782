"""Shared test helpers: access to the shared reference data."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parent.parent
if str(REPO_ROOT) not in sys.path:  # run from anywhere without installing the package
    sys.path.insert(0, str(REPO_ROOT))


def require_shared_datasets() -> Path:
    """The shared datasets directory; if it is missing, fail under CI (env CI set) and skip otherwise."""
    from datasets.paths import ENV_SHARED, shared_datasets_dir

    path = shared_datasets_dir()
    if path is None:
        msg = f"shared datasets not found (<repo>/../shared/datasets or ${ENV_SHARED})"
        if os.environ.get("CI"):
            pytest.fail(msg)
        pytest.skip(msg)
    return path


@pytest.fixture
def shared_datasets() -> Path:
    """Fixture form of :func:`require_shared_datasets`."""
    return require_shared_datasets()


@pytest.fixture(scope="session", autouse=True)
def _kernels_compiled_in_parts():
    """Under pytest-xdist, each worker first compiles one part of spq's kernels (harness.report.compile)
    before its tests. On a fresh checkout numba's cache is empty, and without this both workers meet
    the same kernels first and compile them side by side (numba's first compile is a large share of a cold
    run's time, as in the report, which splits it the same way). Each then loads the other's part
    from the cache. A run without workers compiles as it goes."""
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    if not worker.startswith("gw") or os.environ.get("NUMBA_DISABLE_JIT") == "1":
        return
    from harness.report.compile import PARTS, compile_part

    compile_part(PARTS[int(worker[2:]) % len(PARTS)])
