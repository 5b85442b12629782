"""The ``spq`` command line: a thin table over the suites of harness/suites (each command maps its
arguments onto the suite's Config by name, runs it, writes its output and prints its lines), plus
``spq report``, ``spq scene`` and ``spq history``."""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from harness.suites.bench.timing import BLOCK
from harness.suites.check.gate import SECTIONS, SPEED_FLOOR, CheckConfig
from harness.suites.table1 import CSE_FIT, preset_text

DEFAULT_OUT = Path("reports")


def _with_plugins(names: list[str] | None, specs: list[str] | None) -> list[str] | None:
    """Engine names to run: those named plus the plugins of --engine (registered here), or None
    (every registered engine that imports, the plugins included) when none is named."""
    from harness.engines import register_plugin

    plugins = [register_plugin(spec) for spec in specs or []]
    return list(dict.fromkeys(names + plugins)) if names else None


def config_from(args, cls, **values):
    """cls (a suite's Config) from the parsed arguments of the same names, then ``values``;
    progress bars unless --quiet."""
    fields = {f.name for f in dataclasses.fields(cls)}
    given = {k: v for k, v in vars(args).items() if k in fields}
    given["progress"] = not getattr(args, "quiet", False)
    return cls(**{**given, **values})


def run_suite(name: str, config, out: str | None) -> int:
    """Run harness.suites.<name> with config, write its output into out, print its lines."""
    from importlib import import_module

    from harness.suites import write_output

    start = time.perf_counter()
    output = import_module(f"harness.suites.{name}").run(config)
    paths = write_output(output, Path(out)) if out else []
    print("\n".join(output.lines))
    if paths:
        print(f"\nwrote {', '.join(sorted(p.name for p in paths))} into {out} in {time.perf_counter() - start:.0f} s")
    return output.exit_code


def _suite(name: str, **values):
    """A command that runs suite ``name`` with the arguments of its config's field names."""
    def command(args) -> int:
        from importlib import import_module

        cls = import_module(f"harness.suites.{name}").Config
        return run_suite(name, config_from(args, cls, **{k: v(args) for k, v in values.items()}), args.out)
    return command


def cmd_profile(args) -> int:
    from harness.suites.profile.sampling import ProfilerUnavailable

    try:
        return _suite("profile")(args)
    except ProfilerUnavailable as exc:
        print(f"spq profile: cannot profile here: {exc}", file=sys.stderr)
        return 2


def cmd_bench(args) -> int:
    suite = {"pch": "bench", "stp": "bench", "table1": "table1", "robot": "robot", "robots": "robots", "scaling": "scaling",
             "control": "control"}[args.suite]
    extra = {"kind": args.suite} if suite == "bench" else {}
    if args.workers is None:  # the suite's own default (1; 2 for scaling)
        del args.workers
    if suite == "robot":
        extra["engines"] = args.engines or ["coal", "fcl"]
    from importlib import import_module

    cls = import_module(f"harness.suites.{suite}").Config
    # --configs and --steps not given: each robot suite's own sizes (robot 1000; robots by --quick)
    extra.update({f.name: f.default for f in dataclasses.fields(cls)
                  if f.name in ("configs", "steps") and getattr(args, f.name, None) is None})
    return run_suite(suite, config_from(args, cls, **extra), args.out)


def cmd_check(args) -> int:
    from harness.suites import check

    settings = CheckConfig(seed=args.seed, per_bucket=args.per_bucket, oracle_per_bucket=args.oracle_per_bucket,
                           speed_poses=args.speed_poses, speed_rounds=args.speed_rounds, peer=args.peer,
                           sections=tuple(args.sections))
    return run_suite("check", config_from(args, check.Config, settings=settings,
                                          engines=_with_plugins(args.engines, args.engine)), args.out)


def cmd_report(args) -> int:
    from harness.report.assemble import run_report

    start = time.perf_counter()
    size = "quick" if args.quick else "full" if args.full else "standard"
    paths = run_report(Path(args.out), size=size, seed=args.seed, workers=args.workers)
    print(f"wrote {', '.join(str(p) for p in paths)} in {time.perf_counter() - start:.0f} s")
    return 0


