"""The continuity suite: witness-point and normal Lipschitz ratios and the analytic gradient along
trajectories (witness_continuity.py, beside this entry), and the signed distance through contact
(contact_continuity.py)."""

from __future__ import annotations

import time
from dataclasses import dataclass

from harness.suites import Figure, Output, Table, frame_lines


@dataclass
class Config:
    object: str = "kuka_link_4"  # dataset name or mesh path
    seed: int = 0
    quick: bool = False  # fewer steps and samples
    progress: bool = False


def run(config: Config) -> Output:
    from datasets import load_object
    from harness.report.meta import run_metadata
    from harness.suites.continuity import contact_continuity as cc
    from harness.suites.continuity import witness_continuity as ct

    start = time.perf_counter()
    obj = config.object
    cfg = ct.quick_config(obj, config.seed) if config.quick else ct.ContinuityConfig(object_name=obj,
                                                                                     seed=config.seed)
    table, paths = ct.run(cfg, load_object)
    summary = ct.growth(table)
    # seconds: the continuity part only, as the command has always recorded it
    meta = run_metadata(command="spq continuity", object=obj, seed=config.seed, quick=bool(config.quick),
                        stp_r=cfg.r, stp_R=cfg.R, spq_tol_abs=ct.TOL["tol"], spq_tol_rel=ct.TOL["rel_tol"],
                        steps_s=list(cfg.steps), grid=cfg.grid, fd_step_s=cfg.fd_step,
                        theta_max_rad=cfg.theta_max, gap_m=cfg.gap,
                        seconds=round(time.perf_counter() - start, 1))
    notes = (f"Two copies of {obj}; A fixed, B moving along a trajectory s in [0, 1] "
             "(see harness/suites/continuity/witness_continuity.py). "
             "witness_lipschitz = max |p(s+h) - p(s)| / step over the witness points of A and B (world frame), "
             "normal_lipschitz the same for the unit normal; step = h converted to rad (parallel_faces: B rotates "
             f"about an in-plane axis through a face-to-face parallel configuration, ±{cfg.theta_max} rad), "
             "m (edge_slide: B translates parallel to A's longest hull edge) or kept in s (random_path: Fourier modes "
             "in translation and rotation). Sample points: a uniform grid plus points straddling the largest witness "
             "jumps (located by bisection). grad_abs_error / grad_rel_error: analytic dd/ds (spq.distance_gradients "
             "along B's twist) against a central difference of the distance (step "
             f"{cfg.fd_step:g} in s, spq tolerance 1e-13), max over {cfg.gradient_samples} s values, in m per "
             "unit s and relative to max(|dd/ds|, 1); NaN for external engines (their tolerance is too loose). "
             f"STP-BV r = {cfg.r} m, R = {cfg.R} m; CSE-BV by Superellipsoid.fit; B is shifted by shift_m along "
             "the separation direction so each pair keeps the gap of the hulls.")
    out = Output(meta=meta, tables=[
        Table("continuity", "Continuity of witness points and gradients", table, notes),
        Table("continuity_summary", "Continuity: witness Lipschitz ratio at the largest and smallest steps", summary,
              "growth = ratio at the smallest step / ratio at the largest step "
              "(~ largest/smallest step for a jump, ~1 for a Lipschitz witness).")])
    out.figures += [
        Figure("continuity_lipschitz.png", lambda path: ct.plot_lipschitz(
            table, path, f"Witness-point Lipschitz ratio vs step ({obj}, STP r={cfg.r} m, R={cfg.R} m)")),
        Figure("continuity_witness_paths.png", lambda path: ct.plot_paths(
            paths, path, f"parallel_faces ({obj}): witness point on B along the sweep"))]
    out.lines += frame_lines(summary)

    contact_config = cc.ContactConfig(object_name=obj, r=cfg.r, R=cfg.R, seed=config.seed,
                                      grid=201 if config.quick else 401)
    contact, curves = cc.run(contact_config, load_object, progress=config.progress)
    contact_summary = cc.summary(contact)
    contact_notes = (f"Signed distance (spq, signed=True, tolerance {cc.TOL['tol']:g}) along {contact_config.paths} "
                     f"seeded paths per pair that enter and leave contact (B turns {contact_config.turn} rad while "
                     f"crossing A, from {contact_config.gap} m apart to about {contact_config.depth} m deep and out; "
                     "harness/suites/continuity/contact_continuity.py), on a grid of "
                     f"{contact_config.grid} points. max_crossing_jump_m: |sd| difference left after {cc.BISECTIONS} "
                     "bisections of each sign change (a jump at contact would stay). gradient_jumps: of B's 6-vector "
                     f"gradient, the {cc.JUMP_CANDIDATES} largest relative changes per path bisected "
                     f"{contact_config.gradient_bisections} times; a jump keeps over {cc.JUMP_RESIDUAL} of its change; "
                     "in_contact: at a step where sd < 0; deeper_than_r: where the depth exceeds the STP-BV's "
                     f"small radius r = {cfg.r} m (below it the depth of a pair with an STP-BV is C1; deeper, the "
                     "nearest boundary point of the Minkowski difference can switch, for any bodies).")
    out.tables += [Table("contact_continuity", "Continuity through contact, per path", contact, contact_notes),
                   Table("contact_continuity_summary", "Continuity through contact", contact_summary, contact_notes)]
    out.figures.append(Figure("contact_continuity.png", lambda path: cc.plot(
        curves, path, f"Through contact ({obj}): signed distance and gradient along one path per pair")))
    out.lines += frame_lines(contact_summary)
    return out
