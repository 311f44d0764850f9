"""Scenes: the dict/YAML schema, its validation messages, torque profiles, composite bodies."""
from __future__ import annotations

import copy

import numpy as np
import pytest

from conftest import ROOT
from inertia_ros.core import bodies
from inertia_ros.core.scene import (
    PART_SHAPES,
    TORQUE_TYPES,
    Scene,
    SceneError,
    TorqueComponent,
    parts_inertia,
    rpy_matrix,
)
from inertia_ros.io.scene_file import load_scene, load_scene_dict

SCENES = sorted((ROOT / 'config' / 'scenes').glob('*.yaml'))
NOMINAL = {
    'name': 'nominal', 'seed': 7, 'duration': 60.0,
    'body': {'inertia': [1.0, 1.2, 0.9, 0.05, -0.03, 0.02]},
    'initial_omega': [0.05, -0.03, 0.02],
    'torque': [{'type': 'multisine', 'amplitude': 0.1, 'axes': ['x', 'y', 'z']}],
    'disturbance': [0.0, 0.0, 0.0], 'command_rate': 50.0,
    'gyro': {'rate': 200.0, 'noise_std': 0.002, 'bias': [0, 0, 0], 'frame_id': 'base_link'},
    'torque_sensor': {'rate': 50.0, 'noise_rel': 0.02, 'noise_std': 0.0},
    'imperfections': {'timestamp_jitter': 0.0, 'torque_delay': 0.0, 'drop_rate': 0.0},
}


def _with(path: str, value, base=None):
    """A copy of the nominal dict with the dotted ``path`` set (``None`` value deletes it)."""
    d = copy.deepcopy(NOMINAL if base is None else base)
    keys = path.split('.')
    node = d
    for k in keys[:-1]:
        node = node[int(k)] if isinstance(node, list) else node[k]
    last = keys[-1]
    if value is None:
        del node[last]
    elif isinstance(node, list):
        node[int(last)] = value
    else:
        node[last] = value
    return d


def test_scene_files_exist_for_every_case_the_issue_lists():
    """config/scenes has the default and one scene per case the issue asks for."""
    names = {p.stem for p in SCENES}
    assert {'default', 'satellite', 'cubesat', 'torque_free', 'single_axis', 'disturbance',
            'composite', 'payload_change'} <= names


@pytest.mark.parametrize('path', SCENES, ids=[p.stem for p in SCENES])
def test_every_shipped_scene_loads_and_is_physical(path):
    """Each shipped scene validates; its tensor is symmetric positive definite."""
    scene = load_scene(path)
    ev = np.linalg.eigvalsh(scene.inertia)
    assert ev[0] > 0.0
    np.testing.assert_allclose(scene.inertia, scene.inertia.T, rtol=0, atol=0)
    assert scene.description, 'every shipped scene says what it shows'


def test_default_scene_is_the_nominal_target():
    """default.yaml is the issue-4 nominal scene (tensor, rates, noise, duration)."""
    s = load_scene(ROOT / 'config' / 'scenes' / 'default.yaml')
    np.testing.assert_allclose(s.inertia, [[1.0, 0.05, -0.03], [0.05, 1.2, 0.02],
                                           [-0.03, 0.02, 0.9]], rtol=0, atol=0)
    assert (s.gyro.rate, s.gyro.noise_std) == (200.0, 0.002)
    assert (s.torque_sensor.rate, s.torque_sensor.noise_rel) == (50.0, 0.02)
    assert s.duration == 60.0 and s.command_rate == 50.0
    assert [c.type for c in s.torque] == ['multisine']
    np.testing.assert_allclose(s.torque[0].amplitude, [0.1, 0.1, 0.1], rtol=0, atol=0)


def test_nominal_dict_fields():
    """from_dict maps every key of the schema onto the Scene fields."""
    s = Scene.from_dict(NOMINAL)
    assert s.name == 'nominal' and s.seed == 7 and s.duration == 60.0
    assert s.inertia[0, 1] == 0.05 and s.inertia[0, 2] == -0.03 and s.inertia[1, 2] == 0.02
    np.testing.assert_allclose(s.initial_omega, [0.05, -0.03, 0.02], rtol=0, atol=0)
    assert s.gyro.frame_id == 'base_link' and s.gyro.bias == (0.0, 0.0, 0.0)
    assert s.inertia_change is None and s.parts == ()
    assert s.to_dict() == NOMINAL


