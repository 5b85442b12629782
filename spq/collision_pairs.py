"""Which pairs of a robot's links a collision checker should query, as the field decides it.

MoveIt's setup assistant (``compute_default_collisions``) disables a pair of links (both with
collision geometry) for one of four reasons, tried in this order, a pair keeping the first:

- ``Adjacent``: joined by a joint, or by a chain of joints through links without geometry (a link
  without geometry is removed from the link graph and its neighbours are joined to each other);
- ``Default``: in collision at the default configuration (each joint at 0, or at the middle of its
  limits when 0 is outside them);
- ``Always``: in collision in more than ``always_fraction`` (0.95) of a round of 200 random
  configurations; rounds repeat, each with fresh configurations, until one disables no new pair;
- ``Never``: in collision in none of the random configurations drawn (the Always rounds and then
  ``samples`` more, 10000 by default).

:func:`disabled_pairs_by_sampling` applies these rules to an spq :class:`~spq.scene.Scene`: random
configurations are uniform within the joint limits (continuous joints in [-pi, pi]); a pair of
links is in collision when one pair of their bodies is (GJK status 'touching' or 'overlapping', a
distance <= 0, or a failed query, counted as a collision so that it never makes a pair 'Never').
Bodies are the scene's hulls, primitives or other volumes, so the verdicts are the scene's own.

'Never' speaks of uniformly random configurations only: a pair that meets in rare postures is
disabled by it although a task that drives the two links together makes them collide (JVRC-1, 100000
samples: the fingers of the two hands, a hand and the other elbow; such pairs collide in about 1 of
20000 fresh random configurations). A controller whose tasks bring links together can keep them by
leaving out the 'Never' entries (``[p for p in pairs if p[2] != NEVER]``); more samples disable fewer.

:func:`skip_pairs` maps link pairs (from an SRDF, :func:`spq.io.srdf.read_srdf`, or from the
sampling) onto the body-name pairs that ``Scene(..., skip=...)`` takes: a link may carry several
bodies (``LINK#k``), and a link without bodies is passed over.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from spq.kernels.gjk import FAILED, OUT_DISTANCE, OUT_SIZE, OUT_STATUS, OVERLAPPING, TOUCHING

ADJACENT, DEFAULT, ALWAYS, NEVER = "Adjacent", "Default", "Always", "Never"  # MoveIt's reason strings
REASONS = (ADJACENT, DEFAULT, ALWAYS, NEVER)
DEFAULT_SAMPLES = 10000  # random configurations of the 'never in collision' test (the setup assistant's default)
ALWAYS_ROUND = 200  # random configurations per round of the 'always in collision' test (MoveIt's round size)
DEFAULT_ALWAYS_FRACTION = 0.95  # a pair in collision in more than this share of a round is 'Always' (MoveIt's)
SEPARATION_PRUNE_M = 1e-9  # m: a pair whose bounding spheres are farther apart is separated, with no GJK query
BLOCK = 256  # configurations per compiled call: bounds the result array (BLOCK x pairs x OUT_SIZE float64)


def default_configuration(model) -> np.ndarray:
    """MoveIt's default state as a joint vector (ndof,): 0 for a joint whose limits hold 0, else the
    middle of its limits (radians or metres)."""
    lower, upper = np.asarray(model.lower, dtype=float), np.asarray(model.upper, dtype=float)
    return np.where((lower <= 0.0) & (upper >= 0.0), 0.0, 0.5 * (lower + upper))


def adjacent_links(parent, has_geometry) -> set[tuple[int, int]]:
    """Pairs (i, j), i < j, of links with geometry that MoveIt calls adjacent: joined by one joint,
    or by a chain of joints whose inner links all lack geometry.

    parent: (nlinks,) parent link index per link (-1 for the root); has_geometry: the link indices
    that carry geometry."""
    parent = np.asarray(parent, dtype=np.int64)
    geometry = {int(g) for g in has_geometry}
    neighbours = defaultdict(set)
    for child, par in enumerate(parent):
        if par >= 0:
            neighbours[child].add(int(par))
            neighbours[int(par)].add(child)
    out = set()
    for start in geometry:
        stack, visited = list(neighbours[start]), {start}
        while stack:
            link = stack.pop()
            if link in visited:
                continue
            visited.add(link)
            if link in geometry:
                out.add((min(start, link), max(start, link)))
            else:  # a link without geometry passes the connection on
                stack.extend(neighbours[link] - visited)
    return out


def _check_scene_pairs(scene, lp_index: dict, adjacent: set) -> np.ndarray:
    """Per queried pair of the scene, its link pair's index (-1: bodies on one link, or an obstacle).
    ValueError if a pair of bodies on non-adjacent links is not queried (its verdict would be missing)."""
    per_link = defaultdict(int)
    for b in scene.bodies:
        if b.link >= 0:
            per_link[b.link] += 1
    lp = np.full(len(scene.pairs), -1, dtype=np.int64)
    queried = np.zeros(len(lp_index), dtype=np.int64)
    for p, (a, b) in enumerate(scene.pairs):
        la, lb = scene.bodies[a].link, scene.bodies[b].link
        if la < 0 or lb < 0 or la == lb:
            continue
        lp[p] = lp_index[(min(la, lb), max(la, lb))]
        queried[lp[p]] += 1
    names = scene.model.link_names
    for (i, j), k in lp_index.items():
        if (i, j) not in adjacent and queried[k] < per_link[i] * per_link[j]:
            raise ValueError(f"the scene does not query every pair of bodies on links {names[i]!r} and {names[j]!r}; "
                             "build it with skip_adjacent=False and no skip (e.g. Scene.from_urdf(..., "
                             "skip_adjacent=False)) so that every pair's collisions can be sampled")
    return lp


def _link_collisions(scene, qs: np.ndarray, lp: np.ndarray, nlp: int) -> np.ndarray:
    """(N, nlp) bool: whether each link pair is in collision at each configuration of qs (N, ndof)."""
    member = np.zeros((len(lp), nlp), dtype=np.float32)  # queried pair -> its link pair
    rows = np.flatnonzero(lp >= 0)
    member[rows, lp[rows]] = 1.0
    out = np.zeros((len(qs), nlp), dtype=bool)
    buffer = np.empty((min(BLOCK, len(qs)), len(lp), OUT_SIZE))
    for start in range(0, len(qs), BLOCK):
        block = qs[start:start + BLOCK]
        res = scene.distances_many(block, coherent=False, prune=SEPARATION_PRUNE_M, out=buffer[:len(block)])
        status = res[:, :, OUT_STATUS]
        hit = (status == TOUCHING) | (status == OVERLAPPING) | (status == FAILED) | (res[:, :, OUT_DISTANCE] <= 0.0)
        out[start:start + len(block)] = (hit.astype(np.float32) @ member) > 0.0
    return out


def disabled_pairs_by_sampling(scene, samples: int = DEFAULT_SAMPLES, seed: int = 0,
                               always_fraction: float = DEFAULT_ALWAYS_FRACTION,
                               include_never: bool = True) -> list[tuple[str, str, str]]:
    """The link pairs MoveIt's setup assistant would disable for the robot of ``scene``, by its rules
    (module docstring), as (link1, link2, reason) with link1 < link2, sorted; reason one of REASONS.

    scene: an spq Scene that queries every pair of bodies on non-adjacent links (build it with
    ``skip_adjacent=False`` and no ``skip``); its volumes (PCH, STP-BV, ...) decide collisions.
    samples: random configurations (uniform within the limits) of the 'Never' test, >= 1; seed: of
    numpy's default_rng, which draws every configuration; always_fraction: in (0, 1], the share of a
    200-configuration round above which a pair is 'Always'; include_never: False leaves out the
    'Never' test (the setup assistant's option), so samples are then not drawn.

    Links are named as ``scene.model.link_names``; links without bodies and obstacles (bodies with
    link -1) take no part. ValueError for bad arguments or a scene that skips pairs it would need."""
    samples, seed = int(samples), int(seed)
    if samples < 1:
        raise ValueError(f"samples must be >= 1; got {samples}")
    always_fraction = float(always_fraction)
    if not 0.0 < always_fraction <= 1.0:
        raise ValueError(f"always_fraction must be in (0, 1]; got {always_fraction}")
    model = scene.model
    links = sorted({b.link for b in scene.bodies if b.link >= 0})
    pairs = [(links[i], links[j]) for i in range(len(links)) for j in range(i + 1, len(links))]
    lp_index = {pair: k for k, pair in enumerate(pairs)}
    adjacent = adjacent_links(model.parent, links)
    lp = _check_scene_pairs(scene, lp_index, adjacent)
    nlp = len(pairs)
    reason = np.full(nlp, "", dtype=object)
    for pair in adjacent:
        reason[lp_index[pair]] = ADJACENT

    collide = _link_collisions(scene, default_configuration(model)[None], lp, nlp)[0]
    reason[collide & (reason == "")] = DEFAULT

    rng = np.random.default_rng(seed)
    seen = np.zeros(nlp, dtype=bool)
    limit = int(ALWAYS_ROUND * always_fraction)  # MoveIt: more than this many of a round's configurations
    while True:
        hits = _link_collisions(scene, model.random_configuration(rng, ALWAYS_ROUND), lp, nlp)
        seen |= hits.any(axis=0)
        new = (hits.sum(axis=0) > limit) & (reason == "")
        if not new.any():
            break
        reason[new] = ALWAYS
    if include_never:
        for start in range(0, samples, BLOCK):
            n = min(BLOCK, samples - start)
            seen |= _link_collisions(scene, model.random_configuration(rng, n), lp, nlp).any(axis=0)
        reason[~seen & (reason == "")] = NEVER
    names = model.link_names
    out = []
    for (i, j), why in zip(pairs, reason):
        if why:
            a, b = sorted((names[i], names[j]))
            out.append((a, b, why))
    return sorted(out)


def skip_pairs(bodies, link_pairs, link_names=None, unknown: str = "raise") -> list[tuple[str, str]]:
    """Body-name pairs (for ``Scene(..., skip=...)``) of the disabled link pairs ``link_pairs``.

    bodies: the scene's bodies, either Body objects (``.name``, ``.link``: an index into
    ``link_names``, which is then required; link -1, an obstacle, takes no part) or (body name, link
    name) tuples. link_pairs: (link1, link2) or (link1, link2, reason) entries, e.g. from
    :func:`spq.io.srdf.read_srdf` or :func:`disabled_pairs_by_sampling`. link_names: every link of
    the robot (``model.link_names``); a pair naming a link not in it is refused (ValueError) when
    ``unknown='raise'`` and passed over when ``unknown='ignore'`` (as pinocchio's removeCollisionPairs
    does; an SRDF may be written for a larger variant of the robot). Without link_names a link that
    carries no body cannot be told from an unknown one, and both are passed over.

    Returns every (body of link1, body of link2) pair once, in the order of link_pairs then bodies;
    a link without bodies, and a pair of a link with itself, give none."""
    if unknown not in ("raise", "ignore"):
        raise ValueError(f"unknown must be 'raise' or 'ignore'; got {unknown!r}")
    names = list(link_names) if link_names is not None else None
    by_link = defaultdict(list)
    for k, body in enumerate(bodies):
        if hasattr(body, "name") and hasattr(body, "link"):
            if names is None:
                raise ValueError("skip_pairs: Body objects carry link indices; pass link_names=model.link_names")
            if int(body.link) < 0:
                continue
            by_link[names[int(body.link)]].append(body.name)
        else:
            try:
                name, link = body
            except (TypeError, ValueError):
                raise ValueError(f"bodies[{k}] must be a Body or a (body name, link name) pair; got {body!r}") from None
            by_link[str(link)].append(str(name))
    known = set(names) if names is not None else None
    out, seen = [], set()
    for k, entry in enumerate(link_pairs):
        try:
            link1, link2 = entry[0], entry[1]
        except (TypeError, IndexError, KeyError):
            raise ValueError(f"link_pairs[{k}] must be (link1, link2[, reason]); got {entry!r}") from None
        if not isinstance(link1, str) or not isinstance(link2, str):
            raise ValueError(f"link_pairs[{k}] must name links by strings; got {entry!r}")
        if known is not None:
            missing = [n for n in (link1, link2) if n not in known]
            if missing:
                if unknown == "ignore":
                    continue
                raise ValueError(f"link_pairs[{k}] = {tuple(entry)!r} names unknown link(s) {missing}; the robot's "
                                 f"links: {names} (unknown='ignore' passes such pairs over)")
        if link1 == link2:
            continue
        for a in by_link.get(link1, ()):
            for b in by_link.get(link2, ()):
                key = frozenset((a, b))
                if key not in seen:
                    seen.add(key)
                    out.append((a, b))
    return out