def cmd_scene(args) -> int:
    from harness.parallel.cluster import check_scheduler, describe
    from harness.workloads import scene_file as sf
    from harness.workloads import scene_run as sr
    from spq.workers import check_workers

    check_workers(args.workers)
    check_scheduler(args.scheduler)

    start = time.perf_counter()
    try:
        spec = sf.read_scene_file(args.scene)
        scene = sf.build_scene(spec)
        qs = sf.scene_configurations(spec, scene.model)
    except FileNotFoundError as exc:
        print(f"spq scene: error: {exc}", file=sys.stderr)
        return 2
    urdf = scene.model.source or spec.urdf
    overrides = "; per body: " + ", ".join(f"{k} = {v}" for k, v in spec.policies.items()) if spec.policies else ""
    skipped = ("adjacent bodies skipped" if spec.skip_adjacent else "adjacent bodies queried") + (
        f", {len(spec.skip_pairs)} more pair{'s' if len(spec.skip_pairs) != 1 else ''} skipped")
    print(f"scene           {args.scene}")
    print(f"robot           {spec.name} ({urdf}), {scene.model.ndof} joints")
    print(f"bodies          {len(scene.bodies)}")
    print(f"pairs           {len(scene.pairs)} ({skipped})")
    print(f"pairs per BV    {', '.join(f'{k} {v}' for k, v in scene.kind_counts().items())}")
    print(f"policy          {spec.policy}{overrides}; r = {spec.r:g} m, R = {spec.R:g} m")
    print(f"poses           {spec.poses.describe()}")
    print(f"built in {time.perf_counter() - start:.1f} s")

    spread = args.workers > 1 or args.scheduler is not None
    if spread and spec.poses.coherent:
        print("coherent sweep: serial (each pair starts from its previous simplex, so the order matters); "
              "--workers and --scheduler apply to cold sweeps")
        spread = False
    if spread:
        run = sr.run_scene_spread(scene, qs, spec.poses.prune, args.workers, args.scheduler, progress=not args.quiet)
    else:
        run = sr.run_scene(scene, qs, spec.poses.coherent, spec.poses.prune, progress=not args.quiet)
    ms = run.seconds * 1e3
    a, b = scene.pair_names[run.min_pair[run.closest]]
    print(f"\nconfigurations  {run.configurations}")
    if spread:
        where = f"{args.workers} threads" if args.scheduler is None else describe(args.workers, args.scheduler)
        print(f"time per config {ms.mean():.3g} ms (wall time of blocks of {sr.SPREAD_BLOCK} configurations on "
              f"{where}, shared out: a throughput)")
    else:
        print(f"time per config mean {ms.mean():.3g} ms, median {np.median(ms):.3g} ms (one call each)")
    print(f"pairs per s     {run.configurations * len(scene.pairs) / run.seconds.sum():,.0f}")
    print(f"min distance    {run.min_distance[run.closest]:.6g} m, {a} - {b} "
          f"({run.min_status[run.closest]}), configuration {run.closest}")
    print(f"overlaps        in {int(np.count_nonzero(run.overlapping))} of {run.configurations} configurations")
    print(f"statuses        {', '.join(f'{k} {v}' for k, v in run.status_counts.items())}")
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        stem = Path(args.scene).stem
        paths = (out / f"{stem}_configurations.csv", out / f"{stem}_closest_posture.csv")
        sr.configurations_table(scene, run).to_csv(paths[0], index=False)
        sr.closest_posture_table(scene, run).to_csv(paths[1], index=False)
        print(f"wrote {paths[0]}, {paths[1]}")
    print(f"done in {time.perf_counter() - start:.1f} s")
    return 0


def cmd_view(args) -> int:
    from harness.report.viewer import MissingViewer, serve

    try:
        viewer = serve(args.targets, host=args.host, port=args.port, tolerance=args.tolerance, r=args.r, R=args.R)
    except MissingViewer as exc:
        print(f"spq view: {exc}", file=sys.stderr)
        return 2
    print(f"spq view: serving {' and '.join(args.targets)} at {viewer.url} (open it in a browser; Ctrl-C stops)",
          flush=True)
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        pass
    finally:
        viewer.close()
    return 0


def cmd_history(args) -> int:
    from harness.suites.check import gate as ck

    table = ck.load_history(args.history)
    if table.empty or table.run.nunique() < 1:
        raise ValueError(f"history {args.history!r} holds no runs")
    path = ck.history_chart(table, Path(args.out))
    print(f"{table.run.nunique()} runs, {table.commit.nunique()} commits; chart: {path}")
    return 0