def test_minimal_scene_defaults():
    """Only body is required; the defaults are documented values."""
    s = Scene.from_dict({'body': {'inertia': [1, 2, 2.5, 0, 0, 0]}})
    assert s.duration == 10.0 and s.seed == 0 and s.torque == ()
    assert s.command_rate == 50.0 and s.gyro.rate == 200.0 and s.torque_sensor.rate == 50.0
    assert s.gyro.noise_std == 0.0 and s.gyro.frame_id == 'base_link'
    np.testing.assert_allclose(s.disturbance, 0.0, rtol=0, atol=0)


def test_inertia_as_3x3_equals_theta_form():
    """A 3x3 nested list gives the same tensor as the six-element theta list."""
    m = [[1.0, 0.05, -0.03], [0.05, 1.2, 0.02], [-0.03, 0.02, 0.9]]
    a = Scene.from_dict({'body': {'inertia': m}})
    b = Scene.from_dict(NOMINAL)
    np.testing.assert_allclose(a.inertia, b.inertia, rtol=0, atol=0)


def test_scene_arrays_are_read_only():
    """The scene's arrays cannot be modified in place."""
    s = Scene.from_dict(NOMINAL)
    with pytest.raises(ValueError):
        s.inertia[0, 0] = 5.0
    with pytest.raises(ValueError):
        s.initial_omega[0] = 5.0


BAD = [
    ('scene.nosuchkey: unknown key', _with('nosuchkey', 1)),
    (r'gyro\.nosie_std: unknown key', _with('gyro.nosie_std', 0.1)),
    ('body: missing', _with('body', None)),
    ('body: give exactly one of inertia', _with('body', {'inertia': [1, 1, 1, 0, 0, 0],
                                                         'parts': []})),
    (r'body\.inertia: must be a list of 6', _with('body.inertia', [1, 2, 3])),
    (r'body\.inertia: not positive definite', _with('body.inertia', [1, 1, -1, 0, 0, 0])),
    (r'body\.inertia: violates the triangle', _with('body.inertia', [1, 1, 3, 0, 0, 0])),
    (r'body\.inertia: 3x3 matrix must be symmetric',
     _with('body.inertia', [[1, 0.1, 0], [0, 1, 0], [0, 0, 1]])),
    (r'body\.inertia\[2\]: must be finite', _with('body.inertia.2', float('nan'))),
    ('duration: must be a positive number', _with('duration', -1.0)),
    ('duration: must be a number', _with('duration', 'long')),
    ('duration: .* more than the simulator allows', _with('duration', 1e6)),
    ('seed: must be an integer', _with('seed', 1.5)),
    ('seed: must be >= 0', _with('seed', -3)),
    (r'initial_omega: must be a list of 3', _with('initial_omega', [0, 0])),
    (r'gyro\.rate: must be a positive number', _with('gyro.rate', 0)),
    (r'gyro\.noise_std: must be >= 0', _with('gyro.noise_std', -0.1)),
    (r'gyro\.frame_id: must be a string', _with('gyro.frame_id', 5)),
    (r'gyro\.frame_id: must not be empty', _with('gyro.frame_id', '')),
    (r'torque_sensor\.noise_rel: must be >= 0', _with('torque_sensor.noise_rel', -1)),
    ('command_rate: must be a positive number', _with('command_rate', 0.0)),
    (r'imperfections\.drop_rate: must be at most 0.9', _with('imperfections.drop_rate', 1.0)),
    (r'imperfections\.timestamp_jitter: must be <= a quarter',
     _with('imperfections.timestamp_jitter', 0.01)),
    (r'torque\[0\]\.type: must be one of', _with('torque.0.type', 'sawtooth')),
    (r'torque\[0\]\.type: missing', _with('torque.0', {'amplitude': 0.1})),
    (r'torque\[0\]\.amplitude: missing', _with('torque.0', {'type': 'prbs'})),
    (r'torque\[0\]\.amplitude\[1\]: must be >= 0', _with('torque.0.amplitude', [0.1, -1, 0])),
    (r'torque\[0\]\.axes\[0\]: must be one of x, y, z', _with('torque.0.axes', ['w'])),
    (r"torque\[0\]\.axes: axis 'x' listed twice", _with('torque.0.axes', ['x', 'x'])),
    (r'torque\[0\]\.f_max: must exceed f_min', _with('torque.0.f_max', 0.01)),
    (r'torque\[0\]\.n_freq: must be >= 1', _with('torque.0.n_freq', 0)),
    (r'torque\[0\]\.phases: must be one of', _with('torque.0.phases', 'zero')),
    (r'torque\[0\]\.bit_time: unknown key', _with('torque.0.bit_time', 1.0)),
    (r'torque\[0\]\.start: must be before the end', _with('torque.0.start', 70.0)),
    (r'torque\[0\]\.end: must be after start',
     _with('torque.0', {'type': 'prbs', 'amplitude': 0.1, 'start': 5.0, 'end': 3.0})),
    (r'torque\[0\]\.frequency: missing', _with('torque.0', {'type': 'sine',
                                                            'amplitude': 0.1})),
    (r'torque\[0\]\.period: must be >= 2 \* width',
     _with('torque.0', {'type': 'doublet', 'amplitude': 0.1, 'width': 2.0, 'period': 3.0})),
    (r'inertia_change\.time: must be before the end',
     _with('inertia_change', {'time': 60.0, 'inertia': [1, 1, 1, 0, 0, 0]})),
    (r'inertia_change\.time: missing', _with('inertia_change', {'inertia': [1, 1, 1, 0, 0, 0]})),
    (r'inertia_change: give exactly one of', _with('inertia_change', {'time': 5.0})),
    (r'body\.parts\[0\]\.shape: must be one of',
     _with('body', {'parts': [{'shape': 'torus', 'mass': 1.0}]})),
    (r'body\.parts\[0\]\.size: missing',
     _with('body', {'parts': [{'shape': 'solid_box', 'mass': 1.0}]})),
    (r'body\.parts\[0\]\.mass: must be a positive number',
     _with('body', {'parts': [{'shape': 'solid_sphere', 'mass': 0.0, 'radius': 1.0}]})),
    (r'body\.parts\[0\]\.radius: unknown key',
     _with('body', {'parts': [{'shape': 'solid_box', 'mass': 1.0, 'size': [1, 1, 1],
                               'radius': 1.0}]})),
    (r'body\.parts \(composite\): not positive definite',
     _with('body', {'parts': [{'shape': 'thin_rod', 'mass': 1.0, 'length': 1.0}]})),
    (r'body\.parts: must be a non-empty list', _with('body', {'parts': []})),
]


