"""Distance engines the harness measures, behind one interface (see :mod:`harness.engines.base`).

The registry maps an engine name to a factory that builds a fresh instance. Factories import their
engine's package only when called, so a missing package affects only its own engines. Add an engine
with :func:`register_engine` (e.g. ``register_engine("spq", SpqEngine)``).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterable
from importlib import import_module

from harness.engines.base import STATUSES, BatchResult, Engine, EngineResult, PreparedPair

EngineFactory = Callable[[], Engine]

_ENGINE_CLASSES = {  # exported class -> module, imported on first use
    "SpqEngine": "harness.engines.spq_engine",
    "FclEngine": "harness.engines.fcl_engine",
    "CoalEngine": "harness.engines.coal_engine",
    "BulletEngine": "harness.engines.bullet_engine",
}


def __getattr__(name: str):
    if name in _ENGINE_CLASSES:
        return getattr(import_module(_ENGINE_CLASSES[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _spq() -> Engine:
    from harness.engines.spq_engine import SpqEngine

    return SpqEngine(signed=True)


def _fcl() -> Engine:
    from harness.engines.fcl_engine import FclEngine

    return FclEngine()


def _coal() -> Engine:
    from harness.engines.coal_engine import CoalEngine

    return CoalEngine()


def _bullet() -> Engine:
    from harness.engines.bullet_engine import BulletEngine

    return BulletEngine(margin=0.0, name="bullet")


def _bullet_margin() -> Engine:
    from harness.engines.bullet_engine import BulletEngine

    return BulletEngine(margin=None, name="bullet-margin")


ENGINE_FACTORIES: dict[str, EngineFactory] = {
    "spq": _spq,
    "fcl": _fcl,
    "coal": _coal,
    "bullet": _bullet,  # collision margin 0
    "bullet-margin": _bullet_margin,  # pybullet's default margin, to show its bias
}


def register_engine(name: str, factory: EngineFactory, *, replace: bool = False) -> None:
    """Make ``available_engines`` offer ``name``, built by calling ``factory()``."""
    if not replace and name in ENGINE_FACTORIES:
        raise ValueError(f"engine {name!r} is already registered (pass replace=True to override)")
    ENGINE_FACTORIES[name] = factory


def engine_names() -> list[str]:
    """Registered engine names, in registration order."""
    return list(ENGINE_FACTORIES)


def available_engines(include: Iterable[str] | str | None = None) -> dict[str, Engine]:
    """Fresh engine instances by name.

    include : names to build, in that order; None builds every registered engine and skips (with a
        warning) those whose package cannot be imported. A named engine that cannot be built raises.
    Engines holding resources (pybullet clients) should be ``close()``d by the caller.
    """
    if isinstance(include, str):
        include = [include]
    names = engine_names() if include is None else list(include)
    unknown = [n for n in names if n not in ENGINE_FACTORIES]
    if unknown:
        raise ValueError(f"unknown engine(s) {unknown}; registered: {engine_names()}")
    engines: dict[str, Engine] = {}
    for name in names:
        try:
            engines[name] = ENGINE_FACTORIES[name]()
        except ImportError as exc:
            if include is not None:
                raise
            warnings.warn(f"engine {name!r} skipped: {exc}", RuntimeWarning, stacklevel=2)
    return engines


__all__ = [
    "STATUSES",
    "BatchResult",
    "Engine",
    "EngineResult",
    "PreparedPair",
    "EngineFactory",
    "ENGINE_FACTORIES",
    "register_engine",
    "engine_names",
    "available_engines",
    *_ENGINE_CLASSES,
]
