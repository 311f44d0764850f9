"""The inertia toolkit (inertia_ros.core.inertia): conversions, principal axes, physical
validity and projection, Euler's equations, the InertiaTensor value type and dynamics."""
from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

pytest.importorskip('hypothesis')  # optional test dependency
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize
from scipy.spatial.transform import Rotation

from inertia_ros.core import bodies
from inertia_ros.core import inertia as ti
from inertia_ros.core.inertia import InertiaTensor

# ---------------------------------------------------------------------------------------------
# strategies
# ---------------------------------------------------------------------------------------------
_quat = st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4).filter(
    lambda q: np.linalg.norm(q) > 1e-2)
_rotations = _quat.map(lambda q: Rotation.from_quat(q).as_matrix())
_vec3 = st.lists(st.floats(-5.0, 5.0), min_size=3, max_size=3).map(np.array)
_mass = st.floats(0.01, 100.0)
# second moments of a mass distribution along principal axes (kg m^2): any positive triple
# gives physical principal moments (b + c, a + c, a + b); small values allow near-degeneracy
_second_moments = st.lists(st.sampled_from([0.5, 1.0, 2.0]) | st.floats(0.01, 10.0),
                           min_size=3, max_size=3).map(np.array)


def _physical(J: np.ndarray, R: np.ndarray) -> np.ndarray:
    """A physical tensor with second moments J (3,) along the columns of R."""
    moments = np.sum(J) - J
    return R @ np.diag(moments) @ R.T


_tensors = st.builds(_physical, _second_moments, _rotations)
_symmetric = st.lists(st.floats(-10.0, 10.0), min_size=6, max_size=6).map(
    lambda th: ti.theta_to_matrix(th))

PROPS = settings(derandomize=True, max_examples=60, deadline=None)


def _relerr(a: np.ndarray, b: np.ndarray) -> float:
    """max |a - b| / max |b|."""
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


# ---------------------------------------------------------------------------------------------
# theta <-> matrix
# ---------------------------------------------------------------------------------------------
def test_theta_names_and_layout_follow_the_contract():
    """theta order is [ixx, iyy, izz, ixy, ixz, iyz] and ixy is the matrix element (exact)."""
    assert ti.THETA_NAMES == ('ixx', 'iyy', 'izz', 'ixy', 'ixz', 'iyz')
    m = ti.theta_to_matrix([1.0, 2.0, 3.0, 0.1, 0.2, 0.3])
    np.testing.assert_array_equal(m, [[1.0, 0.1, 0.2], [0.1, 2.0, 0.3], [0.2, 0.3, 3.0]])
    np.testing.assert_array_equal(ti.matrix_to_theta(m), [1.0, 2.0, 3.0, 0.1, 0.2, 0.3])


def test_theta_conversions_are_vectorised_over_leading_dims():
    """(N, K, 6) -> (N, K, 3, 3) -> (N, K, 6) round-trips exactly."""
    theta = np.random.default_rng(1).normal(size=(4, 5, 6))
    mats = ti.theta_to_matrix(theta)
    assert mats.shape == (4, 5, 3, 3)
    np.testing.assert_array_equal(mats, np.swapaxes(mats, -1, -2))
    np.testing.assert_array_equal(ti.matrix_to_theta(mats), theta)


def test_theta_to_matrix_can_let_nan_through_on_request():
    """check_finite=False propagates NaN (for unidentified elements); default rejects it."""
    th = [1.0, 2.0, 3.0, np.nan, 0.0, 0.0]
    assert np.isnan(ti.theta_to_matrix(th, check_finite=False)[1, 0])
    with pytest.raises(ValueError, match='theta: must be finite'):
        ti.theta_to_matrix(th)


# ---------------------------------------------------------------------------------------------
# principal axes
# ---------------------------------------------------------------------------------------------
def _assert_convention(moments: np.ndarray, axes: np.ndarray) -> None:
    """DESIGN.md: ascending, proper rotation, sign rule on columns 0 and 1, third = cross."""
    assert np.all(np.isfinite(axes)) and np.all(np.isfinite(moments))
    assert np.all(np.diff(moments) >= 0.0)
    np.testing.assert_allclose(axes.T @ axes, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(axes), 1.0, atol=1e-12)
    for k in range(2):
        col = axes[:, k]
        assert col[np.argmax(np.abs(col))] > 0.0
    np.testing.assert_allclose(axes[:, 2], np.cross(axes[:, 0], axes[:, 1]), atol=1e-15)


