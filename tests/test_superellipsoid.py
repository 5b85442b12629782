"""Superellipsoids and ellipsoids: support against the implicit function and dense surface sampling,
distances against coal and closed forms, the covering fit on robot links, volume against Monte Carlo.

Every oracle here is independent of spq's own superellipsoid code: the implicit function F and the
octahedron's vertices are written out in the tests, surface samples come from the textbook
parametric form, and distances come from coal, closed forms or spq's (separately tested) polytope
support on a sampled hull.
"""

import math

import numpy as np
import pytest

import spq
from spq.validation import as_pose
from tests.both_orders import both_orders

SHAPES = [  # (a, b, c, e1, e2): boxy, ellipsoid, near-diamond, diamond, mixed
    (0.3, 0.2, 0.1, 0.1, 0.1),
    (0.3, 0.2, 0.1, 1.0, 1.0),
    (0.3, 0.2, 0.1, 1.9, 1.9),
    (0.3, 0.2, 0.1, 2.0, 2.0),
    (0.3, 0.2, 0.1, 0.1, 1.9),
    (0.05, 0.12, 0.08, 2.0, 0.1),
    (0.05, 0.12, 0.08, 0.5, 1.5),
    (1.0, 1.0, 1.0, 1.999999, 0.7),
]
LINKS = ["kuka_link_2", "kuka_link_4", "kuka_link_6", "panda_link_2", "panda_hand"]


def implicit_F(points, a, b, c, e1, e2):
    """F(x) = (|x/a|^(2/e2) + |y/b|^(2/e2))^(e2/e1) + |z/c|^(2/e1), written directly."""
    x, y, z = np.abs(points[:, 0] / a), np.abs(points[:, 1] / b), np.abs(points[:, 2] / c)
    return (x ** (2 / e2) + y ** (2 / e2)) ** (e2 / e1) + z ** (2 / e1)


def parametric_surface(n, a, b, c, e1, e2, seed):
    """n surface points from x = a C(eta)^e1 C(w)^e2, y = b C(eta)^e1 S(w)^e2, z = c S(eta)^e1."""
    rng = np.random.default_rng(seed)
    eta = rng.uniform(-np.pi / 2, np.pi / 2, n)
    w = rng.uniform(-np.pi, np.pi, n)
    spow = lambda t, e: np.sign(t) * np.abs(t) ** e  # noqa: E731
    return np.column_stack([a * spow(np.cos(eta), e1) * spow(np.cos(w), e2),
                            b * spow(np.cos(eta), e1) * spow(np.sin(w), e2),
                            c * spow(np.sin(eta), e1)])


def directions_with_zero_components(n, seed):
    """Random directions, with blocks having one or two zero components and exact ties."""
    v = np.random.default_rng(seed).normal(size=(n, 3))
    k = n // 12
    v[0:k, 0] = 0.0
    v[k:2 * k, 1] = 0.0
    v[2 * k:3 * k, 2] = 0.0
    v[3 * k:4 * k, 0:2] = 0.0
    v[4 * k:5 * k, 1:3] = 0.0
    v[5 * k:6 * k, 0::2] = 0.0
    v[6 * k:7 * k] = np.sign(v[6 * k:7 * k])  # |v_x| = |v_y| = |v_z|
    v[7 * k:8 * k, 1] = 1e-300 * np.sign(v[7 * k:8 * k, 1])  # a vanishing component
    return v


def random_rotation(rng):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def pose(R, t):
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


# ------------------------------------------------------------------------------------------
# 1-2. the support function
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("params", SHAPES)
def test_support_point_lies_on_the_surface_F_equals_one(params):
    v = directions_with_zero_components(10_000, seed=1)
    s = spq.Superellipsoid(*params).support(v)
    assert np.isfinite(s).all()
    np.testing.assert_allclose(implicit_F(s, *params), 1.0, rtol=0, atol=1e-12)
    # and it lies on the side the direction points to
    assert (np.einsum("ij,ij->i", v, s) > 0).all()


@pytest.mark.parametrize("params", SHAPES)
def test_support_is_never_beaten_by_dense_surface_samples(params):
    samples = parametric_surface(100_000, *params, seed=2)
    v = np.random.default_rng(3).normal(size=(300, 3))
    s = spq.Superellipsoid(*params).support(v)
    h_support = np.einsum("ij,ij->i", v, s)
    h_samples = (v @ samples.T).max(axis=1)
    assert (h_samples <= h_support + 1e-12).all()
    # and the samples come close: the support value is not an overestimate of the surface's reach
    assert (h_support - h_samples).max() < 2e-3 * np.abs(v).sum(axis=1).max() * max(params[:3])


@pytest.mark.parametrize("params", SHAPES)
def test_support_value_is_the_reach_of_dense_surface_samples(params):
    from spq.kernels.superellipsoid_support import support_value

    f = spq.Superellipsoid(*params).kernel_data().fdata
    samples = parametric_surface(100_000, *params, seed=4)
    v = directions_with_zero_components(360, seed=5)
    v[::7] *= 1e3  # at the direction's own scale
    h = np.array([support_value(f, *d) for d in v])
    h_samples = (v @ samples.T).max(axis=1)
    scale = np.abs(v).sum(axis=1) * max(params[:3])
    assert (h_samples <= h + 1e-12 * scale).all()
    assert (h - h_samples).max() < (2e-3 * scale).max()