def cmd_srdf(args) -> int:
    """Sample a robot's collision pairs by MoveIt's setup-assistant rules and write them as an SRDF."""
    from collections import Counter

    from datasets.robots import ROBOTS, robot_urdf
    from spq.collision_pairs import REASONS, disabled_pairs_by_sampling
    from spq.io.srdf import write_srdf
    from spq.scene import Scene

    start = time.perf_counter()
    urdf, convex_dir, mesh_root = Path(args.urdf), args.convex_dir, args.mesh_root
    if not urdf.is_file() and args.urdf in ROBOTS:  # a robot of datasets.robots by name (jvrc1: its hulls)
        files = ROBOTS[args.urdf]
        urdf = robot_urdf(args.urdf)
        convex_dir = convex_dir or files.convex_dir
        mesh_root = mesh_root or files.mesh_root
    if not urdf.is_file():
        raise ValueError(f"URDF {args.urdf!r} not found (a file, or one of {sorted(ROBOTS)})")
    scene = Scene.from_urdf(urdf, convex_dir=convex_dir, mesh_root=mesh_root, policy=args.policy,
                            skip_adjacent=False)
    pairs = disabled_pairs_by_sampling(scene, samples=args.samples, seed=args.seed,
                                       always_fraction=args.always_fraction)
    counts = Counter(reason for _, _, reason in pairs)
    links = len({b.link for b in scene.bodies})
    total = links * (links - 1) // 2
    summary = ", ".join(f"{counts.get(r, 0)} {r}" for r in REASONS)
    name = args.name or scene.model.name or urdf.stem
    comment = (f"Generated by `spq srdf` (spq.collision_pairs.disabled_pairs_by_sampling, MoveIt setup assistant's "
               f"rules) from {urdf.name}: {args.policy} bodies, {args.samples} random configurations, seed {args.seed}, "
               f"always_fraction {args.always_fraction:g}. {links} links with bodies, {total} link pairs, "
               f"{len(pairs)} disabled ({summary}), {total - len(pairs)} left.")
    write_srdf(args.out, name, pairs, comment=comment)
    print(comment)
    print(f"wrote {args.out} in {time.perf_counter() - start:.1f} s")
    return 0


def _workers(text: str) -> int:
    """--workers: an integer >= 1 (spq.workers checks the range)."""
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1; got {text!r}") from None


