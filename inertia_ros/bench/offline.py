"""``bench offline``: our read/decode/align/estimate path against ``mcap`` and ``mcap_ros2``.

Builds a log of 200 Hz ``sensor_msgs/Imu`` and 50 Hz ``geometry_msgs/WrenchStamped`` (one
hour by default: 720k + 180k = 900k messages) in a temporary directory, then measures each
stage in a fresh interpreter, so that peak memory (ru_maxrss) belongs to that stage alone:

``ours_read``
    :func:`inertia_ros.io.logs.read_log` (read, decode, clean, align to windows).
``ours_end_to_end``
    ``read_log`` + :func:`inertia_ros.core.estimation.estimate` (the estimate command's path).
``mcap_raw``
    ``mcap.reader.make_reader(...).iter_messages()`` (no decoding).
``mcap_ros2``
    ``make_reader(..., decoder_factories=[mcap_ros2 DecoderFactory()])
    .iter_decoded_messages()`` (about a minute per hour of log; ``skip_slow`` leaves it out).

``--whole`` (:func:`run_whole`) instead times ``python -m inertia_ros estimate LOG --format
json`` as whole processes on the log uncompressed and zstd-chunked (768 KiB), its phases
(interpreter, imports, read, estimate, report) and the ``mcap_ros2`` and ``rosbags`` readers
decoding the same file, and writes the BENCHMARKS.md section (``--md``).

``blas_threads=1`` pins BLAS to one thread: on a loaded 2-core machine OpenBLAS's own threads
can make the estimator's Gram products tens of times slower.
"""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from .common import ROOT, process_env, timed_process

__all__ = ['LAYOUTS', 'STAGES', 'build_log', 'markdown', 'run', 'run_stage', 'run_whole',
           'whole_layout']

#: Measured stages, in order.
STAGES = ('ours_read', 'ours_end_to_end', 'mcap_raw', 'mcap_ros2')
#: Tensor of the synthetic log [kg m^2].
INERTIA = np.array([[0.8, 0.02, -0.01], [0.02, 1.1, 0.03], [-0.01, 0.03, 1.5]])
#: Uncompressed chunk size [bytes] of rosbag2's default MCAP storage preset.
CHUNK_SIZE = 768 * 1024
_FREQ = np.array([[0.11, 0.23], [0.17, 0.31], [0.07, 0.19]])     # [Hz]
_AMP = np.array([[0.6, 0.3], [0.5, 0.25], [0.7, 0.2]])           # [rad/s]


