"""Where a job's time goes, by compiled kernel: one bench job run in a loop under Linux ``perf``, its samples
read by function with numba's kernels named (harness.suites.profile.jit_symbols).

A profile is not a timing: ``perf`` samples the running thread at a fixed rate (cpu-clock, so it also works
on virtual machines without hardware counters), and a function's share is the share of the main thread's
samples that fell in its code. Functions inlined into another are counted as that one. The areas group the
functions by module (``spq.kernels.gjk``, ...), with libm, numpy and the interpreter apart.

Jobs (Table I's shapes, ``spq bench``'s poses): a pair of bounding volumes of one link (PCH: its hull; STP:
its STP-BV; CSE: its covering superellipsoid, or ``cse``'s), batched (``Pair.distances``, cold), per call
(``Pair.cold_distance`` in a loop), or as the plain call (``spq.distance``), signed or unsigned, all poses or
the overlapping ones alone; or a robot scene's cold all-pairs sweep (``Scene.distances_many``) under a policy.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from harness.suites import Output, Table, frame_lines

VOLUMES = ("PCH", "STP", "CSE")
MODES = ("batched", "per-call", "plain")
UNNAMED_WARNING = 10.0  # percent of the samples in unnamed compiled code above which the output says why


@dataclass
class Config:
    pair: str = "STP-STP"  # two of PCH, STP, CSE joined by "-"; ignored with a robot
    mode: str = "batched"
    signed: bool = True
    overlaps: bool = False  # the overlapping poses alone
    object: str = "kuka_link_4"
    poses: int = 20000
    seed: int = 0
    range: float = 0.3  # m: translations uniform in ±range
    r: float = 0.005  # m: STP-BV small radius
    R: float = 2.0  # m: STP-BV big radius
    cse: str = "fit"  # the CSE-BV of the CSE pairs, as spq bench table1's --cse (harness.suites.table1.cse_spec)
    robot: str | None = None  # a robot of datasets.robots: its cold all-pairs sweep instead of a pair
    coherent: bool = False  # with a robot: its coherent sweep along the bench's smooth trajectory instead
    policy: str = "auto"
    configs: int = 1000
    seconds: float = 10.0  # sampled time
    frequency: int = 4999  # samples a second
    top: int = 25  # rows of the functions' and the hot instructions' tables
    annotate: list[str] = field(default_factory=list)  # functions (a full name, or its last part) shown by instruction
    progress: bool = False


def _check(config: Config) -> None:
    kinds = config.pair.split("-")
    if config.robot is None and (len(kinds) != 2 or any(k not in VOLUMES for k in kinds)):
        raise ValueError(f"pair must be two of {list(VOLUMES)} joined by '-' (e.g. STP-PCH); got {config.pair!r}")
    if config.mode not in MODES:
        raise ValueError(f"mode must be one of {list(MODES)}; got {config.mode!r}")
    for name, low in (("poses", 1), ("configs", 1), ("top", 1), ("frequency", 1)):
        if getattr(config, name) < low:
            raise ValueError(f"{name} must be at least {low}; got {getattr(config, name)}")
    if not (np.isfinite(config.seconds) and 0.5 <= config.seconds <= 3600):
        raise ValueError(f"seconds must lie in [0.5, 3600]; got {config.seconds}")
    from harness.suites.table1 import cse_spec

    cse_spec(config.cse)  # its own ValueError names the bad value
    if config.robot is not None:
        from datasets.robots import robot_urdf
        from spq.scene import SCENE_POLICIES

        robot_urdf(config.robot)
        if config.policy not in SCENE_POLICIES:
            raise ValueError(f"policy must be one of {list(SCENE_POLICIES)}; got {config.policy!r}")


def _pair_job(config: Config):
    """(a callable that runs the job once, queries it makes, a description)."""
    import spq
    from datasets import load_object
    from harness.suites.table1.bv_rates import Table1Config, build_bodies
    from harness.workloads.poses import random_poses

    from harness.suites.table1 import cse_spec

    bodies = build_bodies(Table1Config(object_name=config.object, r=config.r, R=config.R, cse=cse_spec(config.cse)[1],
                                       volume_samples=1000, seed=config.seed), load_object)
    a, b = (bodies[k] for k in config.pair.split("-"))
    poses_a, poses_b = random_poses(config.poses, config.seed, config.range)
    pa, pb = poses_a @ a.offset, poses_b @ b.offset
    pair = spq.Pair(a.shape, b.shape, signed=config.signed)
    if config.overlaps:
        hit = pair.distances(pa, pb, coherent=False).status == "overlapping"
        if not hit.any():
            raise ValueError(f"none of the {config.poses} poses overlaps: give a smaller range (now {config.range} m)")
        pa, pb = np.ascontiguousarray(pa[hit]), np.ascontiguousarray(pb[hit])
    kind = "signed" if config.signed else "unsigned"
    what = f"{config.pair} {kind}, {len(pa)} {'overlapping ' if config.overlaps else ''}poses of {config.object}"
    if config.mode == "batched":
        return (lambda: pair.distances(pa, pb, coherent=False)), len(pa), f"{what}, Pair.distances (cold)"
    if config.mode == "per-call":
        def loop():
            for i in range(len(pa)):
                pair.cold_distance(pa[i], pb[i])
        return loop, len(pa), f"{what}, Pair.cold_distance in a loop"

    def plain():
        for i in range(len(pa)):
            spq.distance(a.shape, b.shape, pa[i], pb[i], signed=config.signed)
    return plain, len(pa), f"{what}, spq.distance in a loop"


def _robot_job(config: Config):
    from harness.suites.robot.robot_bench import RobotBenchConfig, load_scene
    from harness.workloads.robot_poses import random_configurations, smooth_trajectory
    from spq.kernels.gjk import OUT_SIZE

    scene = load_scene(RobotBenchConfig(robot=config.robot, r=config.r, R=config.R), config.policy)
    if config.coherent:  # as spq bench robot's coherent rows: each pair warm-starts from its last query
        qs, sweep = smooth_trajectory(scene.model, config.configs, config.seed), "coherent all-pairs sweep"
        where = f"a {len(qs)}-step smooth trajectory"
    else:
        qs, sweep = random_configurations(scene.model, config.configs, config.seed), "cold all-pairs sweep"
        where = f"{len(qs)} random configurations"
    kind = "signed" if config.signed else "unsigned"
    out = np.empty((len(qs), len(scene.pairs), OUT_SIZE))  # as spq bench robot: no page faults of a new array
    return ((lambda: scene.distances_many(qs, coherent=config.coherent, signed=config.signed, out=out)),
            len(qs) * len(scene.pairs), f"{config.robot} {config.policy}, {kind}, {sweep} (Scene.distances_many) over "
            f"{where}")


def area(symbol: str, obj: str) -> str:
    """The area a function counts in: its module for numba's kernels, else its library."""
    jit = obj.startswith(("perf-", "[JIT]")) or obj == "[unknown]"
    if symbol.startswith("0x"):
        return "JIT (unnamed)" if jit else obj
    if jit or symbol.startswith(("spq.", "harness.")):
        name = symbol.split(" [")[0]
        return name.rsplit(".", 1)[0] if "." in name else "JIT (unnamed)"
    if obj.startswith("libm"):
        return "libm"
    if obj.startswith(("libpython", "python")):
        return "Python interpreter"
    if "numpy" in obj or obj.startswith(("_multiarray", "libopenblas", "libscipy_openblas")):
        return "numpy"
    return obj


