"""A fuzz campaign: cases drawn round-robin from the families, judged in tasks on this process, local
processes or a Dask cluster (harness.parallel.cluster), the counts checkpointed after every round.

Case k (k = 0, 1, 2, ...) is family ``families[k % len(families)]`` drawn with
``np.random.default_rng([seed, k])``, so a campaign is a pure function of its seed and families, and a
resumed campaign (the state file names the next case) continues exactly where the last one stopped.
Rounds of ``tasks_per_round`` tasks of ``cases_per_task`` cases run until the time budget or the query
count is reached; the state (counts per family, engine and mode; the wrong and failed spq cases found,
up to ``keep_bad`` per round) is written after each round, atomically. The workers are started once
per campaign and keep their peers (engines in child processes) and spq's loaded kernels from round to
round, and the rounds overlap (a worker free at a round's end takes the next round's first task), so
that no worker waits for a round's slowest task.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

COUNT_KEYS = ("queries", "wrong", "failed", "referenced", "disputed")
DEFAULT_PEERS = ("coal", "mujoco", "bullet")  # python-fcl hangs on some poses (see docs/commands/fuzz.md): --peers fcl adds it


@dataclass
class CampaignConfig:
    seed: int = 0
    families: list | None = None  # None: every family of harness.suites.fuzz.families
    poses: int = 2000  # pose pairs per case (each queried unsigned and signed)
    sample: float = 2e-4  # share of spq's queries referenced whatever the cheap checks say
    peers: list | None = None  # None: DEFAULT_PEERS that import
    cases_per_task: int = 4
    plant: str | None = None  # a planted bug (harness.suites.fuzz.plant), to show the campaign finds it

    def family_names(self) -> list:
        from harness.suites.fuzz.families import FAMILIES, check_family

        return [check_family(f) for f in self.families] if self.families else list(FAMILIES)


@dataclass
class State:
    config: dict
    next_case: int = 0
    counts: dict = field(default_factory=dict)  # "family|engine|mode" -> {queries, wrong, ...}
    bad: list = field(default_factory=list)  # reproducer dicts (unshrunk)
    seconds: float = 0.0
    rounds: int = 0

    def spq_queries(self) -> int:
        return sum(v["queries"] for k, v in self.counts.items() if k.split("|")[1] == "spq")

    def merge(self, task_result: dict) -> None:
        for row in task_result["counts"]:
            key = f"{row['family']}|{row['engine']}|{row['mode']}"
            acc = self.counts.setdefault(key, {**{k: 0 for k in COUNT_KEYS}, "worst_error_m": 0.0})
            for k in COUNT_KEYS:
                acc[k] += int(row[k])
            acc["worst_error_m"] = max(acc["worst_error_m"], float(row["worst_error_m"]))

    def save(self, path) -> None:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(path.suffix + ".tmp")
        tmp.write_text(json.dumps(asdict(self)))
        os.replace(tmp, path)

    @classmethod
    def load_or_new(cls, path, config: CampaignConfig) -> "State":
        """The campaign at ``path`` if it exists (its configuration must be this one), else a new one."""
        wanted = asdict(config)
        if path is not None and Path(path).exists():
            state = cls(**json.loads(Path(path).read_text()))
            if state.config != wanted:
                raise ValueError(f"the campaign state {path} was run with {state.config}, not {wanted}: resume it "
                                 f"with the same settings, or give another --state file")
            return state
        return cls(config=wanted)


def _peers(names):
    """{name: isolated engine} for the peers, built once per process (harness.parallel.cluster.process_cache)."""
    from harness.parallel.cluster import process_cache

    def build():
        from harness.engines import available_engines
        from harness.engines.isolated import isolated

        return isolated(available_engines(list(names)))

    def close(engines):
        for e in engines.values():
            e.close()

    return process_cache(("fuzz-peers", tuple(names)), build, close)


def run_task(task: dict) -> dict:
    """Judge cases task["cases"] of the campaign configured by task["config"]; counts and bad cases."""
    from harness.suites.fuzz.families import draw_case
    from harness.suites.fuzz.judge import judge_case
    from harness.suites.fuzz.plant import planted

    config = CampaignConfig(**task["config"])
    families = config.family_names()
    peers = _peers(task["peers"]) if task["peers"] else {}
    plant = planted(config.plant)
    counts, bad = [], []
    for k in task["cases"]:
        family = families[k % len(families)]
        rng = np.random.default_rng([config.seed, k])
        a, b, pa, pb, _ = draw_case(family, rng, config.poses)
        r = judge_case(family, a, b, pa, pb, rng, peers, config.sample, plant=plant)
        counts.extend(r.counts)
        for x in r.bad:
            bad.append({**x.as_dict(), "case": k})
    return {"counts": counts, "bad": bad}


def warm_worker(config: dict, peers: list, poses: int = 20) -> float:
    """Ready this process for the campaign's tasks (a benchmark's warm-up, run on every worker): the
    peers built and kept, as a task keeps them, and one case of each family judged on ``poses`` pose
    pairs, which loads spq's compiled code for every shape. Returns the seconds it took."""
    start = time.perf_counter()
    families = CampaignConfig(**config).family_names()
    run_task({"config": {**config, "poses": poses}, "peers": list(peers), "cases": list(range(len(families)))})
    return time.perf_counter() - start


def available_peers(names) -> list:
    """The peers among ``names`` whose packages import (None: DEFAULT_PEERS)."""
    from importlib.util import find_spec

    modules = {"coal": "coal", "mujoco": "mujoco", "fcl": "fcl", "bullet": "pybullet"}
    out = []
    for name in (names or DEFAULT_PEERS):
        if name not in modules:
            raise ValueError(f"unknown fuzz peer {name!r}; choose from {list(modules)}")
        if names or find_spec(modules[name]) is not None:
            out.append(name)
    return out


