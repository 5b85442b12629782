"""Suites: each measurement behind one entry signature, a config in and tidy tables out.

    output = suite.run(config)      # config: the suite's own dataclass (seed, sizes, engines, progress)
    paths = write_output(output, out_dir)

An :class:`Output` holds the suite's tables (each with its file stem, title and notes), raw tables
written as CSV (compressed when the name ends in .gz), figures (drawn when written), free-form
documents (Markdown pages a suite composes itself), the run's metadata, the lines a terminal shows
and an exit code (0 unless the suite judges, as ``check`` does). A suite computes; it writes
nothing itself. The command line (harness/cli.py) maps its arguments onto a config, runs the suite,
writes its output and prints its lines; ``spq report`` (harness/report/assemble.py) runs the same
suites with its own configs and builds its sections from the files written; ``spq check``
(harness/suites/check/__init__.py) runs the crosscheck, stability and depth suites at fixed seeds and judges
their raw tables.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd


@dataclass
class Table:
    stem: str  # file stem: stem.csv and stem.md
    title: str
    frame: pd.DataFrame
    notes: str = ""


@dataclass
class Figure:
    name: str  # file name in the output folder (.png)
    draw: Callable[[Path], object]  # draws the figure into the given path


@dataclass
class Output:
    tables: list[Table] = field(default_factory=list)
    raw: dict[str, pd.DataFrame] = field(default_factory=dict)  # file name (.csv or .csv.gz) -> table, no Markdown
    figures: list[Figure] = field(default_factory=list)
    documents: dict[str, str] = field(default_factory=dict)  # file name -> text (a suite's own Markdown page)
    meta: dict = field(default_factory=dict)
    lines: list[str] = field(default_factory=list)  # the summary a terminal shows
    exit_code: int = 0  # 1: the suite judged a regression (check)
    obsolete: list[str] = field(default_factory=list)  # files of an earlier run that must not linger

    def frame(self, stem: str) -> pd.DataFrame:
        """The table with this file stem (or raw file name), for a suite composed from others."""
        for t in self.tables:
            if t.stem == stem:
                return t.frame
        if stem in self.raw:
            return self.raw[stem]
        raise KeyError(f"no table {stem!r} in this output (tables: {[t.stem for t in self.tables]}, "
                       f"raw: {list(self.raw)})")


def write_output(output: Output, out_dir) -> list[Path]:
    """Write the output's raw tables, tables (CSV + Markdown with the metadata), documents and figures
    into out_dir; returns the paths written."""
    from harness.report.tables import write_table

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for name in output.obsolete:
        (out_dir / name).unlink(missing_ok=True)
    for name, frame in output.raw.items():
        frame.to_csv(out_dir / name, index=False)
        paths.append(out_dir / name)
    for t in output.tables:
        paths += write_table(t.frame, out_dir, t.stem, t.title, output.meta, t.notes)
    for name, text in output.documents.items():  # an absolute name (a file the caller named) stays as it is
        (out_dir / name).parent.mkdir(parents=True, exist_ok=True)
        (out_dir / name).write_text(text)
        paths.append(out_dir / name)
    for figure in output.figures:
        figure.draw(out_dir / figure.name)
        paths.append(out_dir / figure.name)
    return paths


def frame_lines(df: pd.DataFrame) -> list[str]:
    """A table as terminal lines (3 significant digits)."""
    with pd.option_context("display.max_rows", 500, "display.width", 200, "display.max_columns", 30,
                           "display.float_format", lambda v: f"{v:.3g}"):
        return df.to_string(index=False).splitlines()
