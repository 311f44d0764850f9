"""Scenes: what the simulator needs to know about a body, its torques and its sensors.

A scene is built from a plain dict (the YAML schema documented in ``docs/SCENES.md``) by
:meth:`Scene.from_dict`.  Every value is SI: s, Hz, kg, m, kg m^2, rad, rad/s, N m.  Validation
errors are :class:`SceneError` (a ``ValueError``) whose message names the offending key, e.g.
``gyro.rate: must be a positive number, got -5``.

This module is pure numpy: the YAML file itself is parsed in ``inertia_ros.io.scene_file``.

Torque components (``torque:`` list, summed) and their type-specific keys, with defaults:

============  ===========================================================================
type          keys (all components also take ``amplitude``, ``axes``, ``start``, ``end``)
============  ===========================================================================
multisine     ``f_min`` 0.02 Hz, ``f_max`` 0.5 Hz, ``n_freq`` 6 (per axis),
              ``phases`` ``schroeder`` | ``random``; axes get interleaved frequencies
sine          ``frequency`` Hz (required), ``phase`` rad (scalar or per axis, default 0)
steps         ``period`` 2.0 s; levels uniform in [-amplitude, amplitude] per axis
prbs          ``bit_time`` 0.5 s; levels +-amplitude, independent random bits per axis
chirp         ``f0`` 0.02 Hz, ``f1`` 1.0 Hz, ``mode`` ``sequential`` (one axis after the
              other) | ``simultaneous`` (axes phase-shifted by 2 pi / 3)
doublet       ``width`` 1.0 s: +amplitude for ``width`` then -amplitude for ``width``,
              repeated every ``period`` (default: ``end - start``, i.e. once)
constant      the (signed) amplitude, held
============  ===========================================================================

``amplitude`` is the peak torque per axis [N m] (scalar or ``[x, y, z]``); for multisine and
chirp the signal is scaled so its peak over the scene's command grid equals it.
"""
from __future__ import annotations

import copy
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from inertia_ros.core._scene_fields import (  # noqa: F401  (re-exported for the parsers)
    MAX_ACTUATOR_SPEED,
    MAX_ACTUATOR_WORK,
    MAX_ACTUATORS,
    MAX_DROP_RATE,
    MAX_DURATION,
    MAX_EVENTS,
    MAX_MAGNITUDE,
    MAX_MULTISINE_TERMS,
    MAX_NAME_CHARS,
    MAX_SUBSTEPS,
    MAX_TORQUE_DELAY,
    SceneError,
    _integer,
    _mapping,
    _number,
    _string,
    _vector,
    _vector_or_scalar,
    too_many_substeps,
)
from inertia_ros.core._validate import show
from inertia_ros.core.tensor import MATRIX_INDEX

__all__ = [
    'TORQUE_TYPES',
    'GyroSpec',
    'Imperfections',
    'InertiaChange',
    'Scene',
    'SceneError',
    'TorqueComponent',
    'TorqueSensorSpec',
    'PART_SHAPES',
    'matrix_from_inertia_value',
    'parts_inertia',
    'rpy_matrix',
]


AXIS_NAMES = ('x', 'y', 'z')

#: Type-specific keys of each torque component type, with their defaults (None = required).
TORQUE_TYPES: Mapping[str, Mapping[str, Any]] = MappingProxyType({
    'multisine': {'f_min': 0.02, 'f_max': 0.5, 'n_freq': 6, 'phases': 'schroeder'},
    'sine': {'frequency': None, 'phase': 0.0},
    'steps': {'period': 2.0},
    'prbs': {'bit_time': 0.5},
    'chirp': {'f0': 0.02, 'f1': 1.0, 'mode': 'sequential'},
    'doublet': {'width': 1.0, 'period': 0.0},
    'constant': {},
})
_COMMON_TORQUE_KEYS = ('type', 'amplitude', 'axes', 'start', 'end')

def matrix_from_inertia_value(value: Any, key: str) -> np.ndarray:
    """Return the (3, 3) tensor [kg m^2] for a scene ``inertia`` value, validated as physical.

    Parameters
    ----------
    value : list of 6 numbers ``[ixx, iyy, izz, ixy, ixz, iyz]`` or a 3x3 nested list
        Tensor about the centre of mass [kg m^2]; ``ixy`` is the matrix element.
    key : str
        Name of the key, used in error messages.

    Returns
    -------
    numpy.ndarray, shape (3, 3)
        Symmetric positive-definite tensor satisfying the triangle inequality.

    Raises
    ------
    SceneError
        If the value is malformed, not symmetric or not a physical rigid-body tensor.
    """
    if isinstance(value, (Sequence, np.ndarray)) and not isinstance(value, str) \
            and len(value) == 3 and all(isinstance(r, (Sequence, np.ndarray)) for r in value):
        rows = [_vector(r, f'{key}[{i}]') for i, r in enumerate(value)]
        m = np.array(rows)
        if not np.allclose(m, m.T, rtol=1e-12, atol=1e-15):
            raise SceneError(f'{key}: 3x3 matrix must be symmetric')
        m = 0.5 * (m + m.T)
    else:
        th = _vector(value, key, 6)
        m = th[MATRIX_INDEX]
    ev = np.linalg.eigvalsh(m)
    if ev[0] <= 0.0:
        raise SceneError(f'{key}: not positive definite (principal moments {ev.tolist()})')
    if ev[0] + ev[1] < ev[2] * (1.0 - 1e-9):
        raise SceneError(f'{key}: violates the triangle inequality I1 + I2 >= I3 '
                         f'(principal moments {ev.tolist()})')
    m.setflags(write=False)
    return m


