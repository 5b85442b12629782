"""Distance engines the harness measures, behind one interface (see :mod:`harness.engines.base`).

The registry maps an engine name to a factory that builds a fresh instance. Factories import their
engine's package only when called, so a missing package affects only its own engines. Add an engine
with :func:`register_engine` (e.g. ``register_engine("spq", SpqEngine)``).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterable
from importlib import import_module

from harness.engines.base import (
    STATUSES,
    BatchResult,
    Engine,
    EngineResult,
    PreparedPair,
)

EngineFactory = Callable[[], Engine]

_ENGINE_CLASSES = {  # exported class -> module, imported on first use
    "SpqEngine": "harness.engines.spq_engine",
    "FclEngine": "harness.engines.fcl_engine",
    "CoalEngine": "harness.engines.coal_engine",
    "BulletEngine": "harness.engines.bullet_engine",
    "MujocoEngine": "harness.engines.mujoco_engine",
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


def _mujoco() -> Engine:
    from harness.engines.mujoco_engine import MujocoEngine

    return MujocoEngine()


ENGINE_FACTORIES: dict[str, EngineFactory] = {
    "spq": _spq,
    "fcl": _fcl,
    "coal": _coal,
    "bullet": _bullet,  # collision margin 0
    "bullet-margin": _bullet_margin,  # pybullet's default margin, to show its bias
    "mujoco": _mujoco,  # mj_geomDistance, native GJK/EPA
}


PLUGIN_SPECS: dict[str, str] = {}  # name -> "module:Class" of the plugins registered here (for worker processes)
ENTRY_POINT_GROUP = "spq.engines"
_entry_points_loaded = False


def load_plugin(spec: str) -> EngineFactory:
    """The engine factory named by ``spec``, "package.module:Attribute": a class (or any callable)
    that takes no arguments and returns an :class:`Engine`. Raises ValueError if it cannot be loaded."""
    module, sep, attr = spec.partition(":")
    if not sep or not module or not attr:
        raise ValueError(f"engine plugin {spec!r}: expected 'package.module:Class'")
    try:
        obj = import_module(module)
    except ImportError as exc:
        raise ValueError(f"engine plugin {spec!r}: cannot import {module!r} ({exc})") from None
    for part in attr.split("."):
        obj = getattr(obj, part, None)
        if obj is None:
            raise ValueError(f"engine plugin {spec!r}: {module!r} has no attribute {attr!r}")
    if not callable(obj):
        raise ValueError(f"engine plugin {spec!r}: {attr!r} is not a class or callable")
    return obj


def _named(factory: EngineFactory, name: str) -> EngineFactory:
    """A factory whose engines report ``name`` (the name they are registered and scored under)."""
    def build() -> Engine:
        engine = factory()
        if not isinstance(engine, Engine):
            raise ValueError(f"engine {name!r}: its factory returned {type(engine).__name__}, not an Engine "
                             "(see harness.engines.base)")
        engine.name = name
        return engine
    return build


def register_plugin(spec: str, name: str | None = None) -> str:
    """Register the engine of ``spec`` ("[name=]package.module:Class", see :func:`load_plugin`) under
    ``name`` (default: the class's ``name`` attribute, else the class name), replacing any engine of
    that name; returns the name."""
    if "=" in spec and name is None:
        name, spec = spec.split("=", 1)
    factory = load_plugin(spec)
    name = name or getattr(factory, "name", None) or getattr(factory, "__name__", None)
    if not isinstance(name, str) or not name:
        raise ValueError(f"engine plugin {spec!r}: give it a name ('name={spec}')")
    ENGINE_FACTORIES[name] = _named(factory, name)
    PLUGIN_SPECS[name] = spec
    return name


def _load_entry_points() -> None:
    """Register the engines that installed packages declare in the entry-point group "spq.engines"
    (name = the entry point's name, value = "package.module:Class"); built-in names win."""
    global _entry_points_loaded
    if _entry_points_loaded:
        return
    _entry_points_loaded = True
    from importlib.metadata import entry_points

    for ep in entry_points(group=ENTRY_POINT_GROUP):
        if ep.name not in ENGINE_FACTORIES:
            ENGINE_FACTORIES[ep.name] = _named(lambda ep=ep: ep.load()(), ep.name)


def register_engine(name: str, factory: EngineFactory, *, replace: bool = False) -> None:
    """Make ``available_engines`` offer ``name``, built by calling ``factory()``."""
    if not replace and name in ENGINE_FACTORIES:
        raise ValueError(f"engine {name!r} is already registered (pass replace=True to override)")
    ENGINE_FACTORIES[name] = factory
    PLUGIN_SPECS.pop(name, None)


def engine_names() -> list[str]:
    """Registered engine names, in registration order (entry-point plugins after the built-in ones)."""
    _load_entry_points()
    return list(ENGINE_FACTORIES)


def available_engines(include: Iterable[str] | str | None = None) -> dict[str, Engine]:
    """Fresh engine instances by name.

    include : names to build, in that order; None builds every registered engine and skips (with a
        warning) those whose package cannot be imported. A named engine that cannot be built raises.
    Engines holding resources (pybullet clients) should be ``close()``d by the caller.
    """
    _load_entry_points()
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
    "register_plugin",
    "PLUGIN_SPECS",
    "load_plugin",
    "ENTRY_POINT_GROUP",
    "engine_names",
    "available_engines",
    *_ENGINE_CLASSES,
]