def run(config: CampaignConfig, state_path=None, budget_s: float | None = None, max_queries: int | None = None,
        workers: int = 1, scheduler: str | None = None, tasks_per_round: int | None = None, keep_bad: int = 50,
        progress: bool = False, runner=None) -> State:
    """Run (or resume) the campaign until budget_s seconds or max_queries spq queries in total.

    The workers (harness.parallel.cluster.TaskRunner: this process, local processes or a Dask cluster) are
    started once for the whole campaign, or given as ``runner`` (open, kept open): each builds its
    peers and loads spq's kernels once. Rounds follow one another without a pause: a worker free
    at the end of a round takes a task of the next while the round's last tasks run, and a round
    enters the state, in case order, once all its tasks are in; the budget is checked as each new
    round is started."""
    from contextlib import nullcontext

    from tqdm import tqdm

    from harness.parallel.cluster import TaskRunner

    if budget_s is None and max_queries is None:
        raise ValueError("a campaign needs a time budget (seconds) or a query count to stop at")
    state = State.load_or_new(state_path, config)
    peers = available_peers(config.peers)
    tasks_per_round = tasks_per_round or max(2, 2 * (runner.workers if runner is not None else workers))
    start = time.perf_counter()
    seconds_before = state.seconds
    with (nullcontext(runner) if runner is not None else TaskRunner(workers, scheduler)) as runner, \
            tqdm(total=max_queries, initial=state.spq_queries(), unit="query", unit_scale=True, desc="spq fuzz",
                 disable=not progress) as bar:
        while not _finished(state, start, budget_s, max_queries):
            rounds = _Rounds(state, state_path, peers, config.cases_per_task, tasks_per_round, keep_bad, start,
                             seconds_before, budget_s, max_queries, bar)
            runner.stream(run_task, rounds.tasks(), rounds.done)
    return state


def _finished(state: State, start: float, budget_s, max_queries) -> bool:
    return ((budget_s is not None and time.perf_counter() - start >= budget_s)
            or (max_queries is not None and state.spq_queries() >= max_queries))


class _Rounds:
    """A campaign's rounds as one stream of tasks: tasks() hands them out round after round (a round:
    ``tasks_per_round`` tasks of ``cases_per_task`` consecutive cases, fewer for the last cases
    max_queries asks), deciding at each new round whether the budget allows it; done() collects the
    results and merges every round whose tasks are all in, in order, saving the state after each."""

    def __init__(self, state: State, state_path, peers: list, cases_per_task: int, tasks_per_round: int,
                 keep_bad: int, start: float, seconds_before: float, budget_s, max_queries, bar):
        self.state, self.state_path, self.peers = state, state_path, peers
        self.cases_per_task, self.tasks_per_round, self.keep_bad = cases_per_task, tasks_per_round, keep_bad
        self.start, self.seconds_before, self.budget_s, self.max_queries, self.bar = \
            start, seconds_before, budget_s, max_queries, bar
        self.per_case = 2 * CampaignConfig(**state.config).poses  # spq queries of a case (unsigned and signed)
        self.rounds: list[dict] = []  # round -> {"cases": n, "results": [task results or None]}
        self.merged = 0  # rounds merged into the state

    def tasks(self):
        """(round, task index) and task, round after round, while the budget and the query count allow."""
        next_case = self.state.next_case
        planned = self.state.spq_queries()  # spq queries once the rounds handed out are in
        while True:
            if self.budget_s is not None and time.perf_counter() - self.start >= self.budget_s:
                return
            n_cases = self.tasks_per_round * self.cases_per_task
            if self.max_queries is not None:
                if planned >= self.max_queries:
                    return
                n_cases = min(n_cases, -(-(self.max_queries - planned) // self.per_case))
            cases = list(range(next_case, next_case + n_cases))
            chunks = [cases[i:i + self.cases_per_task] for i in range(0, n_cases, self.cases_per_task)]
            r = len(self.rounds)
            self.rounds.append({"cases": n_cases, "results": [None] * len(chunks)})
            next_case += n_cases
            planned += n_cases * self.per_case
            for j, chunk in enumerate(chunks):
                yield (r, j), {"config": self.state.config, "peers": self.peers, "cases": chunk}

    def done(self, key, result: dict) -> None:
        r, j = key
        self.rounds[r]["results"][j] = result
        self.bar.update(sum(x["queries"] for x in result["counts"] if x["engine"] == "spq"))
        while self.merged < len(self.rounds) and all(x is not None for x in self.rounds[self.merged]["results"]):
            self._merge(self.rounds[self.merged])
            self.rounds[self.merged] = None  # its results are in the state
            self.merged += 1

    def _merge(self, round_: dict) -> None:
        state = self.state
        round_bad = []
        for result in round_["results"]:
            state.merge(result)
            round_bad.extend(result["bad"])
        state.bad.extend(round_bad[:self.keep_bad])
        state.next_case += round_["cases"]
        state.rounds += 1
        state.seconds = self.seconds_before + time.perf_counter() - self.start
        if self.state_path is not None:
            state.save(self.state_path)


def table(state: State):
    """The counts as a DataFrame: family, engine, mode, queries, wrong, failed, referenced, disputed,
    worst_error_m, sorted."""
    import pandas as pd

    rows = [{"family": k.split("|")[0], "engine": k.split("|")[1], "mode": k.split("|")[2], **v}
            for k, v in state.counts.items()]
    if not rows:
        return pd.DataFrame(columns=["family", "engine", "mode", *COUNT_KEYS, "worst_error_m"])
    return pd.DataFrame(rows).sort_values(["engine", "family", "mode"]).reset_index(drop=True)
