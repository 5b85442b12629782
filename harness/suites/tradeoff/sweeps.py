"""Trade-offs: speed against accuracy (``spq tradeoff``) and the STP-BV big radius R (``spq rtradeoff``).

``tradeoff``: one suite of distance-controlled, separated poses for two links, with exact reference
distances (:func:`harness.workloads.poses.bucket_suite`). The engines that expose a tolerance (spq: ``tol`` =
``rel_tol``; coal: ``gjk_tolerance``; MuJoCo: ``ccd_tolerance``) are swept; every setting is timed on
the same poses, side by side with the others (:func:`harness.suites.bench.timing.blocked_times`:
``repeats`` rounds, each setting's least time per block kept), and its distances compared to the
reference (max and median absolute error). python-fcl and pybullet (margin 0 and its default margin)
run once each at their own settings.

``rtradeoff``: one link's hull vertices covered by STP-BVs at a fixed small radius r and a sweep of R
from just above the smallest admissible R (r + radius of the smallest enclosing ball) upwards. Per R:
the feature count (patches), the volume excess over the hull (Monte Carlo), the STP-PCH batched
queries per second on random poses (every R timed side by side, as above), and the witness-point
Lipschitz ratio of the STP-PCH pair on :mod:`harness.suites.continuity.witness_continuity`'s
parallel-face trajectory at one small step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

import spq
from harness.report.charts import save_figure
from harness.suites.bench.throughput import timing_modes
from harness.suites.bench.timing import blocked_calls, blocked_times

SEPARATED_BUCKETS = ("distant-1", "distant-0.5", "close-1e-1", "close-1e-2", "close-1e-3", "close-1e-4")
FAIL_DISTANCE = 1e6  # m: |distance| above this is a failure (coal can return -DBL_MAX on a separated pose)
ZERO_CLIP = 1e-17  # m: errors of exactly 0 are drawn here on the log axes


# --------------------------------------------------------------------------------------------------
# speed against accuracy
# --------------------------------------------------------------------------------------------------
@dataclass
class TradeoffConfig:
    object_a: str = "kuka_link_4"
    object_b: str = "kuka_link_2"
    per_bucket: int = 200
    seed: int = 0
    buckets: tuple = SEPARATED_BUCKETS
    spq_tols: tuple = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-8, 1e-10, 1e-12)
    coal_tols: tuple = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-8, 1e-10)
    mujoco_tols: tuple = (1e-2, 1e-3, 1e-4, 1e-6, 1e-8, 1e-10)  # ccd_tolerance; empty or no mujoco: none
    others: tuple = ("fcl", "bullet", "bullet-margin")
    repeats: int = 5


def quick_tradeoff_config(seed: int = 0, **overrides) -> TradeoffConfig:
    """A few seconds: 10 poses per bucket, three tolerances per engine, two repeats."""
    settings = dict(seed=seed, per_bucket=10, spq_tols=(1e-2, 1e-3, 1e-6, 1e-10), coal_tols=(1e-3, 1e-6, 1e-10),
                    mujoco_tols=(1e-3, 1e-6, 1e-10), repeats=2)
    settings.update(overrides)
    return TradeoffConfig(**settings)


def _scores(dist, suite, seconds: float) -> dict:
    """Speed and errors of one setting's distances against the suite's reference."""
    dist = np.asarray(dist, dtype=float)
    failed = ~np.isfinite(dist) | (np.abs(dist) > FAIL_DISTANCE)
    err = np.abs(dist - suite.ref_distance)
    err_all = np.where(failed, np.inf, err)
    ok = err[~failed]
    n = len(dist)
    return {"queries": n, "seconds": seconds, "queries_per_s": n / seconds,
            "max_abs_error": float(ok.max()) if len(ok) else np.nan,
            "median_abs_error": float(np.median(err_all)),
            "mean_abs_error": float(ok.mean()) if len(ok) else np.nan,
            "zero_error_fraction": float(np.mean(err_all == 0.0)),
            "failures": int(failed.sum())}


def run_tradeoff(config: TradeoffConfig, load_object, progress: bool = False):
    """(table with one row per engine, mode and tolerance; the pose suite)."""
    import importlib.util

    from tqdm import tqdm

    from harness.engines import available_engines
    from harness.engines.coal_engine import CoalEngine
    from harness.engines.spq_engine import SpqEngine
    from harness.workloads.poses import bucket_suite

    a, b = load_object(config.object_a), load_object(config.object_b)
    suite = bucket_suite(a, b, config.per_bucket, config.seed, buckets=list(config.buckets))
    settings = [("spq", t) for t in config.spq_tols] + [("coal", t) for t in config.coal_tols]
    if config.mujoco_tols and importlib.util.find_spec("mujoco") is not None:
        settings += [("mujoco", t) for t in config.mujoco_tols]
    settings += [(name, None) for name in config.others]
    others = available_engines(list(config.others)) if config.others else {}
    pa, pb = suite.pose_a, suite.pose_b
    prepared, timed_jobs = [], {}
    try:
        for name, tol in settings:
            if name == "spq":
                engine = SpqEngine(tol=tol, rel_tol=tol)
            elif name == "coal":
                engine = CoalEngine(tolerance=tol)
            elif name == "mujoco":
                from harness.engines.mujoco_engine import MujocoEngine

                engine = MujocoEngine(tolerance=tol)
            else:
                engine = others[name]
            pair = engine.prepare(a, b)
            prepared.append(pair)
            for mode, fn in timing_modes(pair):
                fn(pa[:8], pb[:8])  # warm-up: compiled code loaded, first-call costs paid
                timed_jobs[(name, tol, mode)] = (fn, pa, pb)
        # every setting side by side, block by block, so that a shared machine's slow spell falls on all alike
        with tqdm(total=blocked_calls(timed_jobs, config.repeats), desc="tradeoff", unit="run",
                  disable=not progress) as bar:
            timed = blocked_times(timed_jobs, config.repeats, progress=bar)
    finally:
        for pair in prepared:
            pair.close()
        for engine in others.values():
            engine.close()
    rows = [{"engine": name, "mode": mode, "tolerance": tol if tol is not None else np.nan,
             "rel_tol": tol if name == "spq" else np.nan, "swept": tol is not None,
             **_scores(np.concatenate([np.asarray(d, dtype=float) for d in blocks]), suite, seconds)}
            for (name, tol, mode), (seconds, blocks) in timed.items()]
    table = pd.DataFrame(rows)
    table["pareto_max"] = pareto_front(table.queries_per_s, table.max_abs_error.where(table.failures == 0, np.inf))
    table["pareto_median"] = pareto_front(table.queries_per_s, table.median_abs_error)
    table.insert(0, "pair", f"{config.object_a}|{config.object_b}")
    table["seed"] = config.seed
    return table, suite


def pareto_front(speed, error) -> np.ndarray:
    """True where no other point is at least as fast and at least as accurate, and strictly better in
    one of the two (higher speed, lower error). Non-finite errors are never on the front."""
    speed, error = np.asarray(speed, dtype=float), np.asarray(error, dtype=float)
    out = np.zeros(len(speed), dtype=bool)
    for i in range(len(speed)):
        if not np.isfinite(error[i]):
            continue
        dominated = (speed >= speed[i]) & (error <= error[i]) & ((speed > speed[i]) | (error < error[i]))
        out[i] = not dominated.any()
    return out


def plot_tradeoff(table: pd.DataFrame, path, title: str = "") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(13, 5.2))
    panels = [("max_abs_error", "pareto_max", "max |error| (m)"), ("median_abs_error", "pareto_median",
                                                                       "median |error| (m)")]
    for ax, (col, front_col, label) in zip(axes, panels):
        x_all = np.clip(table[col].to_numpy(dtype=float), ZERO_CLIP, None)
        for (engine, mode), g in table.groupby(["engine", "mode"], sort=False):
            x = np.clip(g[col].to_numpy(dtype=float), ZERO_CLIP, None)
            y = g.queries_per_s.to_numpy()
            lab = f"{engine} ({mode})"
            if g.swept.iloc[0]:
                order = np.argsort(g.tolerance.to_numpy())
                line, = ax.plot(x[order], y[order], marker="o", label=lab + ", tol swept")
                for xi, yi, t in zip(x, y, g.tolerance):
                    ax.annotate(f"{t:.0e}", (xi, yi), textcoords="offset points", xytext=(3, 4), fontsize=6,
                                color=line.get_color())
            else:
                ax.plot(x, y, marker="s", markersize=8, linestyle="none", label=lab)
            bad = g.failures.to_numpy() > 0
            if bad.any():
                ax.plot(x[bad], y[bad], marker="o", markersize=13, markerfacecolor="none", markeredgecolor="red",
                        linestyle="none")
                for xi, yi, nf in zip(x[bad], y[bad], g.failures.to_numpy()[bad]):
                    ax.annotate(f"{nf} failed", (xi, yi), textcoords="offset points", xytext=(4, -10), fontsize=6,
                                color="red")
        front = table[front_col].to_numpy()
        fx, fy = x_all[front], table.queries_per_s.to_numpy()[front]
        order = np.argsort(fx)
        ax.step(fx[order], fy[order], where="post", color="black", linewidth=0.8, linestyle=":")
        ax.plot(fx, fy, marker="*", markersize=14, markerfacecolor="none", markeredgecolor="black", linestyle="none",
                label="Pareto front")
        ax.axvline(ZERO_CLIP, color="grey", linewidth=0.6, linestyle="--")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(f"{label} against the exact reference (exact 0 drawn at {ZERO_CLIP:g})")
        ax.set_ylabel("throughput (queries/s)")
        ax.set_title(f"queries/s against {label.split(' (')[0]}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    save_figure(fig, path, title)


# --------------------------------------------------------------------------------------------------
# the STP-BV big radius R
# --------------------------------------------------------------------------------------------------
@dataclass
class RTradeoffConfig:
    object_name: str = "kuka_link_4"
    r: float = 0.005  # m
    R_values: tuple | None = None  # m; default: R_min + logspace(min_excess, R_max - R_min, n_R)
    n_R: int = 8
    R_max: float = 100.0  # m
    min_excess: float = 1e-3  # m above the smallest admissible R
    poses: int = 20000
    translation_range: float = 0.3  # m
    volume_samples: int = 100000
    seed: int = 0
    repeats: int = 3
    step: float = 1e-4  # in s of the parallel_faces trajectory (converted to rad in the table)
    grid: int = 201
    locate_grid: int = 1001
    jumps: int = 2
    threshold_factor: float = 10.0  # recommendation: Lipschitz ratio <= factor * smallest ratio seen


def quick_rtradeoff_config(object_name: str = "kuka_link_4", seed: int = 0, **overrides) -> RTradeoffConfig:
    settings = dict(object_name=object_name, seed=seed, n_R=4, poses=2000, volume_samples=20000, repeats=2,
                    grid=41, locate_grid=201, jumps=1)
    settings.update(overrides)
    return RTradeoffConfig(**settings)


def r_values(points, config: RTradeoffConfig) -> tuple[float, np.ndarray]:
    """(smallest admissible R, the R values swept), in metres."""
    from spq.stp.construction import enclosing_radius

    R_min = config.r + enclosing_radius(points)
    if config.R_values:
        return R_min, np.asarray(config.R_values, dtype=float)
    return R_min, R_min + np.logspace(np.log10(config.min_excess), np.log10(config.R_max - R_min), config.n_R)


def stp_lipschitz(stp, link, config: RTradeoffConfig) -> tuple[float, float, float]:
    """Witness-point Lipschitz ratio (m/rad) of STP-PCH on the parallel_faces trajectory at one step,
    the step in rad, and the smallest distance seen on the path (m)."""
    from harness.suites.continuity import witness_continuity as ct

    cfg = ct.ContinuityConfig(object_name="", r=stp.r, R=stp.R, seed=config.seed, steps=(config.step,),
                              grid=config.grid, locate_grid=config.locate_grid, jumps=config.jumps)
    A, B = ct.Body("STP", stp, np.eye(4)), ct.Body("PCH", link, np.eye(4))
    traj = ct.make_trajectory("parallel_faces", link, cfg)
    q = ct.PairQuery(A, B, traj, ct.pair_shift(A, B, traj, link))
    jumps = ct.locate_jumps(q, cfg.jumps, cfg.locate_grid)
    h = config.step
    base = np.linspace(0.0, 1.0 - h, cfg.grid)
    extra = [j - h * f for j in jumps for f in (0.25, 0.5, 0.75)]
    s = np.clip(np.concatenate([base, extra]), 0.0, 1.0 - h)
    dp, _, ok = ct._witness_step(q, s, h)
    step = h * traj.scale
    dist = q.query(base)[0]
    return (float(np.max(dp[ok]) / step) if ok.any() else np.nan), step, float(np.nanmin(dist))


def run_rtradeoff(config: RTradeoffConfig, load_object, progress: bool = False) -> tuple[pd.DataFrame, dict]:
    """(one row per R; facts about the link: R_min, hull volume, points)."""
    from scipy.spatial import ConvexHull
    from tqdm import tqdm

    from harness.suites.table1.bv_rates import monte_carlo_volume
    from harness.workloads.poses import random_poses

    link = load_object(config.object_name)
    points = link.vertices
    hull_volume = float(ConvexHull(points).volume)
    R_min, Rs = r_values(points, config)
    poses_a, poses_b = random_poses(config.poses, config.seed, config.translation_range)
    stps = [spq.STPBV.from_points(points, config.r, float(R)) for R in tqdm(Rs, desc="rtradeoff: STP-BVs", unit="R",
                                                                             disable=not progress)]
    jobs = {}
    for i, stp in enumerate(stps):
        spq.distances(stp, link, poses_a[:8], poses_b[:8])  # warm-up
        jobs[i] = (lambda pa, pb, stp=stp: spq.distances(stp, link, pa, pb), poses_a, poses_b)
    # every R side by side, block by block, so that a shared machine's slow spell falls on all alike
    with tqdm(total=blocked_calls(jobs, config.repeats), desc="rtradeoff: speed", unit="run",
              disable=not progress) as bar:
        timed = blocked_times(jobs, config.repeats, progress=bar)
    rows = []
    for i, (R, stp) in enumerate(tqdm(list(zip(Rs, stps)), desc="rtradeoff: volume, smoothness", unit="R",
                                      disable=not progress)):
        seconds, blocks = timed[i]
        volume = monte_carlo_volume(stp, config.volume_samples, config.seed)
        ratio, step, min_dist = stp_lipschitz(stp, link, config)
        rows.append({"R": float(R), "R_minus_R_min": float(R - R_min), "features": int(stp.n_patches),
                     "volume_m3": volume, "volume_excess": volume / hull_volume - 1.0,
                     "queries_per_s": config.poses / seconds,
                     "overlapping": int(sum(np.sum(res.status == "overlapping") for res in blocks)),
                     "witness_lipschitz": ratio, "step_rad": step, "min_distance_m": min_dist})
    table = pd.DataFrame(rows)
    table.insert(0, "object", config.object_name)
    table.insert(1, "r", config.r)
    facts = {"R_min": R_min, "hull_volume": hull_volume, "points": len(points)}
    return table, facts


def recommend(table: pd.DataFrame, factor: float) -> tuple[pd.Series | None, str]:
    """The rule: among the R whose Lipschitz ratio is at most ``factor`` times the smallest ratio seen,
    take the one with the smallest volume excess (the tightest cover that stays smooth); ties go to the
    fewer features. Returns (that row, a paragraph written from the measured numbers)."""
    finite = table[np.isfinite(table.witness_lipschitz)]
    if not len(finite):
        return None, "No Lipschitz ratio could be measured (no separated samples); no recommendation."
    best_ratio = float(finite.witness_lipschitz.min())
    threshold = factor * best_ratio
    ok = finite[finite.witness_lipschitz <= threshold]
    pick = ok.sort_values(["volume_excess", "features"]).iloc[0]
    fastest = table.loc[table.queries_per_s.idxmax()]
    tightest = table.loc[table.volume_excess.idxmin()]
    rejected = finite[finite.witness_lipschitz > threshold]
    text = (
        f"Rule: keep the R values whose witness-point Lipschitz ratio is at most {factor:g}x the smallest ratio "
        f"measured ({best_ratio:.3g} m/rad, so at most {threshold:.3g} m/rad), and among them take the one with the "
        f"smallest volume excess over the hull. Recommendation: R = {pick.R:.4g} m (R - R_min = "
        f"{pick.R_minus_R_min:.3g} m): {int(pick.features)} patches, volume excess {100 * pick.volume_excess:.2f} %, "
        f"{pick.queries_per_s:,.0f} STP-PCH queries/s, Lipschitz ratio {pick.witness_lipschitz:.3g} m/rad. "
        f"The fastest R measured ({fastest.R:.4g} m) gives {fastest.queries_per_s:,.0f} queries/s "
        f"({pick.queries_per_s / fastest.queries_per_s:.2f}x of it kept) with {int(fastest.features)} patches and "
        f"{100 * fastest.volume_excess:.2f} % excess; the tightest ({tightest.R:.4g} m) reaches "
        f"{100 * tightest.volume_excess:.2f} % excess but a Lipschitz ratio of {tightest.witness_lipschitz:.3g} m/rad. "
    )
    if len(rejected):
        text += (f"{len(rejected)} of {len(finite)} R values exceed the threshold (from R = "
                 f"{rejected.R.min():.4g} m up): there the patches flatten towards the hull's faces and the witness point "
                 f"moves up to {finite.witness_lipschitz.max():.3g} m per radian of rotation.")
    else:
        text += "No R value measured exceeds the threshold; a larger R_max would show where smoothness is lost."
    return pick, text


def plot_rtradeoff(table: pd.DataFrame, path, facts: dict, pick=None, title: str = "") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [("features", "feature count (patches)", False), ("volume_excess", "volume excess over the hull (%)", False),
              ("queries_per_s", "STP-PCH batched (queries/s)", False),
              ("witness_lipschitz", "witness Lipschitz ratio (m/rad)", True)]
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), sharex=True)
    for ax, (col, label, logy) in zip(axes.ravel(), panels):
        y = table[col] * (100.0 if col == "volume_excess" else 1.0)
        ax.plot(table.R, y, marker="o")
        if pick is not None:
            ax.plot([pick.R], [pick[col] * (100.0 if col == "volume_excess" else 1.0)], marker="*", markersize=15,
                    color="red", linestyle="none", label="recommended R")
            ax.legend(fontsize=7)
        ax.axvline(facts["R_min"], color="grey", linestyle=":", linewidth=0.8)
        ax.set_xscale("log")
        if logy:
            ax.set_yscale("log")
        ax.set_ylabel(label)
        ax.set_xlabel("big radius R (m, log; dotted: smallest admissible R)")
        ax.set_title(label.split(" (")[0])
        ax.grid(True, which="both", alpha=0.3)
    save_figure(fig, path, title)
