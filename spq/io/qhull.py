"""Reader for qhull ``o f`` output (OFF-like header, points, facets, then the ``f`` facet dump).

Layout (NOTES section 3): a line ``3`` (the dimension), a line ``npoints nfacets nridges``, npoints
lines of x y z, then nfacets lines ``k i1 .. ik`` of point indices. What follows (qhull's ``f``
dump: ``- normal:``, ``- vertices:`` blocks) repeats the same facts and is not needed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def read_qhull_off(path) -> tuple[np.ndarray, list[np.ndarray]]:
    """Read a qhull ``o f`` file.

    Returns ``(points, facets)``: points as an (n, 3) float64 array and facets as a list of int
    arrays of point indices. Raises ValueError naming the file and the line for anything that does
    not follow the layout.
    """
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"cannot read qhull file {path}: {exc}") from None

    def fail(lineno: int, what: str):
        raise ValueError(f"{path}:{lineno + 1}: not qhull 'o f' output: {what}")

    rows = [(i, ln.split()) for i, ln in enumerate(lines) if ln.strip()]
    if len(rows) < 2:
        fail(0, "file too short")
    if rows[0][1] != ["3"]:
        fail(rows[0][0], f"first line must be the dimension 3, got {lines[rows[0][0]]!r}")
    lineno, head = rows[1]
    try:
        npoints, nfacets = int(head[0]), int(head[1])
    except (IndexError, ValueError):
        fail(lineno, f"expected 'npoints nfacets nridges', got {lines[lineno]!r}")
    if npoints < 1 or nfacets < 0 or len(rows) < 2 + npoints + nfacets:
        fail(lineno, f"header announces {npoints} points and {nfacets} facets, file has fewer lines")
    points = np.empty((npoints, 3))
    for k in range(npoints):
        lineno, tok = rows[2 + k]
        try:
            if len(tok) != 3:
                raise ValueError
            points[k] = [float(t) for t in tok]
        except ValueError:
            fail(lineno, f"expected three coordinates for point {k}, got {lines[lineno]!r}")
    if not np.isfinite(points).all():
        fail(rows[2][0], "points contain NaN or inf")
    facets = []
    for k in range(nfacets):
        lineno, tok = rows[2 + npoints + k]
        try:
            idx = np.array([int(t) for t in tok], dtype=np.int64)
        except ValueError:
            fail(lineno, f"expected facet indices, got {lines[lineno]!r}")
        if len(idx) < 4 or idx[0] != len(idx) - 1:
            fail(lineno, f"facet {k} must be 'k i1 .. ik' with k >= 3, got {lines[lineno]!r}")
        if idx[1:].min() < 0 or idx[1:].max() >= npoints:
            fail(lineno, f"facet {k} indexes a point outside 0..{npoints - 1}")
        facets.append(idx[1:])
    return points, facets
