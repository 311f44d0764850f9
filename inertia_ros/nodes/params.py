"""Node parameters as ROS users type them: one table per node, coercion, one-line errors, help.

``ros2 run ... --ros-args -p NAME:=VALUE`` parses VALUE as YAML: ``off``/``on``/``true`` arrive
as booleans, ``10`` as an integer.  This module makes every node accept what a user means and
refuse the rest in one line:

- a string parameter given a boolean takes ``'on'``/``'off'`` when those are among its choices
  (else ``'true'``/``'false'``), and a number takes its text;
- a floating-point parameter accepts an integer (and a numeric string), an integer parameter a
  float with an integer value;
- a value of the wrong kind, outside its range or not among its choices is refused with one
  line naming the parameter, its range and the value: at start-up :func:`declare` raises
  :class:`ValueError` (``run_node`` prints it and exits 2), on ``ros2 param set``
  :func:`check_changes` gives the reason of the refused ``SetParametersResult``;
- a parameter name the node does not have is warned about once, with the closest known name;
- ``--help`` prints :func:`usage` (every parameter with its unit, range and default) without
  starting ROS (:func:`print_help_if_asked`).

The tables (:data:`ESTIMATOR`, :data:`PLAYBACK`, :data:`SCENE_SIMULATOR`,
:data:`BAG_PLAYER`, :data:`EXCITER`) are the single source of the declared parameters, the
``--help`` text and the config/*.yaml documentation.  rclpy is imported only where a node is
built, so ``--help`` is fast.
"""
from __future__ import annotations

import difflib
import math
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from inertia_ros.core.estimation.options import (
    BATCH_HOLDS,
    INERTIAL_TORQUE,
    METHODS,
    MODELS,
    TORQUE_BIAS,
)
from inertia_ros.core.estimation.windowed import ONLINE_METHODS

__all__ = ['BAG_PLAYER', 'ESTIMATOR', 'EXCITER', 'NODE_TABLES', 'PLAYBACK', 'SCENE_SIMULATOR',
           'ParamSpec', 'check_changes', 'coerce', 'coerce_changes', 'declare', 'descriptor',
           'print_help_if_asked', 'range_text', 'usage']

#: Parameters every rclpy node has; never reported as unknown.
_STANDARD = frozenset({'use_sim_time', 'start_type_description_service'})


@dataclass(frozen=True)
class ParamSpec:
    """One declared parameter: default, description, range or choices.

    Attributes
    ----------
    default : bool, int, float or str
        Default value; its type is the parameter's type.
    description : str
        One line, the unit in brackets when there is one.
    lo, hi : float, optional
        Inclusive range of a numeric parameter.
    read_only : bool
        Settable only at start-up.
    choices : tuple of str
        Allowed values of a string parameter (empty: any string).
    """

    default: Any
    description: str
    lo: float | None = None
    hi: float | None = None
    read_only: bool = False
    choices: tuple[str, ...] = ()

    @property
    def kind(self) -> type:
        """``bool``, ``int``, ``float`` or ``str``."""
        return type(self.default)


def _kind_name(kind: type) -> str:
    return {bool: 'a boolean', int: 'an integer', float: 'a number', str: 'a string'}[kind]


def _num(v: float) -> str:
    return f'{v:g}' if isinstance(v, float) else str(v)


def range_text(spec: ParamSpec) -> str:
    """What the parameter accepts: ``'a number in [0.01, 1000]'``, ``'one of: a, b'``, ..."""
    if spec.choices:
        return 'one of: ' + ', '.join(repr(c) for c in spec.choices)
    text = _kind_name(spec.kind)
    if spec.lo is not None and spec.kind is not bool:
        text += f' in [{_num(spec.lo)}, {_num(spec.hi)}]'
    return text


def _value_text(value: Any) -> str:
    kind = {bool: 'boolean', int: 'integer', float: 'double', str: 'string'}.get(type(value))
    shown = repr(value)
    if isinstance(value, (list, tuple)):
        kind = 'array'
    return f'{shown} ({kind})' if kind else shown


