"""``spq check``: the harness as a gate. A fixed-seed run of every engine, judged against a baseline.

This module holds the metrics, rules, files and verdicts; harness/suites/check/__init__.py runs the check
by composing the crosscheck, stability and depth suites and the speed rounds below.

A check run measures, with every engine it is given and at fixed seeds:

- accuracy (PCH-PCH, every engine): per distance bucket, the largest error against the exact
  reference (:mod:`harness.references.minkowski`), wrong statuses and failures; on the touching and overlap
  buckets, for engines that give a depth, the largest depth error and sign errors; for engines that
  give certified bounds (spq), the poses whose bounds miss the reference;
- the other bounding volumes (spq): STP-BV and superellipsoid pairs against the independent depth
  oracle (:mod:`harness.references.depth_oracle`): largest error, failures, certified bounds missing it;
- stability (every engine): wrong and failed verdicts on the stability and penetration families
  (:mod:`harness.suites.stability.hard_cases`, one pose per case);
- fuzz (spq, and coal, mujoco and bullet where they run): a small fuzz campaign (:mod:`harness.suites.fuzz`),
  ``fuzz_cases`` cases of every family of :mod:`harness.suites.fuzz.families` at ``fuzz_poses`` pose pairs
  each, spq queried unsigned and signed: per family and mode, spq's wrong, failed and disputed
  queries, and the peers' wrong, failed and disputed ones as the campaign judges them;
- speed: each engine's queries per second divided by the peer's (coal by default), timed in
  interleaved rounds on the same poses, so that a slow spell of a shared machine falls on all alike.
  Ratios only, never absolute times.

Each result is a metric: (engine, check, metric, value, kind, tolerance, noise). Compared with a
baseline run's metric of the same key (:func:`compare`):

- kind "count" (wrong, failed, sign errors, bounds missing the reference): more than the baseline
  is a regression;
- kind "zero" (spq's wrong answers in the fuzz campaign): more than 0 is a regression, whatever the
  baseline says (a baseline cannot accept a wrong answer);
- kind "advisory" (the peers' counts in the fuzz campaign): more than the baseline is reported
  ("more (advisory)"), never failed;
- kind "error" (largest errors, m): above max(2 x baseline, the engine's own tolerance) is a
  regression, and so is a value that is no longer finite;
- kind "ratio" (speed): a regression when below baseline x (1 - threshold), where the threshold is
  noise-aware: max(``speed_floor``, ``NOISE_FACTOR`` x the relative spread of the per-round ratios
  of both runs), capped at ``SPEED_CAP`` (so a 3x slowdown is always caught). The spread is the
  median absolute deviation of a job's per-round ratios over their median. With speed "advisory"
  a slower ratio is reported, never failed;
- kind "info": recorded, never judged.

Exit codes (:func:`exit_code`): 0 no regression, 1 a regression, 2 a usage or environment error
(an engine asked for that cannot be built, an unreadable baseline).
"""

from __future__ import annotations

import json
import math
import platform
import time
import xml.etree.ElementTree as ET
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

SECTIONS = ("accuracy", "oracle", "stability", "fuzz", "speed")
FORMAT = "spq-check/1"
NOISE_FACTOR = 4.0
SPEED_FLOOR = 0.3  # default least threshold: a ratio more than 30% below its baseline
SPEED_CAP = 0.6  # the threshold never exceeds this: a 3x slowdown (-67%) is always a regression
REGRESSION, OK, BETTER, NEW, MISSING, ADVISORY, INFO = ("regression", "ok", "better", "new", "missing",
                                                        "slower (advisory)", "info")
MORE = "more (advisory)"  # a peer's fuzz count above its baseline: reported, never failed
JUDGED_WHEN_MISSING = ("count", "zero", "error", "ratio")  # kinds whose metric may not silently disappear


