"""One Dask worker against N on the same job, side by side: ``python -m harness.parallel.cluster_bench``.

The jobs are the crosscheck (harness.suites.crosscheck.scoring.run_spread: every engine against the exact
reference, and spq against coal) and a fuzz campaign (harness.suites.fuzz.campaign.run), each run through
harness.parallel.cluster.TaskRunner as ``spq crosscheck`` and ``spq fuzz`` run them with ``--scheduler local``.
Both LocalClusters (1 worker and N) are started first and every worker warmed up (its engines built,
spq's compiled code loaded: minutes when the kernels changed and compile anew), so that the timed
runs hold the job alone; then each round times the job on 1 worker, then on N, and the best of the
rounds is kept, so that a busy spell of a shared machine falls on both. Printed per job and cluster:
the start-up and warm-up seconds, the job's best wall seconds, the CPU seconds its workers (and their
engines' child processes) spent, the cores that kept busy, the speed-up (1 worker's job seconds over
N's; "cold": start-up and warm-up included; "by CPU": 1 worker's CPU seconds over the busiest of the N
workers', what idle cores would give) and whether the results are identical (every table
exactly; the campaign's state, its timing aside). ``--serial`` adds the same job in this process,
the serial run of the suites, against which both are compared too.

The machine's load is printed before and after: N workers go N times faster only on N idle cores.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import dataclass, field

import pandas as pd

CROSSCHECK_PER_BUCKET = 150  # poses per bucket over all pairs: some 20 s of one worker on an idle core
CROSSCHECK_AGREEMENT = 100_000  # random poses of spq against coal
FUZZ_QUERIES = 400_000  # spq queries of the campaign: 50 cases of 2000 pose pairs x 2 modes
FUZZ_TASKS_PER_ROUND = 4  # fixed, so that 1 and N workers checkpoint the same rounds (identical states)


@dataclass
class Timing:
    where: str  # "1 Dask worker", "N Dask workers", "this process"
    workers: int
    start_s: float = float("nan")
    warm_s: float = float("nan")
    job_s: list = field(default_factory=list)  # wall seconds per round
    cpu_s: list = field(default_factory=list)  # per round: CPU seconds of each worker (and its children)
    result: object = None

    def best(self) -> int:
        return min(range(len(self.job_s)), key=self.job_s.__getitem__)


def worker_cpu_seconds() -> float:
    """CPU seconds (user + system) of this process and of its living child processes (the engines)."""
    import psutil

    me = psutil.Process()
    total = 0.0
    for proc in [me, *me.children(recursive=True)]:
        try:
            t = proc.cpu_times()
        except psutil.Error:  # ended meanwhile
            continue
        total += t.user + t.system
    return total


def _cpu(runner) -> list[float]:
    """CPU seconds so far of each worker, its engines' processes included."""
    if runner.scheduler is None:
        return [worker_cpu_seconds()]
    return list(runner.on_each_worker(worker_cpu_seconds).values())


# ------------------------------------------------------------------------------------------ the jobs


class CrosscheckJob:
    name = "crosscheck"

    def __init__(self, per_bucket: int, agreement: int, seed: int, engines: list | None):
        from datasets import DEFAULT_OBJECTS
        from harness.engines import available_engines
        from harness.suites.crosscheck import scoring as cc

        plain = available_engines(engines)
        self.engines = list(plain)
        for engine in plain.values():
            engine.close()
        self.config = cc.CrosscheckConfig(objects=DEFAULT_OBJECTS, per_bucket=per_bucket, seed=seed,
                                          engines=self.engines)
        self.agreement = agreement

    def size(self) -> str:
        return (f"{self.config.per_bucket} poses per bucket x 13 buckets over {len(self.config.objects)} pairs, "
                f"{len(self.engines)} engines ({', '.join(self.engines)}), {self.agreement} agreement poses")

    def warm(self, runner) -> float:
        from harness.suites.crosscheck.scoring import warm_worker

        args = (tuple(self.engines), (), self.agreement > 0)
        if runner.scheduler is None:
            return warm_worker(*args)
        return max(runner.on_each_worker(warm_worker, *args).values())

    def run(self, runner):
        from harness.suites.crosscheck.scoring import run_spread

        return run_spread(self.config, self.engines, {}, self.agreement, runner.workers, runner.scheduler,
                          progress=False, runner=runner)

    @staticmethod
    def same(a, b) -> bool:
        try:
            pd.testing.assert_frame_equal(a[0], b[0], check_exact=True)
            if a[1] is not None or b[1] is not None:
                pd.testing.assert_frame_equal(a[1], b[1], check_exact=True)
        except AssertionError:
            return False
        return True