def coerce(name: str, spec: ParamSpec, value: Any) -> Any:
    """The value ``spec`` means by ``value`` as typed by a ROS user, or ValueError.

    Parameters
    ----------
    name : str
        Parameter name (for the message).
    spec : ParamSpec
        Its declaration.
    value : Any
        Value as rclpy delivers it (YAML-parsed: bool, int, float, str, arrays or None).

    Returns
    -------
    bool, int, float or str
        The value with the parameter's type, inside its range and choices.

    Raises
    ------
    ValueError
        One line: ``"parameter 'NAME' must be RANGE, got VALUE (TYPE)"``.
    """
    kind = spec.kind
    out: Any = None
    if kind is str:
        if isinstance(value, bool):
            on_off = {'on', 'off'} <= set(spec.choices)
            out = ('on' if value else 'off') if on_off else ('true' if value else 'false')
        elif isinstance(value, (int, float, str)):
            out = value if isinstance(value, str) else _num(value)
    elif kind is bool:
        if isinstance(value, bool):
            out = value
        elif isinstance(value, str) and value.strip().lower() in ('true', 'false', 'on', 'off',
                                                                  'yes', 'no'):
            out = value.strip().lower() in ('true', 'on', 'yes')
        elif isinstance(value, int) and value in (0, 1):
            out = bool(value)
    elif kind is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            out = float(value)
        elif isinstance(value, str):
            try:
                out = float(value)
            except ValueError:
                out = None
        if out is not None and not math.isfinite(out):
            out = None
    elif kind is int:
        if isinstance(value, int) and not isinstance(value, bool):
            out = int(value)
        elif isinstance(value, float) and math.isfinite(value) and value == int(value):
            out = int(value)
        elif isinstance(value, str):
            try:
                out = int(value.strip())
            except ValueError:
                out = None
    bad = out is None
    if not bad and spec.choices and out not in spec.choices:
        bad = True
    if not bad and spec.lo is not None and kind in (int, float) \
            and not (spec.lo <= out <= spec.hi):
        bad = True
    if bad:
        raise ValueError(f'parameter {name!r} must be {range_text(spec)}, '
                         f'got {_value_text(value)}')
    return out


def descriptor(name: str, spec: ParamSpec) -> Any:
    """The ``rcl_interfaces/ParameterDescriptor`` of one parameter (range, choices, typing).

    Dynamically typed, so that a value of the wrong type set at run time reaches
    :func:`check_changes` (which names the parameter and its range) instead of rclpy's
    anonymous type error; the range is still in the descriptor for ``ros2 param describe``.
    """
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

    desc = ParameterDescriptor(name=name, description=spec.description,
                               read_only=spec.read_only, dynamic_typing=True)
    desc.additional_constraints = range_text(spec)
    if spec.lo is not None and spec.kind is int:
        desc.integer_range = [IntegerRange(from_value=int(spec.lo), to_value=int(spec.hi),
                                           step=0)]
    elif spec.lo is not None and spec.kind is float:
        desc.floating_point_range = [FloatingPointRange(
            from_value=float(spec.lo), to_value=float(spec.hi), step=0.0)]
    return desc


def declare(node: Any, specs: Mapping[str, ParamSpec]) -> dict[str, Any]:
    """Declare ``specs`` on ``node`` from its overrides, coerced; warn about unknown names.

    Parameters
    ----------
    node : rclpy.node.Node
        Node under construction (its ``parameter_overrides`` are the ``-p`` values and the
        params file entries).
    specs : mapping of str to ParamSpec
        Parameters to declare.

    Returns
    -------
    dict
        The declared values, by name.

    Raises
    ------
    ValueError
        One line for the first override that is of the wrong kind, out of range or not
        among the choices.

    Also installs a pre-set callback that coerces values set later (``ros2 param set NODE
    torque_bias off`` arrives as a boolean) the same way; validate them with
    :func:`check_changes` in the node's on-set callback.
    """
    from rclpy.parameter import Parameter

    overrides: dict[str, Any] = getattr(node, '_parameter_overrides', {})
    values: dict[str, Any] = {}
    for name, spec in specs.items():
        if name in overrides:
            value = coerce(name, spec, overrides[name].value)
            if value != overrides[name].value or type(value) is not type(overrides[name].value):
                overrides[name] = Parameter(name, value=value)
        values[name] = node.declare_parameter(name, spec.default,
                                              descriptor(name, spec)).value
    known = set(specs) | _STANDARD | set(getattr(node, '_parameters', {}))
    unknown = sorted(set(overrides) - known)
    if unknown:
        node.get_logger().warning(unknown_text(unknown, known))
    node.add_pre_set_parameters_callback(
        lambda params: coerce_changes(specs, params))
    return values