@dataclass
class CheckConfig:
    seed: int = 0
    objects: list[str] = field(default_factory=lambda: ["kuka_link_4", "panda_link_2"])
    per_bucket: int = 200  # PCH-PCH poses per distance bucket, over the object pairs
    oracle_per_bucket: int = 4  # poses per overlap bucket and BV pair against the depth oracle
    speed_object: str = "kuka_link_4"
    speed_poses: int = 2000
    speed_rounds: int = 11
    peer: str = "coal"
    fuzz_families: list | None = None  # None: every family of harness.suites.fuzz.families
    fuzz_cases: int = 4  # fuzz cases per family: the campaign's cases 0 .. fuzz_cases x families - 1
    fuzz_poses: int = 500  # pose pairs per fuzz case, each queried unsigned and signed
    fuzz_sample: float = 2e-4  # share of spq's fuzz queries referenced whatever the cheap checks say
    fuzz_plant: str | None = None  # a planted bug (harness.suites.fuzz.plant) judged instead of spq: the tests' mutant
    sections: tuple = SECTIONS


@dataclass
class Metric:
    engine: str
    check: str  # section/group, e.g. "accuracy/close-1e-3": one JUnit test case per engine and check
    metric: str
    value: float
    kind: str  # "count", "zero", "advisory", "error", "ratio" or "info"
    tolerance: float | None = None  # the engine's own tolerance (kind "error")
    noise: float | None = None  # relative spread of the repeats (kind "ratio")

    @property
    def key(self) -> tuple[str, str, str]:
        return self.engine, self.check, self.metric


# ------------------------------------------------------------------------------------------
# measuring
# ------------------------------------------------------------------------------------------
def _tol(engine: str, depth: bool = False) -> tuple[float, float]:
    from harness.suites.stability.hard_cases import ENGINE_DEPTH_TOL, tolerance_of

    return ENGINE_DEPTH_TOL.get(engine, tolerance_of(engine)) if depth else tolerance_of(engine)


def _finite_max(x) -> float:
    x = np.asarray(x, dtype=np.float64)
    if len(x) == 0:
        return 0.0
    return float(np.max(x)) if np.isfinite(x).all() else math.inf


def accuracy_metrics(table: pd.DataFrame) -> list[Metric]:
    """Metrics from a crosscheck table (harness.suites.crosscheck.scoring.score's rows)."""
    out = []
    for (engine, bucket), g in table.groupby(["engine", "bucket"], sort=False):
        check = f"accuracy/{bucket}"
        ta, tr = _tol(engine)
        sep = g.ref_signed > 0
        err = np.where(g.status == "failed", 0.0, g.abs_error)  # failures are counted apart
        out.append(Metric(engine, check, "max_abs_error", _finite_max(err), "error",
                          ta + tr * float(g.ref_distance.max())))
        out.append(Metric(engine, check, "wrong_status", int(g.verdict.isin(["false_overlap", "missed_overlap"]).sum()),
                          "count"))
        out.append(Metric(engine, check, "failed", int((g.verdict == "failed").sum()), "count"))
        if sep.any():
            out.append(Metric(engine, check, "max_witness_gap_error",
                              _finite_max(np.nan_to_num(g.witness_gap_error[sep], nan=0.0)), "error",
                              ta + tr * float(g.ref_distance.max())))
        if bool(g.gives_depth.iloc[0]) and (g.target <= 0).all():
            da, dr = _tol(engine, depth=True)
            derr = np.where(g.status == "failed", 0.0, g.depth_abs_error)
            out.append(Metric(engine, check, "max_depth_error", _finite_max(derr), "error",
                              da + dr * float(np.abs(g.ref_signed).max())))
            out.append(Metric(engine, check, "sign_errors", int(g.depth_sign_error.sum()), "count"))
            holds = g.certificate_holds.dropna()
            if len(holds):
                out.append(Metric(engine, check, "bounds_miss_reference", int((holds == 0).sum()), "count"))
    return out