PRINCIPAL_CASES = [
    ('distinct diagonal', np.diag([3.0, 1.0, 2.0]), [1.0, 2.0, 3.0],
     [[0, 0, 1], [1, 0, 0], [0, 1, 0]]),
    ('sphere', 2.0 * np.eye(3), [2.0, 2.0, 2.0], np.eye(3)),
    ('zero tensor', np.zeros((3, 3)), [0.0, 0.0, 0.0], np.eye(3)),
    ('disc, axis z (oblate)', np.diag([1.0, 1.0, 2.0]), [1.0, 1.0, 2.0], np.eye(3)),
    ('rod, axis x (prolate)', np.diag([0.5, 3.0, 3.0]), [0.5, 3.0, 3.0], np.eye(3)),
    ('disc, axis x', np.diag([2.0, 1.0, 1.0]), [1.0, 1.0, 2.0],
     [[0, 0, 1], [1, 0, 0], [0, 1, 0]]),
    # eigenvector of 1 is +-(1, -1, 0)/sqrt2: a tie in magnitude, the first index (x) is made
    # positive; third column = cross product
    ('rotated 45 deg about z', [[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 5.0]],
     [1.0, 3.0, 5.0], np.array([[1.0, 1.0, 0.0], [-1.0, 1.0, 0.0], [0.0, 0.0, np.sqrt(2)]])
     / np.sqrt(2)),
]


@pytest.mark.parametrize(('name', 'I', 'moments', 'axes'), PRINCIPAL_CASES,
                         ids=[c[0] for c in PRINCIPAL_CASES])
def test_principal_axes_table(name, I, moments, axes):
    """Known tensors give the expected moments and axes (atol 1e-12), incl. repeated moments."""
    mom, ax = ti.principal_axes(I)
    np.testing.assert_allclose(mom, moments, atol=1e-12)
    np.testing.assert_allclose(ax, axes, atol=1e-12)
    _assert_convention(mom, ax)


@PROPS
@given(I=_symmetric)
def test_principal_decomposition_reconstructs_any_symmetric_tensor(I):
    """R diag(moments) R^T == I to 1e-12 relative, with the DESIGN.md convention."""
    mom, ax = ti.principal_axes(I)
    _assert_convention(mom, ax)
    if np.max(np.abs(I)) > 0:
        assert _relerr(ax @ np.diag(mom) @ ax.T, I) <= 1e-12


@PROPS
@given(J=_second_moments, R=_rotations)
def test_principal_axes_deterministic_for_repeated_moments(J, R):
    """Rotated (possibly axisymmetric or spherical) tensors: NaN-free, reproducible, exact."""
    I = _physical(J, R)
    mom, ax = ti.principal_axes(I)
    mom2, ax2 = ti.principal_axes(I.copy())
    np.testing.assert_array_equal(ax, ax2)
    np.testing.assert_array_equal(mom, mom2)
    _assert_convention(mom, ax)
    assert _relerr(ax @ np.diag(mom) @ ax.T, I) <= 1e-12
    np.testing.assert_allclose(mom, np.sort(np.sum(J) - J), rtol=1e-12)


def test_rotated_sphere_and_axisymmetric_body_get_canonical_axes():
    """A rotated sphere (round-off only) gives the identity; a tilted disc its symmetry axis."""
    R = Rotation.from_euler('xyz', [0.3, -1.1, 2.0]).as_matrix()
    mom, ax = ti.principal_axes(R @ (0.4 * np.eye(3)) @ R.T)
    np.testing.assert_array_equal(ax, np.eye(3))
    np.testing.assert_allclose(mom, [0.4, 0.4, 0.4], rtol=1e-14)
    disc = R @ np.diag([1.0, 1.0, 2.0]) @ R.T
    mom, ax = ti.principal_axes(disc)
    axis = R[:, 2] * np.sign(R[np.argmax(np.abs(R[:, 2])), 2])
    np.testing.assert_allclose(abs(ax[:, 2] @ axis), 1.0, rtol=1e-12)
    _assert_convention(mom, ax)


@pytest.mark.parametrize(('moments', 'axis'), [
    ([0.5, 3.0, 3.0], 'x'), ([3.0, 0.5, 3.0], 'y'), ([3.0, 3.0, 0.5], 'z'),
    ([2.0, 1.0, 1.0], 'x'), ([1.0, 2.0, 1.0], 'y'), ([1.0, 1.0, 2.0], 'z'),
], ids=['prolate x', 'prolate y', 'prolate z', 'oblate x', 'oblate y', 'oblate z'])
def test_spinning_an_axisymmetric_tensor_about_its_axis_does_not_change_its_axes(moments, axis):
    """R diag R^T with R about the symmetry axis (round-off only) gives the same axes as diag.

    The degenerate plane gets the canonical basis, not whatever LAPACK returns (atol 1e-12).
    """
    I0 = np.diag(moments)
    ref_mom, ref_ax = ti.principal_axes(I0)
    for angle in (0.3, 1.0, 2.2, -0.9):
        R = Rotation.from_euler(axis, angle).as_matrix()
        mom, ax = ti.principal_axes(R @ I0 @ R.T)
        np.testing.assert_allclose(ax, ref_ax, atol=1e-12)
        np.testing.assert_allclose(mom, ref_mom, rtol=1e-14)