def _motion(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """An analytic angular velocity exciting all axes and its derivative, shapes (N, 3)."""
    arg = 2 * np.pi * t[:, None, None] * _FREQ
    return (_AMP * np.sin(arg)).sum(axis=2), (_AMP * 2 * np.pi * _FREQ * np.cos(arg)).sum(axis=2)


def _block(tb: float, rng: np.random.Generator, t0_ns: int) -> tuple[Any, ...]:
    """Stamps [ns] and CDR payloads of one 10 s block of gyro (200 Hz) and torque (50 Hz).

    The torque follows from Euler's equations exactly (``tau = I w' + w x I w``), so the
    estimate can be checked; both streams get 1e-3 white noise.
    """
    from inertia_ros.io import cdr_encode as ce

    t_tau = tb + np.arange(0, 10.0, 0.02)
    w_t, wd_t = _motion(t_tau)
    tau = wd_t @ INERTIA.T + np.cross(w_t, w_t @ INERTIA.T)
    t_g = tb + np.arange(0, 10.0, 0.005)
    om = _motion(t_g)[0] + rng.normal(scale=1e-3, size=(t_g.size, 3))
    tau_m = tau + rng.normal(scale=1e-3, size=tau.shape)
    ns_g = t0_ns + np.rint(t_g * 1e9).astype(np.int64)
    ns_t = t0_ns + np.rint(t_tau * 1e9).astype(np.int64)
    return (ns_g, ce.encode_imu(ns_g, om, 'base_link'), ns_t,
            ce.encode_wrench_stamped(ns_t, tau_m, 'base_link'))


def build_log(path: Path, minutes: float, compression: str, seed: int = 0,
              chunk_size: int = CHUNK_SIZE) -> int:
    """Write the benchmark log as a one-file rosbag2 bag; return the message count.

    ``path`` is the ``.mcap`` file, written with :class:`inertia_ros.io.mcap_writer.McapWriter`
    (the ``ros2 bag record`` layout: ``/imu`` with the sensor-data QoS, ``/torque``); its
    directory also gets the bag's ``metadata.yaml``, so the directory is a rosbag2 bag that
    ``rosbags`` can open.  ``chunk_size`` [bytes] is the uncompressed chunk target (rosbag2's
    default storage preset: 768 KiB, zstd).
    """
    import yaml

    from inertia_ros.io import cdr_encode as ce
    from inertia_ros.io.mcap_writer import McapWriter

    rng = np.random.default_rng(seed)
    n = 0
    with McapWriter(path, overwrite=True, compression=compression,
                    chunk_size=chunk_size) as w:
        w.add_topic('/imu', ce.IMU, qos='sensor_data')
        w.add_topic('/torque', ce.WRENCH_STAMPED)
        k = 0
        while k * 10.0 < minutes * 60.0:
            ns_g, pay_g, ns_t, pay_t = _block(k * 10.0, rng, 1_704_067_200_000_000_000)
            w.write_many('/imu', ns_g, pay_g)
            w.write_many('/torque', ns_t, pay_t)
            n += ns_g.size + ns_t.size
            k += 1
    assert w.bag_metadata is not None
    info = yaml.safe_load(w.bag_metadata)
    (path.parent / 'metadata.yaml').write_text(
        yaml.safe_dump({'rosbag2_bagfile_information': info}, sort_keys=False))
    return n


_STAGE_CODE = r'''
import json, resource, sys, time
sys.path.insert(0, {root!r})
path = {path!r}
stage = {stage!r}
# imports are not timed (they are a fixed cost, not a rate)
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from inertia_ros.io.logs import read_log
from inertia_ros.core.estimation import estimate
t0 = time.perf_counter()
n = 0
extra = {{}}
if stage in ('ours_read', 'ours_end_to_end'):
    log = read_log(path)
    n = log.omega.counts.received + log.torque.counts.received
    extra['used'] = log.omega.counts.used + log.torque.counts.used
    if stage == 'ours_end_to_end':
        t1 = time.perf_counter()
        est = estimate(log.omega.t, log.omega.values, log.torque.t, log.torque.values)
        extra['estimate_s'] = time.perf_counter() - t1
        extra['status'] = est.status
        extra['inertia'] = None if est.inertia is None else est.inertia.tolist()
elif stage == 'mcap_raw':
    with open(path, 'rb') as f:
        for _ in make_reader(f).iter_messages():
            n += 1
elif stage == 'mcap_ros2':
    with open(path, 'rb') as f:
        for _ in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            n += 1
dt = time.perf_counter() - t0
rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
print(json.dumps(dict(stage=stage, messages=n, seconds=dt, msg_per_s=n / dt,
                      peak_rss_mb=rss, **extra)))
'''


def run_stage(path: Path, stage: str, blas_threads: int | None = None) -> dict[str, Any]:
    """Run one stage in a fresh interpreter; return its JSON result (or ``{'error': ...}``)."""
    code = _STAGE_CODE.format(root=str(ROOT), path=str(path), stage=stage)
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          check=False, env=process_env(blas_threads))
    if proc.returncode != 0:
        return {'stage': stage, 'error': proc.stderr.strip().splitlines()[-1:]}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _best(path: Path, stage: str, repeat: int, blas_threads: int | None) -> dict[str, Any]:
    """The fastest of ``repeat`` runs of a stage (load only ever adds time), largest RSS."""
    runs = [run_stage(path, stage, blas_threads) for _ in range(max(1, repeat))]
    good = [x for x in runs if 'error' not in x]
    if not good:
        return runs[0]
    r = min(good, key=lambda x: x['seconds'])
    return dict(r, peak_rss_mb=max(x['peak_rss_mb'] for x in good),
                all_seconds=[x['seconds'] for x in good])


def _print_stage(r: dict[str, Any]) -> None:
    """One table line per stage."""
    if 'error' in r:
        print(f'{r["stage"]:16s} FAILED: {r["error"]}', flush=True)
        return
    est = (f'  (estimate {r["estimate_s"]:.2f} s, {r["status"]})' if 'estimate_s' in r
           else '')
    print(f'{r["stage"]:16s} {r["messages"]:>8d} msgs {r["seconds"]:8.2f} s '
          f'{r["msg_per_s"]:>12,.0f} msg/s  peak RSS {r["peak_rss_mb"]:6.0f} MB' + est,
          flush=True)


