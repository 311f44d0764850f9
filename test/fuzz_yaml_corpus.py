"""Hostile input of the newer kinds: scene YAML (``simulate``), wheels and rotors YAML
(``estimate --wheels/--rotors``) and option values, as command lines run in a subprocess.

:func:`build_cases` writes the files of every case under a directory and returns the
:class:`Case` list; :mod:`test_fuzz_yaml` runs them.  Expectations:

- ``refuse``: exit 2 and exactly one stderr line (short), nothing on stdout;
- ``ok``: exit 0;
- ``any``: exit 0, or a refusal as above.

Every case must also leave its inputs byte-for-byte unchanged, finish in < 10 s and stay
below 1 GiB of resident memory, and print no traceback.
"""
from __future__ import annotations

import copy
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from conftest import ROOT

__all__ = ['Case', 'build_cases', 'bomb', 'deep']

BAGS = ROOT / 'bags'
SCENES = ROOT / 'config' / 'scenes'
MB = 1 << 20


@dataclass
class Case:
    """One command line: ``python -m inertia_ros ARGV``; ``inputs`` must stay unchanged."""

    name: str
    argv: list[str]
    expect: str = 'refuse'
    inputs: list[Path] = field(default_factory=list)
    #: A text that must not appear on stdout or stderr (e.g. LAPACK's own message).
    forbid: str = ''
    #: A text the refusal must contain (e.g. the file's name).
    mention: str = ''
    #: Longest refusal line allowed [characters].
    max_line: int = 500


def bomb(levels: int = 9, fan: int = 9) -> str:
    """A flow-style "billion laughs": ``fan ** levels`` strings from a few hundred bytes."""
    out = '&l0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]'
    for i in range(1, levels + 1):
        out = f'[{out}, &l{i} [' + ', '.join([f'*l{i - 1}'] * fan) + ']]'
    return out


def deep(n: int = 10_000) -> str:
    """Flow sequences nested ``n`` deep."""
    return '[' * n + ']' * n


def _load(path: Path) -> dict:
    return yaml.safe_load(path.read_text())


def _put(d: dict, dotted: str, value: Any) -> dict:
    """A deep copy of ``d`` with ``dotted`` (``a.b.0.c``) set to ``value``."""
    d = copy.deepcopy(d)
    *head, last = dotted.split('.')
    node: Any = d
    for k in head:
        node = node[int(k)] if isinstance(node, list) else node.setdefault(k, {})
    if isinstance(node, list):
        node[int(last)] = value
    else:
        node[last] = value
    return d


def _write(out: Path, name: str, text: str | bytes) -> Path:
    p = out / name
    if isinstance(text, bytes):
        p.write_bytes(text)
    else:
        p.write_text(text)
    return p


def _big(out: Path, name: str) -> Path:
    """A 50 MB YAML file (a comment line, then sparse NUL bytes: written in microseconds)."""
    p = out / name
    with p.open('wb') as f:
        f.write(b'# a 50 MB file\nwheels: []\n')
        f.truncate(50 * MB)
    return p


def dump(d: dict) -> str:
    """``d`` as YAML text: JSON, which YAML reads, written 100 times faster than YAML."""
    return json.dumps(d, indent=1)


def _raw_field(base: dict, dotted: str, raw: str) -> str:
    """The YAML of ``base`` with ``dotted`` holding the raw YAML text ``raw`` (not quoted)."""
    marker = 'RAW_VALUE_MARKER'
    return dump(_put(base, dotted, marker)).replace(f'"{marker}"', raw, 1)