# ---------------------------------------------------------------------------------------------
# physical validity and projection
# ---------------------------------------------------------------------------------------------
CHECK_CASES = [
    ('valid box', bodies.solid_box(1.0, 1.0, 2.0, 3.0).matrix, {}, True, ()),
    ('triangle violated by 1', np.diag([1.0, 1.0, 3.0]), {}, False,
     (r'triangle inequality I1 \+ I2 >= I3 violated by 1 kg m\^2',)),
    ('negative moment', np.diag([-0.5, 2.0, 2.0]), {}, False,
     (r'not positive definite: smallest principal moment I1 = -0.5',
      r'triangle inequality I1 \+ I3 >= I2 violated by 0.5 kg m\^2',
      r'triangle inequality I1 \+ I2 >= I3 violated by 0.5 kg m\^2')),
    ('zero tensor', np.zeros((3, 3)), {}, False, (r'all principal moments are zero',)),
    ('asymmetric', [[1.0, 0.2, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.5]], {}, False,
     (r'not symmetric: max \|I_ij - I_ji\| = 0.2',)),
    ('thin rod strict', bodies.thin_rod(1.0, 1.0).matrix, {}, False,
     (r'not positive definite',)),
    ('thin rod semidefinite', bodies.thin_rod(1.0, 1.0).matrix, {'allow_singular': True},
     True, ()),
    ('negative with allow_singular', np.diag([-0.5, 2.0, 2.0]), {'allow_singular': True},
     False, (r'not positive semi-definite: .* below 0 by 0.5', r'I1 \+ I3 >= I2',
             r'I1 \+ I2 >= I3')),
]


@pytest.mark.parametrize(('name', 'I', 'kwargs', 'valid', 'patterns'), CHECK_CASES,
                         ids=[c[0] for c in CHECK_CASES])
def test_check_physical_names_the_failed_condition_and_amount(name, I, kwargs, valid,
                                                              patterns):
    """check_physical reports validity and one readable line per failed condition."""
    res = ti.check_physical(I, **kwargs)
    assert res.valid is valid and bool(res) is valid
    assert len(res.failures) == len(patterns)
    for pat, line in zip(patterns, res.failures, strict=True):
        assert re.search(pat, line), line


def test_check_physical_margins():
    """Margins are I_j + I_k - I_i for ascending moments (rtol 1e-12)."""
    res = ti.check_physical(np.diag([1.0, 1.0, 3.0]))
    np.testing.assert_allclose(res.triangle_margins, [3.0, 3.0, -1.0], rtol=1e-12)
    assert res.min_moment == pytest.approx(1.0, rel=1e-12)


def _slsqp_projection(lam: np.ndarray, eps: float) -> np.ndarray:
    """Independent projection of moments onto the physical set with scipy's SLSQP."""
    cons = [{'type': 'ineq', 'fun': lambda x, k=k: x[k] - eps} for k in range(3)]
    cons += [{'type': 'ineq', 'fun': lambda x, k=k: np.sum(x) - 2 * x[k]} for k in range(3)]
    res = minimize(lambda x: np.sum((x - lam) ** 2), np.full(3, max(eps, 1.0)),
                   jac=lambda x: 2 * (x - lam), constraints=cons, method='SLSQP',
                   options={'ftol': 1e-14, 'maxiter': 500})
    return res.x


@PROPS
@given(I=_symmetric)
@example(I=ti.theta_to_matrix([0.0, 0.0, 0.0, 0.0, 0.0, 7.839290951911623e-72]))
def test_nearest_physical_is_valid_and_as_close_as_an_independent_solver(I):
    """The projection is physical, keeps the axes, and is no farther than SLSQP's (1e-7 rel)."""
    if np.max(np.abs(I)) == 0:
        return
    P = ti.nearest_physical(I)
    assert ti.check_physical(P).valid
    lam, vecs = np.linalg.eigh(I)
    eps = 1e-8 * np.max(np.abs(lam))
    ref = _slsqp_projection(lam, eps)
    d_ours = np.linalg.norm(P - I)
    d_ref = np.linalg.norm(ref - lam)
    assert d_ours <= d_ref + 1e-7 * max(1.0, np.max(np.abs(lam)))
    # axes kept: P is diagonal in I's eigenbasis
    D = vecs.T @ P @ vecs
    np.testing.assert_allclose(D - np.diag(np.diag(D)), 0.0, atol=1e-12 * np.max(np.abs(lam)))


@PROPS
@given(I=_tensors)
def test_nearest_physical_leaves_valid_tensors_unchanged(I):
    """A physically valid tensor projects to itself (rtol 1e-12) and projection is idempotent."""
    P = ti.nearest_physical(I)
    assert _relerr(P, I) <= 1e-12
    np.testing.assert_allclose(ti.nearest_physical(P), P, rtol=0, atol=1e-14 * np.max(I))


def test_nearest_physical_worked_example():
    """diag(1, 1, 3) projects to diag(4/3, 4/3, 8/3) (rtol 1e-12): the triangle face."""
    np.testing.assert_allclose(ti.nearest_physical(np.diag([1.0, 1.0, 3.0])),
                               np.diag([4 / 3, 4 / 3, 8 / 3]), rtol=1e-12)
    P = ti.nearest_physical(np.diag([-1.0, 1.0, 3.0]), min_moment=0.1)
    assert ti.check_physical(P).valid and np.linalg.eigvalsh(P)[0] >= 0.1 - 1e-12


