"""The report a person opens: one self-contained index.html (images embedded) and REPORT.md.

A report is a list of sections; each has a title, reading paragraphs, tables and charts. An
optional lead (the verdict) comes first, on the first screen, its column headers linking down to the
sections. Every chart is shown with a one-line caption saying what to look at and a paragraph that
says how to read it; wide tables scroll inside their section; the run's metadata closes the page.
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
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 1200px; margin: .8em auto;
       padding: 0 1em; color: #222; line-height: 1.45; }
h1 { border-bottom: 2px solid #444; padding-bottom: .2em; margin: 0 0 .3em; font-size: 1.6em; }
h2 { margin-top: 2em; border-bottom: 1px solid #bbb; }
h2#s0 { margin-top: .6em; }
table { border-collapse: collapse; font-size: .85em; margin: 1em 0; }
th, td { border: 1px solid #ccc; padding: .25em .5em; text-align: right; }
th { background: #f0f0f0; }
td:first-child, th:first-child { text-align: left; }
figure { margin: 1.5em 0; }
figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: .9em; color: #444; margin-top: .4em; }
.meta { font-size: .8em; color: #555; background: #f7f7f7; padding: .8em; white-space: pre-wrap; }
.scroll { overflow-x: auto; max-width: 100%; }
figcaption b.look { color: #222; }
.lead { background: #f6f8fa; border: 1px solid #d0d7de; border-radius: 6px; padding: .3em .8em .5em; }
.lead h2 { margin: .2em 0; border: none; font-size: 1.2em; }
.lead p { margin: .2em 0; font-size: .9em; }
.lead .grid { display: grid; grid-template-columns: minmax(0, 2.1fr) minmax(0, 1fr); gap: .8em; }
.lead table { font-size: .78em; margin: .3em 0; }
.lead td { white-space: nowrap; }
.lead .caption { font-size: .8em; color: #444; margin: .2em 0 0; }
.intro { font-size: .9em; margin: .2em 0 .4em; }
nav.toc { font-size: .82em; margin: .4em 0; }
nav.toc a { white-space: nowrap; }
.gallery { display: grid; grid-template-columns: repeat(2, minmax(0, 1fr)); gap: .6em 1em; }
.gallery figure { margin: .3em 0; }
.gallery figcaption { font-size: .8em; }
"""


@dataclass
class Chart:
    path: Path
    caption: str  # one paragraph: what is plotted, units, and how to read it
    look: str = ""  # one line: what to look at (shown first, in bold)


@dataclass
class Section:
    title: str
    paragraphs: list[str] = field(default_factory=list)
    tables: list[tuple[str, pd.DataFrame]] = field(default_factory=list)  # (caption, table)
    charts: list[Chart] = field(default_factory=list)
    gallery: bool = False  # charts two to a row (pictures), before the paragraphs


@dataclass
class Lead:
    """The verdict at the top of the page: paragraphs, then tables side by side, each (caption,
    table, {column: title of the section the column's figures come from}): those headers link there."""

    title: str
    paragraphs: list[str] = field(default_factory=list)
    tables: list[tuple[str, pd.DataFrame, dict]] = field(default_factory=list)


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


def _table_html(table: pd.DataFrame, links: dict | None = None) -> str:
    """A table inside a div that scrolls sideways when it is wider than its section; header cells
    named in ``links`` ({column: anchor}) link to that anchor."""
    text = _fmt(table).to_html(index=False, escape=True)
    for column, anchor in (links or {}).items():
        cell = f"<th>{html.escape(str(column))}</th>"
        text = text.replace(cell, f"<th><a href='#{anchor}'>{html.escape(str(column))}</a></th>", 1)
    return f"<div class='scroll'>{text}</div>"


def _figure_html(chart: Chart) -> str:
    look = f"<b class='look'>{html.escape(chart.look)}</b><br>" if chart.look else ""
    return f"<figure>{_image_tag(chart.path)}<figcaption>{look}{html.escape(chart.caption)}</figcaption></figure>"


