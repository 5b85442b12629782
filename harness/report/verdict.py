"""The report's one-screen verdict, read from the CSV files the suites wrote.

Per engine: accuracy against the exact reference (largest distance error, wrong verdicts, failures,
largest penetration-depth error) and speed (queries per second as a ratio to coal's, per call, on
the same link and poses); then the paper's Table I. Every figure comes from a file beside the page
(crosscheck_engines.csv, crosscheck_depth.csv, stability_summary.csv, bench_pch.csv, table1.csv,
depth_oracle_summary.csv); a suite that did not run leaves its columns out. Column headers link
down to the sections the figures come from.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from harness.report.html import Lead

# section titles the verdict links to (harness.report.assemble's)
CROSSCHECK = "Cross-check against the exact reference"
STABILITY = "Stability where methods fail"
BENCH = "Throughput, PCH-PCH (every engine)"
TABLE1 = "Table I: PCH, STP and CSE on one link"
DEPTH = "Penetration depth against an independent oracle"


def _read(out: Path, name: str) -> pd.DataFrame | None:
    path = out / name
    return pd.read_csv(path) if path.exists() else None


def _sci(v) -> str:
    return "–" if pd.isna(v) else f"{v:.2g}"


def engine_table(out: Path) -> tuple[pd.DataFrame, dict]:
    """(table, {column: section title}) with one row per engine."""
    cross = _read(out, "crosscheck_engines.csv")
    depth = _read(out, "crosscheck_depth.csv")
    stab = _read(out, "stability_summary.csv")
    bench = _read(out, "bench_pch.csv")
    engines = list(dict.fromkeys([*(cross.engine if cross is not None else []),
                                  *(stab.engine if stab is not None else []),
                                  *(bench.engine if bench is not None else [])]))
    rows, links = [], {}
    for e in engines:
        row = {"engine": e}
        if cross is not None:
            c = cross[cross.engine == e]
            if len(c):
                c = c.iloc[0]
                row["max error (m)"] = _sci(c.max_abs_error)
                row["wrong"] = int(c.false_overlaps + c.missed_overlaps)
                row["failed"] = int(c.failures)
            links.update({"max error (m)": CROSSCHECK, "wrong": CROSSCHECK,
                          "failed": CROSSCHECK})
        if depth is not None:
            d = depth[depth.engine == e]
            scored = d[d.depth == "yes"]
            row["depth error (m)"] = _sci(scored.max_abs_depth_error.max()) if len(scored) else "no depth"
            row["sign errors"] = int(scored.sign_errors.sum()) if len(scored) else "–"
            links.update({"depth error (m)": CROSSCHECK, "sign errors": CROSSCHECK})
        if stab is not None:
            s = stab[stab.engine == e]
            if len(s):
                s = s.iloc[0]
                row["stability wrong/failed"] = f"{int(s.wrong)}/{int(s.failed)} of {int(s.n)}"
            links["stability wrong/failed"] = STABILITY
        if bench is not None:
            b = bench[(bench.engine == e) & (bench.pair == "PCH-PCH") & (bench.poses.astype(str) == "all")]
            per_call = b[b["mode"] == "per-call"]
            batched = b[b["mode"] == "batched"]
            row["speed vs coal"] = f"{per_call.ratio_to_coal_pch.iloc[0]:.2f}x" if len(per_call) else "–"
            row["batched"] = f"{batched.ratio_to_coal_pch.iloc[0]:.2f}x" if len(batched) else "–"
            links.update({"speed vs coal": BENCH, "batched": BENCH})
        rows.append(row)
    return pd.DataFrame(rows), links


def fastest_peer_per_call(bench: pd.DataFrame | None) -> tuple[str, float] | None:
    """(name, spq's per-call rate over it) of the peer with the most PCH-PCH queries per second per
    call on all poses (bench_pch.csv), or None without spq's row or a peer's."""
    if bench is None:
        return None
    b = bench[(bench.pair == "PCH-PCH") & (bench.poses.astype(str) == "all") & (bench["mode"] == "per-call")]
    ours, peers = b[b.engine == "spq"], b[b.engine != "spq"]
    if not len(ours) or not len(peers):
        return None
    best = peers.loc[peers.queries_per_s.idxmax()]
    return str(best.engine), float(ours.queries_per_s.iloc[0] / best.queries_per_s)


def table1_table(out: Path) -> pd.DataFrame | None:
    t = _read(out, "table1.csv")
    if t is None:
        return None
    return pd.DataFrame({
        "pair": t.row + "–" + t.column,
        "queries/s": [f"{v / 1e3:,.0f}k" for v in t.queries_per_s],
        "time vs PCH": [f"{v:.2f}" for v in t.time_vs_pch],
        "paper": [f"{v:.2f}" for v in t.paper_time_vs_pch],
        "failed": t.failed.astype(int),
    })


def verdict(out: Path) -> Lead | None:
    """The verdict from the CSVs in ``out``, or None if no suite it reads has run."""
    engines, links = engine_table(out)
    table1 = table1_table(out)
    if engines.empty and table1 is None:
        return None
    tables = []
    paragraphs = []
    if not engines.empty:
        tables.append(("Against the exact reference on the same poses: largest distance error, wrong overlap "
                       "verdicts, failed queries, largest depth error, sign errors; stability verdicts; queries per "
                       "second over coal's (per call; batched: spq's compiled loop).", engines, links))
        spq_row = engines[engines.engine == "spq"]
        if len(spq_row):
            r = spq_row.iloc[0]
            facts = [f"largest distance error {r.get('max error (m)', '–')} m",
                     f"{r.get('wrong', '–')} wrong overlap verdicts, {r.get('failed', '–')} failed queries",
                     f"largest depth error {r.get('depth error (m)', '–')} m"]
            oracle = _read(out, "depth_oracle_summary.csv")
            if oracle is not None:
                facts.append(f"STP-BV and superellipsoid depths within {oracle.max_abs_error_m.max():.2g} m of an "
                             "independent oracle")
            if "speed vs coal" in r:
                fastest = fastest_peer_per_call(_read(out, "bench_pch.csv"))
                versus = f" ({fastest[1]:.2f}x {fastest[0]}'s, the fastest peer per call)" if fastest else ""
                facts.append(f"{r['speed vs coal']} coal's speed per call{versus}, {r['batched']} batched")
            paragraphs.append("spq: " + "; ".join(facts) + ".")
    if table1 is not None:
        tables.append(("Table I (paper): queries per second between a link's PCH, STP-BV and CSE covers; time "
                       "relative to PCH-PCH, here and in the paper", table1, {c: TABLE1 for c in table1.columns[1:]}))
    return Lead("Verdict", paragraphs, tables)
