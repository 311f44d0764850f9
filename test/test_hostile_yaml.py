"""The limits of the YAML inputs, in-process and fast (the subprocess corpus is
:mod:`test_fuzz_yaml`): the wheels and rotors files, scene budgets, the integrator guard,
the option validators."""
from __future__ import annotations

import argparse
import copy
import time
from pathlib import Path

import pytest
import yaml

from conftest import ROOT
from inertia_ros.core.scene import Scene, SceneError
from inertia_ros.io.rotors import load_rotors, rotors_from_dict
from inertia_ros.io.wheels import load_wheels, wheels_from_dict

WHEEL = {'joint': 'rw1', 'axis': [1.0, 0.0, 0.0], 'inertia': 1e-3}
ROTOR = {'joint': 'a', 'position': [0.1, 0, 0], 'spin': 1, 'k_f': 1e-5, 'k_m': 1e-7}
DEFAULT = yaml.safe_load((ROOT / 'config' / 'scenes' / 'default.yaml').read_text())
WHEELS_SCENE = yaml.safe_load((ROOT / 'config' / 'scenes' / 'wheels.yaml').read_text())


@pytest.mark.parametrize(('entry', 'pattern'), [
    ({'inertia': True}, r'wheels\[0\]\.inertia: must be a number, got True'),
    ({'inertia': '1e-3'}, r'inertia: must be a number'),
    ({'axis': ['1', '0', '0']}, r'axis\[0\]: must be a number'),
    ({'axis': [True, False, False]}, r'axis\[0\]: must be a number'),
    ({'axis': 'x'}, r'axis: must be a list of 3 numbers'),
    ({'axis': [1e200, 0, 0]}, r'axis\[0\]: must be a finite number of magnitude at most 1e\+06'),
    ({'inertia_std': 1e300}, r'inertia_std: must be a finite number'),
    ({'inertia_std': 2e-3}, r'inertia_std: must be at most the value it belongs to'),
    ({'joint': 'a\x01b'}, r'joint: must be a printable name'),
    ({'joint': ['a']}, r'joint: must be a joint name'),
])
def test_wheels_values_must_be_numbers_in_range(entry: dict, pattern: str) -> None:
    """Booleans and strings are not numbers; values out of range are refused (one line)."""
    with pytest.raises(ValueError, match=pattern) as err:
        wheels_from_dict({'wheels': [dict(WHEEL, **entry)]}, 'w.yaml')
    assert str(err.value).startswith('w.yaml: ') and '\n' not in str(err.value)


def test_wheels_and_rotors_files_agree_on_top_level_keys_and_count() -> None:
    """An unknown top-level key is refused by both files; at most 64 entries."""
    with pytest.raises(ValueError, match=r"unknown top-level key\(s\) \['extra'\]"):
        wheels_from_dict({'wheels': [WHEEL], 'extra': 1})
    with pytest.raises(ValueError, match=r"unknown top-level key\(s\) \['extra'\]"):
        rotors_from_dict({'rotors': [ROTOR], 'extra': 1})
    many = [dict(WHEEL, joint=f'w{i}') for i in range(65)]
    with pytest.raises(ValueError, match='65 wheels, more than 64'):
        wheels_from_dict({'wheels': many})
    assert len(wheels_from_dict({'wheels': many[:64]})) == 64


@pytest.mark.parametrize(('entry', 'pattern'), [
    ({'k_f': True}, r'k_f: must be a number, got True'),
    ({'spin': True}, r'spin: must be \+1 or -1'),
    ({'spin': '1'}, r'spin: must be \+1 or -1'),
    ({'k_m_std': 1e300}, r'k_m_std: must be a finite number'),
    ({'k_f_std': 2e-5}, r'k_f_std: must be at most the value'),
    ({'time_constant': 100.0}, r'time_constant: must be a finite number of magnitude at most 10'),
])
def test_rotor_values_must_be_numbers_in_range(entry: dict, pattern: str) -> None:
    """The rotors file checks as the wheels file does."""
    with pytest.raises(ValueError, match=pattern):
        rotors_from_dict({'rotors': [dict(ROTOR, **entry)]}, 'r.yaml')


def test_yaml12_floats_and_duplicate_keys(tmp_path: Path) -> None:
    """``1e-1`` is a number (YAML 1.1 made it a string); a key given twice is refused."""
    p = tmp_path / 'r.yaml'
    p.write_text('rotors: [{joint: a, position: [1e-1, -1E-1, 0], spin: 1, k_f: 1e-5, '
                 'k_m: 1e-7}]\n')
    assert load_rotors(p).rotors[0].position.tolist() == [0.1, -0.1, 0.0]
    p.write_text('wheels: [{joint: a, axis: [1, 0, 0], inertia: 1, inertia: 2}]\n')
    with pytest.raises(ValueError, match=r"line 1: not valid YAML: duplicate key 'inertia'"):
        load_wheels(p)
    p.write_bytes(b'wheels: [{joint: \xe9, axis: [1, 0, 0], inertia: 1}]\n')
    with pytest.raises(ValueError, match=rf'^{p}: not UTF-8 text \(byte 17\)'):
        load_wheels(p)