@pytest.mark.parametrize("params", [(0.3, 0.2, 0.1, 0.1, 0.1), (0.3, 0.2, 0.1, 1.0, 1.0), (0.07, 0.12, 0.09, 0.3, 0.3),
                                    (0.077, 0.083, 0.137, 0.42, 1.02), (0.05, 0.12, 0.08, 0.5, 1.1)])
def test_support_value_along_a_surface_normal_is_the_normal_dot_the_point(params):
    """The closest-point Newton's lower bound takes A's side of the slab without a support call:
    along the normal at x / G(x), A reaches n . (x / G(x)) = 1 / |grad G(x)|. The normal here is
    central differences of F written out (tests' implicit_F), and the point is on the surface."""
    from spq.kernels.closest_points_newton import _to_gauge, implicit
    from spq.kernels.superellipsoid_support import support_value

    f = spq.Superellipsoid(*params).kernel_data().fdata
    rng = np.random.default_rng(6)
    on_surface = parametric_surface(300, *params, seed=7)
    keep = (np.abs(on_surface) > 1e-3 * np.array(params[:3])).all(axis=1)  # away from the coordinate planes
    for x in on_surface[keep]:
        h = 1e-7 * max(params[:3])
        grad = np.array([(implicit_F((x + h * e)[None], *params)[0] - implicit_F((x - h * e)[None], *params)[0]) / (2 * h)
                         for e in np.eye(3)])
        n = grad / np.linalg.norm(grad)
        assert support_value(f, *n) == pytest.approx(n @ x, rel=1e-9)
        # and the kernel's gauge gradient, at a point scaled off the surface, gives the same value
        s = rng.uniform(0.3, 1.5)
        g, H = np.empty(3), np.empty((3, 3))
        G = _to_gauge(implicit(f, *(s * x), g, H), params[3], g, H)
        assert G == pytest.approx(s, rel=1e-13)
        assert 1.0 / np.linalg.norm(g) == pytest.approx(n @ x, rel=1e-9)
        assert 1.0 / np.linalg.norm(g) == pytest.approx(support_value(f, *(g / np.linalg.norm(g))), rel=1e-13)


def test_support_of_the_diamond_limit_e_equals_two_is_an_octahedron_vertex():
    a, b, c = 0.3, 0.2, 0.1
    vertices = np.array([[a, 0, 0], [-a, 0, 0], [0, b, 0], [0, -b, 0], [0, 0, c], [0, 0, -c]])
    v = directions_with_zero_components(3000, seed=4)
    s = spq.Superellipsoid(a, b, c, 2.0, 2.0).support(v)
    np.testing.assert_allclose(np.einsum("ij,ij->i", v, s), (v @ vertices.T).max(axis=1), rtol=0, atol=1e-15)