def scene_cases(out: Path) -> list[Case]:
    """``simulate SCENE -o OUT.mcap`` with hostile scenes."""
    default = _load(SCENES / 'default.yaml')
    wheels = _load(SCENES / 'wheels.yaml')
    rotors = _load(SCENES / 'quadrotor.yaml')
    cases: list[Case] = []

    def sim(name: str, text: str | bytes | Path, expect: str = 'refuse', extra: tuple = (),
            mention: str = '') -> None:
        path = text if isinstance(text, Path) else _write(out, f'{name}.yaml', text)
        argv = ['simulate', str(path), '-o', str(out / f'{name}.mcap'), '-q', *extra]
        cases.append(Case(f'scene/{name}', argv, expect, [path] if path.is_file() else [],
                          mention=mention))

    for f in ('name', 'description', 'body.inertia', 'torque', 'gyro.bias', 'gyro.frame_id',
              'initial_omega', 'imperfections'):
        sim(f'bomb_{f}', _raw_field(default, f, bomb()))
    sim('bomb_wheels_list', _raw_field(wheels, 'wheels.list', bomb()))
    sim('deep_body', _raw_field(default, 'body.inertia', deep()))
    sim('deep_block', 'body:\n' + ''.join('  ' * (i + 1) + f'k{i}:\n' for i in range(2000)))
    sim('digits_seed', _raw_field(default, 'seed', '9' * 5000), mention='digits')
    sim('digits_duration', _raw_field(default, 'duration', '9' * 5000))
    slow = {'gyro': dict(default['gyro'], rate=1.0), 'command_rate': 1.0,
            'torque_sensor': dict(default['torque_sensor'], rate=1.0)}
    sim('rotors_duration_1e6', dump({**rotors, **slow, 'duration': 1e6}))
    sim('rotors_duration_1e5', dump({**rotors, **slow, 'duration': 1e5,
                                     'rotors': dict(rotors['rotors'], rate=1.0)}))
    sim('wheels_rate_1e9', dump(_put(wheels, 'wheels.rate', 1e9)))
    prbs = {'type': 'prbs', 'amplitude': 0.1, 'bit_time': 1e-12}
    sim('prbs_bit_time', dump({**default, 'torque': [prbs]}))
    sim('multisine_n_freq', dump(_put(default, 'torque.0.n_freq', 10**9)))
    khz = {'gyro': dict(default['gyro'], rate=1000.0), 'command_rate': 1000.0,
           'torque_sensor': dict(default['torque_sensor'], rate=1000.0)}
    sim('khz_at_old_limit', dump({**default, **khz, 'duration': 5e7 / 3000}))
    for f, v in (('gyro.noise_std', 1e300), ('torque.0.amplitude', 1e300),
                 ('imperfections.torque_delay', 1e300), ('imperfections.torque_delay', 1e6),
                 ('gyro.bias', [1e300, 0, 0]), ('disturbance', [1e300, 0, 0]),
                 ('initial_omega', [1e6, 0, 0]), ('torque.0.amplitude', 1e12),
                 ('imperfections.drop_rate', 0.999999), ('duration', 1e12)):
        sim(f'{f}={v if not isinstance(v, list) else v[0]:g}', dump(_put(default, f, v)))
    sim('tiny_inertia', dump(_put(default, 'body.inertia', [1e-12, 1e-12, 1e-12, 0, 0, 0])),
        'any')
    sim('hover_thrust_1e300', dump(_put(rotors, 'rotors.hover_thrust', 1e300)))
    sim('hover_thrust_1e12', dump(_put(rotors, 'rotors.hover_thrust', 1e12)), 'any')
    sim('wheel_inertia_1e300', dump(_put(wheels, 'wheels.list.0.inertia', 1e300)))
    sim('wheel_inertia_1e12', dump(_put(wheels, 'wheels.list.0.inertia', 1e12)))
    sim('wheel_speed_1e300', dump(_put(wheels, 'wheels.list.0.speed.amplitude', 1e300)))
    sim('wheel_speed_1e9', dump(_put(wheels, 'wheels.list.0.speed.amplitude', 1e9)))
    sim('wheels_initial_rate', dump(_put(wheels, 'initial_omega', [1e6, 0, 0])))
    many = [{'joint': f'w{i}', 'axis': [1, 0, 0], 'inertia': 1e-3} for i in range(10_000)]
    sim('wheels_10000', dump(_put(wheels, 'wheels.list', many)))
    sim('wheels_65', dump(_put(wheels, 'wheels.list', many[:65])))
    sim('frame_id_1MB', dump(_put(default, 'gyro.frame_id', 'f' * 1_000_000)))
    sim('name_control_chars', dump(_put(default, 'gyro.frame_id', 'a\x01b')), 'any')
    sim('start_ns_past_2038', SCENES / 'default.yaml',
        extra=('--start-ns', str(2**31 * 10**9)))
    sim('start_ns_near_2038', SCENES / 'default.yaml',
        extra=('--start-ns', str((2**31 - 30) * 10**9)))
    sim('dup_key', 'name: a\nname: b\nbody: {inertia: [1, 1, 1, 0, 0, 0]}\n', mention='duplicate')
    sim('latin1', b'name: \xe9t\xe9\nbody: {inertia: [1, 1, 1, 0, 0, 0]}\n', mention='UTF-8')
    sim('recursive_alias', 'body: &a {inertia: [*a]}\n')
    sim('dev_zero', Path('/dev/zero'))
    sim('dev_urandom', Path('/dev/urandom'))
    fifo = out / 'scene.fifo'
    os.mkfifo(fifo)
    sim('fifo', fifo)
    sim('50MB', _big(out, 'big_scene.yaml'))
    sim('yaml12_float', _raw_field(default, 'initial_omega', '[5e-2, -3e-2, 2E-2]'), 'ok')
    # --force with the output being the input scene: the scene must survive
    same = _write(out, 'same.mcap', dump(default))
    cases.append(Case('scene/output_is_input', ['simulate', str(same), '-o', str(same),
                                                '--force', '-q'], 'refuse', [same]))
    return cases


