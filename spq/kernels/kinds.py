"""Integer codes of the shape kinds the compiled support dispatch knows.

A shape reaches the kernels as ``(kind, margin, fdata, idata)``: a kind code, a margin (the radius of
a ball added to the core, in metres), and two flat arrays whose layout the kind defines:

- POLYTOPE: fdata = vertices (n*3, x y z interleaved); idata = [n, G, cells_start, cell slots
  (6*G*G cells of CELL_SLOTS), longer candidate lists...]: the directions are binned into G x G
  cells on each of the six faces of the direction cube, and cell c's support candidates (vertex
  ids, a superset of the supports of all its directions) fill its slots at
  idata[cells_start + CELL_SLOTS * c], the last one repeated; a cell with more than CELL_SLOTS
  holds (-1 - position of its list in idata, its length) instead (kernels/support.py).
- BOX: fdata = half extents (hx, hy, hz); idata unused.
- POINT: the origin (a Sphere is a POINT with its radius as margin); fdata, idata unused.
- SEGMENT: fdata = (half_length,) along the local z axis (a Capsule is a SEGMENT with a margin).
- SUPERELLIPSOID: fdata = (a, b, c, e1, e2, q1, q2, q1 - 1, q2 - 1, 1/q1 - 1, 1/q2 - 1): semi-axes (m),
  exponents in (0, 2] and their dual-norm exponents q = 2/(2 - e) (inf for e = 2), precomputed,
  then the vertices of an inscribed polytope (from FDATA_SIZE on); idata = that polytope's idata
  (layout as POLYTOPE); margin 0. Offsets and packing in kernels/superellipsoid_support.py.

Both arrays also live in one float64 array, ``packed`` (:func:`pack_shape`), which the per-call
kernel takes whole: numba unboxes one argument instead of two.
"""

import numpy as np

# idata's element type: 32-bit indices halve the index pools' cache footprint (a robot scene's STP-BVs
# and hulls hold about 0.5 M of them), which the all-pairs loop reads in random order.
IDATA_DTYPE = np.int32

POLYTOPE = 0
BOX = 1
POINT = 2
SEGMENT = 3
STP = 4  # sphere-torus-patch bounding volume: layout in kernels/stp_support.py
SUPERELLIPSOID = 5  # convex superellipsoid (CSE-BV): layout above and in kernels/superellipsoid_support.py
# An STP-BV's core: its ball hull at radius R - r, whose support is the STP-BV's less r along the unit
# direction (the STP-BV is that core grown by r); layout as STP. Only the signed query's EPA takes it,
# with r carried as a margin (kernels/query.py, signed_from_hulls).
STP_CORE = 6

CUBE_MAP_CELLS = 8  # least G, cells per cube-map face edge (6 * 8 * 8 = 384 cells); more on hulls of > 192 vertices

SHAPE_HEAD = 2  # float64 slots before a packed shape's floats: the float and int32 counts, read as int64


def pack_shape(fdata, idata) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(packed, fdata, idata): one float64 array holding SHAPE_HEAD slots (len(fdata), len(idata) as
    int64), then fdata, then idata as IDATA_DTYPE, two to a slot; and views of it equal to fdata and
    idata, which the shape keeps as its own (so that a change to one is seen through the other)."""
    fdata = np.asarray(fdata, dtype=np.float64).ravel()
    idata = np.asarray(idata, dtype=IDATA_DTYPE).ravel()
    nf, ni = len(fdata), len(idata)
    packed = np.zeros(SHAPE_HEAD + nf + (ni + 1) // 2)
    packed[:SHAPE_HEAD].view(np.int64)[:] = (nf, ni)
    f = packed[SHAPE_HEAD:SHAPE_HEAD + nf]
    f[:] = fdata
    i = packed[SHAPE_HEAD + nf:].view(IDATA_DTYPE)[:ni]
    i[:] = idata
    return packed, f, i