@pytest.mark.parametrize(('pattern', 'd'), BAD, ids=[p for p, _ in BAD])
def test_invalid_scene_raises_scene_error_naming_the_key(pattern, d):
    """Each invalid scene dict raises SceneError (a ValueError) whose message names the key."""
    with pytest.raises(SceneError, match=pattern):
        Scene.from_dict(d)
    assert issubclass(SceneError, ValueError)


def test_load_scene_prefixes_file_name(tmp_path):
    """load_scene reports problems as one line 'FILE: key: problem'."""
    p = tmp_path / 'bad.yaml'
    p.write_text('body:\n  inertia: [1, 1, 1, 0, 0, 0]\ngyro:\n  rate: -5\n')
    with pytest.raises(SceneError) as exc:
        load_scene(p)
    msg = str(exc.value)
    assert msg.startswith(f'{p}: gyro.rate: must be a positive number') and '\n' not in msg


@pytest.mark.parametrize(('text', 'pattern'), [
    ('body: [1, 2\n', r'line \d+: not valid YAML'),
    ('- 1\n- 2\n', 'must be a mapping of keys, got list'),
    ('', 'must be a mapping of keys, got NoneType'),
])
def test_load_scene_yaml_problems(tmp_path, text, pattern):
    """Unparsable or non-mapping YAML gives one SceneError line naming the file."""
    p = tmp_path / 's.yaml'
    p.write_text(text)
    with pytest.raises(SceneError, match=pattern) as exc:
        load_scene_dict(p)
    assert str(exc.value).startswith(str(p)) and '\n' not in str(exc.value)


def test_load_scene_missing_file(tmp_path):
    """A missing scene file is a SceneError naming it."""
    with pytest.raises(SceneError, match='no such scene file'):
        load_scene(tmp_path / 'nope.yaml')


# ------------------------------------------------------------------------- torque profiles
T = np.arange(0, 3001) / 50.0   # 60 s command grid


def _component(d, duration=60.0):
    return TorqueComponent.from_dict(d, 'torque[0]', duration)


@pytest.mark.parametrize('typ', sorted(TORQUE_TYPES))
def test_every_profile_respects_amplitude_axes_and_window(typ):
    """Every type stays within its peak, is zero off its axes and outside [start, end)."""
    d = {'type': typ, 'amplitude': [0.2, 0.0, 0.1], 'axes': ['x', 'z'], 'start': 5.0,
         'end': 50.0}
    if typ == 'sine':
        d['frequency'] = 0.3
    c = _component(d)
    u = c.evaluate(T, np.random.default_rng(1))
    assert u.shape == (T.size, 3)
    assert np.all(np.abs(u[:, 0]) <= 0.2 + 1e-12) and np.all(np.abs(u[:, 2]) <= 0.1 + 1e-12)
    np.testing.assert_array_equal(u[:, 1], 0.0)
    outside = (T < 5.0) | (T >= 50.0)
    np.testing.assert_array_equal(u[outside], 0.0)
    assert np.abs(u[~outside]).max() > 0.0