# ---------------------------------------------------------------------------------------------
# Euler's equations
# ---------------------------------------------------------------------------------------------
def test_euler_torque_worked_example():
    """diag(1,2,3), w = (1,1,0), w_dot = (1,0,0): tau = (1,0,0) + w x (1,2,0) = (1,0,1)."""
    tau = ti.euler_torque(np.diag([1.0, 2.0, 3.0]), [1.0, 1.0, 0.0], [1.0, 0.0, 0.0])
    np.testing.assert_allclose(tau, [1.0, 0.0, 1.0], rtol=0, atol=1e-15)


@PROPS
@given(I=_tensors, seed=st.integers(0, 2**32 - 1))
def test_euler_equations_round_trip_vectorised(I, seed):
    """omega_dot -> torque -> omega_dot over (N, 3) batches (rtol 1e-9 of the batch scale)."""
    rng = np.random.default_rng(seed)
    w = rng.normal(size=(7, 3))
    wd = rng.normal(size=(7, 3))
    tau = ti.euler_torque(I, w, wd)
    assert tau.shape == (7, 3)
    loop = np.array([I @ b + np.cross(a, I @ a) for a, b in zip(w, wd, strict=True)])
    np.testing.assert_allclose(tau, loop, rtol=0, atol=1e-12 * np.max(np.abs(loop)))
    back = ti.euler_omega_dot(I, w, tau)
    cond = np.linalg.cond(I)
    np.testing.assert_allclose(back, wd, rtol=0, atol=1e-13 * cond * np.max(np.abs(wd)) * 10)


def test_euler_broadcasts_time_varying_inertia():
    """A (N, 3, 3) stack of inertias pairs sample-by-sample with (N, 3) rates (rtol 1e-12)."""
    rng = np.random.default_rng(3)
    Is = np.stack([_physical(rng.uniform(0.1, 2.0, 3), np.eye(3)) for _ in range(5)])
    w, wd = rng.normal(size=(5, 3)), rng.normal(size=(5, 3))
    tau = ti.euler_torque(Is, w, wd)
    for k in range(5):
        np.testing.assert_allclose(tau[k], ti.euler_torque(Is[k], w[k], wd[k]), rtol=1e-12)
    np.testing.assert_allclose(ti.euler_omega_dot(Is, w, tau), wd, rtol=1e-10, atol=1e-12)


def test_torque_free_spin_about_principal_axis_needs_no_torque():
    """Steady spin about a principal axis: tau = 0 (atol 1e-15)."""
    np.testing.assert_allclose(ti.euler_torque(np.diag([1.0, 2.0, 3.0]), [0.0, 0.0, 5.0],
                                               [0.0, 0.0, 0.0]), 0.0, atol=1e-15)


EULER_BAD = [
    (lambda: ti.euler_torque(np.eye(3), np.ones((4, 2)), np.ones((4, 3))),
     r'omega: expected shape \(\.\.\., 3\)'),
    (lambda: ti.euler_torque(np.eye(3), np.ones(3), [np.nan, 0, 0]), r'omega_dot: must be finite'),
    (lambda: ti.euler_torque(np.eye(3), np.ones((4, 3)), np.ones((5, 3))),
     r'omega, omega_dot: shapes'),
    (lambda: ti.euler_omega_dot(np.diag([0.0, 1.0, 1.0]), np.ones(3), np.ones(3)),
     r'I: singular'),
    (lambda: ti.euler_omega_dot(np.ones((2, 2)), np.ones(3), np.ones(3)),
     r'I: expected shape \(\.\.\., 3, 3\)'),
]


@pytest.mark.parametrize(('call', 'match'), EULER_BAD)
def test_euler_rejects_bad_input(call, match):
    """Euler's equations raise ValueError naming the bad argument."""
    with pytest.raises(ValueError, match=match):
        call()


# ---------------------------------------------------------------------------------------------
# InertiaTensor
# ---------------------------------------------------------------------------------------------
def test_constructors_agree():
    """from_theta, from_matrix, from_principal and from_inertia_msg build the same body."""
    R = Rotation.from_euler('zyx', [0.4, 0.2, -0.7]).as_matrix()
    mat = R @ np.diag([1.0, 2.0, 2.5]) @ R.T
    a = InertiaTensor.from_matrix(mat, 3.0, [0.1, 0.2, 0.3])
    b = InertiaTensor.from_theta(ti.matrix_to_theta(mat), 3.0, [0.1, 0.2, 0.3])
    c = InertiaTensor.from_principal([1.0, 2.0, 2.5], R, 3.0, [0.1, 0.2, 0.3])
    d = InertiaTensor.from_inertia_msg(**a.to_inertia_msg())
    for other in (b, c, d):
        assert a.allclose(other, rtol=1e-12)
    assert d == a
    np.testing.assert_allclose(a.theta, ti.matrix_to_theta(mat), rtol=1e-15)


