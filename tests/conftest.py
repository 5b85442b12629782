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
