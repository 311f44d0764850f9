"""Topic discovery of the log layer: which topics carry the angular velocity, the torque and
the joint speeds (``sensor_msgs/msg/JointState``), given by name or found by message type.
"""
from __future__ import annotations

from pathlib import Path

from inertia_ros.io.log_types import LogError

__all__ = ['JOINT_STATE', 'OMEGA_TYPES', 'TORQUE_TYPES', 'TRUTH_TOPIC', 'TRUTH_TYPE',
           'choose_joint_topic', 'choose_topics', 'field_for']

#: Angular-velocity message types and the field holding omega [rad/s].
OMEGA_TYPES: dict[str, str] = {
    'sensor_msgs/msg/Imu': 'angular_velocity',
    'geometry_msgs/msg/TwistStamped': 'angular',
    'geometry_msgs/msg/Vector3Stamped': 'vector',
}
#: Torque message types and the field holding the torque [N m].
TORQUE_TYPES: dict[str, str] = {
    'geometry_msgs/msg/WrenchStamped': 'torque',
    'geometry_msgs/msg/Vector3Stamped': 'vector',
}
TRUTH_TYPE = 'geometry_msgs/msg/InertiaStamped'
#: Topic holding the true tensor in simulated logs.
TRUTH_TOPIC = '/truth/inertia'

_OMEGA_WORDS = ('omega', 'angular', 'gyro', 'rate', 'imu', 'twist')
_TORQUE_WORDS = ('torque', 'wrench', 'moment', 'tau')
#: Joint speeds (wheels, rotors): ``velocity`` [rad/s] matched to the joints by ``name``.
JOINT_STATE = 'sensor_msgs/msg/JointState'


def field_for(msg_type: str, topic: str) -> str:
    """The field of ``msg_type`` holding the stream's vector (the truth's: ``inertia``)."""
    if msg_type in OMEGA_TYPES and msg_type not in TORQUE_TYPES:
        return OMEGA_TYPES[msg_type]
    if msg_type in TORQUE_TYPES:
        return TORQUE_TYPES[msg_type]
    return 'inertia'


def _list_topics(topics: dict[str, str]) -> str:
    if not topics:
        return 'the log has no topics'
    return 'topics in the log: ' + ', '.join(f'{t} ({ty or "no schema"})'
                                              for t, ty in sorted(topics.items()))


def choose_topics(path: str | Path, topics: dict[str, str], omega_topic: str | None,
                   torque_topic: str | None, *, need_torque: bool = True) -> tuple[str, str]:
    """Pick the angular-velocity and torque topics (given, or by type and name).

    With ``need_torque`` False the torque topic returned is ``''``.
    """
    for name, given, types, flag in (('angular velocity', omega_topic, OMEGA_TYPES,
                                      '--omega-topic'),
                                     ('torque', torque_topic, TORQUE_TYPES, '--torque-topic')):
        if given is None:
            continue
        if given not in topics:
            raise LogError(f'{path}: topic {given} ({flag}) is not in the log; '
                           f'{_list_topics(topics)}')
        if topics[given] not in types:
            raise LogError(f'{path}: topic {given} has type {topics[given] or "unknown"}, not '
                           f'a {name} type ({", ".join(types)})')
    usable = {t: ty for t, ty in topics.items() if not t.startswith('/truth/')}

    def pick(kind: str, types: dict[str, str], strong: tuple[str, ...],
             words: tuple[str, ...], other: str | None, flag: str) -> str:
        cands = [t for t, ty in usable.items() if ty in strong and t != other]
        if not cands:
            cands = [t for t, ty in usable.items() if ty in types and t != other
                     and any(w in t.lower() for w in words)]
        if not cands:
            cands = [t for t, ty in usable.items() if ty in types and t != other]
        if len(cands) == 1:
            return cands[0]
        if not cands:
            hint = ' (for torque-free data pass --torque-topic none)' if kind == 'torque' else ''
            raise LogError(f'{path}: no {kind} topic (types {", ".join(types)}); '
                           f'{_list_topics(topics)}{hint}')
        raise LogError(f'{path}: several {kind} topics ({", ".join(sorted(cands))}); choose '
                       f'one with {flag}')

    om = omega_topic or pick('angular velocity', OMEGA_TYPES,
                             ('sensor_msgs/msg/Imu', 'geometry_msgs/msg/TwistStamped'),
                             _OMEGA_WORDS, torque_topic, '--omega-topic')
    if not need_torque:
        return om, ''
    tq = torque_topic or pick('torque', TORQUE_TYPES, ('geometry_msgs/msg/WrenchStamped',),
                              _TORQUE_WORDS, om, '--torque-topic')
    if om == tq:
        raise LogError(f'{path}: the same topic {om} cannot be both angular velocity and '
                       'torque; give --omega-topic and --torque-topic')
    return om, tq


# --------------------------------------------------------------------------------------------
# Cleaning



def choose_joint_topic(path: str | Path, topics: dict[str, str], joint_topic: str | None,
                       what: str = 'wheels') -> str:
    """Pick the JointState topic: the one given, or the only one of that type in the log.

    Parameters
    ----------
    path : str or Path
        The log (named in the messages).
    topics : dict of str to str
        Every topic of the log and its type.
    joint_topic : str, optional
        The topic given (``--wheel-topic`` / ``--rotor-topic``).
    what : {'wheels', 'rotors'}
        What the joints are (names the command-line options in the messages).

    Raises
    ------
    LogError
        The topic given is absent or not JointState; none or several found by type.
    """
    flag = f'--{what[:-1]}-topic'
    if joint_topic is not None:
        if joint_topic not in topics:
            raise LogError(f'{path}: topic {joint_topic} ({flag}) is not in the log; '
                           f'{_list_topics(topics)}')
        if topics[joint_topic] != JOINT_STATE:
            raise LogError(f'{path}: topic {joint_topic} has type '
                           f'{topics[joint_topic] or "unknown"}, not {JOINT_STATE}')
        return joint_topic
    found = sorted(t for t, ty in topics.items() if ty == JOINT_STATE)
    if not found:
        raise LogError(f'{path}: no {JOINT_STATE} topic; record the {what[:-1]} speeds as '
                       f'JointState or drop --{what}')
    if len(found) > 1:
        raise LogError(f'{path}: several JointState topics {found}; choose one with {flag}')
    return found[0]
