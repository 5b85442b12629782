"""The report a person opens: one self-contained index.html (images embedded) and REPORT.md.

A report is a list of sections; each has a title, reading paragraphs, tables and charts. Every
chart is shown with a paragraph that says how to read it, and the run's metadata closes the page.
"""

from __future__ import annotations

import base64
import html
import json
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from harness.report.tables import markdown_table

STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 1100px; margin: 2em auto;
       padding: 0 1em; color: #222; line-height: 1.45; }
h1 { border-bottom: 2px solid #444; padding-bottom: .3em; }
h2 { margin-top: 2em; border-bottom: 1px solid #bbb; }
table { border-collapse: collapse; font-size: .85em; margin: 1em 0; }
th, td { border: 1px solid #ccc; padding: .25em .5em; text-align: right; }
th { background: #f0f0f0; }
td:first-child, th:first-child { text-align: left; }
figure { margin: 1.5em 0; }
figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: .9em; color: #444; margin-top: .4em; }
.meta { font-size: .8em; color: #555; background: #f7f7f7; padding: .8em; white-space: pre-wrap; }
"""


@dataclass
class Chart:
    path: Path
    caption: str  # one paragraph: what is plotted, units, and how to read it


@dataclass
class Section:
    title: str
    paragraphs: list[str] = field(default_factory=list)
    tables: list[tuple[str, pd.DataFrame]] = field(default_factory=list)  # (caption, table)
    charts: list[Chart] = field(default_factory=list)


def _fmt(df: pd.DataFrame) -> pd.DataFrame:
    def cell(v):
        if isinstance(v, float):
            if v != v:
                return "–"
            if v != 0.0 and (abs(v) < 1e-3 or abs(v) >= 1e6):
                return f"{v:.3e}"
            return f"{v:.6g}"
        return v

    return df.map(cell)


def _image_tag(path: Path) -> str:
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return f'<img alt="{html.escape(path.stem)}" src="data:image/png;base64,{data}">'


def render(out_dir: Path, title: str, intro: list[str], sections: list[Section], meta: dict) -> list[Path]:
    """Write out_dir/index.html (self-contained) and out_dir/REPORT.md; returns their paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    h = [f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>",
         f"<style>{STYLE}</style></head><body>", f"<h1>{html.escape(title)}</h1>"]
    md = [f"# {title}", ""]
    for p in intro:
        h.append(f"<p>{html.escape(p)}</p>")
        md += [p, ""]
    h.append("<ul>" + "".join(f"<li><a href='#s{i}'>{html.escape(s.title)}</a></li>"
                              for i, s in enumerate(sections)) + "</ul>")
    for i, s in enumerate(sections):
        h.append(f"<h2 id='s{i}'>{html.escape(s.title)}</h2>")
        md += [f"## {s.title}", ""]
        for p in s.paragraphs:
            h.append(f"<p>{html.escape(p)}</p>")
            md += [p, ""]
        for chart in s.charts:
            if chart.path.exists():
                h.append(f"<figure>{_image_tag(chart.path)}<figcaption>{html.escape(chart.caption)}</figcaption></figure>")
                md += [f"![{chart.path.stem}]({chart.path.name})", "", chart.caption, ""]
        for caption, table in s.tables:
            h.append(f"<p><b>{html.escape(caption)}</b></p>" + _fmt(table).to_html(index=False, escape=True))
            md += [f"**{caption}**", "", markdown_table(table), ""]
    h.append("<h2>Run</h2><div class='meta'>" + html.escape(json.dumps(meta, indent=2, sort_keys=True)) + "</div>")
    # lets a headless browser check that every chart decoded and has a size
    h.append("<script>window.addEventListener('load', () => { const imgs = [...document.images]; "
             "document.body.dataset.imagesOk = String(imgs.length > 0 && "
             "imgs.every(i => i.complete && i.naturalWidth > 0)); });</script>")
    h.append("</body></html>")
    md += ["## Run", "", "```", json.dumps(meta, indent=2, sort_keys=True), "```", ""]
    index, report = out_dir / "index.html", out_dir / "REPORT.md"
    index.write_text("\n".join(h))
    report.write_text("\n".join(md))
    return [index, report]
