"""The gate (``spq check``): the crosscheck, stability and depth-oracle suites and a small fuzz campaign
at fixed seeds plus interleaved speed rounds, turned into metrics and judged against a baseline (rules in
harness/suites/check/gate.py)."""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

from harness.suites import Output, frame_lines
from harness.suites.check.gate import SPEED_FLOOR, CheckConfig


@dataclass
class Config:
    settings: CheckConfig = field(default_factory=CheckConfig)  # what is measured (recorded in the results)
    engines: list[str] | None = None  # registered names; None: every one that imports
    baseline: str | None = None  # results file of an earlier run to judge against
    speed: str = "strict"  # or "advisory": slower speed ratios are reported, never failed
    speed_floor: float = SPEED_FLOOR
    junit: str | None = None  # JUnit XML file to write
    history: str | None = None  # history file (JSON lines) to extend with this run
    update_baseline: str | None = None  # write this run's results there as the new baseline
    progress: bool = False


def measure(settings: CheckConfig, engines: dict, progress: bool = False) -> list:
    """The metrics of one run with the given {name: Engine} (built by the caller, not closed here):
    each section runs its suite and turns the suite's per-query table into metrics."""
    from harness.suites import crosscheck, depth, stability
    from harness.suites.check import gate as ck

    metrics: list = []
    names = list(engines)
    if "accuracy" in settings.sections:
        out = crosscheck.run(crosscheck.Config(objects=list(settings.objects), per_bucket=settings.per_bucket,
                                               seed=settings.seed, engines=names, agreement_poses=0,
                                               progress=progress))
        metrics += ck.accuracy_metrics(out.frame("crosscheck.csv.gz"))
    if "stability" in settings.sections:
        out = stability.run(stability.Config(seed=settings.seed, quick=True, engines=names, fcl_gap=False,
                                             coal_sweep=False))
        metrics += ck.stability_metrics(out.frame("stability"))
    if "oracle" in settings.sections and any(ck.is_spq(e) for e in engines.values()):
        out = depth.run(depth.Config(object=settings.speed_object, per_bucket=settings.oracle_per_bucket,
                                     stp_per_bucket=settings.oracle_per_bucket, seed=settings.seed,
                                     progress=progress))
        metrics += ck.oracle_metrics(out.frame("depth_oracle"))
    if "fuzz" in settings.sections and any(ck.is_spq(e) for e in engines.values()):
        metrics += ck.fuzz_section(settings, engines, progress)
    if "speed" in settings.sections:
        metrics += ck.speed_section(settings, engines, progress)
    return metrics


def run(config: Config) -> Output:
    """Measure, judge against the baseline (if any) and return the results file, the diff, the JUnit
    XML, the extended history and the verdict (exit_code 1 on a regression). ValueError: a usage or
    environment error (an engine that cannot be built, an unreadable baseline, the speed peer missing)."""
    from harness.engines import available_engines
    from harness.suites.check import gate as ck

    start = time.perf_counter()
    settings = config.settings
    try:
        engines = available_engines(config.engines)
    except ImportError as exc:
        raise ValueError(f"an engine asked for cannot be built: {exc}") from None
    out = Output()
    try:
        baseline = ck.load_results(config.baseline) if config.baseline else None
        if baseline is not None:
            before = baseline["meta"].get("config", {})
            differ = {k: (before.get(k), v) for k, v in asdict(settings).items()
                      if k != "sections" and before.get(k) != (list(v) if isinstance(v, tuple) else v)}
            if differ:
                out.lines += [f"note: the baseline ran with other settings {differ} (baseline, now); its figures "
                              "are not comparable one for one", ""]
        if "speed" in settings.sections and settings.peer not in engines:
            raise ValueError(f"the speed check times against {settings.peer!r}, which is not running "
                             f"(engines: {list(engines)}); add it or choose --peer")
        metrics = measure(settings, engines, config.progress)
    finally:
        for e in engines.values():
            e.close()
    seconds = time.perf_counter() - start
    doc = ck.results_document(metrics, settings, engines, seconds, config.speed_floor)
    out.meta = doc["meta"]
    out.documents["check.json"] = ck.results_text(doc)
    diff = None
    if baseline is None:
        out.obsolete.append("check_diff.csv")  # a diff of an earlier run must not linger
    else:
        diff = ck.compare(metrics, ck.metrics_of(baseline), set(engines), config.speed, config.speed_floor,
                          settings.sections)
        out.raw["check_diff.csv"] = diff
        shown = diff[~diff.verdict.isin([ck.OK, ck.INFO])]
        if len(shown):
            out.lines += ["Changes against the baseline (metric, baseline, now, verdict):",
                          *frame_lines(shown[["engine", "check", "metric", "baseline", "now", "verdict", "rule"]]), ""]
    # files named by the caller, wherever they are (absolute paths: write_output joins them unchanged)
    if config.junit:
        out.documents[str(Path(config.junit).resolve())] = ck.junit_xml(metrics, diff, seconds)
    if config.history:
        history = Path(config.history).resolve()
        earlier = history.read_text() if history.exists() else ""
        out.documents[str(history)] = earlier + ck.history_line(doc)
    if config.update_baseline:
        out.documents[str(Path(config.update_baseline).resolve())] = out.documents["check.json"]
    out.exit_code = ck.exit_code(diff)
    verdict = "no baseline given" if diff is None else ("REGRESSION" if out.exit_code else "pass")
    out.lines += [*ck.summary_lines(metrics, diff),
                  f"spq check: {verdict} ({len(metrics)} metrics, {len(engines)} engines, {seconds:.0f} s)"]
    return out