def _cse(text: str) -> str:
    """--cse: checked here (harness.suites.table1.bv_rates.cse_spec's ValueError) so that a bad value stops the
    command before the bodies are built; the suite parses it again."""
    from harness.suites.table1 import cse_spec

    try:
        cse_spec(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def _spread_arguments(p, unit: str) -> None:
    """--workers and --scheduler of a suite whose tasks may run on processes or a Dask cluster."""
    p.add_argument("--workers", type=_workers, default=1,
                   help=f"processes, one {unit} (with its own seed) at a time each; the results equal the serial "
                        "run's (default 1: serial); with --scheduler local, the Dask LocalCluster's size")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run the tasks on a Dask cluster: a scheduler address (tcp://HOST:8786) or 'local' "
                        "for a LocalCluster of --workers processes (needs pip install \"dask[distributed]\")")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="spq", description="Smooth Proximity Queries: measurements.")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("report", help="run every suite and write reports/index.html and REPORT.md")
    size = p.add_mutually_exclusive_group()
    size.add_argument("--quick", action="store_true", help="small settings (a minute or two; what the report test runs)")
    size.add_argument("--full", action="store_true",
                      help="the full sizes of the committed report (about 13 minutes with the kernels compiled; the "
                           "default, standard run answers the same questions on fewer samples in about 10 on a fresh "
                           "2-core install)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=str(DEFAULT_OUT))
    p.add_argument("--workers", type=int, default=None,
                   help="processes for the suites that time nothing, run side by side before the benchmarks, "
                        "which run one at a time (default: every core; 1: all in this process, in order)")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("crosscheck", help="every engine on distance-controlled poses vs the exact reference")
    p.add_argument("--objects", nargs="+", help="dataset names or mesh/qhull paths (default: the built-in set)")
    p.add_argument("--per-bucket", type=int, default=1000, help="poses per distance bucket, over all pairs")
    p.add_argument("--agreement-poses", type=int, default=500_000,
                   help="random poses on which spq is also compared with coal (0: none)")
    p.add_argument("--buckets", nargs="+", help="bucket names (default: all)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--engines", nargs="+", help="engine names (default: all that import)")
    p.add_argument("--engine", action="append", metavar="[NAME=]MODULE:CLASS",
                   help="a plugin engine adapter to add (repeatable); see harness/engines/base.py")
    p.add_argument("--out", default=str(DEFAULT_OUT), help="output folder (default: reports)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    _spread_arguments(p, "object pair")
    p.set_defaults(func=_suite("crosscheck", engines=lambda a: _with_plugins(a.engines, a.engine)))

    p = sub.add_parser("bench-support", help="STP-BV support time against feature count (paper Fig. 6/7)")
    p.add_argument("--object", default="kuka_link_1", help="dataset name or mesh path (default: kuka_link_1, 574 points)")
    p.add_argument("--r", type=float, default=0.005)
    p.add_argument("--R-values", type=float, nargs="+", dest="R_values",
                   help="big radii (m); default: 1.0001 to 300 times the smallest admissible R - r, plus r")
    p.add_argument("--directions", type=int, default=20000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--out", default=str(DEFAULT_OUT))
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=_suite("support"))

    p = sub.add_parser("bench", help="throughput benchmarks")
    p.add_argument("suite", choices=["pch", "stp", "table1", "robot", "robots", "scaling", "control"],
                   help="pch: PCH-PCH, every engine; stp: STP-PCH and STP-STP (spq) beside PCH-PCH; "
                        "table1: the paper's Table I, PCH/STP/CSE pairs with coal's PCH-PCH beside; "
                        "robot: all pairs of a robot per configuration, spq policies beside coal and fcl; "
                        "robots: every robot of example-robot-data, one row each, beside pinocchio and coal; "
                        "scaling: 1 against --workers (default 2) workers on batched queries, a scene sweep and "
                        "the crosscheck, results compared (a few minutes); "
                        "control: a collision-avoiding QP controller on seeded tasks with spq's pch, stp, cse and auto "
                        "scenes and pink and mink, and what each volume does to the commands")
    p.add_argument("--object", default="kuka_link_4", help="dataset name or mesh path (default: kuka_link_4)")
    p.add_argument("--poses", type=int, default=20000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--range", type=float, default=0.3, help="translation range (m), uniform in ±range")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--block", type=int, default=BLOCK,
                   help=f"pch, stp, table1: poses per block; each block is timed --repeats times, every engine on it "
                        f"before the next, each timed run after an untimed one on the same block, its least time kept "
                        f"(default {BLOCK})")
    p.add_argument("--engines", nargs="+", help="engine names (default: all that import)")
    p.add_argument("--r", type=float, default=0.005, help="STP-BV small radius (m), stp suite")
    p.add_argument("--R", type=float, default=2.0, help="STP-BV big radius (m), stp suite")
    p.add_argument("--cse", type=_cse, default=CSE_FIT,
                   help=f"table1 suite: the CSE-BV of the CSE rows: '{CSE_FIT}' (default: the link's covering fit), a "
                        f"preset: {preset_text()}, or a,b,c,e1,e2 (semi-axes in m, exponents in (0, 2]); a preset or "
                        "given CSE is centred on the link's bounding box, its axes along the link's")
    p.add_argument("--robot", default="jvrc1", help="robot suite: a robot name (jvrc1, kuka_iiwa, panda)")
    p.add_argument("--configs", type=int, help="robot(s) suites: random configurations (default: robot 1000, "
                                                "robots 100, robots --quick 10)")
    p.add_argument("--steps", type=int, help="robot(s) suites: trajectory steps (default: robot 1000, robots 200, "
                                             "robots --quick 30)")
    p.add_argument("--prune", type=float, default=0.05, help="robot suite: pruning threshold (m) of the pruned rows")
    p.add_argument("--engine-configs", type=int, help="robot suite: configurations coal and fcl run (default: all); "
                                                      "robots suite: configurations coal runs (default 5, quick 2)")
    p.add_argument("--robots", nargs="+", help="robots suite: robot names of example-robot-data (default: all)")
    p.add_argument("--tasks", type=int, default=20, help="control suite: seeded tasks per robot (default 20)")
    p.add_argument("--pink-tasks", type=int, default=3, dest="pink_tasks",
                   help="control suite: pink on this many tasks per robot (default 3; its barrier loops in Python over "
                        "every pair, 50-120 ms a step on the humanoids)")
    p.add_argument("--methods", nargs="+", help="control suite: spq-pch spq-stp spq-cse spq-auto (or pch stp cse auto) "
                                                "pink mink pin-damper mujoco-damper (default: all); control --robots: jvrc1 talos_reduced panda "
                                                "ur5_robot (default: all four); --steps: 5 ms steps per task (default 600)")
    p.add_argument("--quick", action="store_true", help="robots suite: a few small robots, few configurations")
    p.add_argument("--workers", type=_workers, default=None,
                   help="threads of spq's batched rows (pch, stp) and cold scene rows (robot), the results equal "
                        "one thread's; coherent runs stay on one thread (default 1); scaling: the workers set "
                        "against one (default 2)")
    p.add_argument("--out", default=str(DEFAULT_OUT))
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser("ab", help="same-process A/B: spq at two git revisions (or the working tree) timed against "
                                  "each other on the same poses, batched and per call, results compared bit for bit")
    p.add_argument("old", nargs="?", default="HEAD", help="git revision of the old version (default: HEAD), or "
                                                          "'working-tree'")
    p.add_argument("new", nargs="?", default="working-tree",
                   help="git revision of the new version (default: the working tree's files as they are)")
    p.add_argument("--pairs", nargs="*", default=["PCH-PCH", "STP-PCH", "STP-STP"],
                   help="pair types: PCH-PCH STP-PCH STP-STP CSE-PCH CSE-STP CSE-CSE (default: the first three; none, "
                        "with --robot: the robot alone)")
    p.add_argument("--cse", type=_cse, default=CSE_FIT, help="the CSE-BV of CSE pairs, as bench table1's --cse")
    p.add_argument("--object", default="kuka_link_4", help="dataset name or mesh path (default: kuka_link_4)")
    p.add_argument("--poses", type=int, default=20000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--range", type=float, default=0.3, help="translation range (m), uniform in ±range")
    p.add_argument("--repeats", type=int, default=7, help="rounds: each block timed this many times (default 7)")
    p.add_argument("--block", type=int, default=BLOCK, help=f"poses per block (default {BLOCK})")
    p.add_argument("--per-call", type=int, default=4000, dest="per_call",
                   help="poses timed per call (Pair.cold_distance in a loop; default 4000, 0: none)")
    p.add_argument("--unsigned", dest="signed", action="store_false", help="unsigned queries (default: signed)")
    p.add_argument("--r", type=float, default=0.005, help="STP-BV small radius (m)")
    p.add_argument("--R", type=float, default=2.0, help="STP-BV big radius (m)")
    p.add_argument("--robot", default=None,
                   help="also a robot scene's cold all-pairs sweep and its coherent one along a smooth trajectory (a name "
                        "of datasets.robots, e.g. jvrc1)")
    p.add_argument("--policies", nargs="+", default=["pch", "auto"], help="the robot scene's policies (default: pch auto)")
    p.add_argument("--configs", type=int, default=1000, help="the robot's random configurations (default 1000)")
    p.add_argument("--robot-block", type=int, default=50, dest="robot_block",
                   help="configurations per timed block (default 50)")
    p.add_argument("--repo", default=".", help="the git checkout the revisions come from (default: .)")
    p.add_argument("--out", default=None, help="folder for ab.csv and ab.md (default: print only)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=_suite("ab"))

    p = sub.add_parser("continuity", help="witness-point / normal continuity and gradient check along trajectories")
    p.add_argument("--object", default="kuka_link_4", help="dataset name or mesh path (default: kuka_link_4)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=str(DEFAULT_OUT))
    p.add_argument("--quick", action="store_true", help="fewer steps and samples (a few seconds)")
    p.set_defaults(func=_suite("continuity"))

    p = sub.add_parser("stability", help="every engine on cases where distance methods are known to fail")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--engines", nargs="+", help="engine names (default: spq fcl coal bullet bullet-margin mujoco)")
    p.add_argument("--out", default=str(DEFAULT_OUT))
    p.add_argument("--quick", action="store_true", help="one pose per case and fewer sweeps (seconds)")
    p.add_argument("--generated-cases", type=int, default=10_000, metavar="N",
                   help="cases generated from the fuzz families, each one shape pair at one pose (default 10000; "
                        "0: none; with --quick: one per family)")
    p.add_argument("--quiet", action="store_true")
    _spread_arguments(p, "case")
    p.set_defaults(func=_suite("stability", generated=lambda a: a.generated_cases > 0))

    p = sub.add_parser("depth", help="spq's penetration depth against an independent oracle (STP-BV and CSE pairs)")
    p.add_argument("--object", default="kuka_link_4", help="dataset name or mesh path (default: kuka_link_4)")
    p.add_argument("--per-bucket", type=int, default=300, help="poses per overlap bucket (default 300)")
    p.add_argument("--stp-per-bucket", type=int, default=None,
                   help="poses per bucket for pairs with an STP-BV (default: --per-bucket; ~1 s a pose)")
    p.add_argument("--pairs", nargs="+", default=["STP-STP", "STP-PCH", "CSE-CSE", "CSE-PCH"])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=str(DEFAULT_OUT))
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=_suite("depth"))

    p = sub.add_parser("tradeoff", help="speed against accuracy: engines' tolerances swept on one pose suite")
    p.add_argument("--per-bucket", type=int, default=None, help="poses per separated bucket (default 200; quick 10)")
    p.add_argument("--repeats", type=int, default=None, help="rounds of timed runs, each setting's least time kept (default 5; quick 2)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=str(DEFAULT_OUT))
    p.add_argument("--quick", action="store_true", help="small run (a few seconds)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=_suite("tradeoff"))

    p = sub.add_parser("rtradeoff", help="STP-BV big radius R: features, volume excess, speed, witness smoothness")
    p.add_argument("--object", default="kuka_link_4", help="dataset name or mesh path (default: kuka_link_4)")
    p.add_argument("--r", type=float, default=0.005, help="small radius (m)")
    p.add_argument("--R-max", type=float, default=100.0, dest="R_max", help="largest R (m)")
    p.add_argument("--R-values", type=float, nargs="+", dest="R_values", help="explicit R values (m)")
    p.add_argument("--threshold-factor", type=float, default=10.0, dest="threshold_factor",
                   help="recommendation: Lipschitz ratio at most this times the smallest seen")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=str(DEFAULT_OUT))
    p.add_argument("--quick", action="store_true", help="small run (a few seconds)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=_suite("rtradeoff"))

    p = sub.add_parser("pictures", help="3-D pictures (PNG): a link's PCH/STP/CSE covers, the R trade-off as shapes, a "
                                        "robot at its closest posture, an overlapping pair's penetration vector")
    p.add_argument("--object", default="kuka_link_4", help="link of the covers and the R pictures, side A of the overlap")
    p.add_argument("--other", default="kuka_link_2", help="side B of the overlapping pair (its superellipsoid cover)")
    p.add_argument("--r", type=float, default=0.005, help="STP-BV small radius (m)")
    p.add_argument("--R", type=float, default=2.0, help="STP-BV big radius (m) of the covers and the overlap")
    p.add_argument("--R-values", type=float, nargs="+", dest="R_values", help="R values of the R picture (m)")
    p.add_argument("--robot", help="jvrc1 | kuka_iiwa | panda (default: jvrc1 with the shared data, else kuka_iiwa)")
    p.add_argument("--steps", type=int, default=1000, help="trajectory steps searched for the closest posture")
    p.add_argument("--depth", type=float, default=0.02, help="penetration depth of the overlapping pair (m)")
    p.add_argument("--tolerance", type=float, default=1e-3, help="largest mesh-to-surface distance drawn (m)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=str(DEFAULT_OUT))
    p.add_argument("--quick", action="store_true", help="shorter trajectory, coarser meshes")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=_suite("pictures"))

    p = sub.add_parser("scene", help="a robot scene from a TOML file (scenes/*.toml): every pair over its configurations")
    p.add_argument("scene", help="scene file (TOML; see scenes/ and harness/workloads/scene_file.py)")
    p.add_argument("--out", help="folder for the per-configuration and closest-posture CSVs (default: none written)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--workers", type=_workers, default=1,
                   help="cold sweeps: threads sharing each block of configurations, or with --scheduler the Dask "
                        "LocalCluster's size; results equal the serial run's (coherent sweeps stay serial)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="cold sweeps: blocks of configurations as tasks on a Dask cluster (tcp://HOST:8786, or "
                        "'local'; needs pip install \"dask[distributed]\")")
    p.set_defaults(func=cmd_scene)

    p = sub.add_parser("view", help="interactive viewer in the browser (viser): a scene file's robot with joint sliders, "
                                    "live distances and witness segments, or two shapes with a gizmo")
    p.add_argument("targets", nargs="+", metavar="TARGET",
                   help="a scene file (scenes/*.toml), or two shapes NAME[:pch|stp|cse] (dataset names or mesh paths)")
    p.add_argument("--host", default="127.0.0.1", help="address to serve on (default: this machine only)")
    p.add_argument("--port", type=int, default=8080, help="port (0: any free port)")
    p.add_argument("--tolerance", type=float, default=1e-3, help="largest mesh-to-surface distance drawn (m)")
    p.add_argument("--r", type=float, default=0.005, help="STP-BV small radius of a shape pair (m)")
    p.add_argument("--R", type=float, default=2.0, help="STP-BV big radius of a shape pair (m)")
    p.set_defaults(func=cmd_view)

    p = sub.add_parser("check", help="the gate: a fixed-seed run of every engine judged against a baseline (exit 0/1/2)")
    p.add_argument("--baseline", help="results file of an earlier run to compare with (regressions: exit 1)")
    p.add_argument("--update-baseline", metavar="FILE", help="write this run's results as the new baseline")
    p.add_argument("--out", default=str(DEFAULT_OUT), help="folder for the results file check.json (default reports)")
    p.add_argument("--junit", metavar="FILE", help="write JUnit XML: one test case per engine and check")
    p.add_argument("--history", metavar="FILE", help="append this run (commit, date, machine, metrics) to FILE")
    p.add_argument("--engines", nargs="+", help="registered engine names (default: all that import)")
    p.add_argument("--engine", action="append", metavar="[NAME=]MODULE:CLASS",
                   help="a plugin engine adapter to add (repeatable); see harness/engines/base.py")
    p.add_argument("--speed", choices=["strict", "advisory"], default="strict",
                   help="advisory: report slower speed ratios without failing")
    p.add_argument("--speed-floor", type=float, default=SPEED_FLOOR, dest="speed_floor",
                   help=f"least relative drop of a speed ratio that fails (default {SPEED_FLOOR}; noise may raise it)")
    p.add_argument("--sections", nargs="+", default=list(SECTIONS), choices=list(SECTIONS))
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--per-bucket", type=int, default=CheckConfig.per_bucket, help="PCH-PCH poses per distance bucket")
    p.add_argument("--oracle-per-bucket", type=int, default=CheckConfig.oracle_per_bucket,
                   help="poses per overlap bucket and STP/CSE pair against the depth oracle")
    p.add_argument("--speed-poses", type=int, default=CheckConfig.speed_poses)
    p.add_argument("--speed-rounds", type=int, default=CheckConfig.speed_rounds)
    p.add_argument("--peer", default="coal", help="the engine speed ratios are taken against (default coal)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("fuzz", help="a seeded, resumable campaign over adversarial shapes and poses: where each engine "
                                    "fails; spq's wrong or failed cases shrunk to reproducers")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--budget", type=float, help="seconds of this run (with or without --queries)")
    p.add_argument("--queries", type=float, help="stop once the campaign holds this many spq queries (e.g. 1e7)")
    p.add_argument("--families", nargs="+", help="families to draw from (default: all; see docs/commands/fuzz.md)")
    p.add_argument("--poses", type=int, default=2000, help="pose pairs per case (default 2000)")
    p.add_argument("--sample", type=float, default=2e-4,
                   help="share of spq's queries checked by the reference whatever the cheap checks say")
    p.add_argument("--peers", nargs="+", help="peer engines (default: coal mujoco bullet; fcl hangs on some poses)")
    p.add_argument("--state", help="campaign state file: resumed when it exists, written after every round")
    p.add_argument("--no-shrink", dest="shrink", action="store_false", help="do not shrink the failing cases")
    p.add_argument("--fixtures", help="folder for the shrunk reproducers (default tests/fixtures/fuzz)")
    p.add_argument("--plant", help="a planted bug to find (early-stop, refuse-cse)")
    p.add_argument("--out", default=str(DEFAULT_OUT))
    p.add_argument("--quiet", action="store_true")
    _spread_arguments(p, "task of cases")
    p.set_defaults(func=_suite("fuzz", queries=lambda a: None if a.queries is None else int(a.queries)))

    p = sub.add_parser("profile", help="where a bench job's time goes by compiled kernel: the job in a loop under "
                                       "Linux perf, numba's kernels named (needs perf and readelf)")
    p.add_argument("pair", nargs="?", default="STP-STP", help="two of PCH, STP, CSE joined by '-' (default STP-STP)")
    p.add_argument("--mode", choices=["batched", "per-call", "plain"], default="batched",
                   help="batched: Pair.distances, cold (default); per-call: Pair.cold_distance in a loop; plain: "
                        "spq.distance in a loop")
    p.add_argument("--unsigned", dest="signed", action="store_false", help="unsigned queries (default: signed)")
    p.add_argument("--overlaps", action="store_true", help="the overlapping poses alone")
    p.add_argument("--object", default="kuka_link_4", help="dataset name or mesh path (default: kuka_link_4)")
    p.add_argument("--poses", type=int, default=20000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--range", type=float, default=0.3, help="translation range (m), uniform in ±range")
    p.add_argument("--r", type=float, default=0.005, help="STP-BV small radius (m)")
    p.add_argument("--R", type=float, default=2.0, help="STP-BV big radius (m)")
    p.add_argument("--cse", type=_cse, default=CSE_FIT, help="the CSE-BV of CSE pairs, as bench table1's --cse")
    p.add_argument("--robot", default=None, help="a robot's cold all-pairs sweep instead of a pair (e.g. jvrc1)")
    p.add_argument("--policy", default="auto", help="the robot scene's policy (default auto)")
    p.add_argument("--coherent", action="store_true",
                   help="with --robot: its coherent sweep along a smooth trajectory of --configs steps (warm starts)")
    p.add_argument("--configs", type=int, default=1000, help="the robot's random configurations (default 1000)")
    p.add_argument("--seconds", type=float, default=10.0, help="time sampled (default 10 s)")
    p.add_argument("--frequency", type=int, default=4999, help="samples a second (default 4999)")
    p.add_argument("--top", type=int, default=25, help="rows of the functions' and hot instructions' tables (default 25)")
    p.add_argument("--annotate", nargs="+", default=[], metavar="FUNCTION",
                   help="kernels shown instruction by instruction around their --top most sampled ones (a full name "
                        "such as spq.kernels.epa.epa_run, or its last part), into profile_annotate.md")
    p.add_argument("--out", default=None, help="folder for the tables (default: print only)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_profile)

    p = sub.add_parser("srdf", help="sample a robot's collision pairs as MoveIt's setup assistant does; write an SRDF")
    p.add_argument("urdf", help="URDF file, or a robot of datasets/robots.py by name (jvrc1 uses its convex hulls)")
    p.add_argument("--out", required=True, help="SRDF file to write")
    p.add_argument("--samples", type=int, default=10000, help="random configurations of the 'Never' test")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--always-fraction", type=float, default=0.95,
                   help="share of a 200-configuration round above which a pair is 'Always' in collision")
    p.add_argument("--convex-dir", help="folder of qhull hulls NAME-ch.txt per mesh NAME.ext (JVRC-1's convex/)")
    p.add_argument("--mesh-root", help="folder that package:// mesh filenames resolve against")
    p.add_argument("--policy", default="pch", help="bounding volume deciding collisions (default pch: the hulls)")
    p.add_argument("--name", help="robot name written into the SRDF (default: the URDF's)")
    p.set_defaults(func=cmd_srdf)

    p = sub.add_parser("history", help="chart accuracy and speed ratios over the runs of a check history file")
    p.add_argument("history", help="history file written by spq check --history")
    p.add_argument("--out", default=str(DEFAULT_OUT / "check_history.png"))
    p.set_defaults(func=cmd_history)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ValueError as exc:
        print(f"spq {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
