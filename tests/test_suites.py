"""The suites' shape: one entry signature in harness/suites, no way back into the command line."""

from __future__ import annotations

import ast
import dataclasses
import importlib
import inspect
import pkgutil
from pathlib import Path

import pandas as pd

import harness
import harness.suites as suites
from harness.suites import Figure, Output, Table, write_output

HARNESS = Path(harness.__file__).parent


def suite_modules():
    return [importlib.import_module(f"harness.suites.{m.name}") for m in pkgutil.iter_modules(suites.__path__)]


def test_every_suite_has_one_entry_signature():
    modules = suite_modules()
    assert {m.__name__.rsplit(".", 1)[1] for m in modules} >= {
        "crosscheck", "bench", "table1", "robot", "support", "continuity", "stability", "depth", "tradeoff",
        "rtradeoff", "check", "pictures"}
    for module in modules:
        assert dataclasses.is_dataclass(module.Config), module.__name__
        config = module.Config()  # every field has a default
        assert "progress" in {f.name for f in dataclasses.fields(config)}, module.__name__
        params = list(inspect.signature(module.run).parameters)
        assert params == ["config"], (module.__name__, params)
        assert inspect.signature(module.run).return_annotation in ("Output", Output), module.__name__


def imported_modules(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
            names |= {f"{node.module}.{a.name}" for a in node.names}
    return names


def test_only_the_command_line_imports_the_command_line():
    offenders = [str(p.relative_to(HARNESS)) for p in HARNESS.rglob("*.py")
                 if p.name != "cli.py" and any(n == "harness.cli" or n.startswith("harness.cli.")
                                               for n in imported_modules(p))]
    assert offenders == []


def test_write_output_writes_every_kind_and_removes_what_is_obsolete(tmp_path):
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "stale.csv").write_text("x\n1\n")
    elsewhere = tmp_path / "other" / "junit.xml"
    frame = pd.DataFrame({"a": [1, 2], "b": [0.5, 0.25]})

    def draw(path):
        path.write_bytes(b"\x89PNG")

    out = Output(tables=[Table("t", "A table", frame, "notes here")], raw={"r.csv.gz": frame},
                 figures=[Figure("f.png", draw)], documents={"page.md": "# page\n", str(elsewhere): "<x/>"},
                 meta={"seed": 3}, obsolete=["stale.csv"])
    paths = write_output(out, tmp_path / "out")
    names = sorted(p.name for p in paths)
    assert names == ["f.png", "junit.xml", "page.md", "r.csv.gz", "t.csv", "t.md"]
    assert not (tmp_path / "out" / "stale.csv").exists()
    assert pd.read_csv(tmp_path / "out" / "t.csv").equals(frame)
    assert pd.read_csv(tmp_path / "out" / "r.csv.gz").equals(frame)
    md = (tmp_path / "out" / "t.md").read_text()
    assert md.startswith("# A table") and "notes here" in md and '"seed": 3' in md
    assert elsewhere.read_text() == "<x/>"
    assert out.frame("t") is frame and out.frame("r.csv.gz") is frame