def unknown_text(unknown: Sequence[str], known: set[str]) -> str:
    """One line: the unknown names, each with its closest known name when there is one."""
    parts = []
    for name in unknown:
        close = difflib.get_close_matches(name, sorted(known), n=1, cutoff=0.6)
        parts.append(f'{name!r} (did you mean {close[0]!r}?)' if close else repr(name))
    return ('ignoring unknown parameter' + ('s ' if len(parts) > 1 else ' ') + ', '.join(parts)
            + '; --help lists the parameters')


def coerce_changes(specs: Mapping[str, ParamSpec], params: list[Any]) -> list[Any]:
    """Pre-set callback: coerce each change that can be coerced; leave the others as given."""
    from rclpy.parameter import Parameter

    out = []
    for p in params:
        spec = specs.get(p.name)
        if spec is not None:
            try:
                value = coerce(p.name, spec, p.value)
            except ValueError:
                value = None
            if value is not None and type(value) is not type(p.value):
                p = Parameter(p.name, value=value)
        out.append(p)
    return out


def check_changes(specs: Mapping[str, ParamSpec], params: list[Any]) -> str:
    """'' when every change in ``params`` is valid for ``specs``, else the one-line reason."""
    for p in params:
        spec = specs.get(p.name)
        if spec is None:
            continue
        try:
            coerce(p.name, spec, p.value)
        except ValueError as exc:
            return str(exc)
    return ''


def usage(node_name: str, summary: str, specs: Mapping[str, ParamSpec]) -> str:
    """``--help`` text: how to run the node and every parameter with range and default."""
    lines = [f'usage: ros2 run inertia_ros {node_name} [--ros-args -p NAME:=VALUE ...'
             f' | --params-file FILE]', '', summary, '',
             f'parameters (config/{node_name}.yaml documents them; * = start-up only):']
    width = max(len(n) for n in specs) + 2
    for name, spec in specs.items():
        default = repr(spec.default) if isinstance(spec.default, str) else _num(spec.default)
        if isinstance(spec.default, bool):
            default = str(spec.default).lower()
        lines.append(f'  {name + ("*" if spec.read_only else ""):<{width}}'
                     f'{spec.description}')
        lines.append(f'  {"":<{width}}{range_text(spec)}; default {default}')
    lines += ['', 'Standard ROS arguments (--ros-args -r FROM:=TO, use_sim_time, ...) apply.']
    return '\n'.join(lines)


def print_help_if_asked(argv: Sequence[str] | None, text: Callable[[], str]) -> bool:
    """Print ``text()`` and return True when ``argv`` asks for help before ``--ros-args``."""
    args = list(sys.argv[1:] if argv is None else argv)
    if '--ros-args' in args:
        args = args[:args.index('--ros-args')]
    if '-h' in args or '--help' in args:
        try:
            print(text(), flush=True)
        except BrokenPipeError:  # `--help | head`: the reader left, nothing to report
            sys.stdout = None
        return True
    return False