def test_support_ignores_the_direction_length_and_a_zero_direction_gives_the_pole():
    se = spq.Superellipsoid(0.3, 0.2, 0.1, 0.4, 1.3)
    v = np.random.default_rng(5).normal(size=(200, 3))
    s = se.support(v)
    for scale in (1e-300, 1e-150, 1e150, 1e300):
        np.testing.assert_allclose(se.support(v * scale), s, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(se.support([0.0, 0.0, 0.0]), [0.0, 0.0, 0.1])


@pytest.mark.parametrize("k", [1e-290, 1e-150, 1e150, 1e290])
def test_support_of_extreme_semi_axes_is_the_scaled_support_at_any_direction_length(k):
    """Semi-axes k times a reference's (k from 1e-290 to 1e290): the support point is k times the
    reference's, for directions from 1e-100 to 1e100 long (the kernel uses a direction unscaled only
    where the products stay far from overflow and underflow)."""
    se = spq.Superellipsoid(0.3, 0.2, 0.1, 0.4, 1.3)
    big = spq.Superellipsoid(0.3 * k, 0.2 * k, 0.1 * k, 0.4, 1.3)
    v = np.random.default_rng(6).normal(size=(200, 3))
    s = se.support(v)
    for scale in (1e-100, 1.0, 1e100):
        np.testing.assert_allclose(big.support(v * scale) / k, s, rtol=0, atol=1e-14)
    # its volume k^3 times the reference's where representable (0 or inf beyond), not an error
    with np.errstate(over="ignore", under="ignore"):
        expected = float(se.volume() * np.float64(k) ** 3)
    assert big.volume() == pytest.approx(expected, rel=1e-12)


def test_volume_of_semi_axes_whose_product_overflows_on_the_way_is_the_closed_form():
    """2 a b overflows for a = b = 1e300, yet with c = 1e-300 the volume (about 1e300 m^3) is a float:
    it is 1e300 times the unit-axes shape's, and that one the Monte Carlo fraction of its box."""
    unit = spq.Superellipsoid(1.0, 1.0, 1.0, 0.4, 1.3)
    wide = spq.Superellipsoid(1e300, 1e300, 1e-300, 0.4, 1.3)
    assert wide.volume() == pytest.approx(unit.volume() * 1e300, rel=1e-12)
    x = np.random.default_rng(7).uniform(-1.0, 1.0, size=(400_000, 3))
    assert unit.volume() == pytest.approx(8.0 * (unit.inside(x) <= 1.0).mean(), rel=1e-2)


def test_ellipsoid_support_matches_the_closed_form_and_the_general_formula_near_e_one():
    a, b, c = 0.3, 0.2, 0.1
    v = np.random.default_rng(6).normal(size=(2000, 3))
    s = spq.Ellipsoid(a, b, c).support(v)
    u = v * [a, b, c]
    np.testing.assert_allclose(s, u * [a, b, c] / np.linalg.norm(u, axis=1)[:, None], rtol=0, atol=1e-15)
    near = spq.Superellipsoid(a, b, c, 1.0 + 1e-9, 1.0 - 1e-9).support(v)  # the dual-norm path
    np.testing.assert_allclose(near, s, rtol=0, atol=1e-8)


# ------------------------------------------------------------------------------------------
# 3. ellipsoid distances against coal
# ------------------------------------------------------------------------------------------
def _coal_distances(geom_a, geom_b, poses_a, poses_b):
    """coal's distances between two coal geometries, through the harness's coal adapter loop."""
    coal = pytest.importorskip("coal")
    from harness.engines.coal_engine import CoalPair

    request = coal.DistanceRequest()
    request.gjk_tolerance = 1e-8
    return CoalPair(geom_a, geom_b, request).distance_loop(np.asarray(poses_a), np.asarray(poses_b))


def _ellipsoid_to_box_upper(axes, half, pose_a, pose_b):
    """An upper bound on the distance (m) between the ellipsoid ``axes`` at pose_a and the box of
    half-sides ``half`` at pose_b, shared with no solver: the least distance from a point of the
    ellipsoid's surface (its angle parametrisation, best of a grid, then Nelder-Mead) to the box (the
    closest point of a box is its clamp in the box's frame). Every point tried lies on the ellipsoid,
    so every value is the distance of a pair of points of the two bodies: never below the distance."""
    from scipy.optimize import minimize

    a = np.asarray(axes)
    h = np.asarray(half)
    to_b = np.linalg.inv(pose_b) @ pose_a

    def gap(uv):
        u, v = np.atleast_1d(uv[0]), np.atleast_1d(uv[1])
        x = np.stack([a[0] * np.cos(u) * np.cos(v), a[1] * np.sin(u) * np.cos(v), a[2] * np.sin(v)], axis=-1)
        y = x @ to_b[:3, :3].T + to_b[:3, 3]
        return np.linalg.norm(y - np.clip(y, -h, h), axis=-1)

    u, v = np.meshgrid(np.linspace(-np.pi, np.pi, 97), np.linspace(-np.pi / 2, np.pi / 2, 49))
    values = gap((u.ravel(), v.ravel()))
    start = np.array([u.ravel()[np.argmin(values)], v.ravel()[np.argmin(values)]])
    best = minimize(lambda uv: gap(uv)[0], start, method="Nelder-Mead",
                    options={"xatol": 1e-12, "fatol": 1e-16, "maxiter": 4000})
    return min(float(best.fun), float(values.min()))


@pytest.mark.parametrize("other", ["ellipsoid", "box"])
def test_ellipsoid_distances_agree_with_coal(other):
    coal = pytest.importorskip("coal")
    from harness.workloads.poses import random_poses

    poses_a, poses_b = random_poses(1000, 11, 0.2)
    A = spq.Ellipsoid(0.12, 0.08, 0.05)
    if other == "ellipsoid":
        B, geom_b = spq.Ellipsoid(0.1, 0.1, 0.03), coal.Ellipsoid(0.1, 0.1, 0.03)
    else:
        B, geom_b = spq.Box(0.05, 0.07, 0.09), coal.Box(0.1, 0.14, 0.18)  # coal takes full sides
    ours = spq.distances(A, B, poses_a, poses_b)
    theirs = _coal_distances(coal.Ellipsoid(0.12, 0.08, 0.05), geom_b, poses_a, poses_b)
    separated = theirs > 1e-6
    overlapping = theirs < -1e-6
    assert separated.sum() > 500 and overlapping.sum() > 50  # both regimes exercised
    assert (ours.status[separated] == "separated").all()
    assert (ours.status[overlapping] == "overlapping").all()
    # coal stops at gjk_tolerance 1e-8; spq certifies its gap to 1e-10
    np.testing.assert_allclose(ours.distance[separated], theirs[separated], rtol=0, atol=5e-8)
    # coal's distance is near a simplex point's norm, an upper bound, but not exactly: what coal computed
    # before in the same process moves it by ~1e-11 (a Box-Box query first puts the Ellipsoid-Box result at
    # pose 504 7e-12 m below the distance, and 5.8e-12 m below spq's certified lower bound). So the bound
    # holds up to 1e-10 m, far inside coal's own gjk_tolerance (1e-8 m).
    if other == "box":  # the strict check of the lower bound, on an exact upper bound of the distance
        oracle = np.array([_ellipsoid_to_box_upper((0.12, 0.08, 0.05), (0.05, 0.07, 0.09), poses_a[i], poses_b[i])
                           for i in np.flatnonzero(separated)])
        assert (ours.lower_bound[separated] <= oracle + 1e-12).all()
        assert np.abs(ours.distance[separated] - oracle).max() <= 1e-9  # the oracle is tight: the check can tell
    excess = ours.lower_bound[separated] - theirs[separated]
    worst = int(np.argmax(excess))
    assert excess[worst] <= 1e-10, (f"coal {theirs[separated][worst]!r} below spq's lower bound "
                                    f"{ours.lower_bound[separated][worst]!r} (upper {ours.distance[separated][worst]!r}) "
                                    f"at pose {np.flatnonzero(separated)[worst]}")


def test_sphere_like_ellipsoids_match_the_closed_form_distance_and_never_overlap_when_apart():
    rng = np.random.default_rng(12)
    r1, r2 = 0.07, 0.11
    A, B = spq.Ellipsoid(r1, r1, r1), spq.Ellipsoid(r2, r2, r2)
    n = 300
    gaps = 10.0 ** rng.uniform(-8, 0, n)
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    ca = rng.uniform(-1, 1, size=(n, 3))
    cb = ca + dirs * (r1 + r2 + gaps)[:, None]
    poses_a = np.array([pose(random_rotation(rng), t) for t in ca])
    poses_b = np.array([pose(random_rotation(rng), t) for t in cb])
    batch = spq.distances(A, B, poses_a, poses_b)
    exact = np.linalg.norm(cb - ca, axis=1) - r1 - r2
    assert (batch.status == "separated").all()
    np.testing.assert_allclose(batch.distance, exact, rtol=0, atol=1e-9)


# ------------------------------------------------------------------------------------------
# 4. the covering fit
# ------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def link_fits():
    from datasets import load_object

    out = {}
    for name in LINKS:
        points = load_object(name).vertices
        out[name] = (points, spq.Superellipsoid.fit(points))
    print("\nsuperellipsoid fits (volume / convex-hull volume):")
    for name, (points, fit) in out.items():
        s = fit.shape
        print(f"  {name:13s} {len(points):4d} pts  a={s.a:.4f} b={s.b:.4f} c={s.c:.4f} e1={s.e1:.3f} "
              f"e2={s.e2:.3f}  volume {fit.volume:.3e} m^3  ratio {fit.volume_ratio:.3f}")
    return out


@pytest.mark.parametrize("name", LINKS)
def test_fit_contains_every_point_of_the_link(link_fits, name):
    points, fit = link_fits[name]
    shape, T = fit  # unpacks as (shape, pose)
    R = as_pose(T)[:3, :3]  # a valid rigid transform
    local = (points - T[:3, 3]) @ R
    s = shape
    assert implicit_F(local, s.a, s.b, s.c, s.e1, s.e2).max() <= 1.0 + 1e-12
    assert 0.0 < s.e1 <= 2.0 and 0.0 < s.e2 <= 2.0


@pytest.mark.parametrize("name", LINKS)
def test_fit_volume_is_at_least_the_hull_volume_and_at_most_the_enclosing_ellipsoids(link_fits, name):
    from scipy.spatial import ConvexHull

    points, fit = link_fits[name]
    hull_volume = ConvexHull(points).volume
    assert fit.hull_volume == pytest.approx(hull_volume, rel=1e-12)
    assert fit.volume == pytest.approx(fit.shape.volume(), rel=1e-12)
    assert 1.0 <= fit.volume_ratio < 3.0  # any convex cover holds the hull; a sensible fit is not huge
    ellipsoid = spq.Ellipsoid.fit(points)
    assert ellipsoid.max_f <= 1.0 + 1e-12
    assert fit.volume <= ellipsoid.volume * (1.0 + 1e-6)  # the family contains the ellipsoid


def test_fit_is_deterministic(link_fits):
    points, first = link_fits["kuka_link_4"]
    second = spq.Superellipsoid.fit(points.copy())
    s1, s2 = first.shape, second.shape
    assert (s1.a, s1.b, s1.c, s1.e1, s1.e2) == (s2.a, s2.b, s2.c, s2.e1, s2.e2)
    np.testing.assert_array_equal(first.pose, second.pose)


def test_fit_of_points_sampled_on_a_known_superellipsoid_recovers_its_volume():
    params = (0.2, 0.1, 0.05, 0.5, 0.8)
    R = random_rotation(np.random.default_rng(13))
    t = np.array([0.3, -0.1, 0.2])
    points = parametric_surface(3000, *params, seed=14) @ R.T + t
    fit = spq.Superellipsoid.fit(points)
    true_volume = spq.Superellipsoid(*params).volume()
    assert true_volume * 0.98 <= fit.volume <= true_volume * 1.02


@pytest.mark.parametrize("points, problem", [
    (np.zeros((3, 3)), "at least 4"),
    (np.c_[np.random.default_rng(0).normal(size=(20, 2)), np.zeros(20)], "flat"),
    (np.outer(np.linspace(0, 1, 10), [1.0, 2.0, 3.0]), "degenerate"),
    (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, np.nan]]), "NaN"),
])
def test_fit_rejects_too_few_flat_collinear_or_nan_points(points, problem):
    with pytest.raises(ValueError, match=problem):
        spq.Superellipsoid.fit(points)