def _lead_html(lead: Lead, anchors: dict) -> str:
    parts = [f"<section class='lead' id='verdict'><h2>{html.escape(lead.title)}</h2>"]
    parts += [f"<p>{html.escape(p)}</p>" for p in lead.paragraphs]
    cells = []
    for caption, table, links in lead.tables:
        resolved = {c: anchors[t] for c, t in links.items() if t in anchors}
        cells.append(f"<div>{_table_html(table, resolved)}<p class='caption'>{html.escape(caption)}"
                     + "".join(f" <a href='#{a}'>{html.escape(t)}</a>" for t, a in anchors.items()
                               if t in set(links.values())) + "</p></div>")
    parts.append("<div class='grid'>" + "".join(cells) + "</div></section>")
    return "".join(parts)


def render(out_dir: Path, title: str, intro: list[str], sections: list[Section], meta: dict,
           lead: Lead | None = None) -> list[Path]:
    """Write out_dir/index.html (self-contained) and out_dir/REPORT.md; returns their paths. ``lead``
    (the verdict) goes first, above the table of contents."""
    out_dir.mkdir(parents=True, exist_ok=True)
    h = [f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>",
         f"<style>{STYLE}</style></head><body>", f"<h1>{html.escape(title)}</h1>"]
    md = [f"# {title}", ""]
    for p in intro:
        h.append(f"<p class='intro'>{html.escape(p)}</p>")
        md += [p, ""]
    anchors = {s.title: f"s{i}" for i, s in enumerate(sections)}
    if lead is not None:
        h.append(_lead_html(lead, anchors))
        md += [f"## {lead.title}", ""]
        for p in lead.paragraphs:
            md += [p, ""]
        for caption, table, _ in lead.tables:
            md += [f"**{caption}**", "", markdown_table(table), ""]
    h.append("<nav class='toc'>" + " · ".join(f"<a href='#s{i}'>{html.escape(s.title)}</a>"
                                              for i, s in enumerate(sections)) + "</nav>")
    for i, s in enumerate(sections):
        h.append(f"<h2 id='s{i}'>{html.escape(s.title)}</h2>")
        md += [f"## {s.title}", ""]
        charts = [c for c in s.charts if c.path.exists()]
        if s.gallery and charts:
            h.append("<div class='gallery'>" + "".join(_figure_html(c) for c in charts) + "</div>")
        for p in s.paragraphs:
            h.append(f"<p>{html.escape(p)}</p>")
            md += [p, ""]
        for chart in charts:
            if not s.gallery:
                h.append(_figure_html(chart))
            md += [f"![{chart.path.stem}]({chart.path.name})", ""]
            md += [f"**{chart.look}**", ""] if chart.look else []
            md += [chart.caption, ""]
        for caption, table in s.tables:
            h.append(f"<p><b>{html.escape(caption)}</b></p>" + _table_html(table))
            md += [f"**{caption}**", "", markdown_table(table), ""]
    h.append("<h2>Run</h2><div class='meta'>" + html.escape(json.dumps(meta, indent=2, sort_keys=True)) + "</div>")
    # lets a headless browser check that every chart decoded and has a size, and where the verdict
    # and the first figure sit against the first screen (pixels from the top of the page)
    h.append("<script>window.addEventListener('load', () => { const imgs = [...document.images]; "
             "document.body.dataset.imagesOk = String(imgs.length > 0 && "
             "imgs.every(i => i.complete && i.naturalWidth > 0)); "
             "const lead = document.getElementById('verdict'); const fig = document.querySelector('figure img'); "
             "document.body.dataset.screenHeight = String(window.innerHeight); "
             "document.body.dataset.verdictBottom = lead ? String(Math.round(lead.getBoundingClientRect().bottom)) : ''; "
             "document.body.dataset.firstFigureTop = fig ? String(Math.round(fig.getBoundingClientRect().top)) : ''; "
             "});</script>")
    h.append("</body></html>")
    md += ["## Run", "", "```", json.dumps(meta, indent=2, sort_keys=True), "```", ""]
    index, report = out_dir / "index.html", out_dir / "REPORT.md"
    index.write_text("\n".join(h))
    report.write_text("\n".join(md))
    return [index, report]