# --------------------------------------------------------------------------- the tables
#: ``inertia_estimator`` (config/inertia_estimator.yaml documents the same set).
ESTIMATOR: dict[str, ParamSpec] = {
    'omega_msg_type': ParamSpec('imu', "gyro input: 'imu' (sensor_msgs/Imu on 'imu') or "
                                "'vector3' (geometry_msgs/Vector3Stamped on 'omega')",
                                read_only=True, choices=('imu', 'vector3')),
    'torque_msg_type': ParamSpec('wrench', "torque input: 'wrench' (geometry_msgs/"
                                 "WrenchStamped, torque part) or 'vector3' (Vector3Stamped) "
                                 '[N m]', read_only=True, choices=('wrench', 'vector3')),
    'torque_topic': ParamSpec('torque', "torque input topic; 'none' = no torque stream: "
                              'torque-free estimation (ratios and principal axes, status '
                              'scale_unobservable)', read_only=True),
    'wheels_file': ParamSpec('', "wheels/flywheels YAML (joint, axis, inertia[, inertia_std] "
                             "per wheel): their momentum from the wheel speeds on "
                             "'joint_states' (sensor_msgs/JointState) enters the estimate; "
                             "'' = none", read_only=True),
    'rotors_file': ParamSpec('', "multirotor rotors YAML (joint, position, spin, k_f, k_m[, "
                             "time_constant, inertia, *_std] per rotor): the rotor torques "
                             "(and momentum) from the speeds on 'joint_states' are the known "
                             "torque; '' = none", read_only=True),
    'qos_depth': ParamSpec(10000, 'history depth of the sensor-data subscriptions [messages]',
                           1, 100000, read_only=True),
    'poll_period': ParamSpec(0.01, 'period at which queued input messages are taken and '
                             'decoded in one batch [s]', 0.0005, 1.0, read_only=True),
    'frame_id': ParamSpec('', "frame the gyro and torque must be expressed in; '' adopts the "
                          "first gyro message's frame"),
    'method': ParamSpec('recursive', "'recursive' (core RecursiveEstimator over all data or "
                        "the window), 'tracking' (core TrackingEstimator: a Kalman filter that "
                        'follows a changing tensor with memory window, default 10 s, and '
                        "finds payload steps) or 'batch' (core estimate() re-solved over the "
                        'sliding window)', choices=(*ONLINE_METHODS, 'tracking')),
    'batch_method': ParamSpec('integral', "core estimator of the 'batch' method: 'integral' "
                              "(fast), 'ml' (maximum likelihood, at the Cramer-Rao bound, ~5x "
                              "the time), 'auto' or another name of the core's METHODS",
                              choices=METHODS),
    'model': ParamSpec('full', "tensor parameters: 'full' (6), 'diagonal' (3), 'axisymmetric' "
                       "(2, needs symmetry_axis) or 'auto' (model selection in the core)",
                       choices=MODELS),
    'symmetry_axis': ParamSpec('', "symmetry axis for model 'axisymmetric': 'x', 'y' or 'z' "
                               "('' = none)", choices=('', 'x', 'y', 'z')),
    'torque_bias': ParamSpec('auto', "estimate a constant unmeasured disturbance torque "
                             "[N m]: 'off', 'on' or 'auto' (kept when significant; the "
                             'recursive method re-tests it about once a second)',
                             choices=TORQUE_BIAS),
    'inertial_torque': ParamSpec('auto', "estimate a disturbance torque constant in inertial "
                                 "axes [N m] beside torque_bias: 'off', 'on' or 'auto' (kept "
                                 "when significant; recursive method with a torque input: "
                                 "elsewhere 'auto' runs without it and 'on' is refused)",
                                 choices=INERTIAL_TORQUE),
    'forgetting': ParamSpec(1.0, 'recursive forgetting factor per gyro sample; 1 = none '
                            '[dimensionless]', 0.5, 1.0),
    'window': ParamSpec(0.0, 'recursive: memory time constant, weights decay as '
                        'exp(-age/window) [s], 0 = no decay; tracking: the same memory, 0 = '
                        '10 s; batch: sliding-window length [s], 0 = 30 s', 0.0, 86400.0),
    'hold': ParamSpec('auto', "torque between samples: 'auto' (recursive, also with "
                      'wheels/rotors: held or linear, chosen by evidence at each '
                      're-selection, the batch rule; tracking: both filtered until that rule '
                      "settles; batch: held), 'zoh' (held) or 'linear'",
                      choices=BATCH_HOLDS),
    'torque_scale_std': ParamSpec(0.0, 'relative one-sigma uncertainty of the torque scale '
                                  '(0.02 = 2 %), added to every sigma [dimensionless]',
                                  0.0, 0.5),
    'gyro_scale_std': ParamSpec(0.0, 'relative one-sigma uncertainty of the gyro scale '
                                '(0.01 = 1 %), added to every sigma [dimensionless]',
                                0.0, 0.5),
    'publish_rate': ParamSpec(10.0, 'maximum estimate/publish rate [Hz]', 0.01, 1000.0),
    'urdf_mass': ParamSpec(1.0, 'mass written by the ~/urdf service [kg] (rotation data '
                           'cannot tell it)', 1e-9, 1e9),
    'urdf_link': ParamSpec('base_link', 'link name written by the ~/urdf service'),
    'publish_partial': ParamSpec(False, 'also publish ~/inertia when partially_identifiable '
                                 '(undetermined elements NaN)'),
    'stream_timeout': ParamSpec(1.0, 'warn when a stream is silent this long [s]',
                                0.01, 3600.0),
    'clock_jump_threshold': ParamSpec(0.5, 'a stamp further than this from the newest one is '
                                      'suspect: refused unless the next samples confirm it '
                                      '(then backward = reset, forward = gap) [s]',
                                      0.0, 3600.0),
    'max_refused_fraction': ParamSpec(0.1, 'WARN when more than this fraction of a stream '
                                      'was refused (NaN, bad stamp, wrong frame, malformed) '
                                      'over the last second [dimensionless]', 0.0, 1.0),
    'marker_scale': ParamSpec(0.5, 'display size of the markers (longest ellipsoid '
                              'semi-axis) [m]', 0.001, 100.0),
}

