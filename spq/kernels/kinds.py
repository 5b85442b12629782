"""Integer codes of the shape kinds the compiled support dispatch knows.

A shape reaches the kernels as ``(kind, margin, fdata, idata)``: a kind code, a margin (the radius of
a ball added to the core, in metres), and two flat arrays whose layout the kind defines:

- POLYTOPE: fdata = vertices (n*3, x y z interleaved); idata = [n, G, table_start, offsets (n+1),
  neighbours..., table (6*G*G)]: the vertex adjacency in CSR form (offsets index into the neighbour
  list, which starts at n + 4), then a cube map of G x G cells on each of the six faces of the
  direction cube holding the support vertex of each cell's centre direction, where a climb starts,
  or -(v + 1) where v is the support vertex of every direction of the cell (no climb needed).
- BOX: fdata = half extents (hx, hy, hz); idata unused.
- POINT: the origin (a Sphere is a POINT with its radius as margin); fdata, idata unused.
- SEGMENT: fdata = (half_length,) along the local z axis (a Capsule is a SEGMENT with a margin).
- SUPERELLIPSOID: fdata = (a, b, c, e1, e2, q1, q2, q1 - 1, q2 - 1, 1/q1 - 1, 1/q2 - 1): semi-axes (m),
  exponents in (0, 2] and their dual-norm exponents q = 2/(2 - e) (inf for e = 2), precomputed,
  then the vertices of an inscribed polytope (from FDATA_SIZE on); idata = that polytope's idata
  (layout as POLYTOPE); margin 0. Offsets and packing in kernels/superellipsoid_support.py.
"""

POLYTOPE = 0
BOX = 1
POINT = 2
SEGMENT = 3
STP = 4  # sphere-torus-patch bounding volume: layout in kernels/stp_support.py
SUPERELLIPSOID = 5  # convex superellipsoid (CSE-BV): layout above and in kernels/superellipsoid_support.py

CUBE_MAP_CELLS = 8  # G: cells per cube-map face edge; 6 * 8 * 8 = 384 start vertices
BRUTE_FORCE_MAX_VERTICES = 32  # below this a linear scan beats hill climbing (NOTES section 5)