def run(config: Config) -> Output:
    from harness.report.meta import run_metadata
    from harness.suites.profile import jit_symbols, sampling

    _check(config)
    sampling.perf_path()
    jit_symbols.require_tools()
    jit_symbols.install()  # before the first kernel call, so that every kernel is named
    job, queries, what = _robot_job(config) if config.robot else _pair_job(config)
    job()  # compiles or loads every kernel the job takes, outside the recording
    folder = Path(os.environ.get("SPQ_PROFILE_DIR", "/tmp")) / f"spq-profile-{os.getpid()}"
    data = folder / "perf.data"
    runs, bar = 0, None
    if config.progress:
        from tqdm import tqdm

        bar = tqdm(total=round(config.seconds), desc="profile", unit="s", leave=False)
    with sampling.Recording(data, config.frequency):
        start = time.perf_counter()
        while (elapsed := time.perf_counter() - start) < config.seconds:
            job()
            runs += 1
            if bar is not None:
                bar.n = min(round(elapsed), bar.total)
                bar.refresh()
        seconds = time.perf_counter() - start
    if bar is not None:
        bar.close()
    map_path, named = jit_symbols.write_perf_map()  # perf reads it at report time
    samples, count = sampling.samples_by_symbol(data, os.getpid())
    samples["function"] = [jit_symbols.readable(s) for s in samples.symbol]
    samples["area"] = [area(f, o) for f, o in zip(samples.function, samples.object)]
    functions, areas = _percent_by(samples, ["function", "area"]), _percent_by(samples, ["area"])
    top = functions.head(config.top)
    meta = run_metadata(command="spq profile", job=what, seed=config.seed, seconds=round(seconds, 2), runs=runs,
                        queries=queries * runs, us_per_query=round(1e6 * seconds / max(queries * runs, 1), 4),
                        samples=count, frequency=config.frequency, functions_named=named, perf_data=str(data),
                        perf_map=str(map_path), perf_event_paranoid=sampling.paranoid_level())
    notes = (f"{what}: run {runs} times in {seconds:.1f} s under perf record -F {config.frequency} (cpu-clock), "
             f"the main thread's samples by function; kernels named from numba's objects ({named} functions). "
             "A function inlined into another counts as that one; 'JIT (unnamed)' is compiled code the map "
             "does not cover. Not a timing: shares of samples.")
    spot_notes = (" Hot instructions: the sampled addresses in named kernels, each with its offset in its function and "
                  "its instruction as objdump reads the kernel's object file (profile_symbols.csv says which file; "
                  "objdump -d --disassemble=<symbol> <file> gives the whole function). A sample usually lands on the "
                  "instruction after the one that held the thread up (skid).")
    out = Output(meta=meta, tables=[Table("profile_functions", f"Profile by function: {what}", top, notes),
                                    Table("profile_areas", f"Profile by area: {what}", areas, notes)],
                 raw={"profile_samples.csv": samples[["share", "object", "symbol", "function", "area"]]})
    placed = jit_symbols.symbols()
    objects = jit_symbols.dump_objects(folder / "objects")
    addresses = sampling.sample_addresses(data, os.getpid())
    spots, out.raw["profile_symbols.csv"] = _hot_spots(addresses, placed, objects, config.top)
    out.tables.append(Table("profile_hot_spots", f"Hot instructions: {what}", spots, notes + spot_notes))
    annotations = _annotations(config.annotate, addresses, placed, objects, config.top)
    if annotations:
        out.documents["profile_annotate.md"] = (f"# Instructions of the annotated kernels: {what}\n\n"
                                                "percent of all samples, offset in the function, instruction, "
                                                f"around its {config.top} most sampled ones (a sample usually lands "
                                                "on the instruction after the one that held the thread up)\n"
                                                + "".join(f"\n## {name}\n\n```\n" + "\n".join(lines) + "\n```\n"
                                                          for name, lines in annotations.items()))
    out.lines = ([what, f"{runs} runs in {seconds:.1f} s, {1e6 * seconds / max(queries * runs, 1):.3f} us a query "
                  f"(under perf), {count} samples; perf data and the kernels' objects in {folder}"]
                 + frame_lines(areas.head(12)) + [""] + frame_lines(top) + [""] + frame_lines(spots.head(12)))
    for name, lines in annotations.items():
        out.lines += ["", name] + lines
    unnamed = float(areas.loc[areas.area == "JIT (unnamed)", "percent"].sum())
    if unnamed > UNNAMED_WARNING:
        out.lines.append(f"warning: {unnamed:.0f}% of the samples fell in compiled code no map names: kernels this "
                         "process loaded before the profiler started keep no object code (run spq profile in a "
                         "process of its own)")
    return out