#: Playback parameters shared by ``scene_simulator`` and ``bag_player``.
PLAYBACK: dict[str, ParamSpec] = {
    'rate': ParamSpec(1.0, 'playback speed factor (2 = twice real time) [dimensionless]',
                      0.01, 1000.0),
    'loop': ParamSpec(False, 'restart from the beginning at the end (stamps jump back)'),
    'omega_msg_type': ParamSpec('imu', "gyro output: 'imu' (sensor_msgs/Imu on 'imu') or "
                                "'vector3' (geometry_msgs/Vector3Stamped on 'omega')",
                                read_only=True, choices=('imu', 'vector3')),
    'tick': ParamSpec(0.002, 'playback timer period [s]', 0.0002, 1.0, read_only=True),
    'qos_depth': ParamSpec(1000, 'history depth of the sensor publishers [messages]',
                           1, 100000, read_only=True),
    'wait_for_subscribers': ParamSpec(1, 'subscribers to wait for on both the gyro and the '
                                      'torque topic before playback starts (matched '
                                      'subscriptions) [count]', 0, 1000),
    'wait_timeout': ParamSpec(30.0, 'start anyway (with a warning) when the subscribers are '
                              'not matched after this long; 0 = wait forever [s]',
                              0.0, 86400.0, read_only=True),
    'start_delay': ParamSpec(0.0, 'extra wait before playback starts [s]', 0.0, 3600.0,
                             read_only=True),
    'exit_on_end': ParamSpec(False, 'exit the process when the data end (ignored with loop)',
                             read_only=True),
    'publish_clock': ParamSpec(False, 'publish /clock (rosgraph_msgs/Clock, best effort, '
                               'depth 1) at the header stamps being published, for nodes run '
                               'with use_sim_time (not this one)'),
}

#: ``scene_simulator``: the playback parameters plus these.
SCENE_SIMULATOR: dict[str, ParamSpec] = {
    'scene': ParamSpec('', "scene YAML file; '' = the package's config/scenes/default.yaml",
                       read_only=True),
    'seed': ParamSpec(-1, "seed of the simulation's random draws; -1 = the scene's own seed",
                      -1, 2**31 - 1, read_only=True),
    'command_topic': ParamSpec('', 'closed loop: integrate the body under the torque '
                               'commanded on this topic (geometry_msgs/WrenchStamped, held '
                               "until the next command, zero before the first) instead of the "
                               "scene's own profile; '' = open loop", read_only=True),
    **PLAYBACK,
}

#: ``bag_player``: the playback parameters plus these.
BAG_PLAYER: dict[str, ParamSpec] = {
    'path': ParamSpec('', 'log to play: a .mcap file or a rosbag2 directory (required)',
                      read_only=True),
    'omega_topic': ParamSpec('', "angular-velocity topic in the log; '' = found by message "
                             'type', read_only=True),
    'torque_topic': ParamSpec('', "torque topic in the log; '' = found by message type",
                              read_only=True),
    'original_stamps': ParamSpec(True, 'keep the recorded header stamps (else restamp from '
                                 'the node clock)', read_only=True),
    **PLAYBACK,
}

