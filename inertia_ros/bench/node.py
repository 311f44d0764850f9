"""``bench node``: the inertia_estimator node as a separate process fed at 1 kHz + 1 kHz.

Starts ``python -m inertia_ros.inertia_estimator_node`` on a private ROS_DOMAIN_ID, then
publishes from this process a simulated gyro stream (sensor_msgs/Imu) at ``rate`` Hz (default
1000) and torque stream (geometry_msgs/WrenchStamped) at ``torque_rate`` Hz (default: the
gyro rate) for ``duration`` seconds (default 60), with sensor-data QoS.  Gyro sample k is sent
at k / rate and torque sample j half a gyro period after j / torque_rate, each stamped with
its own send schedule, so an input stamp identifies its message and send instant.

Measured:

- dropped messages: messages sent minus those the estimator counted as received (its
  /diagnostics ``gyro_received`` / ``torque_received``), split by a witness process
  (``python -m inertia_ros.nodes.probe``, subscribed to both inputs as the estimator is) into
  those the witness did not get either (lost between the publisher and the subscribers: the
  benchmark's share) and those only the estimator lacks (the estimator's share);
- the publisher's own timing: sends more than one gyro period late, the lateness median /
  p99 / max and the longest run of consecutive late sends (a catch-up burst);
- CPU of the estimator process while streaming [% of one core] from /proc/PID/stat;
- latency from the newest input to the published estimate: the estimate's header stamp is
  the newest input stamp it has seen; latency = receive time of the estimate here minus the
  send time of that input (both CLOCK_MONOTONIC in this process) [ms]: median, p95, p99, max;
- the estimator's resident memory [MiB] when streaming starts and when it ends (VmRSS of
  /proc/PID/status): flat memory means the two agree.

Targets: no drop, CPU < 30 % of a core, median latency < 5 ms.  Prints one table and a JSON
line; exit status 0 when all targets are met, 1 otherwise, 2 when the node never subscribed.
Needs a ROS 2 Python environment (rclpy and the message packages); the ROS side (publishers,
the listener) is :class:`inertia_ros.nodes.probe.EstimatorProbe`, imported when this runs.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from .common import nominal_scene

__all__ = ['TARGETS', 'cpu_seconds', 'latencies_ms', 'lateness_summary', 'rss_mib', 'run',
           'schedule']

#: The pass criteria: dropped messages, CPU [% of one core], median latency [ms].
TARGETS = {'dropped': 0, 'cpu_percent': 30.0, 'median_latency_ms': 5.0}
ROOT = Path(__file__).resolve().parents[2]


def cpu_seconds(pid: int) -> float:
    """utime + stime of a process [s] from /proc/PID/stat."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def schedule(n_gyro: int, n_torque: int, gyro_period_ns: int,
             torque_period_ns: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Send order of both streams: due time [ns from the start], stream (0 gyro, 1 torque)
    and sample index of every message, sorted by due time (gyro first on a tie).

    Gyro k is due at ``k * gyro_period_ns``, torque j at ``j * torque_period_ns +
    gyro_period_ns // 2``; each message is stamped ``epoch + due``.
    """
    due = np.r_[np.arange(n_gyro, dtype=np.int64) * gyro_period_ns,
                np.arange(n_torque, dtype=np.int64) * torque_period_ns + gyro_period_ns // 2]
    stream = np.r_[np.zeros(n_gyro, np.int64), np.ones(n_torque, np.int64)]
    index = np.r_[np.arange(n_gyro), np.arange(n_torque)]
    order = np.lexsort((stream, due))
    return due[order], stream[order], index[order]


def latencies_ms(stamps: np.ndarray, recv_ns: np.ndarray, epoch: int, due_ns: np.ndarray,
                 send_mono: np.ndarray) -> np.ndarray:
    """Latency of each estimate from the newest input that carried its stamp [ms].

    Parameters
    ----------
    stamps : numpy.ndarray of int64, shape (E,)
        Header stamps of the received estimates [ns].
    recv_ns : numpy.ndarray of int64, shape (E,)
        Their monotonic receive times [ns].
    epoch : int
        Stamp of gyro sample 0 [ns].
    due_ns : numpy.ndarray of int64, shape (M,)
        Due times of the sent messages in send order, from :func:`schedule` [ns].
    send_mono : numpy.ndarray of int64, shape (M,)
        Monotonic send time of each message, in the same order [ns].
    """
    offset = stamps - epoch
    i = np.searchsorted(due_ns, offset, side='right') - 1   # the last send with that stamp
    ok = (i >= 0) & (due_ns[np.maximum(i, 0)] == offset)
    return (recv_ns[ok] - send_mono[i[ok]]) * 1e-6


def rss_mib(pid: int) -> float:
    """Resident memory of a process [MiB] (VmRSS of /proc/PID/status)."""
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024.0
    return float('nan')


def _start_estimator(publish_rate: float, method: str) -> tuple[subprocess.Popen, Any]:
    """The estimator node as a child process, its console output into a temporary log."""
    cmd = [sys.executable, '-m', 'inertia_ros.inertia_estimator_node', '--ros-args',
           '--params-file', str(ROOT / 'config' / 'inertia_estimator.yaml'),
           '-p', f'publish_rate:={publish_rate}', '-p', f'method:={method}']
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    log = open(Path(os.environ.get('TMPDIR', '/tmp')) / f'bench_node_{os.getpid()}.log', 'w')
    return subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT), log


def _start_witness() -> tuple[subprocess.Popen, Any]:
    """The witness (:func:`inertia_ros.nodes.probe.count_inputs`) as a child process."""
    cmd = [sys.executable, '-m', 'inertia_ros.nodes.probe']
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    log = open(Path(os.environ.get('TMPDIR', '/tmp')) / f'bench_witness_{os.getpid()}.log',
               'w+')
    return subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT), log


def _witness_counts(proc: subprocess.Popen, log: Any) -> dict[str, int] | None:
    """Stop the witness and read its counts (None if it printed none)."""
    _stop(proc)
    log.seek(0)
    for line in reversed(log.read().splitlines()):
        if line.startswith('{'):
            return {k: int(v) for k, v in json.loads(line).items()}
    return None


def _wait_matched(probe: Any, proc: subprocess.Popen, timeout: float = 20.0,
                  subscribers: int = 1) -> bool:
    """Wait until both inputs have ``subscribers`` subscribers (False when the node died or
    timed out)."""
    deadline = time.monotonic() + timeout
    while not probe.matched(subscribers):
        if time.monotonic() > deadline or proc.poll() is not None:
            return False
        time.sleep(0.05)
    time.sleep(1.0)
    return True


def _stream(probe: Any, msgs: list[list[Any]], due_ns: np.ndarray, stream: np.ndarray,
            index: np.ndarray, period_ns: int) -> tuple[np.ndarray, int, np.ndarray]:
    """Publish every message at its due time (:func:`schedule`).

    Returns the monotonic send times in send order [ns], the number of sends more than one
    gyro period late and every send's lateness (send time minus due time) [ns].
    """
    send_mono = np.zeros(due_ns.size, dtype=np.int64)
    t0 = time.monotonic_ns()
    late = 0
    for m, (d, j, k) in enumerate(zip(due_ns.tolist(), stream.tolist(), index.tolist(),
                                             strict=True)):
        due = t0 + d
        now = time.monotonic_ns()
        if due > now:
            time.sleep((due - now) * 1e-9)
        elif now - due > period_ns:
            late += 1
        send_mono[m] = time.monotonic_ns()
        probe.publish(j, msgs[j][k])
    return send_mono, late, send_mono - (t0 + due_ns)


def lateness_summary(lateness_ns: np.ndarray, period_ns: int) -> dict[str, float | int]:
    """The publisher's timing: lateness median / p99 / max [ms] and the longest run of
    consecutive sends more than ``period_ns`` late (a catch-up burst) [messages].

    Parameters
    ----------
    lateness_ns : numpy.ndarray of int64
        Send time minus due time of every send [ns].
    period_ns : int
        The gyro period [ns].
    """
    if lateness_ns.size == 0:
        return {'median_ms': 0.0, 'p99_ms': 0.0, 'max_ms': 0.0, 'longest_late_run': 0}
    late = np.r_[False, lateness_ns > period_ns, False].astype(np.int8)
    edges = np.flatnonzero(np.diff(late))
    runs = edges[1::2] - edges[::2]
    ms = lateness_ns * 1e-6
    return {'median_ms': round(float(np.median(ms)), 3),
            'p99_ms': round(float(np.percentile(ms, 99)), 3),
            'max_ms': round(float(ms.max()), 3),
            'longest_late_run': int(runs.max()) if runs.size else 0}


def _stop(proc: subprocess.Popen) -> None:
    """SIGINT the node (a clean ROS shutdown), then kill it if it lingers."""
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()


def _summary(n: tuple[int, int], late: int, wall: float, cpu_pct: float, lat: np.ndarray,
             listener: Any, config: dict[str, Any],
             witness: dict[str, int] | None = None) -> dict[str, Any]:
    """The JSON result; ``n`` is (gyro, torque) messages sent, ``witness`` what the witness
    received."""
    last = listener.diags[-1] if listener.diags else {}
    upd = np.array([float(d['update_ms']) for d in listener.diags if 'update_ms' in d])
    got_g, got_q = int(last.get('gyro_received', -1)), int(last.get('torque_received', -1))

    def q(p: float) -> float | None:
        return round(float(np.percentile(lat, p)), 3) if lat.size else None

    result = dict(config, sent={'gyro': n[0], 'torque': n[1]},
                  received={'gyro': got_g, 'torque': got_q},
                  dropped=(n[0] - got_g) + (n[1] - got_q), publisher_late_sends=late,
                  witness_received=witness,
                  lost_before_subscribers=None if witness is None else
                  {'gyro': n[0] - witness['gyro'], 'torque': n[1] - witness['torque']},
                  lost_by_estimator=None if witness is None else
                  {'gyro': witness['gyro'] - got_g, 'torque': witness['torque'] - got_q},
                  stream_wall_s=round(wall, 3),
                  estimator_cpu_percent_of_core=round(cpu_pct, 1),
                  estimates_received=len(listener.received),
                  latency_ms={'median': q(50), 'p95': q(95), 'p99': q(99), 'max': q(100)},
                  last_status=last.get('status'),
                  update_ms_median=round(float(np.median(upd)), 3) if upd.size else None)
    result['targets_met'] = bool(
        result['dropped'] <= TARGETS['dropped'] and cpu_pct < TARGETS['cpu_percent']
        and lat.size > 0 and result['latency_ms']['median'] < TARGETS['median_latency_ms'])
    return result


def _print(r: dict[str, Any]) -> None:
    """The table and the JSON line."""
    print(f"sent {r['sent']['gyro']} + {r['sent']['torque']} messages in "
          f"{r['stream_wall_s']} s "
          f"({r['publisher_late_sends']} sends more than one period late)")
    pl = r.get('publisher_lateness')
    if pl:
        print(f"publisher lateness: median {pl['median_ms']} ms, p99 {pl['p99_ms']} ms, max "
              f"{pl['max_ms']} ms; longest run of late sends {pl['longest_late_run']}")
    print(f"received by the estimator: gyro {r['received']['gyro']}, torque "
          f"{r['received']['torque']}; dropped {r['dropped']} (target 0)")
    if r.get('witness_received'):
        w, lb, le = r['witness_received'], r['lost_before_subscribers'], r['lost_by_estimator']
        print(f"witness subscriber received gyro {w['gyro']}, torque {w['torque']}: lost "
              f"before the subscribers gyro {lb['gyro']}, torque {lb['torque']}; lost by the "
              f"estimator alone gyro {le['gyro']}, torque {le['torque']}")
    print(f"estimator CPU: {r['estimator_cpu_percent_of_core']:.1f} % of one core "
          f"(target < {TARGETS['cpu_percent']:g} %)")
    lat = r['latency_ms']
    print(f"estimates: {r['estimates_received']}; latency newest input -> estimate: median "
          f"{lat['median']} ms, p95 {lat['p95']} ms, p99 {lat['p99']} ms, max {lat['max']} ms "
          f"(target median < "
          f"{TARGETS['median_latency_ms']:g} ms); core flush + estimate per update: median "
          f"{r['update_ms_median']} ms")
    mem = r['estimator_rss_mib']
    print(f"estimator memory: {mem['start']} MiB at the start of streaming, {mem['end']} MiB "
          f"at its end")
    print(json.dumps(r))


def run(rate: float = 1000.0, duration: float = 60.0, publish_rate: float = 10.0,
        method: str = 'recursive', seed: int = 1, torque_rate: float | None = None) -> int:
    """Run the benchmark; return 0 when every target is met, 1 when not, 2 on no match.

    Parameters
    ----------
    rate : float
        Gyro rate [Hz].
    duration : float
        Streamed time [s].
    publish_rate : float
        The estimator's ``publish_rate`` parameter [Hz].
    method : str
        The estimator's ``method`` parameter.
    seed : int
        Simulation seed.
    torque_rate : float, optional
        Torque rate [Hz]; default ``rate``.
    """
    from inertia_ros.core.simulation import simulate

    # The listener thread must not wait up to the default 5 ms GIL switch interval behind the
    # publishing loop: that would be the benchmark's latency, not the estimator's.
    sys.setswitchinterval(2e-4)
    os.environ['ROS_DOMAIN_ID'] = str(150 + os.getpid() % 70)
    torque_rate = rate if torque_rate is None else torque_rate
    sim = simulate(nominal_scene(duration, rate=rate), seed=seed)
    t_rate = 1.0 / float(np.median(np.diff(sim.t_torque)))
    step = max(1, int(round(t_rate / torque_rate)))      # the scene's torque, decimated
    t_torque, torque = sim.t_torque[::step], sim.torque[::step]
    ng = sim.t_gyro.size
    nt = min(t_torque.size, int(duration * torque_rate) + 1)
    from inertia_ros.nodes.probe import EstimatorProbe

    proc, log = _start_estimator(publish_rate, method)
    wproc, wlog = _start_witness()
    listener = EstimatorProbe()
    witness = None
    try:
        if not _wait_matched(listener, proc, subscribers=2):
            print(f'estimator (or the witness) did not subscribe; see {log.name} and '
                  f'{wlog.name}', file=sys.stderr)
            return 2
        pg, pt = int(round(1e9 / rate)), int(round(1e9 / torque_rate))
        epoch = time.time_ns()
        due, stream, index = schedule(ng, nt, pg, pt)
        msgs = [[listener.gyro_message(epoch + k * pg, sim.omega[k], sim.frame_id)
                 for k in range(ng)],
                [listener.torque_message(epoch + j * pt + pg // 2, torque[j], sim.frame_id)
                 for j in range(nt)]]
        cpu0, wall0, rss0 = cpu_seconds(proc.pid), time.monotonic(), rss_mib(proc.pid)
        send_mono, late, lateness = _stream(listener, msgs, due, stream, index, pg)
        wall, cpu = time.monotonic() - wall0, cpu_seconds(proc.pid) - cpu0
        rss1 = rss_mib(proc.pid)
        time.sleep(2.5)      # let the last estimate and a watchdog diagnostic arrive
        witness = _witness_counts(wproc, wlog)
    finally:
        listener.close()
        _stop(proc)
        if wproc.poll() is None:
            _stop(wproc)
        log.close()
        wlog.close()
    rec = np.array(listener.received, dtype=np.int64).reshape(-1, 2)
    lat = latencies_ms(rec[:, 0], rec[:, 1], epoch, due, send_mono)
    result = _summary((ng, nt), late, wall, 100.0 * cpu / wall, lat, listener,
                      {'rate_hz': rate, 'torque_rate_hz': torque_rate, 'duration_s': duration,
                       'method': method, 'publish_rate_hz': publish_rate}, witness)
    result['publisher_lateness'] = lateness_summary(lateness, pg)
    result['estimator_rss_mib'] = {'start': round(rss0, 1), 'end': round(rss1, 1)}
    _print(result)
    return 0 if result['targets_met'] else 1