class FuzzJob:
    name = "fuzz"

    def __init__(self, queries: int, seed: int, peers: list | None):
        from harness.suites.fuzz import campaign as cp

        self.config = cp.CampaignConfig(seed=seed, peers=peers)
        self.peers = cp.available_peers(peers)
        self.queries = queries

    def size(self) -> str:
        cases = -(-self.queries // (2 * self.config.poses))
        return (f"{self.queries} spq queries: {cases} cases of {self.config.poses} pose pairs over "
                f"{len(self.config.family_names())} families, {self.config.cases_per_task} cases a task, "
                f"peers {', '.join(self.peers) or 'none'}")

    def warm(self, runner) -> float:
        from dataclasses import asdict

        from harness.suites.fuzz.campaign import warm_worker

        args = (asdict(self.config), self.peers)
        if runner.scheduler is None:
            return warm_worker(*args)
        return max(runner.on_each_worker(warm_worker, *args).values())

    def run(self, runner):
        from harness.suites.fuzz import campaign as cp

        return cp.run(self.config, None, max_queries=self.queries, tasks_per_round=FUZZ_TASKS_PER_ROUND,
                      runner=runner)

    @staticmethod
    def same(a, b) -> bool:
        from dataclasses import asdict

        def content(state):
            return json.dumps({k: v for k, v in asdict(state).items() if k != "seconds"}, sort_keys=True)

        return content(a) == content(b)


# ----------------------------------------------------------------------------------- measuring


def measure(job, workers: int, repeats: int, serial: bool, say) -> list[Timing]:
    """[1 Dask worker, N Dask workers(, this process)] timings of ``job`` (module docstring)."""
    from contextlib import ExitStack

    from harness.parallel.cluster import LOCAL, TaskRunner

    timings = [Timing("1 Dask worker", 1), Timing(f"{workers} Dask workers", workers)]
    if serial:
        timings.append(Timing("this process", 1))
    with ExitStack() as stack:
        runners = []
        for t in timings:
            t0 = time.perf_counter()
            scheduler = None if t.where == "this process" else LOCAL
            runners.append(stack.enter_context(TaskRunner(t.workers, scheduler)))
            t.start_s = time.perf_counter() - t0
            t0 = time.perf_counter()
            job.warm(runners[-1])
            t.warm_s = time.perf_counter() - t0
            say(f"  {t.where}: started in {t.start_s:.1f} s, warmed up in {t.warm_s:.1f} s")
        for r in range(repeats):
            for t, runner in zip(timings, runners):
                c0, t0 = _cpu(runner), time.perf_counter()
                t.result = job.run(runner)
                t.job_s.append(time.perf_counter() - t0)
                t.cpu_s.append([c - b for c, b in zip(_cpu(runner), c0)])
            say(f"  round {r + 1}: " + ", ".join(f"{t.where} {t.job_s[-1]:.1f} s" for t in timings)
                + f"; load average {os.getloadavg()[0]:.2f}")
    return timings


def rows(job, timings: list[Timing]) -> pd.DataFrame:
    one = timings[0]
    out = []
    for t in timings:
        b, b1 = t.best(), one.best()
        job_s, cpu_s = t.job_s[b], sum(t.cpu_s[b])
        out.append({"job": job.name, "where": t.where, "workers": t.workers, "start_s": round(t.start_s, 1),
                    "warm_up_s": round(t.warm_s, 1), "job_s": round(job_s, 2), "job_cpu_s": round(cpu_s, 1),
                    "cores_busy": round(cpu_s / job_s, 2),
                    "speedup": round(one.job_s[b1] / job_s, 2),
                    "speedup_by_cpu": round(sum(one.cpu_s[b1]) / max(t.cpu_s[b]), 2),
                    "speedup_cold": round((one.start_s + one.warm_s + one.job_s[b1])
                                          / (t.start_s + t.warm_s + job_s), 2),
                    "identical": "yes" if job.same(one.result, t.result) else "NO"})
    return pd.DataFrame(out)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m harness.parallel.cluster_bench", description=__doc__.split("\n\n")[0])
    p.add_argument("--jobs", nargs="+", choices=["crosscheck", "fuzz"], default=["crosscheck", "fuzz"])
    p.add_argument("--workers", type=int, default=2, help="the bigger cluster's workers (default 2)")
    p.add_argument("--repeats", type=int, default=2, help="interleaved rounds, best kept (default 2)")
    p.add_argument("--per-bucket", type=int, default=CROSSCHECK_PER_BUCKET,
                   help=f"crosscheck: poses per bucket over all pairs (default {CROSSCHECK_PER_BUCKET})")
    p.add_argument("--agreement", type=int, default=CROSSCHECK_AGREEMENT,
                   help=f"crosscheck: random poses of spq against coal (default {CROSSCHECK_AGREEMENT})")
    p.add_argument("--engines", nargs="+", help="crosscheck engines (default: every one that imports)")
    p.add_argument("--queries", type=float, default=FUZZ_QUERIES,
                   help=f"fuzz: spq queries of the campaign (default {FUZZ_QUERIES:.0f})")
    p.add_argument("--peers", nargs="+", help="fuzz peers (default: coal, mujoco, bullet, those that import)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--serial", action="store_true", help="also run each job in this process (the serial run)")
    args = p.parse_args(argv)

    def say(text: str) -> None:
        print(text, flush=True)

    load = os.getloadavg()
    say(f"{os.cpu_count()} cores, load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} (1, 5, 15 min) before")
    tables = []
    for name in args.jobs:
        job = (CrosscheckJob(args.per_bucket, args.agreement, args.seed, args.engines) if name == "crosscheck"
               else FuzzJob(int(args.queries), args.seed, args.peers))
        say(f"{name}: {job.size()}")
        tables.append(rows(job, measure(job, args.workers, args.repeats, args.serial, say)))
    load = os.getloadavg()
    say(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} (1, 5, 15 min) after")
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        say("\n" + pd.concat(tables, ignore_index=True).to_string(index=False))
    say("\nspeedup: the 1-worker job's best wall seconds over this row's (warm workers); speedup_cold: with the "
        "cluster's start-up and warm-up counted; cores_busy: job CPU seconds (workers and their engine "
        "processes) over wall seconds; speedup_by_cpu: the 1-worker job's CPU seconds over the busiest worker's "
        "here, the speed-up on idle cores if a task costs the same CPU wherever it runs (a shared machine's "
        "load lowers speedup, much less this); identical: results equal to the 1-worker run's")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
