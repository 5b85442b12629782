"""Tables as CSV and Markdown, each with the metadata of the run that produced it."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pandas as pd


def _cell(value) -> str:
    if isinstance(value, float):
        if math.isnan(value):
            return "–"
        if value != 0.0 and (abs(value) < 1e-3 or abs(value) >= 1e6):
            return f"{value:.3e}"
        return f"{value:.6g}"
    return str(value)


def markdown_table(df: pd.DataFrame) -> str:
    """GitHub Markdown for a DataFrame (numbers in short scientific form)."""
    head = "| " + " | ".join(str(c) for c in df.columns) + " |"
    rule = "|" + "|".join("---" for _ in df.columns) + "|"
    rows = ["| " + " | ".join(_cell(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join([head, rule, *rows])


def write_table(df: pd.DataFrame, out_dir: Path, stem: str, title: str, meta: dict, notes: str = "") -> list[Path]:
    """Write ``stem.csv`` and ``stem.md`` (title, notes, table, metadata) into out_dir."""
    out_dir.mkdir(parents=True, exist_ok=True)
    csv = out_dir / f"{stem}.csv"
    md = out_dir / f"{stem}.md"
    df.to_csv(csv, index=False)
    text = [f"# {title}", ""]
    if notes:
        text += [notes.strip(), ""]
    text += [markdown_table(df), "", "Run: `" + json.dumps(meta, sort_keys=True) + "`", ""]
    md.write_text("\n".join(text))
    return [csv, md]