def oracle_metrics(table: pd.DataFrame) -> list[Metric]:
    """Metrics from a depth-oracle table (harness.references.depth_oracle.compare's rows), engine 'spq'."""
    out = []
    for (pair, bucket), g in table.groupby(["pair", "bucket"], sort=False):
        check = f"oracle/{pair}/{bucket}"
        failed = g.spq_status == "failed"
        out.append(Metric("spq", check, "max_abs_error", _finite_max(np.where(failed, 0.0, g.abs_error_m)), "error",
                          1e-9))
        out.append(Metric("spq", check, "failed", int(failed.sum()), "count"))
        out.append(Metric("spq", check, "bounds_miss_oracle", int((~g.contains & ~failed).sum()), "count"))
    return out


def stability_metrics(table: pd.DataFrame) -> list[Metric]:
    """Metrics from a stability table (harness.suites.stability.hard_cases.run_cases' rows)."""
    out = []
    for (engine, family), g in table.groupby(["engine", "family"], sort=False):
        check = f"stability/{family}"
        out.append(Metric(engine, check, "wrong", int((g.verdict == "wrong").sum()), "count"))
        out.append(Metric(engine, check, "failed", int((g.verdict == "failed").sum()), "count"))
        if (g.depth_verdict != "").any():
            out.append(Metric(engine, check, "depth_wrong", int((g.depth_verdict == "wrong").sum()), "count"))
            out.append(Metric(engine, check, "depth_failed", int((g.depth_verdict == "failed").sum()), "count"))
    return out


def fuzz_metrics(table: pd.DataFrame) -> list[Metric]:
    """Metrics from a fuzz campaign's table (harness.suites.fuzz.campaign.table's rows): per engine, family and
    mode, spq's wrong answers (none allowed), failures (no more than the baseline's) and disputed
    queries (recorded); the peers' wrong, failed (advisory) and disputed (recorded)."""
    out = []
    for r in table.itertuples():
        check = f"fuzz/{r.family}/{r.mode}"
        spq_ = r.engine == "spq"
        out.append(Metric(r.engine, check, "wrong", int(r.wrong), "zero" if spq_ else "advisory"))
        out.append(Metric(r.engine, check, "failed", int(r.failed), "count" if spq_ else "advisory"))
        out.append(Metric(r.engine, check, "disputed", int(r.disputed), "info"))
    return out


def fuzz_campaign(config: CheckConfig, engines: dict, progress: bool = False):
    """The check's fuzz campaign, on this process: cases 0 .. fuzz_cases x families - 1 of the campaign
    at config.seed (those ``spq fuzz --seed S --poses P --queries 2 x P x cases`` runs first), judged by
    harness.suites.fuzz.campaign.run_task with the peers among ``engines``. Returns the campaign's State."""
    from dataclasses import asdict

    from tqdm import tqdm

    from harness.suites.fuzz import campaign as cp

    peers = [p for p in cp.DEFAULT_PEERS if p in engines]
    cc = cp.CampaignConfig(seed=config.seed, families=config.fuzz_families, poses=config.fuzz_poses,
                           sample=config.fuzz_sample, peers=peers, plant=config.fuzz_plant)
    families = cc.family_names()
    state = cp.State(config=asdict(cc))
    with tqdm(total=config.fuzz_cases, desc="check fuzz", unit="round", disable=not progress) as bar:
        for k in range(config.fuzz_cases):  # one task per round of the families
            cases = list(range(k * len(families), (k + 1) * len(families)))
            state.merge(cp.run_task({"config": state.config, "peers": peers, "cases": cases}))
            state.next_case, state.rounds = cases[-1] + 1, state.rounds + 1
            bar.update(1)
    return state


def fuzz_section(config: CheckConfig, engines: dict, progress: bool = False) -> list[Metric]:
    """Fuzz metrics (:func:`fuzz_metrics`) of the check's campaign (:func:`fuzz_campaign`)."""
    from harness.suites.fuzz.campaign import table

    return fuzz_metrics(table(fuzz_campaign(config, engines, progress)))