def run(minutes: float = 60.0, compression: str = 'zstd', skip_slow: bool = False,
        repeat: int = 1, json_path: Path | None = None,
        blas_threads: int | None = None, whole: bool = False, peer_repeat: int = 5,
        md_path: Path | None = None) -> int:
    """Build the log, run the stages, print a table (and optionally write JSON); return 0.

    Parameters
    ----------
    minutes : float
        Log length [min].
    compression : str
        ``zstd``, ``lz4`` or ``none``.
    skip_slow : bool
        Leave out the ``mcap_ros2`` decode.
    repeat : int
        Runs per stage; the fastest is reported, the peak RSS is the largest.
    json_path : Path, optional
        Also write the results here.
    blas_threads : int, optional
        ``OPENBLAS/OMP/MKL_NUM_THREADS`` of the stages (default: inherited).
    whole : bool
        Run :func:`run_whole` instead (both layouts, whole processes; ``compression`` is
        then ignored, ``skip_slow`` leaves out the peers).
    peer_repeat : int
        ``whole``: runs per peer reader.
    md_path : Path, optional
        ``whole``: write the BENCHMARKS.md section here.
    """
    if whole:
        return run_whole(minutes, repeat, not skip_slow, peer_repeat, json_path, md_path,
                         blas_threads)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'bench.mcap'
        t = time.perf_counter()
        n = build_log(path, minutes, compression)
        print(f'built {path.name}: {n} messages, {path.stat().st_size / 1e6:.1f} MB '
              f'({compression}) in {time.perf_counter() - t:.1f} s', flush=True)
        results = []
        for stage in STAGES:
            if not (stage == 'mcap_ros2' and skip_slow):
                results.append(_best(path, stage, repeat, blas_threads))
                _print_stage(results[-1])
    by = {r['stage']: r for r in results if 'error' not in r}
    for other, what in (('mcap_ros2', 'mcap_ros2 decoding alone'),
                        ('mcap_raw', 'mcap raw iteration')):
        if 'ours_end_to_end' in by and other in by:
            ratio = by['ours_end_to_end']['msg_per_s'] / by[other]['msg_per_s']
            print(f'end-to-end is {ratio:.1f}x {what}')
    if json_path is not None:
        json_path.write_text(json.dumps({'messages': n, 'minutes': minutes,
                                         'compression': compression,
                                         'blas_threads': blas_threads, 'repeat': repeat,
                                         'results': results}, indent=2))
    return 0


# --------------------------------------------------------------------------------------------
# Whole process: ``python -m inertia_ros estimate LOG --format json`` from exec to exit

#: Layouts of the one-hour log measured by :func:`run_whole`: (name, chunk compression).
LAYOUTS = (('uncompressed', 'none'), ('zstd', 'zstd'))

#: Target of issue 18 item 6 [messages/s, whole process].
TARGET_MSG_PER_S = 1_000_000

_PHASE_CODE = r'''
import json, sys, time
t0 = time.perf_counter()
sys.path.insert(0, {root!r})
from inertia_ros.cli import estimate as cli_estimate
from inertia_ros.cli.report import build_report, numerical_warnings
from inertia_ros.core.estimation import estimate
from inertia_ros.io.logs import read_log
from inertia_ros.runtime import keep_freed_memory
keep_freed_memory()                     # as the command's main() does
t1 = time.perf_counter()
with numerical_warnings() as found:
    c1 = time.process_time()
    log = read_log({path!r})
    t2 = time.perf_counter()
    c2 = time.process_time()
    est = estimate(log.omega.t, log.omega.values, log.torque.t, log.torque.values)
    t3 = time.perf_counter()
text = json.dumps(build_report(est, log, 0.0, 'auto', list(found)), indent=2, allow_nan=False)
t4 = time.perf_counter()
print(json.dumps(dict(imports=t1 - t0, read=t2 - t1, estimate=t3 - t2, report=t4 - t3,
                      read_cpu=c2 - c1,
                      messages=int(log.omega.counts.received + log.torque.counts.received))))
'''

_PEER_CODE = r'''
import json, sys, time
from pathlib import Path
t0 = time.perf_counter()
import numpy as np
peer, path = {peer!r}, Path({path!r})
n = 0
cols = {{'/imu': ([], [], [], []), '/torque': ([], [], [], [])}}
if peer == 'mcap_ros2':
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    with open(path, 'rb') as f:
        for _, ch, m, msg in make_reader(
                f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            v = msg.angular_velocity if ch.topic == '/imu' else msg.wrench.torque
            c = cols[ch.topic]
            c[0].append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
            c[1].append(v.x); c[2].append(v.y); c[3].append(v.z)
            n += 1
else:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
    with AnyReader([path.parent], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as r:
        for conn, _, raw in r.messages():
            msg = r.deserialize(raw, conn.msgtype)
            v = msg.angular_velocity if conn.topic == '/imu' else msg.wrench.torque
            c = cols[conn.topic]
            c[0].append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
            c[1].append(v.x); c[2].append(v.y); c[3].append(v.z)
            n += 1
arrays = {{k: (np.array(c[0], np.int64), np.column_stack(c[1:])) for k, c in cols.items()}}
print(json.dumps(dict(messages=n, decode=time.perf_counter() - t0)))
'''