def _annotations(names: list[str], addresses, placed, objects, top: int) -> dict[str, list[str]]:
    """{function: its annotated lines} for each name (a full name, or the last part of one)."""
    from harness.suites.profile import jit_symbols

    found = {}
    for name in names:
        matches = [s for s in placed if jit_symbols.readable(s.name) == name
                   or jit_symbols.readable(s.name).endswith("." + name)]
        if not matches:
            raise ValueError(f"annotate: no compiled kernel named {name!r} ran in this job: it may be inlined into "
                             "its caller, which then holds its code (profile_symbols.csv lists the kernels that ran)")
        for symbol in matches:  # a kernel compiled for several argument types has one symbol each
            key = jit_symbols.readable(symbol.name)
            key = key if key not in found else f"{key} ({hex(symbol.address)})"
            found[key] = jit_symbols.annotated(addresses, symbol, objects[symbol.object_index], top)
    return found


def _percent_by(samples: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """Samples' shares summed by ``keys``, as percent, largest first."""
    frame = samples.groupby(keys, as_index=False)["share"].sum().sort_values("share", ascending=False,
                                                                             ignore_index=True)
    return frame.assign(share=(100 * frame.share).round(2)).rename(columns={"share": "percent"})


def _hot_spots(addresses, placed, objects, top: int) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(the top hot instructions of the kernels, every named kernel's symbol row)."""
    from harness.suites.profile import jit_symbols

    spots = jit_symbols.hot_spots(addresses, placed, top)
    table = pd.DataFrame({"function": spots.function, "offset": [hex(v) for v in spots.offset],
                          "percent": (100 * spots.share).round(2),
                          "instruction": jit_symbols.instructions(objects, spots)})
    symbols = pd.DataFrame(
        {"function": [jit_symbols.readable(s.name) for s in placed], "address": [hex(s.address) for s in placed],
         "size": [s.size for s in placed], "object_file": [str(objects[s.object_index]) for s in placed],
         "offset": [hex(s.offset) for s in placed], "symbol": [s.name for s in placed]})
    return table, symbols
