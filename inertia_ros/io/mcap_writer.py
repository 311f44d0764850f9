"""rosbag2-compatible MCAP writer, and :func:`write_simulation` for simulator output.

The container format is written by the ``mcap`` package's ``Writer``; this module adds what
makes a file a rosbag2 log (the conventions of ``rosbag2_storage_mcap`` in ROS 2 Jazzy):

- header profile ``ros2``;
- one schema per message type: name ``pkg/msg/Type``, encoding ``ros2msg``, data the full
  message text with its dependency blocks (:func:`inertia_ros.io.msgtypes.schema_text`);
- one channel per topic: message encoding ``cdr``, metadata ``offered_qos_profiles`` (the
  rosbag2 v9 YAML list) and ``topic_type_hash`` (the type's RIHS01 hash as the installed ROS
  interface packages state it, :func:`inertia_ros.io.msgtypes.type_description_hash`; empty
  if not installed);
- a metadata record ``rosbag2`` whose ``serialized_metadata`` is the bag's
  ``BagMetadata`` YAML (version 9: topics, counts, start time, duration);
- chunked data (zstd by default), message indexes and a summary with statistics.

Messages are buffered and written in log-time order when the writer closes, so topics may
be added in any order.  Times are integer nanoseconds.
"""
from __future__ import annotations

import json
import os
import shutil
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np
import yaml
from mcap.writer import CompressionType, Writer

from inertia_ros.core.simulation import SimResult
from inertia_ros.io import cdr_encode
from inertia_ros.io.errors import McapWriterError
from inertia_ros.io.msgtypes import schema_text as _schema_text
from inertia_ros.io.msgtypes import type_description_hash

__all__ = [
    'DEFAULT_START_NS',
    'QOS_PRESETS',
    'McapWriter',
    'McapWriterError',
    'qos_yaml',
    'seconds_to_ns',
    'type_description_hash',
    'write_simulation',
]

#: Start epoch [ns] of simulated logs: 2024-01-01T00:00:00Z.
DEFAULT_START_NS = 1_704_067_200_000_000_000

_INFINITE = {'sec': 9223372036, 'nsec': 854775807}  # rmw "infinite" duration as rosbag2 dumps it
_ZERO = {'sec': 0, 'nsec': 0}


def _qos(reliability: str, durability: str, depth: int) -> dict[str, Any]:
    return {'history': 'keep_last', 'depth': depth, 'reliability': reliability,
            'durability': durability, 'deadline': dict(_INFINITE),
            'lifespan': dict(_INFINITE), 'liveliness': 'automatic',
            'liveliness_lease_duration': dict(_INFINITE),
            'avoid_ros_namespace_conventions': False}


#: QoS profiles offered by the simulated publishers (rosbag2 v9 dict form).
QOS_PRESETS: Mapping[str, dict[str, Any]] = {
    'sensor_data': _qos('best_effort', 'volatile', 5),
    'reliable': _qos('reliable', 'volatile', 10),
    'latched': _qos('reliable', 'transient_local', 1),
}


def qos_yaml(qos: str | Mapping[str, Any]) -> str:
    """The ``offered_qos_profiles`` channel metadata string for one offered profile.

    Parameters
    ----------
    qos : str or Mapping
        A preset name from :data:`QOS_PRESETS` or a rosbag2 v9 QoS dict.

    Returns
    -------
    str
        A YAML list with one profile, as rosbag2 (Jazzy) writes it.
    """
    if isinstance(qos, str):
        if qos not in QOS_PRESETS:
            raise McapWriterError(f'qos: unknown preset {qos!r} '
                                  f'(known: {", ".join(QOS_PRESETS)})')
        qos = QOS_PRESETS[qos]
    return yaml.safe_dump([dict(qos)], sort_keys=False).strip()


def seconds_to_ns(t: Any, start_ns: int = 0) -> np.ndarray:
    """Float seconds -> integer nanoseconds ``start_ns + round(t * 1e9)``, shape of ``t``."""
    return np.int64(start_ns) + np.rint(np.asarray(t, dtype=np.float64) * 1e9).astype(np.int64)


@dataclass
class _Topic:
    name: str
    msgtype: str
    qos: str
    channel_id: int
    log_ns: list[np.ndarray] = field(default_factory=list)
    payloads: list[list[bytes]] = field(default_factory=list)

    @property
    def count(self) -> int:
        return sum(a.size for a in self.log_ns)


_COMPRESSION = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
                'none': CompressionType.NONE}