def test_multisine_peak_equals_amplitude_and_axes_are_not_collinear():
    """Multisine reaches its peak exactly and the three axes are linearly independent."""
    c = _component({'type': 'multisine', 'amplitude': [0.1, 0.2, 0.3]})
    u = c.evaluate(T, np.random.default_rng(0))
    np.testing.assert_allclose(np.abs(u).max(axis=0), [0.1, 0.2, 0.3], rtol=1e-12)
    s = np.linalg.svd(u / np.abs(u).max(axis=0), compute_uv=False)
    assert s[-1] / s[0] > 0.3


def test_random_phases_depend_on_the_generator_only():
    """Random-phase multisine: same seed same signal, other seed other signal."""
    c = _component({'type': 'multisine', 'amplitude': 0.1, 'phases': 'random'})
    a = c.evaluate(T, np.random.default_rng(4))
    b = c.evaluate(T, np.random.default_rng(4))
    e = c.evaluate(T, np.random.default_rng(5))
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - e).max() > 1e-3


def test_prbs_levels_and_hold_time():
    """PRBS takes only +-amplitude and changes only at multiples of the bit time."""
    c = _component({'type': 'prbs', 'amplitude': 0.05, 'bit_time': 0.5})
    u = c.evaluate(T, np.random.default_rng(2))
    np.testing.assert_allclose(np.abs(u), 0.05, rtol=0, atol=0)
    changes = T[1:][np.any(np.diff(u, axis=0) != 0, axis=1)]
    np.testing.assert_allclose(np.mod(changes + 1e-9, 0.5), 0.0, rtol=0, atol=1e-6)


def test_steps_are_held_and_bounded():
    """Steps hold a level for the whole period, within [-amplitude, amplitude]."""
    c = _component({'type': 'steps', 'amplitude': 0.05, 'period': 2.0})
    u = c.evaluate(T, np.random.default_rng(3))
    assert np.all(np.abs(u) <= 0.05)
    for k in range(29):
        block = u[(T >= 2.0 * k) & (T < 2.0 * (k + 1) - 1e-9)]
        np.testing.assert_array_equal(block, np.broadcast_to(block[0], block.shape))


def test_doublet_pattern():
    """Doublet: +A for width, -A for width, then zero until the next period."""
    c = _component({'type': 'doublet', 'amplitude': 0.1, 'axes': ['z'], 'width': 2.0,
                    'period': 10.0})
    u = c.evaluate(np.array([0.0, 1.9, 2.0, 3.9, 4.0, 9.9, 10.0, 12.5]),
                   np.random.default_rng(0))
    np.testing.assert_allclose(u[:, 2], [0.1, 0.1, -0.1, -0.1, 0, 0, 0.1, -0.1], atol=1e-15)
    np.testing.assert_array_equal(u[:, :2], 0.0)


def test_sequential_chirp_excites_one_axis_at_a_time():
    """A sequential chirp has at most one non-zero axis at every instant."""
    c = _component({'type': 'chirp', 'amplitude': 0.1})
    u = c.evaluate(T, np.random.default_rng(0))
    assert np.all(np.count_nonzero(u, axis=1) <= 1)
    for ax in range(3):
        assert np.abs(u[:, ax]).max() > 0.09


def test_constant_is_signed():
    """A constant component keeps the sign of its amplitude."""
    c = _component({'type': 'constant', 'amplitude': [0.01, -0.02, 0.0]})
    u = c.evaluate(T[:5], np.random.default_rng(0))
    np.testing.assert_array_equal(u, np.tile([0.01, -0.02, 0.0], (5, 1)))


# ------------------------------------------------------------------------- composite bodies
def test_rpy_matrix_is_urdf_convention():
    """rpy_matrix = Rz(yaw) Ry(pitch) Rx(roll), a proper rotation."""
    r, p, y = 0.3, -0.7, 1.9

    def rx(a):
        return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])

    def ry(a):
        return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])

    def rz(a):
        return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])

    R = rpy_matrix([r, p, y])
    np.testing.assert_allclose(R, rz(y) @ ry(p) @ rx(r), rtol=0, atol=1e-15)
    np.testing.assert_allclose(R @ R.T, np.eye(3), rtol=0, atol=1e-15)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-15)