def _scene(base: dict, **changes: object) -> dict:
    d = copy.deepcopy(base)
    for dotted, v in changes.items():
        *head, last = dotted.split('__')
        node = d
        for k in head:
            node = node[int(k)] if isinstance(node, list) else node[k]
        node[last] = v
    return d


@pytest.mark.parametrize(('changes', 'pattern'), [
    ({'duration': 1e7}, r'duration: at most 1e\+06 s'),
    ({'duration': 8000.0}, r'duration: 8000 s at these rates makes about 2\.4e\+06 samples'),
    ({'torque__0__n_freq': 10**9}, r'torque\[0\]\.n_freq: 1000000000 frequencies'),
    ({'torque': [{'type': 'prbs', 'amplitude': 0.1, 'bit_time': 1e-12}]},
     r'torque\[0\]\.bit_time: 1e-12 s makes 6e\+13 levels'),
    ({'gyro__noise_std': 1e300}, r'gyro\.noise_std: must be at most 1e\+12 in magnitude'),
    ({'imperfections__torque_delay': 11.0}, r'torque_delay: must be within \+-10 s'),
    ({'imperfections__drop_rate': 0.999999}, r'drop_rate: must be at most 0\.9'),
    ({'initial_omega': [1e6, 0.0, 0.0]},
     r'initial_omega: 60 s .* initial rate of 8.26e\+05 rad/s needs about 4.96e\+09 '
     r'integration steps'),
    ({'gyro__frame_id': 'f' * 257}, r'gyro\.frame_id: at most 256 characters, got 257'),
    ({'seed': 2**63}, r'seed: must be < 2\^63'),
])
def test_scene_budgets_refuse_before_allocating(changes: dict, pattern: str) -> None:
    """Each limit is one SceneError naming the key, in well under a second."""
    t0 = time.perf_counter()
    with pytest.raises(SceneError, match=pattern):
        Scene.from_dict(_scene(DEFAULT, **changes))
    assert time.perf_counter() - t0 < 1.0


@pytest.mark.parametrize(('changes', 'pattern'), [
    ({'wheels__rate': 1e9}, r'duration: 20 s at these rates makes about 6e\+10 samples'),
    ({'wheels__list__0__speed': {'amplitude': 1e9}}, r'spin at up to 1e\+09 rad/s'),
    ({'duration': 2000.0}, r'with 3 wheels or rotors .* needs about 5e\+05 integration steps'),
    ({'wheels__list': [dict(WHEEL, joint=f'w{i}') for i in range(65)]},
     r'wheels\.list: 65 wheels, more than the simulator allows \(64\)'),
])
def test_wheel_scene_budgets(changes: dict, pattern: str) -> None:
    """Wheels: JointState samples, speed, integration work and count are bounded."""
    with pytest.raises(SceneError, match=pattern):
        Scene.from_dict(_scene(WHEELS_SCENE, **changes))


def test_integrator_guard_refuses_a_runaway_at_once() -> None:
    """A 1e-12 kg m^2 body under 0.1 N m passes the static bound (its rate starts at 0.06
    rad/s) but the first segment's rate bound exceeds the step budget: refused at once."""
    from inertia_ros.core.simulation import simulate

    scene = Scene.from_dict(_scene(DEFAULT, body={'inertia': [1e-12, 1e-12, 1e-12, 0, 0, 0]}))
    t0 = time.perf_counter()
    with pytest.raises(SceneError, match='turns too fast to simulate in bounded time'):
        simulate(scene)
    assert time.perf_counter() - t0 < 2.0


def test_option_validators() -> None:
    """Numbers: no underflow to 0, short echoes; paths and names: bounded, non-empty."""
    from inertia_ros.cli import bounded, name_arg, path_arg

    parse = bounded(0.0, 0.5, '')
    assert parse('0') == 0.0 and parse('0.25') == 0.25 and parse('0e5') == 0.0
    for bad, pattern in (('1e-400', 'too small for a float'), ('', 'must be a number'),
                         ('nan', r'within \[0, 0.5\]'), ('inf', r'within \[0, 0.5\]'),
                         ('1' * 5000, r"\(5000 characters\)")):
        with pytest.raises(argparse.ArgumentTypeError, match=pattern) as err:
            parse(bad)
        assert len(str(err.value)) < 120
    assert path_arg('a/b.json') == Path('a/b.json')
    for bad in ('', ' ', 'a/' * 3000, 'x' * 256):
        with pytest.raises(argparse.ArgumentTypeError):
            path_arg(bad)
    assert name_arg('/imu') == '/imu'
    for bad in ('', 'a b', 'x' * 257, 'a\x00'):
        with pytest.raises(argparse.ArgumentTypeError):
            name_arg(bad)
