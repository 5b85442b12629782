"""Where the EPA keeps its polytope: rows of a query's float scratch and a run of its int scratch.

The query kernels allocate nothing (spq.kernels.jit), so the expanding polytope of a signed query
lives in the caller's scratch arrays, after the GJK's own rows: ``work`` rows from
gjk.EPA_ROW and ``iwork`` entries from gjk.EPA_IOFF.

Float rows (4 columns): the polytope's vertices w = a - b (x, y, z), their points of A and of B,
then one plane per face slot (unit normal, offset), the planes of an expansion's new faces before
they are made, then three rows of support scratch, then five for the nearest point of a face to an origin outside P
(its corners, weights, and a row of scratch), then two per vertex for the sphere D's boundary follows
around it (centre, radius; direction, cosine of the cap's half-angle: spq.kernels.epa_caps), one
per face slot for its certified offset (column 0; column 1 the same while the face lives, +inf
once it is dead: the key epa._least_face scans; column 2: 1 once curved sets were tried on it,
spq.kernels.epa_curved), three for the best exact witness (a, b, normal; column 3 of the first: 1
once set), and six for the deepest curved set found (epa_curved._keep_set).
Ints: the count of free face slots, the count of expansions, whether the run uses sphere caps, then per face its corners (3), its neighbours (3: across the
edge from corner k to corner k + 1), an alive flag and a visit stamp; the free slots; the horizon
of an expansion (4 per edge: from, to, outside face, that face's edge); the walk's stack (3 per
entry: face, next edge, edges left); the faces an expansion removes; per vertex the support
features of A and of B it came from (a polytope's vertex, an STP-BV's patch).

The bounds from a ball hull's set of centres (spq.kernels.ball_hull_depth) keep their own polytope in
the upper halves of the vertex blocks and of the per-face int blocks, which a run that tries them
midway (spq.kernels.epa.CENTRES_AFTER) has not reached, so that it can go on from its polytope after.
"""

EPA_MAX_VERTICES = 4096  # support points: the initial tetrahedron, then one per EPA step (see epa.EPA_MAX_STEPS)
EPA_MAX_FACES = 2 * EPA_MAX_VERTICES  # a closed triangulated polytope has 2V - 4 faces

# Every block starts PAD bytes (three cache lines) further along the cache's sets than the one before:
# the blocks' sizes are multiples of 4 KiB, so unpadded their starts would share one set of the L1
# cache, and an EPA step, which reads a few entries of each block, would evict its own lines.
PAD_ROWS = 6  # float rows of 32 bytes
PAD_INTS = 24  # int64 entries

# float rows
EPA_W = 0
EPA_PA = EPA_W + EPA_MAX_VERTICES + PAD_ROWS
EPA_PB = EPA_PA + EPA_MAX_VERTICES + PAD_ROWS
EPA_PLANES = EPA_PB + EPA_MAX_VERTICES + PAD_ROWS
EPA_FAN = EPA_PLANES + EPA_MAX_FACES + PAD_ROWS
EPA_TMP = EPA_FAN + EPA_MAX_FACES + PAD_ROWS
EPA_NEAR = EPA_TMP + 3  # a face's corners (3 rows), the weights of its point nearest the origin, scratch
EPA_SPHERES = EPA_NEAR + 5 + PAD_ROWS
EPA_CERTIFIED = EPA_SPHERES + 2 * EPA_MAX_VERTICES + PAD_ROWS
EPA_BEST = EPA_CERTIFIED + EPA_MAX_FACES + PAD_ROWS
EPA_SET = EPA_BEST + 3  # the deepest curved set found (spq.kernels.epa_curved), six rows
EPA_TORI = EPA_SET + 6  # the last two cores' curved patches tried (epa_curved.torus_pair_set), four rows
EPA_FLOAT_ROWS = EPA_TORI + 4

# ints
EPA_NFREE = 0
EPA_CLOCK = 1  # expansions so far: each stamps the faces it visits with its own number
EPA_CAPS = 2  # 1 while the run's shapes can carry sphere caps (spq.kernels.epa_caps), else 0
EPA_CORNERS = 3
EPA_ADJ = EPA_CORNERS + 3 * EPA_MAX_FACES + PAD_INTS
EPA_ALIVE = EPA_ADJ + 3 * EPA_MAX_FACES + PAD_INTS
EPA_STAMP = EPA_ALIVE + EPA_MAX_FACES + PAD_INTS
EPA_FREE = EPA_STAMP + EPA_MAX_FACES + PAD_INTS
EPA_HORIZON = EPA_FREE + EPA_MAX_FACES + PAD_INTS
EPA_STACK = EPA_HORIZON + 4 * EPA_MAX_FACES + PAD_INTS
EPA_DEAD = EPA_STACK + 3 * EPA_MAX_FACES + PAD_INTS
EPA_FEATURES = EPA_DEAD + EPA_MAX_FACES + PAD_INTS
EPA_INT_SIZE = EPA_FEATURES + 2 * EPA_MAX_VERTICES