def _peer_available(peer: str) -> str | None:
    """None when the peer reader is importable, else the note saying how to install it."""
    import importlib.util

    mod = {'mcap_ros2': 'mcap_ros2', 'rosbags': 'rosbags'}[peer]
    if importlib.util.find_spec(mod) is None:
        return f'{peer}: not installed (pip install -r requirements-bench.txt); skipped'
    return None


def whole_layout(path: Path, repeat: int = 5, peers: bool = True, peer_repeat: int = 5,
                 blas_threads: int | None = None, pycache: Path | None = None
                 ) -> dict[str, Any]:
    """Measure one log: the estimate command as a process, its phases, and the peer readers.

    Parameters
    ----------
    path : Path
        The ``.mcap`` file (its directory a rosbag2 bag, as :func:`build_log` writes it).
    repeat : int
        Counted runs of the command and of the phase script (one warm-up run first).
    peers : bool
        Also time ``mcap_ros2`` and ``rosbags`` decoding the same file (skipped with a note
        when not installed).
    peer_repeat : int
        Counted runs per peer (each decodes all 900k messages in Python: ~20 s).
    blas_threads : int, optional
        BLAS threads of the measured processes.
    pycache : Path, optional
        Bytecode directory of the measured processes (default: a temporary one).

    Returns
    -------
    dict
        ``whole_s`` (list of wall times [s]), ``whole_median_s``, ``msg_per_s`` (median),
        ``phases`` (median seconds per phase: interpreter, imports, read, estimate, report),
        ``read_cpu_s`` (median CPU time of the read phase [s], all threads),
        ``peers`` (per peer: list of seconds, median, msg/s) and ``notes``.
    """
    if pycache is None:
        with tempfile.TemporaryDirectory() as tmp:
            return whole_layout(path, repeat, peers, peer_repeat, blas_threads, Path(tmp))
    env = process_env(blas_threads, str(pycache))
    cmd = [sys.executable, '-m', 'inertia_ros', 'estimate', str(path), '--format', 'json',
           '--no-progress']
    timed_process(cmd, env)                                   # warm-up: page cache, .pyc files
    whole: list[float] = []
    phases: list[dict[str, float]] = []
    report = ''
    for _ in range(repeat):
        dt, report = timed_process(cmd, env)
        whole.append(dt)
        ph_cmd = [sys.executable, '-c', _PHASE_CODE.format(root=str(ROOT), path=str(path))]
        ph_dt, out = timed_process(ph_cmd, env)
        ph = json.loads(out.strip().splitlines()[-1])
        ph['interpreter'] = ph_dt - sum(ph[k] for k in ('imports', 'read', 'estimate', 'report'))
        phases.append(ph)
    n = int(phases[0]['messages'])
    med = float(np.median(whole))
    res: dict[str, Any] = {
        'file': path.name, 'bytes': path.stat().st_size, 'messages': n, 'whole_s': whole,
        'whole_median_s': med, 'msg_per_s': n / med,
        'phases': {k: float(np.median([p[k] for p in phases]))
                   for k in ('interpreter', 'imports', 'read', 'estimate', 'report')},
        'read_cpu_s': float(np.median([p['read_cpu'] for p in phases])),
        'status': json.loads(report)['status'], 'peers': {}, 'notes': []}
    for peer in (('mcap_ros2', 'rosbags') if peers else ()):
        note = _peer_available(peer)
        if note is not None:
            res['notes'].append(note)
            continue
        code = _PEER_CODE.format(peer=peer, path=str(path))
        times = []
        for _ in range(peer_repeat):
            dt, out = timed_process([sys.executable, '-c', code], env)
            got = json.loads(out.strip().splitlines()[-1])
            if got['messages'] != n:
                raise RuntimeError(f'{peer}: decoded {got["messages"]} messages, expected {n}')
            times.append(dt)
        pm = float(np.median(times))
        res['peers'][peer] = {'whole_s': times, 'whole_median_s': pm, 'msg_per_s': n / pm}
    return res


