"""Copies of the spq package at two revisions, importable side by side in one process.

A same-process A/B times two versions of the kernels against each other on the same poses, block by
block, so that a shared machine's slow and fast spells fall on both alike (harness.suites.bench.timing).
Two versions cannot both be ``spq``: each is copied under its own name (``spq_<key>``), with every
``spq.`` import in its sources renamed to that name, and imported from a folder of its own. Each copy
keeps its numba cache in its own ``__pycache__`` folders (the kernels' cache stamp is per folder, see
spq.kernels.jit), so a copy compiles once, on its first use, and a later run of the same sources
loads it. The copies leave out the C extension (spq._entry): their per-call queries take the Python
path, the same in both.
"""

from __future__ import annotations

import hashlib
import importlib
import io
import os
import re
import shutil
import subprocess
import sys
import tarfile
from pathlib import Path

WORKING_TREE = "working-tree"
_IMPORTS = re.compile(r"\b(from|import)\s+spq(?=[.\s])")
_QUALIFIED = re.compile(r"\bspq\.kernels\b")


def cache_root() -> Path:
    """Where the copies live: SPQ_AB_CACHE, else ~/.cache/spq-ab."""
    return Path(os.environ.get("SPQ_AB_CACHE", Path.home() / ".cache" / "spq-ab"))


def rename_imports(source: str, name: str) -> str:
    """The source of a module of spq with its imports of spq (``from spq.x import``, ``import spq.x``,
    ``from spq import``) and its qualified ``spq.kernels`` names turned to package ``name``."""
    return _QUALIFIED.sub(f"{name}.kernels", _IMPORTS.sub(lambda m: f"{m.group(1)} {name}", source))


def _git(repo: Path, *args: str) -> bytes:
    try:
        return subprocess.run(["git", "-C", str(repo), *args], check=True, capture_output=True).stdout
    except FileNotFoundError as exc:
        raise ValueError("an A/B against a revision needs git on the PATH") from exc
    except subprocess.CalledProcessError as exc:
        raise ValueError(f"git {' '.join(args)} failed in {repo}: {exc.stderr.decode().strip()}") from exc


def _sources(repo: Path, revision: str) -> tuple[str, dict[str, bytes]]:
    """(resolved revision, {path under spq/: bytes}) of the package's Python sources."""
    if revision == WORKING_TREE:
        root = repo / "spq"
        if not root.is_dir():
            raise ValueError(f"no spq package in {repo}")
        files = {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*.py"))
                 if "__pycache__" not in p.parts}
        return WORKING_TREE, files
    commit = _git(repo, "rev-parse", "--verify", f"{revision}^{{commit}}").decode().strip()
    archive = _git(repo, "archive", "--format=tar", commit, "spq")
    files = {}
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        for member in tar.getmembers():
            if member.isfile() and member.name.endswith(".py"):
                files[member.name[len("spq/"):]] = tar.extractfile(member).read()
    if not files:
        raise ValueError(f"revision {revision} ({commit[:12]}) has no spq package")
    return commit, files


def _key(files: dict[str, bytes]) -> str:
    h = hashlib.sha256()
    for path in sorted(files):
        h.update(path.encode())
        h.update(hashlib.sha256(files[path]).digest())
    return h.hexdigest()[:12]


def prepare(repo, revision: str, root: Path | None = None) -> tuple[str, str, Path]:
    """Copy spq at ``revision`` of the git checkout ``repo`` (WORKING_TREE: its files as they are) as
    package ``spq_<key>`` under ``root`` (default :func:`cache_root`), key a digest of the sources, and
    return (package name, resolved revision, folder to put on sys.path). An existing copy of the same
    sources is reused with its compiled kernels."""
    repo = Path(repo).resolve()
    resolved, files = _sources(repo, revision)
    key = _key(files)
    name = f"spq_{key}"
    folder = (root or cache_root()) / key
    package = folder / name
    if not (package / "__init__.py").is_file():
        staging = folder / f".{name}.{os.getpid()}"
        shutil.rmtree(staging, ignore_errors=True)
        for path, data in files.items():
            target = staging / path
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(rename_imports(data.decode("utf-8"), name), encoding="utf-8")
        try:
            staging.rename(package)
        except OSError:  # another process made it first: theirs is the same
            shutil.rmtree(staging, ignore_errors=True)
    return name, resolved, folder


def load(name: str, folder: Path):
    """Import a prepared copy."""
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))
    return importlib.import_module(name)
