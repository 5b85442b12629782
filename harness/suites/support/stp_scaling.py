"""Support-function scaling (the paper's Fig. 6 and 7): time per STP-BV support call against the
feature count, for the naive scan, the guided march and the hull-accelerated search, cold and warm.

The feature count is varied, as in the paper, by changing R on one link: from just above the smallest
admissible R (a few patches: the hull is nearly the enclosing sphere) to R hundreds of times larger
(flat big spheres: nearly every hull vertex, edge and face becomes a patch). Cold calls take uniformly random
directions with no warm start; warm calls follow a smooth path of directions, each call starting
from the previous call's patch (temporal coherence).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import pandas as pd

from harness.report.charts import save_figure
from spq.kernels.stp_batch import support_batch
from spq.kernels.stp_support import METHOD_NAMES
from spq.shapes.stpbv import STPBV


@dataclass
class ScalingConfig:
    object_name: str = "kuka_link_1"
    r: float = 0.005
    R_values: tuple | None = None  # metres; None: R_FACTORS times the smallest admissible R - r, plus r
    R_factors: tuple = (1.0001, 1.001, 1.01, 1.03, 1.1, 1.3, 2.0, 4.0, 10.0, 50.0, 300.0)
    directions: int = 20000
    seed: int = 0
    repeats: int = 3


def smooth_directions(n: int, seed: int) -> np.ndarray:
    """(n, 3) unit directions along a smooth closed path over the sphere (about 0.01 rad per step)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    k1, k2 = rng.uniform(1.0, 3.0, size=2)
    d = np.stack([np.cos(t * k1) * np.cos(3 * t), np.sin(t * k1) * np.cos(3 * t), np.sin(t * k2 + 0.3)], axis=1)
    return d / np.linalg.norm(d, axis=1)[:, None]


def _time_per_call(stp: STPBV, method: int, dirs: np.ndarray, coherent: bool, repeats: int) -> tuple[float, float]:
    kd = stp.kernel_data()
    support_batch(kd.fdata, kd.idata, method, dirs[:4], coherent)  # compile / warm caches
    best = np.inf
    steps = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        _, _, steps = support_batch(kd.fdata, kd.idata, method, dirs, coherent)
        best = min(best, time.perf_counter() - t0)
    return best / len(dirs), float(np.mean(steps))


def run(config: ScalingConfig, load_points, progress: bool = True) -> pd.DataFrame:
    """One row per (R, method, mode): feature counts, ns per support call, mean search steps."""
    from tqdm import tqdm

    from spq.stp.construction import enclosing_radius

    points = load_points(config.object_name)
    R_values = config.R_values or tuple(config.r + enclosing_radius(points) * f for f in config.R_factors)
    rng = np.random.default_rng(config.seed)
    cold = rng.normal(size=(config.directions, 3))
    warm = smooth_directions(config.directions, config.seed)
    rows = []
    for R in tqdm(R_values, desc="support scaling", unit="R", disable=not progress):
        try:
            stp = STPBV.from_points(points, config.r, R)
        except ValueError as exc:  # R below the cloud's feasibility bound
            print(f"skipping R = {R}: {exc}")
            continue
        for m, name in enumerate(METHOD_NAMES):
            for mode, dirs, coherent in (("cold", cold, False), ("warm", warm, True)):
                seconds, steps = _time_per_call(stp, m, dirs, coherent, config.repeats)
                rows.append({"object": config.object_name, "points": len(points), "r": config.r, "R": R,
                             "features": stp.n_patches, "small_spheres": stp.n_small, "big_spheres": stp.n_big,
                             "tori": stp.n_tori, "method": name, "mode": mode, "ns_per_call": seconds * 1e9,
                             "mean_steps": steps})
    return pd.DataFrame(rows)


def loglog_slopes(table: pd.DataFrame) -> pd.DataFrame:
    """Least-squares slope of log(time) against log(features) per method and mode (1 = linear)."""
    out = []
    for (method, mode), g in table.groupby(["method", "mode"], sort=False):
        if len(g) >= 2:
            slope = np.polyfit(np.log(g.features), np.log(g.ns_per_call), 1)[0]
            out.append({"method": method, "mode": mode, "loglog_slope": slope})
    return pd.DataFrame(out)


def plot(table: pd.DataFrame, path) -> None:
    """Chart: ns per support call against feature count, log-log, one line per method and mode."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    styles = {"naive": "tab:red", "march": "tab:blue", "hull": "tab:green"}
    for (method, mode), g in table.groupby(["method", "mode"], sort=False):
        g = g.sort_values("features")
        ax.plot(g.features, g.ns_per_call, marker="o", color=styles[method],
                linestyle="-" if mode == "cold" else "--", label=f"{method}, {mode}")
    f = np.array(sorted(table.features.unique()), dtype=float)
    naive = table[(table.method == "naive") & (table["mode"] == "cold")].sort_values("features")
    march = table[(table.method == "march") & (table["mode"] == "cold")].sort_values("features")
    if len(f) >= 2 and len(naive) and len(march):
        ax.plot(f, naive.ns_per_call.iloc[0] * f / f[0], color="grey", linewidth=0.8, label="∝ n (reference)")
        ax.plot(f, march.ns_per_call.iloc[0] * np.sqrt(f / f[0]), color="grey", linestyle=":", linewidth=1.0,
                label="∝ √n (reference)")
    obj = table.object.iloc[0]
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("STP-BV feature count n (small + big spheres + tori)")
    ax.set_ylabel("time per support call (ns)")
    ax.set_title(f"STP-BV support scaling on {obj} ({table.points.iloc[0]} points, r = {table.r.iloc[0]} m, R varied)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    save_figure(fig, path)