def speed_jobs(engines: dict, shapes: dict, poses_a: np.ndarray, poses_b: np.ndarray) -> tuple[dict, list]:
    """({(engine, mode): zero-argument call}, prepared pairs to close): every engine's per-call loop
    on PCH-PCH; spq also batched, batched signed, and batched on its other BV pairs."""
    import spq
    from harness.engines.spq_engine import SpqEngine

    pch = shapes["PCH"]
    jobs, prepared = {}, []
    for name, engine in engines.items():
        pair = engine.prepare(pch, pch)
        prepared.append(pair)
        jobs[(name, "PCH-PCH per-call")] = lambda pair=pair: pair.distance_loop(poses_a, poses_b)
        if isinstance(engine, SpqEngine):
            for bv in ("PCH-PCH", "STP-PCH", "STP-STP", "CSE-CSE", "CSE-PCH"):
                a, b = (shapes[k] for k in bv.split("-"))
                p = spq.Pair(a, b)
                jobs[(name, f"{bv} batched")] = lambda p=p: p.distances(poses_a, poses_b, coherent=False)
            ps = spq.Pair(pch, pch, signed=True)
            jobs[(name, "PCH-PCH batched signed")] = lambda: ps.distances(poses_a, poses_b, coherent=False)
    return jobs, prepared


def time_rounds(jobs: dict, rounds: int, progress=None) -> dict:
    """{key: (rounds,) seconds}: every job once per round, in turn, after one untimed warm-up call."""
    for fn in jobs.values():
        fn()
    times = {key: np.empty(rounds) for key in jobs}
    for r in range(rounds):
        for key, fn in jobs.items():
            t0 = time.perf_counter()
            fn()
            times[key][r] = time.perf_counter() - t0
            if progress is not None:
                progress.update(1)
    return times


def speed_metrics(times: dict, peer_key, queries: int) -> list[Metric]:
    """Each job's rate over the peer's, per round; value = the median ratio, noise = its relative MAD."""
    out = []
    peer = times[peer_key]
    for (engine, mode), t in times.items():
        if (engine, mode) == peer_key:
            out.append(Metric(engine, "speed", f"{mode} queries_per_s", float(queries / np.median(t)), "info"))
            continue
        ratios = peer / t
        med = float(np.median(ratios))
        mad = float(np.median(np.abs(ratios - med))) / med if med > 0 else math.inf
        out.append(Metric(engine, "speed", f"{mode} ratio_to_{peer_key[0]}", med, "ratio", noise=mad))
    return out


def is_spq(engine) -> bool:
    from harness.engines.spq_engine import SpqEngine

    return isinstance(engine, SpqEngine)


def speed_section(config: CheckConfig, engines: dict, progress: bool = False) -> list[Metric]:
    """Speed ratios to the peer: every engine's PCH, STP and CSE jobs timed in interleaved rounds."""
    from tqdm import tqdm

    import spq
    from datasets import load_object
    from harness.workloads.poses import random_poses

    pch = load_object(config.speed_object)
    fit = spq.Superellipsoid.fit(pch.vertices)
    shapes = {"PCH": pch, "STP": spq.STPBV.from_points(pch.vertices, 0.005, 2.0), "CSE": fit.shape}
    poses_a, poses_b = random_poses(config.speed_poses, config.seed)
    # the peer first, then every other engine, each round
    ordered = {config.peer: engines[config.peer], **{k: v for k, v in engines.items() if k != config.peer}}
    jobs, prepared = speed_jobs(ordered, shapes, poses_a, poses_b)
    try:
        with tqdm(total=len(jobs) * config.speed_rounds, desc="check speed", unit="run", disable=not progress) as bar:
            times = time_rounds(jobs, config.speed_rounds, bar)
    finally:
        for p in prepared:
            p.close()
    return speed_metrics(times, (config.peer, "PCH-PCH per-call"), config.speed_poses)