#: Part shapes of a composite body: the toolkit primitive and the size keys it takes.
#: Symmetry axes are along the part's z axis (see ``inertia_ros.core.bodies``).
PART_SHAPES: Mapping[str, tuple[str, ...]] = MappingProxyType({
    'point_mass': (),
    'thin_rod': ('length',),
    'rectangular_lamina': ('size',),
    'thin_disc': ('radius',),
    'thin_ring': ('radius',),
    'solid_sphere': ('radius',),
    'hollow_sphere': ('radius',),
    'solid_box': ('size',),
    'solid_cylinder': ('radius', 'length'),
    'thin_walled_cylinder': ('radius', 'length'),
    'hollow_cylinder': ('radius', 'inner_radius', 'length'),
    'solid_cone': ('radius', 'length'),
    'tensor': ('inertia',),
})
_PART_COMMON = ('shape', 'mass', 'position', 'rpy', 'subtract', 'name')


def rpy_matrix(rpy: Sequence[float]) -> np.ndarray:
    """Rotation matrix for URDF roll-pitch-yaw [rad]: ``R = Rz(yaw) Ry(pitch) Rx(roll)``.

    Parameters
    ----------
    rpy : sequence of 3 float
        Roll, pitch, yaw [rad] about the fixed x, y, z axes.

    Returns
    -------
    numpy.ndarray, shape (3, 3)
        Proper rotation mapping part axes to body axes.
    """
    r, p, y = (float(v) for v in rpy)
    cr, sr, cp, sp, cy, sy = (math.cos(r), math.sin(r), math.cos(p), math.sin(p),
                              math.cos(y), math.sin(y))
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _part_body(part: Any, key: str) -> tuple[Any, float]:
    """One part as a toolkit ``InertiaTensor`` placed in body axes, and its sign."""
    from inertia_ros.core import bodies
    from inertia_ros.core.inertia import InertiaTensor

    if not isinstance(part, Mapping):
        raise SceneError(f'{key}: must be a mapping with shape and mass, got {show(part)}')
    if 'shape' not in part:
        raise SceneError(f'{key}.shape: missing (one of {", ".join(PART_SHAPES)})')
    shape = _string(part['shape'], f'{key}.shape', tuple(PART_SHAPES))
    sizes = PART_SHAPES[shape]
    _mapping(part, key, _PART_COMMON + sizes)
    if 'mass' not in part:
        raise SceneError(f'{key}.mass: missing (kg)')
    mass = _number(part['mass'], f'{key}.mass', positive=True)
    for k in sizes:
        if k not in part:
            raise SceneError(f'{key}.{k}: missing (required for shape {shape})')
    try:
        if shape == 'point_mass':
            body = bodies.point_mass(mass)
        elif shape == 'tensor':
            body = InertiaTensor(matrix_from_inertia_value(part['inertia'], f'{key}.inertia'),
                                 mass)
        elif shape in ('rectangular_lamina', 'solid_box'):
            n = 2 if shape == 'rectangular_lamina' else 3
            size = _vector(part['size'], f'{key}.size', n, nonneg=True)
            body = getattr(bodies, shape)(mass, *size.tolist())
        else:
            args = [_number(part[k], f'{key}.{k}', nonneg=True) for k in sizes]
            if shape == 'hollow_cylinder':
                args = [args[0], args[1], args[2]]
            body = getattr(bodies, shape)(mass, *args)
    except ValueError as exc:
        if isinstance(exc, SceneError):
            raise
        raise SceneError(f'{key}: {exc}') from None
    pos = _vector(part.get('position', [0.0, 0.0, 0.0]), f'{key}.position')
    rot = rpy_matrix(_vector(part.get('rpy', [0.0, 0.0, 0.0]), f'{key}.rpy'))
    subtract = part.get('subtract', False)
    if not isinstance(subtract, bool):
        raise SceneError(f'{key}.subtract: must be true or false, got {show(subtract)}')
    if 'name' in part:
        _string(part['name'], f'{key}.name')
    return body.transformed(rot, pos), (-1.0 if subtract else 1.0)