#: ``exciter`` (config/exciter.yaml documents the same set).
EXCITER: dict[str, ParamSpec] = {
    'scene': ParamSpec('', "scene YAML whose torque profile is commanded (a planned scene; "
                       "its body tensor is the prior of the rate prediction); '' = the "
                       "package's config/scenes/default.yaml", read_only=True),
    'command_topic': ParamSpec('torque_command', 'topic of the torque command '
                               '(geometry_msgs/WrenchStamped)', read_only=True),
    'frame_id': ParamSpec('', "frame of the command; '' = the scene's gyro frame",
                          read_only=True),
    'estimator': ParamSpec('/inertia_estimator', "the estimator node whose "
                           "'<estimator>/inertia_covariance', principal moments and axes and "
                           '/diagnostics are followed', read_only=True),
    'max_torque': ParamSpec(0.1, 'largest commanded torque per axis; a planned command over '
                            'it is held at zero [N m]', 1e-9, 1e6, read_only=True),
    'max_slew': ParamSpec(1.0, 'largest change of the command per axis [N m/s]', 1e-9, 1e9,
                          read_only=True),
    'max_rate': ParamSpec(1.0, 'largest body rate |omega|: hold zero when it would be crossed '
                          '[rad/s]', 1e-6, 1e4, read_only=True),
    'rate_margin': ParamSpec(0.2, 'relative uncertainty of the tensor in the rate prediction '
                             '[dimensionless]', 0.0, 1.0, read_only=True),
    'rate_hysteresis': ParamSpec(0.8, 'after a rate hold, resume under this fraction of '
                                 'max_rate [dimensionless]', 0.01, 0.99, read_only=True),
    'target_rel_std': ParamSpec(0.02, 'stop when every principal moment has a relative '
                                'sigma at or below this [dimensionless]', 1e-6, 1.0,
                                read_only=True),
    'timeout': ParamSpec(120.0, 'stop after this much excitation [s]', 0.1, 86400.0,
                         read_only=True),
    'estimator_timeout': ParamSpec(10.0, 'stop when no covariance arrived for this long '
                                   '(from the start of the excitation until the first) [s]',
                                   0.1, 3600.0, read_only=True),
    'stall_window': ParamSpec(20.0, 'stop when the relative sigma fell less than 2 % over '
                              'this window [s]', 0.1, 86400.0, read_only=True),
    'rate': ParamSpec(50.0, 'command rate [Hz]', 1.0, 1000.0, read_only=True),
    'replan_period': ParamSpec(5.0, 're-plan the profile from the current estimate every this '
                               'many seconds; 0 = command the scene profile throughout [s]',
                               0.0, 3600.0, read_only=True),
    'replan_horizon': ParamSpec(10.0, 'length of each re-planned profile [s]', 0.5, 3600.0,
                                read_only=True),
    'exit_on_stop': ParamSpec(False, 'exit the process 2 s after the final zero command',
                              read_only=True),
    'wheels': ParamSpec('', "wheels YAML (config/wheels/ schema with max_speed [rad/s] per "
                        "wheel) whose speeds on 'joint_states' are kept within max_speed: "
                        "hold zero when a wheel would cross it; '' = no wheels",
                        read_only=True),
}

#: Node name -> (one-line summary, parameter table), for ``--help`` and the tests.
NODE_TABLES: dict[str, tuple[str, dict[str, ParamSpec]]] = {
    'inertia_estimator': ('Live inertia-tensor estimator: subscribes imu (or omega) and '
                          'torque, publishes ~/inertia, ~/inertia_covariance, '
                          '~/principal_moments(_std), ~/principal_axes, ~/principal_ratios'
                          '(_std), ~/markers and /diagnostics.', ESTIMATOR),
    'scene_simulator': ("Simulates a scene and publishes its imu (or omega) and torque "
                        "streams and ~/truth; waits for the estimator's subscriptions "
                        'first.', SCENE_SIMULATOR),
    'bag_player': ('Plays a recorded log (.mcap or rosbag2 directory) back on imu (or omega) '
                   "and torque, with ~/truth; waits for the estimator's subscriptions first.",
                   BAG_PLAYER),
    'exciter': ('Commands a planned torque profile on torque_command within its torque, slew '
                "and body-rate limits, follows the estimator's covariance and stops at the "
                'target sigma, a timeout, a reset, a lost or stalled estimator; state on '
                '/diagnostics.', EXCITER),
}


def help_text(node_name: str) -> str:
    """:func:`usage` of one of the package's nodes."""
    summary, specs = NODE_TABLES[node_name]
    return usage(node_name, summary, specs)