def test_from_inertia_msg_accepts_vector3_like_com_and_unknown_mass():
    """com may be an object with x, y, z; m = 0 means unknown mass (mass=None)."""
    com = type('Vector3', (), {'x': 1.0, 'y': 2.0, 'z': 3.0})()
    t = InertiaTensor.from_inertia_msg(m=0.0, com=com, ixx=1.0, ixy=0.0, ixz=0.0, iyy=1.0,
                                       iyz=0.0, izz=1.0)
    assert t.mass is None
    np.testing.assert_array_equal(t.com, [1.0, 2.0, 3.0])
    assert t.to_inertia_msg()['m'] == 0.0


def test_inertia_tensor_is_immutable():
    """Fields cannot be reassigned and the stored arrays are read-only; the input is copied."""
    src = np.diag([1.0, 2.0, 3.0])
    t = InertiaTensor(src, 1.0)
    src[0, 0] = 99.0
    assert t.matrix[0, 0] == 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        t.mass = 2.0  # type: ignore[misc]
    with pytest.raises(ValueError, match='read-only'):
        t.matrix[0, 0] = 5.0
    assert hash(t) == hash(InertiaTensor(np.diag([1.0, 2.0, 3.0]), 1.0))


TENSOR_BAD = [
    (lambda: InertiaTensor(np.diag([1.0, np.nan, 1.0])), r'matrix: must be finite'),
    (lambda: InertiaTensor(np.eye(2)), r'matrix: expected shape \(3, 3\), got \(2, 2\)'),
    (lambda: InertiaTensor.from_matrix([[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]),
     r'matrix: not symmetric: max \|I_ij - I_ji\| = 0.1'),
    (lambda: InertiaTensor(np.eye(3), mass=-1.0), r'mass: must be >= 0 kg, got -1.0'),
    (lambda: InertiaTensor(np.eye(3), mass='heavy'), r'mass: expected a number'),
    (lambda: InertiaTensor(np.eye(3), com=[0, 0]), r'com: expected shape \(3,\)'),
    (lambda: InertiaTensor.from_theta([1, 2, 3]), r'theta: expected shape \(6,\)'),
    (lambda: InertiaTensor.from_principal([1, 2, 3], np.ones((3, 3))),
     r'axes: not orthonormal'),
    (lambda: InertiaTensor.from_principal([1, 2, 3], np.diag([1.0, 1.0, -1.0])),
     r'axes: det = -1 is a reflection'),
    (lambda: InertiaTensor.from_inertia_msg(1.0, [0, 0, 0], 1, 0, 0, 1, 0, float('inf')),
     r'izz: must be finite'),
    (lambda: InertiaTensor(np.eye(3), 1.0).about_axis([0, 0, 0]), r'axis: zero vector'),
    (lambda: InertiaTensor(np.eye(3)).shifted([1, 0, 0]), r'mass: shifted .* needs the mass'),
    (lambda: InertiaTensor(np.eye(3)) + InertiaTensor(np.eye(3)), r'parts\[0\]: mass is None'),
    (lambda: InertiaTensor(np.eye(3), 1.0) - InertiaTensor(np.eye(3), 2.0),
     r'parts: total mass must be > 0'),
    (lambda: InertiaTensor(np.eye(3), 1.0).ellipsoid('potato'), r"kind: expected 'inertia'"),
    (lambda: InertiaTensor(np.eye(3), 1.0).pendulum_period([0, 0, 0], [0, 0, 1]),
     r'pivot: the centre of mass lies on the pivot axis'),
    (lambda: InertiaTensor(np.eye(3), 1.0).rotated(2 * np.eye(3)), r'rotation: not orthonormal'),
    (lambda: ti.nearest_physical(np.zeros((3, 3))), r'I: all principal moments are zero'),
    (lambda: ti.nearest_physical(np.eye(3), min_moment=-1.0), r'min_moment: must be'),
    (lambda: ti.pendulum_period(1.0, 1.0, -0.1), r'h: must be > 0'),
    (lambda: InertiaTensor.from_point_masses(np.zeros((2, 3)), [1.0, -1.0]),
     r'masses: must be >= 0 kg'),
]


@pytest.mark.parametrize(('call', 'match'), TENSOR_BAD)
def test_inertia_tensor_rejects_bad_input_naming_the_argument(call, match):
    """Bad input raises ValueError naming the argument and the problem."""
    with pytest.raises(ValueError, match=match):
        call()


def test_symmetric_within_tolerance_is_accepted_and_symmetrised():
    """A 1e-12 relative asymmetry passes and the stored matrix is exactly symmetric."""
    m = np.diag([1.0, 2.0, 3.0])
    m[0, 1] = 1e-12
    t = InertiaTensor.from_matrix(m)
    np.testing.assert_array_equal(t.matrix, t.matrix.T)


@PROPS
@given(I=_tensors, m=_mass, r=_vec3, q=_vec3)
def test_parallel_axis_round_trip_is_identity(I, m, r, q):
    """CoM -> P -> Q -> CoM returns the same tensor (atol 1e-12 of the largest term)."""
    body = InertiaTensor(I, m, com=r)
    there = body.shifted(q).shifted(r + q).about_com()
    scale = np.max(np.abs(I)) + m * (r @ r + q @ q + (r + q) @ (r + q))
    np.testing.assert_allclose(there.matrix, body.matrix, rtol=0, atol=1e-12 * scale)
    back = ti.parallel_axis_to_com(ti.parallel_axis(I, m, q), m, q)
    np.testing.assert_allclose(back, I, rtol=0, atol=1e-12 * (np.max(np.abs(I)) + m * q @ q))


def test_parallel_axis_worked_example():
    """Solid sphere m=5 r=0.2 about a point 1 m along x: I_yy = I_zz = 0.08 + 5 (rtol 1e-14)."""
    s = bodies.solid_sphere(5.0, 0.2).shifted([1.0, 0.0, 0.0])
    np.testing.assert_allclose(np.diag(s.matrix), [0.08, 5.08, 5.08], rtol=1e-14)
    np.testing.assert_allclose(ti.parallel_axis(np.diag([1.0, 1, 1]), 2.0, [0, 1, 1]),
                               [[5, 0, 0], [0, 3, -2], [0, -2, 3]], rtol=1e-15)


@PROPS
@given(I=_tensors, R=_rotations, t=_vec3, m=_mass)
def test_rotation_changes_frame_not_physics(I, R, t, m):
    """transformed(R, t): matrix R I R^T, same moments, axes rotated, about_axis covariant."""
    body = InertiaTensor(I, m)
    moved = body.transformed(R, t)
    np.testing.assert_allclose(moved.matrix, R @ I @ R.T, rtol=0, atol=1e-13 * np.max(I))
    np.testing.assert_allclose(moved.principal_moments, body.principal_moments, rtol=1e-11)
    np.testing.assert_allclose(moved.com, t, rtol=0, atol=0)
    n = np.array([0.3, -0.5, 0.8])
    assert moved.about_axis(R @ n) == pytest.approx(body.about_axis(n), rel=1e-12)


@PROPS
@given(I=_tensors, n=_vec3.filter(lambda v: np.linalg.norm(v) > 1e-3))
def test_about_axis_normalises_and_lies_between_extreme_moments(I, n):
    """n^T I n / |n|^2, scale-free in n, between the smallest and largest moment (rtol 1e-12)."""
    t = InertiaTensor(I, 2.0)
    val = t.about_axis(n)
    assert val == pytest.approx(n @ I @ n / (n @ n), rel=1e-12)
    assert t.about_axis(7.5 * n) == pytest.approx(val, rel=1e-12)
    lo, hi = t.principal_moments[[0, 2]]
    assert lo * (1 - 1e-12) <= val <= hi * (1 + 1e-12)


def test_radius_of_gyration_and_ellipsoids():
    """Sphere: k = sqrt(2/5) r; equivalent ellipsoid of a sphere has semi-axes r (rtol 1e-12)."""
    s = bodies.solid_sphere(3.0, 0.5)
    assert s.radius_of_gyration([1.0, 1.0, 0.0]) == pytest.approx(np.sqrt(0.4) * 0.5, rel=1e-12)
    np.testing.assert_allclose(s.principal_radii_of_gyration(), np.sqrt(0.4) * 0.5, rtol=1e-12)
    np.testing.assert_allclose(s.ellipsoid('equivalent').semi_axes, 0.5, rtol=1e-12)
    box = bodies.solid_box(2.0, 1.0, 2.0, 3.0)
    ell = box.ellipsoid('inertia')
    np.testing.assert_allclose(ell.semi_axes, 1.0 / np.sqrt(box.principal_moments), rtol=1e-12)
    x, y, z = ell.surface(8)
    pts = np.stack([x, y, z], axis=-1) - ell.center
    np.testing.assert_allclose(np.einsum('...i,ij,...j->...', pts, box.matrix, pts), 1.0,
                               rtol=1e-12)
    np.testing.assert_allclose(Rotation.from_quat(ell.quaternion).as_matrix(), ell.axes,
                               atol=1e-12)


def test_equivalent_ellipsoid_of_a_solid_ellipsoid_point_cloud():
    """A sampled uniform ellipsoid (0.3, 0.5, 1.1 m) recovers its semi-axes (rtol 1e-2)."""
    rng = np.random.default_rng(7)
    u = rng.uniform(-1.0, 1.0, (200_000, 3))
    pts = u[np.sum(u**2, axis=1) <= 1.0] * [0.3, 0.5, 1.1]
    cloud = InertiaTensor.from_point_masses(pts, 2.0 / len(pts))
    np.testing.assert_allclose(np.sort(cloud.ellipsoid('equivalent').semi_axes),
                               [0.3, 0.5, 1.1], rtol=1e-2)


# ---------------------------------------------------------------------------------------------
# dynamics
# ---------------------------------------------------------------------------------------------
@PROPS
@given(I=_tensors, w=_vec3, v=_vec3, m=_mass)
def test_kinetic_energy_is_half_omega_dot_L(I, w, v, m):
    """T_rot = 1/2 w.L, T = 1/2 m v^2 + T_rot, and T_rot >= 0 (rtol 1e-12)."""
    body = InertiaTensor(I, m)
    L = body.angular_momentum(w)
    t_rot = body.kinetic_energy(w)
    assert t_rot == pytest.approx(0.5 * w @ L, rel=1e-12, abs=1e-300)
    assert t_rot >= 0.0
    assert body.kinetic_energy(w, v) == pytest.approx(t_rot + 0.5 * m * v @ v, rel=1e-12)


@PROPS
@given(J=_second_moments, R=_rotations, m=_mass, w=_vec3, v=_vec3, c=_vec3, p=_vec3)
def test_angular_momentum_about_point_matches_particle_sum(J, R, m, w, v, c, p):
    """L_P = I_C w + m r_PC x v_C equals sum m_k (r_k - P) x v_k over a particle model.

    Six particles of m/6 at c +- sqrt(3 J_k / m) along each principal axis reproduce the tensor
    (checked, rtol 1e-12); their velocities are those of the rigid motion (v, w).
    """
    I = _physical(J, R)
    offs = np.concatenate([R * np.sqrt(3.0 * J / m), -R * np.sqrt(3.0 * J / m)], axis=1).T
    pos = c + offs
    vel = v + np.cross(w, offs)
    cloud = InertiaTensor.from_point_masses(pos, m / 6)
    np.testing.assert_allclose(cloud.matrix, I, rtol=0, atol=1e-12 * np.max(I))
    L_sum = np.sum((m / 6) * np.cross(pos - p, vel), axis=0)
    L = InertiaTensor(I, m, com=c).angular_momentum(w, velocity=v, point=p)
    scale = (np.max(I) + m * np.sum((c - p) ** 2)) * np.linalg.norm(w) \
        + m * np.linalg.norm(c - p) * np.linalg.norm(v) + m * np.max(offs**2) * np.linalg.norm(w)
    np.testing.assert_allclose(L, L_sum, rtol=0, atol=1e-11 * max(scale, 1e-300))
    L_c = InertiaTensor(I, m, com=c).angular_momentum(w)
    np.testing.assert_allclose(L_c, I @ w, rtol=0, atol=1e-13 * np.max(I) * np.linalg.norm(w))


def test_pendulum_periods():
    """Simple pendulum 2 pi sqrt(l/g); rod about its end 2 pi sqrt(2L/(3g)) (rtol 1e-12)."""
    g = ti.STANDARD_GRAVITY
    bob = bodies.point_mass(0.7, (0.0, 0.0, -2.0))
    assert bob.pendulum_period([0.0, 0.0, 0.0], [1.0, 0.0, 0.0]) == pytest.approx(
        2 * np.pi * np.sqrt(2.0 / g), rel=1e-12)
    # an offset along the pivot axis changes neither I about the axis nor h
    bob_off = bodies.point_mass(0.7, (0.5, 0.0, -2.0))
    assert bob_off.pendulum_period([0.0, 0.0, 0.0], [3.0, 0.0, 0.0]) == pytest.approx(
        2 * np.pi * np.sqrt(2.0 / g), rel=1e-12)
    rod = bodies.thin_rod(1.3, 1.5, about='end')
    assert rod.pendulum_period([0.0, 0.0, 0.0], [0.0, 1.0, 0.0], g=9.81) == pytest.approx(
        2 * np.pi * np.sqrt(2 * 1.5 / (3 * 9.81)), rel=1e-12)
    assert ti.pendulum_period(2.0, 1.0, 0.5, g=4.0) == pytest.approx(2 * np.pi, rel=1e-15)


@PROPS
@given(I=_tensors, m=_mass, seed=st.integers(0, 2**32 - 1))
def test_power_identity_holds_with_newton_euler(I, m, seed):
    """dT/dt (analytic) == v.F + w.M when F = m a and M from Euler's equation (rtol 1e-10)."""
    rng = np.random.default_rng(seed)
    v, a, w, wd = (rng.normal(size=(6, 3)) for _ in range(4))
    rate = ti.kinetic_energy_rate(I, m, v, a, w, wd)
    power = ti.mechanical_power(v, m * a, w, ti.euler_torque(I, w, wd))
    scale = m * np.abs(v * a).sum(axis=1) + np.abs(w * (I @ wd.T).T).sum(axis=1)
    np.testing.assert_allclose(rate, power, rtol=0, atol=1e-12 * np.max(scale))


def _simulate(I: np.ndarray, m: float, t: np.ndarray):
    """Integrate Euler's equations and Newton's law under smooth known torque and force."""
    from scipy.integrate import solve_ivp

    def torque(s):
        return np.array([np.sin(s), 0.5 * np.cos(2 * s), 0.2])

    def force(s):
        return np.array([1.0, -np.sin(s), 0.3 * s])

    def rhs(s, y):
        w, v = y[:3], y[3:]
        return np.concatenate([ti.euler_omega_dot(I, w, torque(s)), force(s) / m]) + 0 * v[0]

    sol = solve_ivp(rhs, (t[0], t[-1]), [0.3, -0.2, 1.0, 0.5, 0.0, -0.1], t_eval=t,
                    rtol=1e-11, atol=1e-12)
    w, v = sol.y[:3].T, sol.y[3:].T
    return w, v, np.array([torque(s) for s in t]), np.array([force(s) for s in t])


def test_power_identity_residual_on_a_simulated_trajectory():
    """Residual of sampled dT/dt - (v.F + w.M) is ~0 for the right inertia, not for a wrong one.

    With 2001 samples over 4 s the finite-difference residual is below 1e-4 of the power
    scale; using an inertia 10% too large in T makes it exceed 1e-2.
    """
    I = bodies.solid_box(2.0, 0.3, 0.5, 0.7).matrix
    m = 2.0
    t = np.linspace(0.0, 4.0, 2001)
    w, v, tau, f = _simulate(I, m, t)
    power = ti.mechanical_power(v, f, w, tau)
    energy = ti.kinetic_energy(I, m, w, v)
    res = ti.power_identity_residual(t, energy, v, f, w, tau)
    scale = np.max(np.abs(power))
    assert np.max(np.abs(res)) < 1e-4 * scale
    wrong = ti.kinetic_energy(1.1 * I, m, w, v)
    assert np.max(np.abs(ti.power_identity_residual(t, wrong, v, f, w, tau))) > 1e-2 * scale


def test_power_identity_residual_rejects_bad_time():
    """Non-increasing t and mismatched energy raise ValueError naming the argument."""
    z = np.zeros((3, 3))
    with pytest.raises(ValueError, match='t: must be strictly increasing'):
        ti.power_identity_residual([0.0, 1.0, 1.0], np.zeros(3), z, z, z, z)
    with pytest.raises(ValueError, match=r'energy: expected shape \(3,\)'):
        ti.power_identity_residual([0.0, 1.0, 2.0], np.zeros(4), z, z, z, z)


# ---------------------------------------------------------------------------------------------
# documentation
# ---------------------------------------------------------------------------------------------
def _public_callables():
    """Every public function and public method/property of the toolkit's classes."""
    import inspect
    out = []
    for mod in (ti, bodies):
        for name in mod.__all__:
            obj = getattr(mod, name)
            if inspect.isfunction(obj):
                out.append((f'{mod.__name__}.{name}', obj))
            elif inspect.isclass(obj):
                out.append((f'{mod.__name__}.{name}', obj))
                for attr, member in vars(obj).items():
                    if attr.startswith('_'):
                        continue
                    if isinstance(member, property):
                        member = member.fget
                    elif isinstance(member, classmethod | staticmethod):
                        member = member.__func__
                    if inspect.isfunction(member):
                        out.append((f'{mod.__name__}.{name}.{attr}', member))
    return out


@pytest.mark.parametrize(('qualname', 'obj'), _public_callables(), ids=lambda x: str(x)[:60])
def test_every_public_callable_documents_its_parameters(qualname, obj):
    """Each public function/method has a docstring naming every one of its parameters."""
    import inspect
    doc = inspect.getdoc(obj)
    assert doc, f'{qualname} has no docstring'
    if inspect.isclass(obj):
        return
    params = [p for p in inspect.signature(obj).parameters if p not in ('self', 'cls')]
    missing = [p for p in params if not re.search(rf'\b{p}\b', doc)]
    assert not missing, f'{qualname}: parameters {missing} not documented'


def test_array_functions_accept_an_inertia_tensor():
    """Functions taking I accept an InertiaTensor as well as a matrix (exact agreement)."""
    body = bodies.solid_box(2.0, 0.3, 0.5, 0.7)
    w, wd = np.array([0.1, -0.4, 0.9]), np.array([1.0, 0.5, -0.2])
    np.testing.assert_array_equal(ti.euler_torque(body, w, wd),
                                  ti.euler_torque(body.matrix, w, wd))
    np.testing.assert_array_equal(ti.principal_axes(body)[1], body.principal_axes)
    assert ti.check_physical(body).valid


def test_axes_to_quaternion_ros_order():
    """Identity -> [0, 0, 0, 1]; 90 deg about z -> [0, 0, sin 45, cos 45] (atol 1e-15)."""
    np.testing.assert_allclose(ti.axes_to_quaternion(np.eye(3)), [0, 0, 0, 1], atol=1e-15)
    rz = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    s = np.sqrt(0.5)
    np.testing.assert_allclose(ti.axes_to_quaternion(rz), [0, 0, s, s], atol=1e-15)
