"""Primitives against textbook tables, the perpendicular-axis theorem, point-cloud integration,
composites of halves and the triangle inequality (inertia_ros.core.bodies)."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip('hypothesis')  # optional test dependency
from hypothesis import given, settings
from hypothesis import strategies as st

from inertia_ros.core import bodies
from inertia_ros.core.inertia import InertiaTensor, check_physical, composite

# (name, factory call, expected diag(ixx, iyy, izz) in kg m^2, worked by hand from the tables)
TEXTBOOK = [
    ('rod centre m=3 L=2', lambda: bodies.thin_rod(3.0, 2.0), (1.0, 1.0, 0.0)),
    ('rod end m=3 L=2', lambda: bodies.thin_rod(3.0, 2.0, about='end'), (4.0, 4.0, 0.0)),
    ('lamina m=12 a=1 b=2', lambda: bodies.rectangular_lamina(12.0, 1.0, 2.0), (4.0, 1.0, 5.0)),
    ('disc m=4 r=1', lambda: bodies.thin_disc(4.0, 1.0), (1.0, 1.0, 2.0)),
    ('ring m=2 r=3', lambda: bodies.thin_ring(2.0, 3.0), (9.0, 9.0, 18.0)),
    ('solid sphere m=5 r=0.2', lambda: bodies.solid_sphere(5.0, 0.2), (0.08, 0.08, 0.08)),
    ('hollow sphere m=3 r=0.5', lambda: bodies.hollow_sphere(3.0, 0.5), (0.5, 0.5, 0.5)),
    ('box m=12 1x2x3', lambda: bodies.solid_box(12.0, 1.0, 2.0, 3.0), (13.0, 10.0, 5.0)),
    ('solid cylinder m=12 r=1 h=2', lambda: bodies.solid_cylinder(12.0, 1.0, 2.0),
     (7.0, 7.0, 6.0)),
    ('thin-walled cylinder m=12 r=1 h=2', lambda: bodies.thin_walled_cylinder(12.0, 1.0, 2.0),
     (10.0, 10.0, 12.0)),
    ('hollow cylinder m=12 r2=2 r1=1 h=2',
     lambda: bodies.hollow_cylinder(12.0, 2.0, 1.0, 2.0), (19.0, 19.0, 30.0)),
    ('solid cone m=80 r=1 h=2', lambda: bodies.solid_cone(80.0, 1.0, 2.0), (24.0, 24.0, 24.0)),
    ('solid cone m=10 r=2 h=1', lambda: bodies.solid_cone(10.0, 2.0, 1.0),
     (6.375, 6.375, 12.0)),
    ('point mass', lambda: bodies.point_mass(2.0, (1.0, 2.0, 3.0)), (0.0, 0.0, 0.0)),
]


@pytest.mark.parametrize(('name', 'make', 'expected'), TEXTBOOK, ids=[c[0] for c in TEXTBOOK])
def test_primitive_matches_textbook_table(name, make, expected):
    """Each primitive's tensor equals the tabulated diagonal (rtol 1e-12, atol 1e-15)."""
    body = make()
    np.testing.assert_allclose(body.matrix, np.diag(expected), rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize('make', [
    lambda: bodies.rectangular_lamina(2.5, 0.3, 1.7),
    lambda: bodies.thin_disc(1.3, 0.45),
    lambda: bodies.thin_ring(0.7, 2.2),
], ids=['rectangular_lamina', 'thin_disc', 'thin_ring'])
def test_perpendicular_axis_theorem_for_every_lamina(make):
    """For a lamina in the xy plane, I_zz = I_xx + I_yy (rtol 1e-14)."""
    m = make().matrix
    np.testing.assert_allclose(m[2, 2], m[0, 0] + m[1, 1], rtol=1e-14)


def _sample_cloud(kind: str, rng: np.random.Generator, n: int) -> np.ndarray:
    """Uniform samples of each body's mass distribution (geometry as in bodies.py)."""
    u = rng.random((n, 3))
    if kind == 'rod':                                    # L = 2
        return np.column_stack([np.zeros(n), np.zeros(n), 2.0 * u[:, 0] - 1.0])
    if kind == 'lamina':                                 # a = 1, b = 2
        return np.column_stack([u[:, 0] - 0.5, 2.0 * u[:, 1] - 1.0, np.zeros(n)])
    if kind in ('disc', 'ring'):                         # r = 1
        rad = np.sqrt(u[:, 0]) if kind == 'disc' else np.ones(n)
        ang = 2.0 * np.pi * u[:, 1]
        return np.column_stack([rad * np.cos(ang), rad * np.sin(ang), np.zeros(n)])
    if kind == 'hollow_sphere':                          # r = 1
        g = rng.normal(size=(n, 3))
        return g / np.linalg.norm(g, axis=1, keepdims=True)
    if kind == 'tube':                                   # r = 1, h = 2
        ang = 2.0 * np.pi * u[:, 0]
        return np.column_stack([np.cos(ang), np.sin(ang), 2.0 * u[:, 1] - 1.0])
    box = 2.0 * u - 1.0                                  # rejection from [-1, 1]^3
    if kind == 'box':                                    # 1 x 2 x 3
        return box * [0.5, 1.0, 1.5]
    if kind == 'sphere':
        return box[np.sum(box**2, axis=1) <= 1.0]
    if kind == 'cylinder':                               # r = 1, h = 2
        return box[np.sum(box[:, :2] ** 2, axis=1) <= 1.0]
    if kind == 'cone':                                   # r = 1, h = 2: base z=-h/4, apex 3h/4
        pts = box + [0.0, 0.0, 0.5]
        rad_at_z = (1.5 - pts[:, 2]) / 2.0
        return pts[np.sum(pts[:, :2] ** 2, axis=1) <= rad_at_z**2]
    raise AssertionError(kind)


CLOUD_CASES = [
    ('rod', lambda: bodies.thin_rod(1.0, 2.0)),
    ('lamina', lambda: bodies.rectangular_lamina(1.0, 1.0, 2.0)),
    ('disc', lambda: bodies.thin_disc(1.0, 1.0)),
    ('ring', lambda: bodies.thin_ring(1.0, 1.0)),
    ('hollow_sphere', lambda: bodies.hollow_sphere(1.0, 1.0)),
    ('tube', lambda: bodies.thin_walled_cylinder(1.0, 1.0, 2.0)),
    ('box', lambda: bodies.solid_box(1.0, 1.0, 2.0, 3.0)),
    ('sphere', lambda: bodies.solid_sphere(1.0, 1.0)),
    ('cylinder', lambda: bodies.solid_cylinder(1.0, 1.0, 2.0)),
    ('cone', lambda: bodies.solid_cone(1.0, 1.0, 2.0)),
]


@pytest.mark.parametrize(('kind', 'make'), CLOUD_CASES, ids=[c[0] for c in CLOUD_CASES])
def test_primitive_matches_integrated_point_cloud(kind, make):
    """Formula == inertia of 200k seeded uniform samples of the body (atol 0.5% of trace).

    Also checks the documented centre-of-mass placement (the cone's CoM at the origin, i.e. a
    quarter of the height above its base) to 0.01 m.
    """
    rng = np.random.default_rng(20240611)
    pts = _sample_cloud(kind, rng, 200_000)
    cloud = InertiaTensor.from_point_masses(pts, 1.0 / len(pts))
    body = make()
    np.testing.assert_allclose(cloud.com, body.com, atol=1e-2)
    np.testing.assert_allclose(cloud.matrix, body.matrix, atol=0.005 * body.trace)


def test_hollow_cylinder_limits_are_solid_and_thin_walled():
    """hollow_cylinder(r1=0) == solid_cylinder and (r1=r2) == thin_walled_cylinder (rtol 1e-14)."""
    np.testing.assert_allclose(bodies.hollow_cylinder(2.0, 0.3, 0.0, 1.1).matrix,
                               bodies.solid_cylinder(2.0, 0.3, 1.1).matrix, rtol=1e-14)
    np.testing.assert_allclose(bodies.hollow_cylinder(2.0, 0.3, 0.3, 1.1).matrix,
                               bodies.thin_walled_cylinder(2.0, 0.3, 1.1).matrix, rtol=1e-14)


def test_rod_end_and_centre_related_by_parallel_axis():
    """The rod about its end, moved to its CoM, is the rod about its centre shifted to z=L/2."""
    end = bodies.thin_rod(3.0, 2.0, about='end')
    np.testing.assert_allclose(end.com, [0.0, 0.0, 1.0], atol=0.0)
    np.testing.assert_allclose(end.about_com().matrix, bodies.thin_rod(3.0, 2.0).matrix,
                               rtol=1e-14, atol=1e-15)


def test_point_mass_shifted_gives_m_r_squared():
    """A point mass at r, about the origin, is m (|r|^2 1 - r r^T) (rtol 1e-14)."""
    r = np.array([1.0, -2.0, 0.5])
    pm = bodies.point_mass(2.0, r).shifted([0.0, 0.0, 0.0])
    np.testing.assert_allclose(pm.matrix, 2.0 * (r @ r * np.eye(3) - np.outer(r, r)),
                               rtol=1e-14)


ALL_PRIMITIVES = [
    bodies.point_mass(1.0), bodies.thin_rod(1.0, 1.0), bodies.thin_rod(1.0, 1.0, 'end'),
    bodies.rectangular_lamina(1.0, 0.2, 3.0), bodies.thin_disc(1.0, 0.5),
    bodies.thin_ring(1.0, 0.5), bodies.solid_sphere(1.0, 0.5), bodies.hollow_sphere(1.0, 0.5),
    bodies.solid_box(1.0, 0.1, 0.2, 5.0), bodies.solid_cylinder(1.0, 0.1, 3.0),
    bodies.thin_walled_cylinder(1.0, 2.0, 0.1), bodies.hollow_cylinder(1.0, 1.0, 0.5, 0.2),
    bodies.solid_cone(1.0, 2.0, 0.1), bodies.solid_cone(1.0, 0.1, 2.0),
]


@pytest.mark.parametrize('body', ALL_PRIMITIVES, ids=repr)
def test_triangle_inequality_holds_for_every_primitive(body):
    """Every primitive passes check_physical (semi-definite allowed for rods and points)."""
    res = check_physical(body.matrix, allow_singular=True)
    assert res.valid, res.failures
    assert np.all(res.triangle_margins >= -1e-12 * max(res.moments.max(), 1e-300))


_dims = st.floats(0.05, 5.0)
_masses = st.floats(0.1, 100.0)
_fractions = st.floats(0.05, 0.95)


@settings(derandomize=True, max_examples=40, deadline=None)
@given(m=_masses, a=_dims, b=_dims, c=_dims, f=_fractions)
def test_composite_of_two_box_halves_is_the_whole(m, a, b, c, f):
    """A box cut across x at fraction f: the two pieces recombine to the whole (rtol 1e-12)."""
    left = bodies.solid_box(m * f, a * f, b, c).translated([-a / 2 + a * f / 2, 0.0, 0.0])
    right = bodies.solid_box(m * (1 - f), a * (1 - f), b, c).translated(
        [a / 2 - a * (1 - f) / 2, 0.0, 0.0])
    whole = bodies.solid_box(m, a, b, c)
    both = left + right
    np.testing.assert_allclose(both.mass, m, rtol=1e-12)
    np.testing.assert_allclose(both.com, [0.0, 0.0, 0.0], atol=1e-12 * a)
    np.testing.assert_allclose(both.matrix, whole.matrix, rtol=0, atol=1e-12 * whole.trace)


@settings(derandomize=True, max_examples=30, deadline=None)
@given(m=_masses, r=_dims, h=_dims, q=st.lists(st.floats(-1, 1), min_size=4, max_size=4),
       t=st.lists(st.floats(-3, 3), min_size=3, max_size=3))
def test_composite_of_cylinder_halves_equals_whole_in_any_placement(m, r, h, q, t):
    """Two half-height cylinders, both moved by the same rigid motion, equal the moved whole.

    Also removing one half from the whole (``-``) leaves the other (rtol 1e-9 of the trace).
    """
    from scipy.spatial.transform import Rotation
    qv = np.array(q) if np.linalg.norm(q) > 1e-3 else np.array([0.0, 0.0, 0.0, 1.0])
    R = Rotation.from_quat(qv).as_matrix()
    top = bodies.solid_cylinder(m / 2, r, h / 2).translated([0.0, 0.0, h / 4])
    bottom = bodies.solid_cylinder(m / 2, r, h / 2).translated([0.0, 0.0, -h / 4])
    whole = bodies.solid_cylinder(m, r, h).transformed(R, t)
    both = composite([top.transformed(R, t), bottom.transformed(R, t)])
    tol = 1e-9 * whole.trace
    np.testing.assert_allclose(both.matrix, whole.matrix, rtol=0, atol=tol)
    np.testing.assert_allclose(both.com, t, atol=1e-9 * (1 + h))
    rest = whole - top.transformed(R, t)
    np.testing.assert_allclose(rest.matrix, bottom.transformed(R, t).matrix, rtol=0, atol=tol)
    np.testing.assert_allclose(rest.com, bottom.transformed(R, t).com, atol=1e-9 * (1 + h))


_SOLIDS = [bodies.solid_box, bodies.solid_cylinder, bodies.solid_cone, bodies.solid_sphere]


@settings(derandomize=True, max_examples=40, deadline=None)
@given(data=st.data())
def test_triangle_inequality_holds_for_random_composites(data):
    """Composites of 2-4 randomly placed and oriented solid primitives are physically valid."""
    from scipy.spatial.transform import Rotation
    n = data.draw(st.integers(2, 4))
    parts = []
    for _ in range(n):
        kind = data.draw(st.sampled_from(_SOLIDS))
        nargs = {bodies.solid_box: 3, bodies.solid_cylinder: 2, bodies.solid_cone: 2,
                 bodies.solid_sphere: 1}[kind]
        dims = [data.draw(_dims) for _ in range(nargs)]
        q = np.array(data.draw(st.lists(st.floats(-1, 1), min_size=4, max_size=4)))
        R = Rotation.from_quat(q if np.linalg.norm(q) > 1e-3 else [0, 0, 0, 1.0]).as_matrix()
        t = data.draw(st.lists(st.floats(-2, 2), min_size=3, max_size=3))
        parts.append(kind(data.draw(_masses), *dims).transformed(R, t))
    total = sum(parts)
    res = total.check()
    assert res.valid, res.failures


BAD_ARGS = [
    (lambda: bodies.solid_sphere(-1.0, 1.0), r'm: must be > 0 kg'),
    (lambda: bodies.solid_sphere(0.0, 1.0), r'm: must be > 0 kg'),
    (lambda: bodies.solid_sphere(float('nan'), 1.0), r'm: must be finite'),
    (lambda: bodies.thin_disc(1.0, 0.0), r'r: must be > 0 m'),
    (lambda: bodies.solid_box(1.0, 1.0, -2.0, 1.0), r'b: must be > 0 m'),
    (lambda: bodies.solid_cylinder(1.0, 1.0, float('inf')), r'h: must be finite'),
    (lambda: bodies.thin_rod(1.0, 1.0, about='middle'), r"about: expected 'center' or 'end'"),
    (lambda: bodies.hollow_cylinder(1.0, 1.0, 2.0, 1.0), r'r_inner: must be <= r_outer'),
    (lambda: bodies.point_mass(1.0, (0.0, 1.0)), r'position: expected shape \(3,\)'),
    (lambda: bodies.solid_cone(1.0, 'wide', 1.0), r'r: expected a number'),
]


@pytest.mark.parametrize(('call', 'match'), BAD_ARGS)
def test_primitives_reject_bad_input_naming_the_argument(call, match):
    """Bad dimensions or masses raise ValueError naming the argument and the problem."""
    with pytest.raises(ValueError, match=match):
        call()


def test_composite_accepts_parts_about_any_reference_point_and_sum():
    """Parts given about other points (rod about its end) combine as if about their CoMs.

    A dumbbell (two spheres on a rod, about the rod's end) equals the same parts about their
    centres; ``sum(parts)`` equals ``composite(parts)`` (rtol 1e-12).
    """
    rod_end = bodies.thin_rod(1.0, 2.0, about='end')                     # CoM at z = 1
    rod_mid = bodies.thin_rod(1.0, 2.0).translated([0.0, 0.0, 1.0])
    s0 = bodies.solid_sphere(2.0, 0.1)
    s1 = bodies.solid_sphere(2.0, 0.1).translated([0.0, 0.0, 2.0])
    a = composite([rod_end, s0, s1])
    b = sum([rod_mid, s0, s1])
    assert a.allclose(b, rtol=1e-12)
    np.testing.assert_allclose(a.com, [0.0, 0.0, 1.0], rtol=1e-12)
    expected_xx = 1.0 * 4 / 12 + 2 * (0.4 * 2.0 * 0.01 + 2.0 * 1.0)
    np.testing.assert_allclose(np.diag(a.matrix), [expected_xx, expected_xx, 2 * 0.008],
                               rtol=1e-12)