# ------------------------------------------------------------------------------------------
# 5. volume, bounding radius, bad input
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("params", SHAPES)
def test_volume_formula_agrees_with_monte_carlo(params):
    a, b, c = params[:3]
    n = 400_000
    x = np.random.default_rng(15).uniform(-1, 1, size=(n, 3)) * [a, b, c]
    frac = (implicit_F(x, *params) <= 1.0).mean()
    sigma = math.sqrt(frac * (1 - frac) / n)
    assert spq.Superellipsoid(*params).volume() == pytest.approx(8 * a * b * c * frac, abs=5 * sigma * 8 * a * b * c)


def test_volume_closed_forms_ellipsoid_and_octahedron():
    assert spq.Ellipsoid(0.3, 0.2, 0.1).volume() == pytest.approx(4 / 3 * math.pi * 0.006, rel=1e-14)
    assert spq.Superellipsoid(0.3, 0.2, 0.1, 2, 2).volume() == pytest.approx(4 / 3 * 0.006, rel=1e-14)


@pytest.mark.parametrize("params", SHAPES)
def test_bounding_radius_is_the_farthest_surface_sample(params):
    samples = parametric_surface(200_000, *params, seed=16)
    reach = np.linalg.norm(samples, axis=1).max()
    radius = spq.Superellipsoid(*params).bounding_radius()
    assert reach <= radius * (1 + 1e-14)
    assert reach >= radius * (1 - 1e-4)