def actuator_cases(out: Path) -> list[Case]:
    """``estimate LOG --wheels|--rotors FILE`` with hostile description files."""
    wheels = _load(BAGS / 'wheels_wheels.yaml')
    rotors = _load(BAGS / 'quadrotor_rotors.yaml')
    cases: list[Case] = []

    def est(name: str, kind: str, text: str | bytes | Path, expect: str = 'refuse',
            forbid: str = '', mention: str = '') -> None:
        path = text if isinstance(text, Path) else _write(out, f'{kind}_{name}.yaml', text)
        log = BAGS / ('wheels.mcap' if kind == 'wheels' else 'quadrotor.mcap')
        argv = ['estimate', str(log), f'--{kind}', str(path), '--format', 'json',
                '--no-progress']
        cases.append(Case(f'{kind}/{name}', argv, expect, [path, log] if path.is_file()
                          else [log], forbid, mention))

    for f in ('wheels.0.axis', 'wheels.0.joint', 'wheels.0.inertia'):
        est(f'bomb_{f}', 'wheels', _raw_field(wheels, f, bomb()))
    for f in ('rotors.0.k_f', 'rotors.0.spin', 'rotors.0.position', 'rotors.0.joint',
              'thrust_axis'):
        est(f'bomb_{f}', 'rotors', _raw_field(rotors, f, bomb()))
    est('deep', 'wheels', _raw_field(wheels, 'wheels.0.axis', deep()))
    for kind in ('wheels', 'rotors'):
        est('dev_zero', kind, Path('/dev/zero'))
        est('dev_urandom', kind, Path('/dev/urandom'))
        fifo = out / f'{kind}.fifo'
        os.mkfifo(fifo)
        est('fifo', kind, fifo)
        est('50MB', kind, _big(out, f'{kind}_big.yaml'))
        est('latin1', kind, b'# \xe9\n' + dump(wheels if kind == 'wheels' else rotors).encode(),
            mention=f'{kind}_latin1.yaml')
        est('unknown_top_key', kind, dump({**(wheels if kind == 'wheels' else rotors),
                                           'extra': 1}), mention='extra')
    est('inertia_true', 'wheels', dump(_put(wheels, 'wheels.0.inertia', True)))
    est('axis_strings', 'wheels', dump(_put(wheels, 'wheels.0.axis', ['1', '0', '0'])))
    est('axis_bools', 'wheels', dump(_put(wheels, 'wheels.0.axis', [True, False, False])))
    est('axis_string', 'wheels', dump(_put(wheels, 'wheels.0.axis', 'x')))
    est('axis_1e200', 'wheels', dump(_put(wheels, 'wheels.0.axis', [1e200, 0, 0])))
    est('inertia_std_1e300', 'wheels', dump(_put(wheels, 'wheels.0.inertia_std', 1e300)),
        forbid='DLASCL')
    est('digits', 'wheels', _raw_field(wheels, 'wheels.0.inertia', '9' * 5000),
        mention='wheels_digits.yaml')
    est('dup_key', 'wheels', 'wheels:\n- {joint: rw1, axis: [1, 0, 0], inertia: 1.2e-3, '
        'inertia: 1.0}\n', mention='duplicate')
    many = [{'joint': f'missing_joint_{i}', 'axis': [1, 0, 0], 'inertia': 1e-3}
            for i in range(10_000)]
    est('10000_missing_joints', 'wheels', dump({'wheels': many}))
    est('65_wheels', 'wheels', dump({'wheels': many[:65]}))
    est('64_missing_joints', 'wheels', dump({'wheels': [
        dict(w, joint=f'{i:03d}' + 'j' * 125) for i, w in enumerate(many[:64])]}))
    # The missing-joint message (io/joint_state.py) lists every name: bounded by the file's
    # limits (64 joints of <= 128 characters), not yet cut to a few names and a count.
    cases[-1].max_line = 64 * 132 + 200
    est('k_f_true', 'rotors', dump(_put(rotors, 'rotors.0.k_f', True)))
    est('k_f_std_1e300', 'rotors', dump(_put(rotors, 'rotors.0.k_f_std', 1e300)),
        forbid='DLASCL')
    est('k_m_std_1e300', 'rotors', dump(_put(rotors, 'rotors.0.k_m_std', 1e300)),
        forbid='DLASCL')
    est('spin_string', 'rotors', dump(_put(rotors, 'rotors.0.spin', '1')))
    est('position_1e-1', 'rotors', _raw_field(rotors, 'rotors.0.position', '[1.2e-1, -1.2e-1, 0]'),
        'ok')
    return cases


