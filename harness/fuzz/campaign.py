"""A fuzz campaign: cases drawn round-robin from the families, judged in tasks on this process, local
processes or a Dask cluster (harness.cluster), the counts checkpointed after every round.

Case k (k = 0, 1, 2, ...) is family ``families[k % len(families)]`` drawn with
``np.random.default_rng([seed, k])``, so a campaign is a pure function of its seed and families, and a
resumed campaign (the state file names the next case) continues exactly where the last one stopped.
Rounds of ``tasks_per_round`` tasks of ``cases_per_task`` cases run until the time budget or the query
count is reached; the state (counts per family, engine and mode; the wrong and failed spq cases found,
up to ``keep_bad`` per round) is written after each round, atomically.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

COUNT_KEYS = ("queries", "wrong", "failed", "referenced", "disputed")
DEFAULT_PEERS = ("coal", "mujoco", "bullet")  # python-fcl hangs on some poses (see README): --peers fcl adds it


@dataclass
class CampaignConfig:
    seed: int = 0
    families: list | None = None  # None: every family of harness.fuzz.families
    poses: int = 2000  # pose pairs per case (each queried unsigned and signed)
    sample: float = 2e-4  # share of spq's queries referenced whatever the cheap checks say
    peers: list | None = None  # None: DEFAULT_PEERS that import
    cases_per_task: int = 4
    plant: str | None = None  # a planted bug (harness.fuzz.plant), to show the campaign finds it

    def family_names(self) -> list:
        from harness.fuzz.families import FAMILIES, check_family

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
    """{name: isolated engine} for the peers, built once per process (harness.cluster.process_cache)."""
    from harness.cluster import process_cache

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
    from harness.fuzz.families import draw_case
    from harness.fuzz.judge import judge_case
    from harness.fuzz.plant import planted

    config = CampaignConfig(**task["config"])
    families = config.family_names()
    peers = _peers(task["peers"]) if task["peers"] else {}
    plant = planted(config.plant)
    counts, bad = [], []
    for k in task["cases"]:
        family = families[k % len(families)]
        rng = np.random.default_rng([config.seed, k])
        a, b, pa, pb, _ = draw_case(family, rng, config.poses)
        shapes, outputs = (None, None) if plant is None else plant(a, b, pa, pb)
        r = judge_case(family, a, b, pa, pb, rng, peers, config.sample, spq_shapes=shapes, outputs=outputs)
        counts.extend(r.counts)
        for x in r.bad:
            bad.append({**x.as_dict(), "case": k})
    return {"counts": counts, "bad": bad}


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
        progress: bool = False) -> State:
    """Run (or resume) the campaign until budget_s seconds or max_queries spq queries in total."""
    from tqdm import tqdm

    from harness.cluster import run_tasks

    if budget_s is None and max_queries is None:
        raise ValueError("a campaign needs a time budget (seconds) or a query count to stop at")
    state = State.load_or_new(state_path, config)
    peers = available_peers(config.peers)
    per_case = 2 * config.poses
    tasks_per_round = tasks_per_round or max(2, 2 * workers)
    start = time.perf_counter()
    total = max_queries if max_queries is not None else None
    with tqdm(total=total, initial=state.spq_queries(), unit="query", unit_scale=True, desc="spq fuzz",
              disable=not progress) as bar:
        while True:
            spent = time.perf_counter() - start
            if budget_s is not None and spent >= budget_s:
                break
            if max_queries is not None and state.spq_queries() >= max_queries:
                break
            left = None if max_queries is None else max_queries - state.spq_queries()
            n_cases = tasks_per_round * config.cases_per_task
            if left is not None:
                n_cases = min(n_cases, -(-left // per_case))
            cases = list(range(state.next_case, state.next_case + n_cases))
            chunks = [cases[i:i + config.cases_per_task] for i in range(0, len(cases), config.cases_per_task)]
            tasks = [{"config": state.config, "peers": peers, "cases": c} for c in chunks]
            results = run_tasks(run_task, tasks, workers=workers, scheduler=scheduler,
                                done=lambda i, r: bar.update(sum(x["queries"] for x in r["counts"]
                                                                 if x["engine"] == "spq")))
            round_bad = []
            for r in results:
                state.merge(r)
                round_bad.extend(r["bad"])
            state.bad.extend(round_bad[:keep_bad])
            state.next_case += n_cases
            state.rounds += 1
            state.seconds += time.perf_counter() - start - spent
            if state_path is not None:
                state.save(state_path)
    return state


def table(state: State):
    """The counts as a DataFrame: family, engine, mode, queries, wrong, failed, referenced, disputed,
    worst_error_m, sorted."""
    import pandas as pd

    rows = [{"family": k.split("|")[0], "engine": k.split("|")[1], "mode": k.split("|")[2], **v}
            for k, v in state.counts.items()]
    if not rows:
        return pd.DataFrame(columns=["family", "engine", "mode", *COUNT_KEYS, "worst_error_m"])
    return pd.DataFrame(rows).sort_values(["engine", "family", "mode"]).reset_index(drop=True)