def test_inside_returns_F_and_surface_points_have_F_one():
    params = (0.3, 0.2, 0.1, 0.4, 1.6)
    se = spq.Superellipsoid(*params)
    x = np.random.default_rng(17).normal(size=(1000, 3)) * 0.2
    np.testing.assert_allclose(se.inside(x), implicit_F(x, *params), rtol=1e-12)
    np.testing.assert_allclose(implicit_F(se.surface_points(5000, seed=1), *params), 1.0, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(se.surface_points(100, seed=1), se.surface_points(100, seed=1))
    assert se.n_features == 1


@pytest.mark.parametrize("args, problem", [
    ((0.0, 1, 1, 1, 1), "a must be finite and > 0"),
    ((1, -1, 1, 1, 1), "b must be finite and > 0"),
    ((1, 1, np.inf, 1, 1), "c must be finite and > 0"),
    ((1, 1, np.nan, 1, 1), "c must be finite and > 0"),
    ((1, 1, 1, 0.0, 1), r"e1 must be in \(0, 2\]"),
    ((1, 1, 1, 1, 2.5), r"e2 must be in \(0, 2\]"),
    ((1, 1, 1, np.nan, 1), r"e1 must be in \(0, 2\]"),
    ((1, 1, 1, -1, 1), r"e1 must be in \(0, 2\]"),
])
def test_bad_parameters_raise_value_error_naming_the_problem(args, problem):
    with pytest.raises(ValueError, match=problem):
        spq.Superellipsoid(*args)


def test_ellipsoid_rejects_bad_semi_axes():
    with pytest.raises(ValueError, match="a must be finite and > 0"):
        spq.Ellipsoid(-1, 1, 1)


# ------------------------------------------------------------------------------------------
# 6. GJK with a superellipsoid on either side
# ------------------------------------------------------------------------------------------
def test_gjk_with_the_superellipsoid_on_either_side_agrees_with_a_sampled_hull():
    params = (0.1, 0.07, 0.05, 0.4, 1.4)
    se = spq.Superellipsoid(*params)
    rng = np.random.default_rng(18)
    poly = spq.Polyhedron.from_points(rng.normal(size=(60, 3)) * [0.05, 0.08, 0.03])
    inner = spq.Polyhedron.from_points(parametric_surface(20_000, *params, seed=19))  # inside se
    n = 200
    poses_se = np.array([pose(random_rotation(rng), rng.uniform(-0.2, 0.2, 3)) for _ in range(n)])
    poses_poly = np.array([pose(random_rotation(rng), rng.uniform(-0.2, 0.2, 3)) for _ in range(n)])
    forward, backward = both_orders(se, poly, poses_se, poses_poly)
    sampled = spq.distances(inner, poly, poses_se, poses_poly)
    sep = forward.status == "separated"
    # witness points on a curved surface are fixed only to ~sqrt(gap * radius) = sqrt(1e-10 * 0.1) m
    np.testing.assert_allclose(forward.point_a[sep], backward.point_b[sep], rtol=0, atol=2e-5)
    # the sampled hull lies inside the superellipsoid and hugs it: its distance is a close upper bound
    assert (sampled.distance >= forward.distance - 1e-10).all()
    assert (sampled.distance - forward.distance).max() < 1e-3
    # the single query gives the batch's answer
    for i in range(0, n, 20):
        r = spq.distance(se, poly, poses_se[i], poses_poly[i])
        assert r.status == forward.status[i]
        assert r.distance == pytest.approx(forward.distance[i], abs=1e-12)
    # witness points: on A's surface (in A's frame) at the reported distance from B's
    for i in np.flatnonzero(sep)[:30]:
        T = poses_se[i]
        local = (forward.point_a[i] - T[:3, 3]) @ T[:3, :3]
        assert implicit_F(local[None], *params)[0] == pytest.approx(1.0, abs=1e-6)
        assert np.linalg.norm(forward.point_b[i] - forward.point_a[i]) == pytest.approx(forward.distance[i], abs=1e-12)


# ------------------------------------------------------------------------------------------
# 7. the support map's derivative and Newton's finish between two smooth superellipsoids
# ------------------------------------------------------------------------------------------
SMOOTH_SHAPES = [p for p in SHAPES if max(p[3], p[4]) < 2.0]


@pytest.mark.parametrize("params", SMOOTH_SHAPES)
def test_support_jacobian_matches_central_differences_of_the_support(params):
    from spq.kernels.superellipsoid_support import pack, superellipsoid_support_jacobian

    f = pack(*params)
    se = spq.Superellipsoid(*params)
    rng = np.random.default_rng(21)
    checked = 0
    for v in rng.normal(size=(200, 3)):
        v /= np.linalg.norm(v)
        out, jac = np.empty(3), np.empty((3, 3))
        if not superellipsoid_support_jacobian(f, v[0], v[1], v[2], out, jac):
            continue
        np.testing.assert_allclose(out, se.support(v), rtol=0, atol=1e-15)
        h = 1e-6 * min(np.abs(v).min(), 1.0)  # stay inside the octant: |s| is not smooth across it
        fd = np.column_stack([(se.support(v + h * e) - se.support(v - h * e)) / (2 * h) for e in np.eye(3)])
        scale = np.abs(fd).max() + 1e-3
        assert np.abs(jac - fd).max() <= 1e-4 * scale, (v, jac, fd)
        # degree -1 homogeneity: the support does not move along the direction itself
        np.testing.assert_allclose(jac @ v, 0.0, atol=1e-8 * scale)
        checked += 1
    assert checked > 150


def _newton_system(rng, scale):
    """A random system of the closest-point Newton's shape (closest_points_newton._solve) as a dense
    5 x 5 matrix and right-hand side, and in the kernel's (10, 4) layout."""
    M = np.zeros((5, 5))
    M[:3, :3] = rng.normal(size=(3, 3)) * scale[0]
    M[:3, 3] = rng.normal(size=3) * scale[1]
    M[:3, 4] = rng.normal(size=3) * scale[2]
    M[3, :3] = rng.normal(size=3) * scale[1]
    M[4, :4] = rng.normal(size=4) * scale[2]
    rhs = rng.normal(size=5)
    mat = np.zeros((13, 4))
    for i in range(5):
        for j in range(6):
            mat[2 * i + (j >> 2), j & 3] = M[i, j] if j < 5 else rhs[i]
    return M, rhs, mat


@pytest.mark.parametrize("scale", [(1.0, 1.0, 1.0), (1e-6, 20.0, 15.0), (50.0, 0.1, 3.0)])
def test_newton_system_solve_matches_lapack_on_every_pivot_order(scale):
    from spq.kernels.closest_points_newton import _solve

    rng = np.random.default_rng(5)
    pivots = set()
    checked = 0
    for _ in range(300):
        M, rhs, mat = _newton_system(rng, scale)
        if np.linalg.cond(M) > 1e8:
            continue
        step = np.empty((2, 4))
        assert _solve(mat, step)
        x = np.array([step[0, 0], step[0, 1], step[0, 2], step[0, 3], step[1, 0]])
        ref = np.linalg.solve(M, rhs)
        np.testing.assert_allclose(x, ref, rtol=0, atol=1e-8 * np.abs(ref).max())
        pivots.add((int(np.argmax(np.abs(M[:3, 4]))), int(np.argmax(np.abs(M[3, :3])))))
        checked += 1
    assert checked > 150 and len(pivots) == 9  # every row for dmu with every column for dx


def test_newton_system_solve_reports_a_singular_system():
    from spq.kernels.closest_points_newton import _solve

    M, rhs, mat = _newton_system(np.random.default_rng(1), (1.0, 1.0, 1.0))
    step = np.empty((2, 4))
    flat = mat.copy()
    flat[1::2, 0] = 0.0  # column 4 (dmu's) all zero: g_B vanishes
    assert not _solve(flat, step)
    flat = mat.copy()
    flat[6, :3] = 0.0  # row 3 (g_A) all zero
    assert not _solve(flat, step)


@pytest.mark.parametrize("params", [(0.3, 0.2, 0.1, 0.1, 0.1), (0.3, 0.2, 0.1, 1.0, 1.0), (0.07, 0.12, 0.09, 0.3, 0.3),
                                    (0.077, 0.083, 0.137, 0.42, 1.02)])
def test_implicit_function_gradient_and_hessian_match_central_differences(params):
    from spq.kernels.closest_points_newton import implicit

    rng = np.random.default_rng(27)
    f = spq.Superellipsoid(*params).kernel_data().fdata
    for x in rng.uniform(-1.2, 1.2, size=(100, 3)) * np.array(params[:3]):
        g, H = np.empty(3), np.empty((3, 3))
        F = implicit(f, *x, g, H)
        assert F == pytest.approx(implicit_F(x[None], *params)[0], rel=1e-12)
        h = 1e-6 * np.abs(x).min()  # stay inside the octant
        fd_g = np.array([(implicit_F((x + h * e)[None], *params)[0] - implicit_F((x - h * e)[None], *params)[0]) / (2 * h)
                         for e in np.eye(3)])
        np.testing.assert_allclose(g, fd_g, rtol=1e-5, atol=1e-6 * np.abs(fd_g).max())
        fd_H = np.empty((3, 3))
        for j, e in enumerate(np.eye(3)):
            gp, gm, Hs = np.empty(3), np.empty(3), np.empty((3, 3))
            implicit(f, *(x + h * e), gp, Hs)
            implicit(f, *(x - h * e), gm, Hs)
            fd_H[:, j] = (gp - gm) / (2 * h)
        np.testing.assert_allclose(H, fd_H, rtol=1e-4, atol=1e-5 * np.abs(fd_H).max())


@pytest.mark.parametrize("point", [(1e-310, 0.05, 0.03), (2.2e-48, 1e-49, 0.08), (0.02, -1e-320, -0.06)])
def test_implicit_gradient_holds_within_rounding_of_a_coordinate_plane(point):
    """A coordinate far below any length (subnormal, or whose power is): the packed reciprocals would
    overflow there, so implicit must still give the gradient the formula gives (finite), not inf or NaN."""
    from spq.kernels.closest_points_newton import implicit

    a, b, c, e1, e2 = 0.07, 0.12, 0.09, 0.3, 0.3  # equal exponents: F = sum |x_i / a_i|^p, p = 2 / e
    f = spq.Superellipsoid(a, b, c, e1, e2).kernel_data().fdata
    g, H = np.empty(3), np.empty((3, 3))
    x = np.array(point)
    F = implicit(f, *x, g, H)
    p = 2.0 / e1
    axes = np.array([a, b, c])
    expected = p * np.abs(x / axes) ** (p - 1) / axes * np.sign(x)
    assert F == pytest.approx(implicit_F(x[None], a, b, c, e1, e2)[0], rel=1e-12)
    assert np.all(np.isfinite(g))
    # (a subnormal power keeps fewer digits: the tiny entries to the gradient's scale, the others exactly)
    np.testing.assert_allclose(g, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("params", SHAPES)
def test_inner_polytope_lies_inside_and_hugs_the_surface(params):
    se = spq.Superellipsoid(*params)
    inner = se.inner_polytope()
    # inside: the implicit function written out here, at every vertex
    assert (implicit_F(inner.vertices, *params) <= 1.0).all()
    # hugging: its support value along random directions is close to the shape's (dense samples)
    samples = parametric_surface(50_000, *params, seed=25)
    v = np.random.default_rng(26).normal(size=(500, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    h_inner = (v @ inner.vertices.T).max(axis=1)
    h_samples = (v @ samples.T).max(axis=1)
    assert (h_samples - h_inner).max() < 0.05 * max(params[:3])


def _parametric_distance(pa, pb, params_a, params_b, start):
    """min |x(theta_a) - y(theta_b)| over the two parametric surfaces (world frame), by Nelder-Mead
    from start = (eta_a, w_a, eta_b, w_b): an oracle that uses neither the support function nor GJK."""
    from scipy.optimize import minimize

    def world_point(T, eta, w, a, b, c, e1, e2):  # in plain floats: the oracle's tens of thousands of calls
        spow = lambda t, e: math.copysign(abs(t) ** e, t)  # noqa: E731
        ce = spow(math.cos(eta), e1)
        x, y, z = a * ce * spow(math.cos(w), e2), b * ce * spow(math.sin(w), e2), c * spow(math.sin(eta), e1)
        return [r[0] * x + r[1] * y + r[2] * z + r[3] for r in T]

    Ta, Tb = pa[:3].tolist(), pb[:3].tolist()

    def gap2(z):
        x = world_point(Ta, z[0], z[1], *params_a)
        y = world_point(Tb, z[2], z[3], *params_b)
        return (x[0] - y[0]) ** 2 + (x[1] - y[1]) ** 2 + (x[2] - y[2]) ** 2

    res = minimize(gap2, start, method="Nelder-Mead",
                   options={"xatol": 1e-13, "fatol": 1e-22, "maxiter": 20_000, "maxfev": 40_000})
    return math.sqrt(res.fun)


def _surface_parameters(n, seed):
    """The (eta, w) that parametric_surface(n, ..., seed) samples."""
    rng = np.random.default_rng(seed)
    eta = rng.uniform(-np.pi / 2, np.pi / 2, n)
    return np.column_stack([eta, rng.uniform(-np.pi, np.pi, n)])


@pytest.mark.parametrize("params_a, params_b", [((0.1, 0.07, 0.05, 0.4, 1.4), (0.08, 0.08, 0.12, 1.2, 0.6)),
                                                ((0.05, 0.12, 0.08, 0.5, 1.5), (0.3, 0.2, 0.1, 1.9, 1.9)),
                                                # boxy (Newton on the closest points) and one fitted cover
                                                ((0.07, 0.12, 0.09, 0.3, 0.3), (0.08, 0.05, 0.1, 0.5, 0.9)),
                                                ((0.077, 0.083, 0.137, 0.42, 1.02), (0.07, 0.12, 0.09, 0.1, 0.6))])
def test_distances_between_two_smooth_superellipsoids_agree_with_a_minimisation_over_the_parametric_surfaces(params_a, params_b):
    A, B = spq.Superellipsoid(*params_a), spq.Superellipsoid(*params_b)
    rng = np.random.default_rng(22)
    n = 300
    poses_a = np.array([pose(random_rotation(rng), rng.uniform(-0.3, 0.3, 3)) for _ in range(n)])
    poses_b = np.array([pose(random_rotation(rng), rng.uniform(-0.3, 0.3, 3)) for _ in range(n)])
    batch = spq.distances(A, B, poses_a, poses_b)
    # sampled hulls lie inside each body: their distance is an upper bound, and close
    inner_a = spq.Polyhedron.from_points(parametric_surface(20_000, *params_a, seed=23))
    inner_b = spq.Polyhedron.from_points(parametric_surface(20_000, *params_b, seed=24))
    sampled = spq.distances(inner_a, inner_b, poses_a, poses_b)
    sep = batch.status == "separated"
    assert sep.sum() > 100 and (~sep).sum() > 10
    assert (batch.status != "failed").all()
    assert (sampled.status[~sep] == "overlapping").sum() >= 0.9 * (~sep).sum()
    assert (sampled.distance[sep] >= batch.distance[sep] - 1e-10).all()
    assert (sampled.distance[sep] - batch.distance[sep]).max() < 2e-3
    # the certified interval is tight, and the witness points span the distance
    assert ((batch.distance - batch.lower_bound)[sep] <= 1e-10 + 1e-10 * batch.distance[sep]).all()
    gaps = np.linalg.norm(batch.point_b - batch.point_a, axis=1)
    np.testing.assert_allclose(gaps[sep], batch.distance[sep], rtol=0, atol=1e-12)
    # an independent minimisation over the parametric surfaces, from the sampled hulls' witnesses
    theta_a, theta_b = _surface_parameters(20_000, 23), _surface_parameters(20_000, 24)
    samples_a = parametric_surface(20_000, *params_a, seed=23)
    samples_b = parametric_surface(20_000, *params_b, seed=24)
    for i in np.flatnonzero(sep)[:25]:
        ia = np.argmin(np.linalg.norm(samples_a @ poses_a[i][:3, :3].T + poses_a[i][:3, 3] - sampled.point_a[i], axis=1))
        ib = np.argmin(np.linalg.norm(samples_b @ poses_b[i][:3, :3].T + poses_b[i][:3, 3] - sampled.point_b[i], axis=1))
        exact = _parametric_distance(poses_a[i], poses_b[i], params_a, params_b,
                                     np.concatenate([theta_a[ia], theta_b[ib]]))
        assert batch.distance[i] == pytest.approx(exact, abs=1e-9)
    # and the single query gives the batch's answer
    for i in range(0, n, 25):
        r = spq.distance(A, B, poses_a[i], poses_b[i])
        assert r.status == batch.status[i]
        assert r.distance == pytest.approx(batch.distance[i], abs=1e-12)


def test_a_pointy_needle_builds_its_inner_polytope():
    """Exponents near 2 and axis ratio 67 (fuzz campaign seed 0, case 1108): most support directions
    end near the tips, and qhull refused the cloud; the distance along the long axis to a ball is
    a - 0.5 - r by hand."""
    a = 0.31567336923415057
    s = spq.Superellipsoid(a, 0.00468976329781721, 0.05395211381063139, 1.7983703780697284, 1.849628863084512)
    ball = np.eye(4)
    ball[0, 3] = 0.5
    r = spq.distance(s, spq.Sphere(0.01), np.eye(4), ball)
    assert r.status == "separated"
    assert r.distance == pytest.approx(0.5 - a - 0.01, abs=1e-9)


def test_a_flat_diamond_builds_its_inner_polytope():
    """e1 near 2 and c 30 times smaller than a and b (fuzz campaign seed 79, case 593): the tips are
    the support only within 2 degrees of the poles, which the lattice misses, so every support lay on
    the rim, a flat cloud, and the query raised. The distance along z to a ball is by hand."""
    a, b, c = 3.5779274090865605, 3.4113603976981994, 0.11904480993764104
    s = spq.Superellipsoid(a, b, c, 1.889471166730982, 1.7905347051727012)
    inner = s.inner_polytope()
    assert (implicit_F(inner.vertices, a, b, c, s.e1, s.e2) <= 1.0).all()
    assert inner.vertices[:, 2].max() == pytest.approx(c, rel=1e-8)
    ball = np.eye(4)
    ball[2, 3] = 0.5
    r = spq.distance(s, spq.Sphere(0.01), np.eye(4), ball)
    assert r.status == "separated"
    assert r.distance == pytest.approx(0.5 - c - 0.01, abs=1e-9)