def parts_inertia(parts: Any, key: str = 'body.parts') -> tuple[np.ndarray, float, np.ndarray]:
    """Composite of primitive parts about the composite centre of mass.

    Parameters
    ----------
    parts : list of Mapping
        Each ``{shape, mass, <size keys>, position, rpy, subtract}`` (see ``docs/SCENES.md``):
        ``mass`` [kg], sizes [m], ``position`` [m] of the part's centre of mass and ``rpy``
        [rad] of its axes in body axes; ``subtract: true`` removes it (a hole).
    key : str, optional
        Name used in error messages.

    Returns
    -------
    inertia : numpy.ndarray, shape (3, 3)
        Tensor about the composite centre of mass [kg m^2], body axes (parallel-axis theorem).
    mass : float
        Total mass [kg].
    com : numpy.ndarray, shape (3,)
        Composite centre of mass [m] in the parts' coordinates.

    Raises
    ------
    SceneError
        If a part is malformed or the composite has no positive mass.
    """
    from inertia_ros.core.inertia import composite

    if not isinstance(parts, Sequence) or isinstance(parts, str) or len(parts) == 0:
        raise SceneError(f'{key}: must be a non-empty list of parts')
    placed = [_part_body(p, f'{key}[{i}]') for i, p in enumerate(parts)]
    try:
        total = composite([b for b, _ in placed], [s for _, s in placed])
    except ValueError as exc:
        raise SceneError(f'{key}: {exc}') from None
    return np.array(total.matrix), float(total.mass), np.array(total.com)


def _body_inertia(body: Any, key: str) -> tuple[np.ndarray, tuple[Mapping[str, Any], ...],
                                                float | None, np.ndarray | None]:
    """(tensor, parts, mass or None, centre of mass or None) of a ``body`` mapping."""
    body = _mapping(body, key, ('inertia', 'parts'))
    has_i, has_p = 'inertia' in body, 'parts' in body
    if has_i == has_p:
        raise SceneError(f'{key}: give exactly one of inertia | parts')
    if has_i:
        return matrix_from_inertia_value(body['inertia'], f'{key}.inertia'), (), None, None
    parts = body['parts']
    m, mass, com = parts_inertia(parts, f'{key}.parts')
    m = matrix_from_inertia_value(m.tolist(), f'{key}.parts (composite)')
    com.setflags(write=False)
    return m, tuple(MappingProxyType(dict(p)) for p in parts), mass, com