def markdown(results: dict[str, dict[str, Any]], command: str, repeat: int,
             peer_repeat: int) -> str:
    """The BENCHMARKS.md section of a :func:`run_whole` result (one entry per layout)."""
    lines = ['## Offline single log: whole process', '',
             f'Rerun: `{command}`. The one-hour log: 720k `sensor_msgs/msg/Imu` (200 Hz) + 180k '
             '`geometry_msgs/msg/WrenchStamped` (50 Hz) = 900k messages in one rosbag2 MCAP '
             'file, written uncompressed and zstd-chunked with 768 KiB chunks (rosbag2\'s '
             'default storage preset). **Whole process** = `python -m inertia_ros estimate LOG '
             '--format json --no-progress` from exec to exit, wall clock, median of '
             f'{repeat} runs after one warm-up; target >= {TARGET_MSG_PER_S:,} msg/s '
             '(< 0.9 s). Phases: the same work in a fresh interpreter with timers between the '
             'steps (median of the same runs; interpreter = its process time less the timed '
             f'steps). Peers (median of {peer_repeat} whole processes): decoding every message '
             'of the same file into time + xyz arrays, no estimation: `mcap_ros2` '
             '(`make_reader(..., decoder_factories=[DecoderFactory()]).iter_decoded_messages()`) '
             'and `rosbags` (`AnyReader` on the bag directory + `deserialize`).', '',
             '| layout | file | whole process (median) | msg/s | min-max | interpreter | '
             'imports | read + decode | estimate | report | mcap_ros2 | rosbags |',
             '|---|---|---|---|---|---|---|---|---|---|---|---|']
    for name, r in results.items():
        ph = r['phases']

        def peer(p: str, r: dict[str, Any] = r) -> str:
            q = r['peers'].get(p)
            return ('skipped' if q is None else
                    f'{q["whole_median_s"]:.1f} s ({q["msg_per_s"] / 1e3:,.0f}k msg/s)')

        lines.append(
            f'| {name} | {r["bytes"] / 1e6:.0f} MB | {r["whole_median_s"]:.2f} s | '
            f'{r["msg_per_s"] / 1e3:,.0f}k | {min(r["whole_s"]):.2f}-{max(r["whole_s"]):.2f} s | '
            f'{ph["interpreter"]:.2f} s | {ph["imports"]:.2f} s | {ph["read"]:.2f} s | '
            f'{ph["estimate"]:.2f} s | {ph["report"]:.2f} s | {peer("mcap_ros2")} | '
            f'{peer("rosbags")} |')
    notes = sorted({n for r in results.values() for n in r['notes']})
    lines += [''] + [f'- {n}' for n in notes]
    return '\n'.join(lines).rstrip('\n') + '\n'


def run_whole(minutes: float = 60.0, repeat: int = 5, peers: bool = True,
              peer_repeat: int = 5, json_path: Path | None = None,
              md_path: Path | None = None, blas_threads: int | None = None) -> int:
    """``bench offline --whole``: both layouts, whole process, phases and peers; return 0.

    Prints one table line per layout and writes the JSON results and the Markdown section
    when asked (``md_path``).
    """
    results: dict[str, dict[str, Any]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, comp in LAYOUTS:
            bag = Path(tmp) / name
            bag.mkdir()
            path = bag / f'{name}_0.mcap'
            n = build_log(path, minutes, comp)
            print(f'built {name}: {n} messages, {path.stat().st_size / 1e6:.0f} MB', flush=True)
            r = whole_layout(path, repeat, peers, peer_repeat, blas_threads,
                             Path(tmp) / 'pycache')
            results[name] = r
            ph = ', '.join(f'{k} {v:.2f} s' for k, v in r['phases'].items())
            peer_txt = ''.join(f'; {p} {q["whole_median_s"]:.1f} s ({q["msg_per_s"]:,.0f} msg/s)'
                               for p, q in r['peers'].items())
            print(f'{name:13s} whole process {r["whole_median_s"]:.2f} s = '
                  f'{r["msg_per_s"]:,.0f} msg/s (median of {repeat}; {ph}){peer_txt}',
                  flush=True)
            print(f'{"":13s} read phase CPU time {r["read_cpu_s"]:.2f} s (median; all threads '
                  'of the process: on a loaded machine the wall time of the read waits for a '
                  'CPU)', flush=True)
            for note in r['notes']:
                print(f'  note: {note}', flush=True)
    command = (f'python -m inertia_ros bench offline --whole --minutes {minutes:g} '
               f'--repeat {repeat} --peer-repeat {peer_repeat}'
               + ('' if peers else ' --skip-slow'))
    if json_path is not None:
        json_path.write_text(json.dumps({'command': command, 'minutes': minutes,
                                         'results': results}, indent=2))
    if md_path is not None:
        md_path.write_text(markdown(results, command, repeat, peer_repeat))
    return 0