# ------------------------------------------------------------------------------------------
# results files, baselines, verdicts
# ------------------------------------------------------------------------------------------
def results_document(metrics: list[Metric], config: CheckConfig, engines: dict, seconds: float,
                     speed_floor: float = SPEED_FLOOR) -> dict:
    """The tidy results file: format, run metadata (versions, seeds, machine, tolerances), metrics."""
    from harness.report.meta import run_metadata
    from harness.suites.stability.hard_cases import ENGINE_DEPTH_TOL, ENGINE_TOL

    meta = run_metadata(command="spq check", seed=config.seed, seconds=round(seconds, 1), config=asdict(config),
                        engines={name: _version(e) for name, e in engines.items()},
                        engine_tolerances={k: list(v) for k, v in ENGINE_TOL.items()},
                        engine_depth_tolerances={k: list(v) for k, v in ENGINE_DEPTH_TOL.items()},
                        speed_rule={"noise_factor": NOISE_FACTOR, "floor": speed_floor, "cap": SPEED_CAP},
                        commit=_commit())
    return {"format": FORMAT, "meta": meta, "metrics": [asdict(m) for m in metrics]}


def _version(engine) -> str:
    try:
        return engine.version()
    except Exception as exc:  # a plugin's version() must not end the run
        return f"unknown ({type(exc).__name__})"


def _commit() -> str:
    import subprocess

    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, timeout=10,
                             cwd=Path(__file__).resolve().parent)
        return out.stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def load_results(path) -> dict:
    """A results file written by :func:`save_results`; ValueError if it is not one."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"cannot read check results {str(path)!r}: {exc}") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT or not isinstance(doc.get("metrics"), list):
        raise ValueError(f"{str(path)!r} is not a spq check results file (format {FORMAT!r})")
    return doc


def results_text(doc: dict) -> str:
    """The results file's text (JSON)."""
    return json.dumps(doc, indent=1, default=_json_default) + "\n"


def save_results(doc: dict, path) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(results_text(doc))


def _json_default(x):
    if isinstance(x, (np.integer, np.floating)):
        return x.item()
    return str(x)


def metrics_of(doc: dict) -> list[Metric]:
    return [Metric(**m) for m in doc["metrics"]]


def speed_threshold(now: Metric, base: Metric, floor: float = SPEED_FLOOR) -> float:
    """The relative drop a speed ratio may show before it counts as slower: NOISE_FACTOR times the
    larger relative spread of the two runs' rounds, at least ``floor``, at most SPEED_CAP."""
    noise = max(now.noise or 0.0, base.noise or 0.0)
    return min(SPEED_CAP, max(floor, NOISE_FACTOR * noise))


def judge(now: Metric, base: Metric | None, speed: str = "strict", floor: float = SPEED_FLOOR) -> tuple[str, str]:
    """(verdict, rule) of one metric against its baseline."""
    if now.kind == "zero" and now.value > 0:
        return REGRESSION, "must be 0, whatever the baseline"
    if base is None:
        return NEW, "not in the baseline"
    if now.kind == "info":
        return INFO, ""
    v, b = now.value, base.value
    if now.kind == "count":
        if v > b:
            return REGRESSION, f"count above the baseline's {b:g}"
        return (BETTER if v < b else OK), f"count <= {b:g}"
    if now.kind == "zero":
        return (BETTER if b > 0 else OK), "0"
    if now.kind == "advisory":
        if v > b:
            return MORE, f"count above the baseline's {b:g} (advisory)"
        return (BETTER if v < b else OK), f"count <= {b:g}"
    if now.kind == "error":
        allowed = max(2.0 * b, now.tolerance or 0.0) if math.isfinite(b) else math.inf
        if not math.isfinite(v) and math.isfinite(b):
            return REGRESSION, "no longer finite"
        if v > allowed:
            return REGRESSION, f"above max(2 x baseline, tolerance) = {allowed:.3g}"
        return (BETTER if v < 0.5 * b else OK), f"<= {allowed:.3g}"
    if now.kind == "ratio":
        th = speed_threshold(now, base, floor)
        limit = b * (1.0 - th)
        if v < limit:
            return (ADVISORY if speed == "advisory" else REGRESSION), f"below baseline x (1 - {th:.2f}) = {limit:.3g}"
        return (BETTER if v > b * (1.0 + th) else OK), f">= {limit:.3g} (threshold {th:.2f})"
    return INFO, f"unknown kind {now.kind!r}"