# --------------------------------------------------------------------------------------------
# scene parts
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class TorqueComponent:
    """One commanded-torque component; the scene's command is the sum of its components.

    Attributes
    ----------
    type : str
        One of :data:`TORQUE_TYPES`.
    amplitude : numpy.ndarray, shape (3,)
        Peak torque per body axis [N m], zero on axes that are not excited.  Signed for
        ``constant``.
    axes : tuple of int
        Excited axes (0 = x, 1 = y, 2 = z), in the order given.
    start, end : float
        Active window [s]; the component is zero outside ``start <= t < end``.  ``end`` is
        ``inf`` unless given (active to the end of the run, the last command included).
    params : Mapping[str, Any]
        Type-specific parameters with defaults filled in (see the module docstring).
    """

    type: str
    amplitude: np.ndarray
    axes: tuple[int, ...]
    start: float
    end: float
    params: Mapping[str, Any]

    @classmethod
    def from_dict(cls, d: Any, key: str, duration: float) -> TorqueComponent:
        """Validate one ``torque`` list entry; ``key`` names it in errors (``torque[0]``)."""
        if not isinstance(d, Mapping):
            raise SceneError(f'{key}: must be a mapping with a type, got {show(d)}')
        if 'type' not in d:
            raise SceneError(f'{key}.type: missing (one of {", ".join(TORQUE_TYPES)})')
        typ = _string(d['type'], f'{key}.type', tuple(TORQUE_TYPES))
        defaults = TORQUE_TYPES[typ]
        _mapping(d, key, _COMMON_TORQUE_KEYS + tuple(defaults))
        axes_raw = d.get('axes', list(AXIS_NAMES))
        if isinstance(axes_raw, str):
            axes_raw = [axes_raw]
        if not isinstance(axes_raw, Sequence) or len(axes_raw) == 0:
            raise SceneError(f'{key}.axes: must be a non-empty list of x, y, z')
        axes = []
        for i, a in enumerate(axes_raw):
            name = _string(a, f'{key}.axes[{i}]', AXIS_NAMES)
            if AXIS_NAMES.index(name) in axes:
                raise SceneError(f'{key}.axes: axis {show(name)} listed twice')
            axes.append(AXIS_NAMES.index(name))
        if 'amplitude' not in d:
            raise SceneError(f'{key}.amplitude: missing (peak torque, N m)')
        amp = np.array(_vector_or_scalar(d['amplitude'], f'{key}.amplitude',
                                         nonneg=typ != 'constant'))
        mask = np.zeros(3, dtype=bool)
        mask[axes] = True
        amp[~mask] = 0.0
        amp.setflags(write=False)
        start = _number(d.get('start', 0.0), f'{key}.start', nonneg=True)
        if start >= duration:
            raise SceneError(f'{key}.start: must be before the end of the run ({duration} s), '
                             f'got {start}')
        end = math.inf if d.get('end') is None else _number(d['end'], f'{key}.end',
                                                              nonneg=True)
        if end <= start:
            raise SceneError(f'{key}.end: must be after start ({start}), got {end}')
        params: dict[str, Any] = {}
        for k, default in defaults.items():
            if k not in d and default is None:
                raise SceneError(f'{key}.{k}: missing (required for type {typ})')
            params[k] = d.get(k, default)
        params = cls._check_params(typ, params, key, min(end, duration) - start)
        return cls(typ, amp, tuple(axes), start, end, MappingProxyType(params))

    @staticmethod
    def _check_params(typ: str, p: dict[str, Any], key: str, span: float) -> dict[str, Any]:
        if typ == 'multisine':
            p['f_min'] = _number(p['f_min'], f'{key}.f_min', positive=True)
            p['f_max'] = _number(p['f_max'], f'{key}.f_max', positive=True)
            if p['f_max'] <= p['f_min']:
                raise SceneError(f'{key}.f_max: must exceed f_min ({p["f_min"]} Hz)')
            p['n_freq'] = _integer(p['n_freq'], f'{key}.n_freq', minimum=1)
            p['phases'] = _string(p['phases'], f'{key}.phases', ('schroeder', 'random'))
        elif typ == 'sine':
            p['frequency'] = _number(p['frequency'], f'{key}.frequency', positive=True)
            p['phase'] = _vector_or_scalar(p['phase'], f'{key}.phase')
        elif typ == 'steps':
            p['period'] = _number(p['period'], f'{key}.period', positive=True)
        elif typ == 'prbs':
            p['bit_time'] = _number(p['bit_time'], f'{key}.bit_time', positive=True)
        elif typ == 'chirp':
            p['f0'] = _number(p['f0'], f'{key}.f0', positive=True)
            p['f1'] = _number(p['f1'], f'{key}.f1', positive=True)
            p['mode'] = _string(p['mode'], f'{key}.mode', ('sequential', 'simultaneous'))
        elif typ == 'doublet':
            p['width'] = _number(p['width'], f'{key}.width', positive=True)
            p['period'] = _number(p['period'], f'{key}.period', nonneg=True)
            if p['period'] == 0.0:
                p['period'] = max(span, 2.0 * p['width'])
            if p['period'] < 2.0 * p['width']:
                raise SceneError(f'{key}.period: must be >= 2 * width ({2 * p["width"]} s)')
        return p

    def evaluate(self, t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Commanded torque of this component at times ``t``.

        Parameters
        ----------
        t : numpy.ndarray, shape (M,)
            Command update times [s], increasing (the scene's command grid).
        rng : numpy.random.Generator
            Source of the component's random phases / levels (seeded by the caller).

        Returns
        -------
        numpy.ndarray, shape (M, 3)
            Torque [N m] in body axes; zero outside ``[start, end)``.
        """
        t = np.asarray(t, dtype=float)
        out = np.zeros((t.size, 3))
        active = (t >= self.start - 1e-12) & (t < self.end - 1e-12)
        tau = t[active] - self.start
        span = (min(self.end, float(t[-1])) if t.size else self.end) - self.start
        span = max(span, 1e-12)
        p = self.params
        n_ax = len(self.axes)
        sig = np.zeros((tau.size, 3))
        if self.type == 'multisine':
            n = p['n_freq']
            freqs = np.linspace(p['f_min'], p['f_max'], n * n_ax)
            if p['phases'] == 'random':
                phases = rng.uniform(0.0, 2.0 * np.pi, size=n * n_ax)
            else:  # Schroeder phases over all the frequencies, low crest factor
                k = np.arange(1, n * n_ax + 1)
                phases = -np.pi * k * (k - 1) / (n * n_ax)
            for j, ax in enumerate(self.axes):
                f, ph = freqs[j::n_ax], phases[j::n_ax]
                s = np.cos(2.0 * np.pi * np.outer(tau, f) + ph).sum(axis=1)
                peak = np.max(np.abs(s)) if s.size else 1.0
                sig[:, ax] = s / peak if peak > 0 else s
        elif self.type == 'sine':
            for ax in self.axes:
                sig[:, ax] = np.sin(2.0 * np.pi * p['frequency'] * tau + p['phase'][ax])
        elif self.type == 'steps':
            n_lv = int(math.ceil(span / p['period'])) + 1
            levels = rng.uniform(-1.0, 1.0, size=(n_lv, 3))
            idx = np.minimum((tau / p['period'] + 1e-9).astype(int), n_lv - 1)
            sig = levels[idx]
        elif self.type == 'prbs':
            n_lv = int(math.ceil(span / p['bit_time'])) + 1
            levels = np.where(rng.random(size=(n_lv, 3)) < 0.5, -1.0, 1.0)
            idx = np.minimum((tau / p['bit_time'] + 1e-9).astype(int), n_lv - 1)
            sig = levels[idx]
        elif self.type == 'chirp':
            f0, f1 = p['f0'], p['f1']
            if p['mode'] == 'sequential':
                win = span / n_ax
                for j, ax in enumerate(self.axes):
                    tl = tau - j * win
                    on = (tl >= 0.0) & ((tl < win) | (j == n_ax - 1))
                    ph = 2.0 * np.pi * (f0 * tl + 0.5 * (f1 - f0) / win * tl ** 2)
                    sig[on, ax] = np.sin(ph[on])
            else:
                ph = 2.0 * np.pi * (f0 * tau + 0.5 * (f1 - f0) / span * tau ** 2)
                for j, ax in enumerate(self.axes):
                    sig[:, ax] = np.sin(ph + 2.0 * np.pi * j / 3.0)
        elif self.type == 'doublet':
            tp = np.mod(tau, p['period'])
            s = np.where(tp < p['width'], 1.0, np.where(tp < 2.0 * p['width'], -1.0, 0.0))
            sig[:, list(self.axes)] = s[:, None]
        elif self.type == 'constant':
            sig[:] = 1.0
        out[active] = sig * self.amplitude
        return out


@dataclass(frozen=True)
class GyroSpec:
    """Gyro stream: sample rate [Hz], white-noise std [rad/s], constant bias [rad/s], frame,
    first-order low-pass time constant [s] (0: none) and quantisation step [rad/s] (0: none).
    """

    rate: float = 200.0
    noise_std: float = 0.0
    bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
    frame_id: str = 'base_link'
    time_constant: float = 0.0
    lsb: float = 0.0


@dataclass(frozen=True)
class TorqueSensorSpec:
    """Torque stream: rate [Hz]; per-axis noise std = noise_std [N m] + noise_rel * rms(cmd)."""

    rate: float = 50.0
    noise_rel: float = 0.0
    noise_std: float = 0.0


@dataclass(frozen=True)
class Imperfections:
    """Stamp jitter std [s], torque-stream stamp delay [s], independent drop probability."""

    timestamp_jitter: float = 0.0
    torque_delay: float = 0.0
    drop_rate: float = 0.0


@dataclass(frozen=True, eq=False)
class InertiaChange:
    """A step change of the tensor at ``time`` [s] to ``inertia`` (3, 3) [kg m^2].

    ``mass`` [kg] and ``com`` (3,) [m] are known only when the new body is given as parts.
    """

    time: float
    inertia: np.ndarray
    mass: float | None = None
    com: np.ndarray | None = None


_TOP_KEYS = ('name', 'description', 'seed', 'duration', 'body', 'initial_omega', 'torque',
             'disturbance', 'command_rate', 'gyro', 'torque_sensor', 'imperfections',
             'inertia_change', 'wheels', 'rotors', 'damping')


@dataclass(frozen=True, eq=False)
class Scene:
    """A validated simulation scene (see ``docs/SCENES.md`` for the schema).

    Attributes
    ----------
    name : str
        Scene name (``'scene'`` when not given).
    seed : int
        Default seed for every random draw of the simulation.
    duration : float
        Length of the run [s].
    inertia : numpy.ndarray, shape (3, 3)
        Body tensor about the centre of mass at t = 0 [kg m^2], body axes.
    parts : tuple of Mapping
        The ``body.parts`` entries when the body is a composite, else empty.
    initial_omega : numpy.ndarray, shape (3,)
        Angular velocity at t = 0 [rad/s], body axes.
    torque : tuple of TorqueComponent
        Commanded-torque components, summed; empty = torque-free.
    disturbance : numpy.ndarray, shape (3,)
        Constant torque acting on the body but absent from the torque stream [N m].
    damping : numpy.ndarray, shape (3,)
        Diagonal aerodynamic damping ``D`` [N m s/rad]: the torque ``-D w`` acts on the body
        but is absent from the torque stream.
    command_rate : float
        Torque command update rate [Hz]; commands are held between updates (zero-order hold).
    gyro : GyroSpec
    torque_sensor : TorqueSensorSpec
    imperfections : Imperfections
    inertia_change : InertiaChange or None
    mass : float or None
        Total mass [kg] when the body is given as parts (the tensor alone does not fix it).
    com : numpy.ndarray, shape (3,), or None
        Composite centre of mass [m] in the parts' coordinates, when given as parts.
    description : str
        Free text.
    source : Mapping
        The dict the scene was built from (read-only view).
    """

    name: str
    seed: int
    duration: float
    inertia: np.ndarray
    initial_omega: np.ndarray
    torque: tuple[TorqueComponent, ...]
    disturbance: np.ndarray
    command_rate: float
    gyro: GyroSpec
    torque_sensor: TorqueSensorSpec
    imperfections: Imperfections
    inertia_change: InertiaChange | None = None
    parts: tuple[Mapping[str, Any], ...] = ()
    mass: float | None = None
    com: np.ndarray | None = None
    description: str = ''
    source: Mapping[str, Any] = field(default_factory=dict, repr=False)
    #: The ``wheels`` section (:class:`inertia_ros.core.wheel_sim.WheelScene`) or the
    #: ``rotors`` one (:class:`inertia_ros.core.rotor_sim.RotorScene`), or None.
    wheels: Any = None
    #: Diagonal aerodynamic damping ``D`` (3,) [N m s/rad]; ``-D w`` acts, unmeasured.
    damping: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], *, max_events: float = MAX_EVENTS) -> Scene:
        """Build and validate a scene from a plain dict (the YAML schema).

        Parameters
        ----------
        d : Mapping
            Scene description; only ``body`` is required.  See ``docs/SCENES.md``.
        max_events : float, optional
            Sample budget (default :data:`MAX_EVENTS`, what a user's scene file may ask for);
            the integration-work budgets scale with it.  Benchmarks of long runs, whose
            scenes are the package's own, pass more.

        Returns
        -------
        Scene

        Raises
        ------
        SceneError
            For an unknown key, a missing required key or an invalid value; the message
            starts with the dotted key, e.g. ``torque[1].f_max: must exceed f_min``.
        """
        if not isinstance(d, Mapping):
            raise SceneError(f'scene: must be a mapping of keys, got {type(d).__name__}')
        _mapping(d, 'scene', _TOP_KEYS)
        name = _string(d.get('name', 'scene'), 'name')
        description = _string(d.get('description', ''), 'description', max_chars=20_000)
        seed = _integer(d.get('seed', 0), 'seed', minimum=0)
        duration = _number(d.get('duration', 10.0), 'duration', positive=True)
        if duration > MAX_DURATION:
            raise SceneError(f'duration: at most {MAX_DURATION:g} s, got {duration:g}')
        if 'body' not in d:
            raise SceneError('body: missing (give body.inertia or body.parts)')
        inertia, parts, mass, com = _body_inertia(d['body'], 'body')
        omega0 = _vector(d.get('initial_omega', [0.0, 0.0, 0.0]), 'initial_omega')
        torque_raw = d.get('torque') or []
        if isinstance(torque_raw, Mapping):
            torque_raw = [torque_raw]
        if not isinstance(torque_raw, Sequence) or isinstance(torque_raw, str):
            raise SceneError('torque: must be a list of components (or omitted)')
        torque = tuple(TorqueComponent.from_dict(c, f'torque[{i}]', duration)
                       for i, c in enumerate(torque_raw))
        disturbance = _vector(d.get('disturbance', [0.0, 0.0, 0.0]), 'disturbance')
        command_rate = _number(d.get('command_rate', 50.0), 'command_rate', positive=True)

        gyro, torque_sensor, imperfections = _sensors(d)
        change = _inertia_change(d.get('inertia_change'), duration)
        wheels = _actuators(d, duration, max_events,
                            duration * (gyro.rate + torque_sensor.rate + command_rate))
        scene = cls(wheels=wheels, damping=_damping(d, wheels), name=name, seed=seed,
                    duration=duration, inertia=inertia,
                    initial_omega=omega0, torque=torque, disturbance=disturbance,
                    command_rate=command_rate, gyro=gyro, torque_sensor=torque_sensor,
                    imperfections=imperfections, inertia_change=change, parts=parts,
                    mass=mass, com=com,
                    description=description, source=MappingProxyType(dict(d)))
        _check_work(scene, max_events / MAX_EVENTS)
        return scene
    def to_dict(self) -> dict[str, Any]:
        """Return a copy of the dict the scene was built from (``Scene.from_dict`` round-trips)."""
        return copy.deepcopy(dict(self.source))


def _damping(d: Mapping[str, Any], actuators: Any) -> np.ndarray:
    """The ``damping`` key (3,) [N m s/rad], each >= 0; refused with wheels or rotors."""
    damping = _vector(d.get('damping', [0.0, 0.0, 0.0]), 'damping', nonneg=True)
    if actuators is not None and np.any(damping > 0.0):
        raise SceneError('damping: not simulated together with wheels or rotors; give one '
                         'of them')
    return damping


def _actuators(d: Mapping[str, Any], duration: float, max_events: float, n_events: float
               ) -> Any:
    """The ``wheels`` or ``rotors`` section, after checking the sample budget (the streams'
    samples ``n_events`` plus the JointState values) before anything is allocated."""
    given = [k for k in ('wheels', 'rotors') if d.get(k) is not None]
    if len(given) == 2:
        raise SceneError('rotors: a scene has wheels or rotors, not both')
    rate, n_joints = 0.0, 0
    if given:
        key = given[0]
        sec = d[key]
        if isinstance(sec, Mapping):
            rate = _number(sec.get('rate', 100.0 if key == 'wheels' else 200.0), f'{key}.rate',
                           positive=True)
            items = sec.get('list')
            n_joints = len(items) if isinstance(items, list) else 0
            if n_joints > MAX_ACTUATORS:
                raise SceneError(f'{key}.list: {n_joints} {key}, more than the simulator '
                                 f'allows ({MAX_ACTUATORS})')
    total = n_events + duration * rate * max(n_joints, 1)
    if total > max_events:
        raise SceneError(f'duration: {duration:g} s at these rates makes about {total:.3g} '
                         f'samples, more than the simulator allows ({max_events:.0e}); shorten '
                         'the run or lower the rates')
    if not given:
        return None
    if given[0] == 'wheels':
        from inertia_ros.core.wheel_sim import parse_wheels
        act = parse_wheels(d['wheels'])
        top = max(abs(w.offset) + abs(w.amplitude) for w in act.wheels)
    else:
        from inertia_ros.core.rotor_sim import parse_rotors  # JointState actuators as wheels
        act = parse_rotors(d['rotors'], duration)
        P = act._allocation
        u = act.hover_thrust * P[:, 0] + np.abs(P[:, 1:]) @ (1.5 * act.amplitude)
        top = math.sqrt(max(float(np.max(u)), 0.0))
    if top > MAX_ACTUATOR_SPEED:
        key = 'speed' if given[0] == 'wheels' else 'hover_thrust'
        raise SceneError(f'{given[0]}: {key} makes {given[0]} spin at up to {top:.3g} rad/s, '
                         f'more than the simulator allows ({MAX_ACTUATOR_SPEED:g} rad/s)')
    return act


def _check_work(scene: Scene, scale: float = 1.0) -> None:
    """Refuse a scene whose integration surely needs more substeps than the simulator allows
    (:data:`MAX_SUBSTEPS`, or :data:`MAX_ACTUATOR_WORK` per joint with wheels or rotors,
    times ``scale``).

    Lower bound of the work: one substep per event (gyro sample, command update), and one per
    ``MAX_STEP_ANGLE`` of rotation, where the rate can fall from its start ``|I w0| / I_max``
    at most as fast as the largest torque allows (``||I^-1|| tau_max``).
    """
    from inertia_ros.core.simulation import MAX_STEP_ANGLE

    _check_torque_sizes(scene, scale)
    T = scene.duration
    events = T * (scene.gyro.rate + scene.command_rate)
    w0 = float(np.linalg.norm(scene.inertia @ scene.initial_omega)) \
        / float(np.linalg.eigvalsh(scene.inertia)[-1])
    tau = sum(float(np.linalg.norm(c.amplitude)) for c in scene.torque) \
        + float(np.linalg.norm(scene.disturbance))
    if scene.wheels is not None:
        tau += float(scene.wheels.max_hdot())
    slow = float(np.linalg.norm(np.linalg.inv(scene.inertia), 2)) * tau      # rad/s^2
    if np.any(scene.damping > 0.0):
        slow = math.inf                              # damping may stop it: no bound
    turn = T * (w0 - 0.5 * slow * T) if slow * T <= w0 else w0 * w0 / (2.0 * slow)
    steps = events + turn / MAX_STEP_ANGLE
    joints = len(scene.wheels.wheels) if scene.wheels is not None else 0
    limit = scale * (MAX_ACTUATOR_WORK / joints if joints else MAX_SUBSTEPS)
    if steps > limit:
        what = f' with {joints} wheels or rotors' if joints else ''
        key = 'initial_omega' if turn / MAX_STEP_ANGLE > events else 'duration'
        raise SceneError(f'{key}: {T:g} s{what} at these rates and an initial rate of '
                         f'{w0:.3g} rad/s needs about {steps:.3g} integration steps, more than '
                         f'the simulator allows ({limit:.3g}); shorten the run, lower the rates '
                         'or initial_omega')


def _check_torque_sizes(scene: Scene, scale: float) -> None:
    """Refuse torque components whose evaluation would allocate beyond the sample budget:
    a multisine's command samples x frequencies, the levels of steps and PRBS."""
    n_cmd = scene.duration * scene.command_rate + 1.0
    for i, c in enumerate(scene.torque):
        span = min(c.end, scene.duration) - c.start
        if c.type == 'multisine':
            terms = n_cmd * c.params['n_freq'] * len(c.axes)
            if terms > MAX_MULTISINE_TERMS * scale:
                raise SceneError(f'torque[{i}].n_freq: {c.params["n_freq"]} frequencies on '
                                 f'{n_cmd:.3g} command samples make {terms:.3g} terms, more '
                                 f'than the simulator allows ({MAX_MULTISINE_TERMS * scale:.0e})')
        elif c.type in ('prbs', 'steps'):
            k = 'bit_time' if c.type == 'prbs' else 'period'
            if span / c.params[k] > MAX_EVENTS * scale:
                raise SceneError(f'torque[{i}].{k}: {c.params[k]:g} s makes '
                                 f'{span / c.params[k]:.3g} levels, more than the simulator '
                                 f'allows ({MAX_EVENTS * scale:.0e})')


def _sensors(d: Mapping[str, Any]) -> tuple[GyroSpec, TorqueSensorSpec, Imperfections]:
    """The ``gyro``, ``torque_sensor`` and ``imperfections`` sections, validated."""
    g = _mapping(d.get('gyro'), 'gyro', ('rate', 'noise_std', 'bias', 'frame_id',
                                         'time_constant', 'lsb'))
    gyro = GyroSpec(
        rate=_number(g.get('rate', 200.0), 'gyro.rate', positive=True),
        noise_std=_number(g.get('noise_std', 0.0), 'gyro.noise_std', nonneg=True),
        bias=tuple(_vector(g.get('bias', [0.0, 0.0, 0.0]), 'gyro.bias').tolist()),
        frame_id=_string(g.get('frame_id', 'base_link'), 'gyro.frame_id'),
        time_constant=_number(g.get('time_constant', 0.0), 'gyro.time_constant',
                              nonneg=True),
        lsb=_number(g.get('lsb', 0.0), 'gyro.lsb', nonneg=True))
    if not gyro.frame_id:
        raise SceneError('gyro.frame_id: must not be empty')
    if gyro.time_constant > 1.0:
        raise SceneError(f'gyro.time_constant: a first-order sensor filter of '
                         f'{gyro.time_constant:g} s is not a gyro; give at most 1 s')
    ts = _mapping(d.get('torque_sensor'), 'torque_sensor', ('rate', 'noise_rel', 'noise_std'))
    torque_sensor = TorqueSensorSpec(
        rate=_number(ts.get('rate', 50.0), 'torque_sensor.rate', positive=True),
        noise_rel=_number(ts.get('noise_rel', 0.0), 'torque_sensor.noise_rel', nonneg=True),
        noise_std=_number(ts.get('noise_std', 0.0), 'torque_sensor.noise_std', nonneg=True))
    im = _mapping(d.get('imperfections'), 'imperfections',
                  ('timestamp_jitter', 'torque_delay', 'drop_rate'))
    imperfections = Imperfections(
        timestamp_jitter=_number(im.get('timestamp_jitter', 0.0),
                                 'imperfections.timestamp_jitter', nonneg=True),
        torque_delay=_number(im.get('torque_delay', 0.0), 'imperfections.torque_delay'),
        drop_rate=_number(im.get('drop_rate', 0.0), 'imperfections.drop_rate', nonneg=True))
    if imperfections.drop_rate > MAX_DROP_RATE:
        raise SceneError(f'imperfections.drop_rate: must be at most {MAX_DROP_RATE:g} (beyond '
                         f'it a stream may keep no sample), got {imperfections.drop_rate}')
    if abs(imperfections.torque_delay) > MAX_TORQUE_DELAY:
        raise SceneError(f'imperfections.torque_delay: must be within +-{MAX_TORQUE_DELAY:g} '
                         f's, got {imperfections.torque_delay:g}')
    min_period = 1.0 / max(gyro.rate, torque_sensor.rate)
    if imperfections.timestamp_jitter > 0.25 * min_period:
        raise SceneError(f'imperfections.timestamp_jitter: must be <= a quarter of the '
                         f'fastest sample period ({0.25 * min_period:g} s) so stamps stay '
                         f'increasing, got {imperfections.timestamp_jitter}')
    return gyro, torque_sensor, imperfections


def _inertia_change(value: Any, duration: float) -> InertiaChange | None:
    """The optional ``inertia_change`` section, validated against the run's ``duration``."""
    if value is None:
        return None
    c = _mapping(value, 'inertia_change', ('time', 'inertia', 'parts'))
    if 'time' not in c:
        raise SceneError('inertia_change.time: missing (s)')
    t_c = _number(c['time'], 'inertia_change.time', positive=True)
    if t_c >= duration:
        raise SceneError(f'inertia_change.time: must be before the end of the run '
                         f'({duration} s), got {t_c}')
    i_c, _, m_c, com_c = _body_inertia({k: v for k, v in c.items() if k != 'time'},
                                       'inertia_change')
    return InertiaChange(t_c, i_c, m_c, com_c)