class McapWriter:
    """Write a rosbag2-compatible MCAP file (a context manager).

    Parameters
    ----------
    path : str or pathlib.Path
        Output ``.mcap`` file.
    overwrite : bool, optional
        Replace an existing file; without it an existing path raises ``FileExistsError``.
    compression : {'zstd', 'lz4', 'none'}, optional
        Chunk compression (default zstd).
    chunk_size : int, optional
        Target uncompressed chunk size [bytes].
    ros_distro : str, optional
        Recorded in the rosbag2 metadata.

    Examples
    --------
    >>> with McapWriter('out.mcap') as w:                      # doctest: +SKIP
    ...     w.add_topic('/torque', cdr_encode.WRENCH_STAMPED, qos='sensor_data')
    ...     w.write_many('/torque', t_ns, cdr_encode.encode_wrench_stamped(t_ns, tau, 'base'))
    """

    def __init__(self, path: str | os.PathLike[str], *, overwrite: bool = False,
                 compression: str = 'zstd', chunk_size: int = 1 << 20,
                 ros_distro: str = 'jazzy') -> None:
        self.path = Path(path)
        if compression not in _COMPRESSION:
            raise McapWriterError(f'compression: must be one of {", ".join(_COMPRESSION)}, '
                                  f'got {compression!r}')
        if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size <= 0:
            raise McapWriterError(f'chunk_size: must be a positive integer, got {chunk_size!r}')
        if self.path.is_dir():
            raise McapWriterError(f'path: {self.path} is a directory')
        if self.path.exists() and not overwrite:
            raise FileExistsError(f'{self.path} exists (pass overwrite=True to replace it)')
        if not self.path.parent.is_dir():
            raise McapWriterError(f'path: directory {self.path.parent} does not exist')
        self._overwrite = overwrite
        self._compression = _COMPRESSION[compression]
        self._ros_distro = ros_distro
        self._topics: dict[str, _Topic] = {}
        self._schemas: dict[str, int] = {}
        self._metadata: list[tuple[str, dict[str, str]]] = []
        self._stream = None
        self._writer: Writer | None = None
        self._closed = False
        #: the rosbag2 ``BagMetadata`` YAML written into the file, set by :meth:`close`
        self.bag_metadata: str | None = None
        self._tmp = self.path.with_name(self.path.name + '.partial')
        self._stream = open(self._tmp, 'wb')  # closed in close() / abort()
        self._writer = Writer(self._stream, chunk_size=chunk_size,
                              compression=self._compression)
        self._writer.start(profile='ros2', library='inertia_ros')

    # ---------------------------------------------------------------- context manager
    def __enter__(self) -> McapWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    # ---------------------------------------------------------------- topics and data
    def add_topic(self, topic: str, msgtype: str, *,
                  qos: str | Mapping[str, Any] = 'reliable',
                  schema_text: str | None = None) -> None:
        """Declare a topic (one MCAP channel) of a known message type.

        Parameters
        ----------
        topic : str
            Absolute topic name, e.g. ``/imu``.
        msgtype : str
            ``pkg/msg/Type``; its schema must be in :data:`inertia_ros.io.msgtypes.MSG_FIELDS`.
        qos : str or Mapping, optional
            Offered QoS: a :data:`QOS_PRESETS` name or a rosbag2 v9 QoS dict.
        schema_text : str, optional
            The ros2msg schema with its dependency blocks, for a type
            :data:`inertia_ros.io.msgtypes.MSG_FIELDS` lacks (payloads are then serialised by
            the caller, e.g. with rclpy; the text from
            :func:`inertia_ros.io.msgtypes.schema_text_from_share`).  Default: the hand-written
            schema for ``msgtype``.
        """
        self._check_open()
        if not isinstance(topic, str) or not topic.startswith('/') or topic.endswith('/'):
            raise McapWriterError(f'topic: must be an absolute name like /imu, got {topic!r}')
        if topic in self._topics:
            raise McapWriterError(f'topic: {topic} was already added')
        if schema_text is not None:
            if not isinstance(schema_text, str) or not schema_text.strip():
                raise McapWriterError(f'schema_text: must be a non-empty ros2msg text for '
                                      f'{msgtype}')
            text = schema_text
        else:
            try:
                text = _schema_text(msgtype)
            except ValueError as exc:
                raise McapWriterError(str(exc)) from None
        qos_text = qos_yaml(qos)
        assert self._writer is not None
        if msgtype not in self._schemas:
            self._schemas[msgtype] = self._writer.register_schema(
                name=msgtype, encoding='ros2msg', data=text.encode('utf-8'))
        cid = self._writer.register_channel(
            topic=topic, message_encoding='cdr', schema_id=self._schemas[msgtype],
            metadata={'offered_qos_profiles': qos_text,
                      'topic_type_hash': type_description_hash(msgtype)})
        self._topics[topic] = _Topic(topic, msgtype, qos_text, cid)

    def write_many(self, topic: str, log_time_ns: Any, payloads: Sequence[bytes]) -> None:
        """Queue serialised messages on a topic.

        Parameters
        ----------
        topic : str
            A topic added with :meth:`add_topic`.
        log_time_ns : array_like of int, shape (N,)
            Log (receive) times [ns], >= 0; also used as publish times.
        payloads : sequence of bytes, length N
            CDR-encoded messages of the topic's type.
        """
        self._check_open()
        if topic not in self._topics:
            raise McapWriterError(f'topic: {topic} was not added (call add_topic first)')
        t = np.asarray(log_time_ns)
        if t.dtype.kind not in 'iu':
            raise McapWriterError(f'log_time_ns: must be integer nanoseconds, got {t.dtype}')
        t = t.astype(np.int64).reshape(-1)
        if t.size != len(payloads):
            raise McapWriterError(f'payloads: {len(payloads)} messages for {t.size} log times')
        if t.size and t.min() < 0:
            raise McapWriterError('log_time_ns: log times must be >= 0')
        self._topics[topic].log_ns.append(t)
        self._topics[topic].payloads.append(list(payloads))

    def write(self, topic: str, log_time_ns: int, payload: bytes) -> None:
        """Queue one serialised message (see :meth:`write_many`)."""
        self.write_many(topic, np.array([log_time_ns], dtype=np.int64), [payload])

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Add an MCAP metadata record (string keys and values); ``rosbag2`` is reserved."""
        self._check_open()
        if name == 'rosbag2':
            raise McapWriterError('name: the rosbag2 metadata record is written by close()')
        if not all(isinstance(k, str) and isinstance(v, str) for k, v in data.items()):
            raise McapWriterError(f'data: metadata {name!r} must map strings to strings')
        self._metadata.append((name, dict(data)))

    # ---------------------------------------------------------------- finishing
    def _bag_metadata(self, start: int, end: int, count: int) -> str:
        topics = [{
            'topic_metadata': {'name': tp.name, 'type': tp.msgtype,
                               'serialization_format': 'cdr',
                               'offered_qos_profiles': yaml.safe_load(tp.qos),
                               'type_description_hash': type_description_hash(tp.msgtype)},
            'message_count': tp.count,
        } for tp in self._topics.values()]
        meta = {
            'version': 9,
            'storage_identifier': 'mcap',
            'duration': {'nanoseconds': int(end - start)},
            'starting_time': {'nanoseconds_since_epoch': int(start)},
            'message_count': int(count),
            'topics_with_message_count': topics,
            'compression_format': '',
            'compression_mode': '',
            'relative_file_paths': [self.path.name],
            'files': [{'path': self.path.name,
                       'starting_time': {'nanoseconds_since_epoch': int(start)},
                       'duration': {'nanoseconds': int(end - start)},
                       'message_count': int(count)}],
            'custom_data': {},
            'ros_distro': self._ros_distro,
        }
        return yaml.safe_dump(meta, sort_keys=False)

    def close(self) -> None:
        """Write the messages in log-time order, the metadata and the summary; finish."""
        if self._closed:
            return
        assert self._writer is not None and self._stream is not None
        try:
            chans, times, data, seqs = [], [], [], []
            for tp in self._topics.values():
                if not tp.log_ns:
                    continue
                t = np.concatenate(tp.log_ns)
                times.append(t)
                chans.append(np.full(t.size, tp.channel_id, dtype=np.int64))
                seqs.append(np.arange(t.size, dtype=np.int64))
                for p in tp.payloads:
                    data.extend(p)
            count = len(data)
            if count:
                t_all = np.concatenate(times)
                c_all = np.concatenate(chans)
                s_all = np.concatenate(seqs)
                order = np.lexsort((c_all, t_all))
                add = self._writer.add_message
                for i, t, c, s in zip(order.tolist(), t_all[order].tolist(),
                                      c_all[order].tolist(), s_all[order].tolist(),
                                      strict=True):
                    add(channel_id=c, log_time=t, data=data[i], publish_time=t, sequence=s)
                start, end = int(t_all.min()), int(t_all.max())
            else:
                start = end = 0
            for name, md in self._metadata:
                self._writer.add_metadata(name, md)
            self.bag_metadata = self._bag_metadata(start, end, count)
            self._writer.add_metadata('rosbag2', {'serialized_metadata': self.bag_metadata})
            self._writer.finish()
            self._stream.close()
            if not self._overwrite and self.path.exists():
                raise FileExistsError(f'{self.path} appeared while writing '
                                      f'(pass overwrite=True to replace it)')
            os.replace(self._tmp, self.path)
        except BaseException:
            self.abort()
            raise
        self._closed = True

    def abort(self) -> None:
        """Discard the partial file (the target path is left untouched)."""
        if self._closed:
            return
        self._closed = True
        if self._stream is not None and not self._stream.closed:
            self._stream.close()
        self._tmp.unlink(missing_ok=True)

    def _check_open(self) -> None:
        if self._closed:
            raise McapWriterError(f'{self.path}: writer is closed')


def _jsonable(obj: Any) -> Any:
    """JSON fallback for numpy values in a scene dict."""
    if hasattr(obj, 'tolist'):
        return obj.tolist()
    return str(obj)


def write_simulation(path: str | os.PathLike[str], result: SimResult, *,
                     start_ns: int = DEFAULT_START_NS, overwrite: bool = False,
                     imu_topic: str = '/imu', torque_topic: str = '/torque',
                     truth_topic: str = '/truth/inertia', compression: str = 'zstd',
                     extra_metadata: Mapping[str, str] | None = None,
                     rosbag2_dir: bool = False,
                     wheel_topic: str = '/joint_states') -> dict[str, int]:
    """Write a simulation result as a rosbag2-compatible MCAP log.

    A scene with wheels also gets ``wheel_topic`` (``sensor_msgs/msg/JointState``: the wheel
    speeds as ``velocity`` [rad/s], joints named as in the scene).

    Parameters
    ----------
    path : str or pathlib.Path
        Output ``.mcap`` file, or with ``rosbag2_dir`` the bag directory to create.
    result : SimResult
        What :func:`inertia_ros.core.simulation.simulate` returned.
    start_ns : int, optional
        Epoch [ns] added to the simulation's float-second times (header stamps and log
        times are ``start_ns + round(t * 1e9)``).
    overwrite : bool, optional
        Replace an existing file.
    imu_topic, torque_topic, truth_topic : str, optional
        Topic names: ``sensor_msgs/msg/Imu`` (angular velocity, covariance diag(sigma^2)),
        ``geometry_msgs/msg/WrenchStamped`` (torque; zero force) and
        ``geometry_msgs/msg/InertiaStamped`` (the true tensor at t = 0 and at each change,
        with mass and centre of mass when the body is built from parts, else 0; latched
        QoS).
    compression : {'zstd', 'lz4', 'none'}, optional
        Chunk compression.
    extra_metadata : Mapping[str, str], optional
        Added to the ``inertia_ros.scene`` metadata record.
    rosbag2_dir : bool, optional
        Write a rosbag2 bag directory as ``ros2 bag record -o PATH`` does:
        ``PATH/metadata.yaml`` and ``PATH/<name>_0.mcap``.  ``PATH`` must not exist (an
        existing directory is never replaced, whatever ``overwrite`` says).

    Returns
    -------
    dict
        Message counts per topic.
    """
    if not isinstance(result, SimResult):
        raise McapWriterError(f'result: expected a SimResult, got {type(result).__name__}')
    if isinstance(start_ns, bool) or not isinstance(start_ns, (int, np.integer)) \
            or start_ns < 0:
        raise McapWriterError(f'start_ns: must be a non-negative integer, got {start_ns!r}')
    stamps = _stamps(result, start_ns)
    meta = _scene_metadata(result, start_ns, extra_metadata)
    out = Path(path)
    tmp = _bag_dir_begin(out) if rosbag2_dir else None
    try:
        with McapWriter(out if tmp is None else tmp / f'{out.name}_0.mcap',
                        overwrite=overwrite, compression=compression) as w:
            counts = _write_streams(w, result, stamps, start_ns, imu_topic, torque_topic,
                                    truth_topic, wheel_topic)
            w.add_metadata('inertia_ros.scene', meta)
        if tmp is not None:
            assert w.bag_metadata is not None
            _bag_dir_finish(tmp, out, w.bag_metadata)
    except BaseException:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        raise
    return counts


def _stamps(result: SimResult, start_ns: int) -> dict[str, np.ndarray]:
    """Log times [ns] of the gyro, torque and truth messages of a simulation.

    Returns
    -------
    dict
        ``'gyro'``, ``'torque'``, ``'truth'``: int64 (n,) times ``start_ns + round(t * 1e9)``
        (the truth at t = 0 and at each inertia change).
    """
    truth_t = [0.0] + [t for t, _ in result.inertia_changes]
    return {'gyro': seconds_to_ns(result.t_gyro, start_ns),
            'torque': seconds_to_ns(result.t_torque, start_ns),
            'truth': seconds_to_ns(np.array(truth_t), start_ns)}


def _scene_metadata(result: SimResult, start_ns: int,
                    extra_metadata: Mapping[str, str] | None) -> dict[str, str]:
    """The ``inertia_ros.scene`` metadata record of a simulation log."""
    scene = result.scene
    meta = {
        'scene_name': scene.name,
        'seed': str(result.seed),
        'scene_json': json.dumps(scene.to_dict(), sort_keys=True, default=_jsonable),
        'start_ns': str(int(start_ns)),
        'frame_id': result.frame_id,
        'disturbance_torque': json.dumps([float(x) for x in result.torque_bias_true]),
    }
    if extra_metadata:
        meta.update({str(k): str(v) for k, v in extra_metadata.items()})
    return meta


def _write_streams(w: McapWriter, result: SimResult, stamps: dict[str, np.ndarray],
                   start_ns: int, imu_topic: str, torque_topic: str, truth_topic: str,
                   wheel_topic: str) -> dict[str, int]:
    """Write a simulation's topics (and its wheels' JointState, if any): counts per topic.

    The truth carries the mass and centre of mass of the body (and of the changed body)
    when the scene builds it from parts, else 0.
    """
    scene, frame = result.scene, result.frame_id
    sigma = scene.gyro.noise_std
    t_g, t_t, t_i = stamps['gyro'], stamps['torque'], stamps['truth']
    truth_i = np.stack([result.inertia] + [m for _, m in result.inertia_changes])
    bodies = [(scene.mass, scene.com)]
    if scene.inertia_change is not None and result.inertia_changes:
        bodies.append((scene.inertia_change.mass, scene.inertia_change.com))
    truth_m = [0.0 if m is None else m for m, _ in bodies]
    truth_c = [np.zeros(3) if c is None else c for _, c in bodies]
    w.add_topic(imu_topic, cdr_encode.IMU, qos='sensor_data')
    w.add_topic(torque_topic, cdr_encode.WRENCH_STAMPED, qos='sensor_data')
    w.add_topic(truth_topic, cdr_encode.INERTIA_STAMPED, qos='latched')
    w.write_many(imu_topic, t_g, cdr_encode.encode_imu(
        t_g, result.omega, frame,
        angular_velocity_covariance=np.diag([sigma ** 2] * 3).ravel()))
    w.write_many(torque_topic, t_t, cdr_encode.encode_wrench_stamped(
        t_t, result.torque, frame))
    w.write_many(truth_topic, t_i, cdr_encode.encode_inertia_stamped(
        t_i, truth_i, frame, mass=np.array(truth_m), com=np.array(truth_c)))
    counts = {imu_topic: int(t_g.size), torque_topic: int(t_t.size),
              truth_topic: int(t_i.size)}
    if result.t_wheel is not None and scene.wheels is not None:
        from .joint_state import JOINT_STATE, encode_joint_state
        t_w = seconds_to_ns(result.t_wheel, start_ns)
        w.add_topic(wheel_topic, JOINT_STATE, qos='sensor_data')
        w.write_many(wheel_topic, t_w, encode_joint_state(
            t_w, [wh.joint for wh in scene.wheels.wheels], result.wheel_speed))
        counts[wheel_topic] = int(t_w.size)
    return counts


def _bag_dir_begin(out: Path) -> Path:
    """Check that the bag directory ``out`` can be created; make its ``.partial`` twin."""
    if out.exists():
        raise FileExistsError(f'{out} exists (a bag directory is never replaced: remove it '
                              'or choose another name)')
    if out.name in ('', '.', '..'):
        raise McapWriterError(f'path: {out} does not name a new directory')
    if not out.parent.is_dir():
        raise McapWriterError(f'path: directory {out.parent} does not exist')
    tmp = out.with_name(out.name + '.partial')
    if tmp.exists():
        raise FileExistsError(f'{tmp} exists (left by an interrupted run? remove it)')
    tmp.mkdir()
    return tmp


def _bag_dir_finish(tmp: Path, out: Path, bag_metadata: str) -> None:
    """Write ``metadata.yaml`` (as ``ros2 bag record`` does) and move the bag into place."""
    info = yaml.safe_load(bag_metadata)
    (tmp / 'metadata.yaml').write_text(
        yaml.safe_dump({'rosbag2_bagfile_information': info}, sort_keys=False))
    if out.exists():
        raise FileExistsError(f'{out} appeared while writing; it was left as it is')
    tmp.rename(out)