def compare(now: list[Metric], base: list[Metric], ran: set[str], speed: str = "strict",
            floor: float = SPEED_FLOOR, sections=SECTIONS) -> pd.DataFrame:
    """The diff table: one row per metric key in either run (engine, check, metric, baseline, now,
    verdict, rule). A baseline metric missing now is a regression if its engine and its section
    ran (a check that silently disappeared) and it is judged (JUDGED_WHEN_MISSING), else 'missing'."""
    bmap = {m.key: m for m in base}
    rows = []
    for m in now:
        verdict, rule = judge(m, bmap.get(m.key), speed, floor)
        b = bmap.get(m.key)
        rows.append((m.engine, m.check, m.metric, m.kind, b.value if b else math.nan, m.value, verdict, rule))
    seen = {m.key for m in now}
    for b in base:
        if b.key not in seen:
            asked = b.engine in ran and b.check.split("/")[0] in sections
            verdict = REGRESSION if asked and b.kind in JUDGED_WHEN_MISSING else MISSING
            rows.append((b.engine, b.check, b.metric, b.kind, b.value, math.nan, verdict,
                         "in the baseline, not measured now"))
    return pd.DataFrame(rows, columns=["engine", "check", "metric", "kind", "baseline", "now", "verdict", "rule"])


def exit_code(diff: pd.DataFrame | None) -> int:
    """0: no regression (or no baseline), 1: a regression."""
    return int(diff is not None and (diff.verdict == REGRESSION).any())


def junit_xml(metrics: list[Metric], diff: pd.DataFrame | None, seconds: float) -> str:
    """JUnit XML: one test suite, one test case per engine and check (classname = engine), failed
    when one of its metrics regressed; its metrics (with baseline and verdict) in system-out."""
    if diff is None:
        diff = pd.DataFrame([(m.engine, m.check, m.metric, m.kind, math.nan, m.value, "no baseline", "")
                             for m in metrics],
                            columns=["engine", "check", "metric", "kind", "baseline", "now", "verdict", "rule"])
    groups = list(diff.groupby(["engine", "check"], sort=False))
    failures = sum(int((g.verdict == REGRESSION).any()) for _, g in groups)
    suite = ET.Element("testsuite", name="spq check", tests=str(len(groups)), failures=str(failures), errors="0",
                       skipped="0", time=f"{seconds:.3f}")
    for (engine, check), g in groups:
        case = ET.SubElement(suite, "testcase", classname=str(engine), name=str(check), time="0")
        bad = g[g.verdict == REGRESSION]
        if len(bad):
            lines = [f"{r.metric}: {r.now:.6g} (baseline {r.baseline:.6g}) {r.rule}" for r in bad.itertuples()]
            fail = ET.SubElement(case, "failure", message="; ".join(lines), type="regression")
            fail.text = "\n".join(lines)
        out = ET.SubElement(case, "system-out")
        out.text = "\n".join(f"{r.metric} = {r.now:.6g} (baseline {r.baseline:.6g}): {r.verdict}"
                             for r in g.itertuples())
    root = ET.Element("testsuites", name="spq check", tests=str(len(groups)), failures=str(failures))
    root.append(suite)
    ET.indent(root)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"


def history_line(doc: dict) -> str:
    """One line (JSON) of a history file: the run's commit, date, machine and metrics."""
    meta = doc["meta"]
    entry = {"commit": meta.get("commit", "unknown"), "date": meta.get("date"), "machine": meta.get("machine"),
             "host": platform.node(), "metrics": doc["metrics"]}
    return json.dumps(entry, default=_json_default) + "\n"