def test_two_half_boxes_make_one_box():
    """Two boxes side by side (parallel-axis theorem) equal one box of twice the length."""
    half = {'shape': 'solid_box', 'mass': 1.5, 'size': [0.2, 0.3, 0.4]}
    parts = [dict(half, position=[-0.1, 0.0, 0.0]), dict(half, position=[0.1, 0.0, 0.0])]
    mat, mass, com = parts_inertia(parts)
    whole = bodies.solid_box(3.0, 0.4, 0.3, 0.4)
    np.testing.assert_allclose(mat, whole.matrix, rtol=1e-12, atol=1e-15)
    assert mass == pytest.approx(3.0, rel=1e-15)
    np.testing.assert_allclose(com, 0.0, rtol=0, atol=1e-15)


def test_rotated_part_and_off_centre_composite():
    """A yawed box swaps its x/y moments; an offset point mass adds m (|r|^2 1 - r r^T)."""
    mat, _, _ = parts_inertia([{'shape': 'solid_box', 'mass': 2.0, 'size': [0.1, 0.5, 0.2],
                                'rpy': [0.0, 0.0, np.pi / 2]}])
    np.testing.assert_allclose(mat, bodies.solid_box(2.0, 0.5, 0.1, 0.2).matrix,
                               rtol=1e-12, atol=1e-15)
    sphere = {'shape': 'solid_sphere', 'mass': 4.0, 'radius': 0.1}
    point = {'shape': 'point_mass', 'mass': 1.0, 'position': [0.5, 0.5, 0.0]}
    mat, mass, com = parts_inertia([sphere, point])
    c = np.array([0.1, 0.1, 0.0])
    expected = 0.016 * np.eye(3)
    for m_i, r in ((4.0, -c), (1.0, np.array([0.5, 0.5, 0.0]) - c)):
        expected = expected + m_i * (r @ r * np.eye(3) - np.outer(r, r))
    np.testing.assert_allclose(mat, expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(com, c, rtol=1e-12)
    assert mass == 5.0


def test_subtracted_part_is_a_hole():
    """Removing a box's half (subtract: true) leaves the other half's tensor."""
    whole = {'shape': 'solid_box', 'mass': 2.0, 'size': [0.4, 0.2, 0.2]}
    half = {'shape': 'solid_box', 'mass': 1.0, 'size': [0.2, 0.2, 0.2],
            'position': [0.1, 0.0, 0.0], 'subtract': True}
    mat, mass, com = parts_inertia([whole, half])
    np.testing.assert_allclose(mat, bodies.solid_box(1.0, 0.2, 0.2, 0.2).matrix,
                               rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(com, [-0.1, 0.0, 0.0], rtol=1e-12)
    assert mass == pytest.approx(1.0, rel=1e-15)


@pytest.mark.parametrize('shape', sorted(PART_SHAPES))
def test_every_part_shape_is_accepted(shape):
    """Each documented part shape builds with its documented size keys."""
    sizes = {'length': 0.4, 'size': [0.3, 0.2, 0.1], 'radius': 0.2, 'inner_radius': 0.1,
             'inertia': [0.1, 0.1, 0.1, 0, 0, 0]}
    part = {'shape': shape, 'mass': 1.0,
            **{k: sizes[k] for k in PART_SHAPES[shape]}}
    if shape == 'rectangular_lamina':
        part['size'] = [0.3, 0.2]
    base = {'shape': 'solid_sphere', 'mass': 1.0, 'radius': 0.1, 'position': [0, 0, 0.3]}
    s = Scene.from_dict({'body': {'parts': [base, part]}})
    assert np.linalg.eigvalsh(s.inertia)[0] > 0.0
    assert len(s.parts) == 2


def test_composite_scene_truth_matches_toolkit_composite():
    """The composite scene's tensor is the toolkit composite of its placed parts."""
    from inertia_ros.core.inertia import composite

    scene = load_scene(ROOT / 'config' / 'scenes' / 'composite.yaml')
    placed = []
    for p in scene.parts:
        prim = getattr(bodies, p['shape'])
        args = (p['size'] if 'size' in p else
                [p[k] for k in PART_SHAPES[p['shape']]])
        placed.append(prim(p['mass'], *args).transformed(rpy_matrix(p.get('rpy', [0, 0, 0])),
                                                         p.get('position', [0, 0, 0])))
    total = composite(placed)
    np.testing.assert_allclose(scene.inertia, total.matrix, rtol=1e-12, atol=0)
    assert scene.mass == pytest.approx(15.6, rel=1e-12)
    np.testing.assert_allclose(scene.com, total.com, rtol=1e-12, atol=0)
    assert Scene.from_dict(NOMINAL).mass is None, 'a bare tensor does not fix the mass'
    assert abs(scene.inertia[0, 2]) > 1e-3, 'the composite has products of inertia'