def option_cases(out: Path) -> list[Case]:
    """Option values: empty, nan, inf, underflow, 1 MB, 130 kB paths."""
    log = BAGS / 'default.mcap'
    cases: list[Case] = []
    huge = 'x' * 100_000          # the OS passes at most 128 kB in one argument
    long_path = 'a/' * 65_000 + 'r.json'
    base = ['estimate', str(log), '--format', 'json', '--no-progress']
    for opt in ('--torque-scale-std', '--gyro-scale-std', '--torque-delay', '--mass'):
        for v in ('', 'nan', 'inf', '-inf', '1e-400', huge, '1' * 5000):
            cases.append(Case(f'option{opt}={v[:8]}', [*base, opt, v], 'refuse', [log]))
    for opt in ('-o', '--plot', '--urdf', '--wheels', '--rotors'):
        for v in ('', long_path, 'a' * 300 + '.yaml'):
            extra = ['--mass', '1'] if opt == '--urdf' else []
            cases.append(Case(f'option{opt}={v[:8]}', [*base, opt, v, *extra], 'refuse', [log]))
    for opt in ('--omega-topic', '--torque-topic', '--wheel-topic'):
        for v in ('', huge, 'a b'):
            cases.append(Case(f'option{opt}={v[:8]}', [*base, opt, v], 'refuse', [log]))
    cases.append(Case('option-path=130kB', ['estimate', long_path], 'refuse'))
    cases.append(Case('option-path=empty', ['estimate', ''], 'refuse'))
    scene = SCENES / 'default.yaml'
    for v in ('', 'nan', '-1', huge, '9' * 5000):
        cases.append(Case(f'simulate--seed={v[:8]}', ['simulate', str(scene), '-o',
                                                       str(out / 's.mcap'), '--seed', v],
                          'refuse', [scene]))
    for v in ('', 'nan', '1e300', huge):
        cases.append(Case(f'simulate--start-ns={v[:8]}', ['simulate', str(scene), '-o',
                                                           str(out / 's.mcap'), '--start-ns',
                                                           v], 'refuse', [scene]))
    cases.append(Case('simulate-o=130kB', ['simulate', str(scene), '-o', long_path + '.mcap'],
                      'refuse', [scene]))
    return cases


def build_cases(out: Path) -> list[Case]:
    """Every case, its files written under ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    return scene_cases(out) + actuator_cases(out) + option_cases(out)