def append_history(doc: dict, path) -> None:
    """Append the run to the history file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("a") as f:
        f.write(history_line(doc))


def load_history(path) -> pd.DataFrame:
    """The history file as a tidy table: one row per run and metric (run = line number)."""
    path = Path(path)
    try:
        lines = [ln for ln in path.read_text().splitlines() if ln.strip()]
    except OSError as exc:
        raise ValueError(f"cannot read history {str(path)!r}: {exc}") from None
    rows = []
    for run, line in enumerate(lines):
        try:
            entry = json.loads(line)
        except json.JSONDecodeError as exc:
            raise ValueError(f"history {str(path)!r}, line {run + 1}: not JSON ({exc})") from None
        for m in entry.get("metrics", []):
            rows.append({"run": run, "commit": entry.get("commit"), "date": entry.get("date"), **m})
    return pd.DataFrame(rows)


def summary_lines(metrics: list[Metric], diff: pd.DataFrame | None) -> list[str]:
    """A few lines for the terminal: per engine, accuracy and speed at a glance, then the verdict."""
    lines = []
    df = pd.DataFrame([asdict(m) for m in metrics])
    for engine, g in df.groupby("engine", sort=False):
        counts = g[g.kind.isin(["count", "zero"])]
        errs = g[(g.kind == "error") & g.check.str.startswith("accuracy")]
        ratio = g[(g.kind == "ratio") & g.metric.str.startswith("PCH-PCH per-call")]
        parts = [f"{engine:14s}", f"checks {g.check.nunique():3d}",
                 f"wrong/failed {int(counts.value.sum()):5d}"]
        if len(errs):
            parts.append(f"max PCH error {errs.value.max():.2g} m")
        if len(ratio):
            parts.append(f"speed {ratio.value.iloc[0]:.2f}x peer")
        advisory = g[g.kind == "advisory"]
        if len(advisory):
            parts.append(f"fuzz wrong/failed {int(advisory.value.sum())} (advisory)")
        lines.append("  ".join(parts))
    if diff is not None:
        n = diff.verdict.value_counts()
        lines.append("against the baseline: " + ", ".join(f"{k} {v}" for k, v in n.items()))
    return lines


def history_chart(table: pd.DataFrame, path) -> Path:
    """Two panels over the runs of a history (x: run, labelled by commit): per engine, the largest
    PCH-PCH error of the accuracy checks (log scale) and the wrong/failed count; and every speed
    ratio to the peer. Returns the path written (PNG)."""
    from harness.report.charts import pyplot, save_figure

    plt = pyplot()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    runs = sorted(table.run.unique())
    labels = [str(table[table.run == r].commit.iloc[0]) for r in runs]
    fig, (ax1, ax2, ax3) = plt.subplots(1, 3, figsize=(15, 4.2))
    acc = table[(table.kind == "error") & table.check.str.startswith("accuracy")]
    for engine, g in acc.groupby("engine", sort=False):
        y = g.groupby("run").value.max().reindex(runs)
        ax1.semilogy(runs, np.maximum(y.to_numpy(dtype=float), 1e-18), marker="o", label=engine)
    ax1.set_title("largest PCH-PCH error (m)")
    counts = table[table.kind.isin(["count", "zero"])]
    for engine, g in counts.groupby("engine", sort=False):
        y = g.groupby("run").value.sum().reindex(runs)
        ax2.plot(runs, y.to_numpy(dtype=float), marker="o", label=engine)
    ax2.set_yscale("symlog", linthresh=1.0)  # a few cases of one engine beside hundreds of another's
    ax2.set_title("wrong + failed + missed bounds (count)")
    speed = table[table.kind == "ratio"]
    for (engine, metric), g in speed.groupby(["engine", "metric"], sort=False):
        y = g.set_index("run").value.reindex(runs)
        ax3.plot(runs, y.to_numpy(dtype=float), marker="o", label=f"{engine} {metric.split(' ratio_')[0]}")
    ax3.set_title("speed ratio to the peer")
    for ax in (ax1, ax2, ax3):
        ax.set_xticks(runs, labels, rotation=45, ha="right", fontsize=7)
        ax.set_xlabel("run (commit)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6)
    save_figure(fig, path, "spq check history")
    return path
