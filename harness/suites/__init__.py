"""Suites: each measurement behind one entry signature, a config in and tidy tables out.

    output = suite.run(config)      # config: the suite's own dataclass (seed, sizes, engines, progress)
    paths = write_output(output, out_dir)

An :class:`Output` holds the suite's tables (each with its file stem, title and notes), raw tables
written as compressed CSV, the run's metadata and the lines a terminal shows. The command line
(harness/cli.py) maps its arguments onto a config, runs the suite, writes its output and prints its
lines; ``spq check`` (harness/check.py) composes the same suites' functions.

Migrated so far: crosscheck. The others still run through their ``cmd_*`` functions in cli.py.
"""

from __future__ import annotations

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
class Output:
    tables: list[Table] = field(default_factory=list)
    raw: dict[str, pd.DataFrame] = field(default_factory=dict)  # file name (.csv.gz) -> per-query table
    meta: dict = field(default_factory=dict)
    lines: list[str] = field(default_factory=list)  # the summary a terminal shows


def write_output(output: Output, out_dir) -> list[Path]:
    """Write the output's tables (CSV + Markdown with the metadata) and raw tables into out_dir."""
    from harness.report.tables import write_table

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, frame in output.raw.items():
        frame.to_csv(out_dir / name, index=False)
        paths.append(out_dir / name)
    for t in output.tables:
        paths += write_table(t.frame, out_dir, t.stem, t.title, output.meta, t.notes)
    return paths


def frame_lines(df: pd.DataFrame) -> list[str]:
    """A table as terminal lines (3 significant digits)."""
    with pd.option_context("display.max_rows", 500, "display.width", 200, "display.max_columns", 30,
                           "display.float_format", lambda v: f"{v:.3g}"):
        return df.to_string(index=False).splitlines()
