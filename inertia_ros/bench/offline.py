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

``blas_threads=1`` pins BLAS to one thread: on a loaded 2-core machine OpenBLAS's own threads
can make the estimator's Gram products tens of times slower.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ['STAGES', 'build_log', 'run', 'run_stage']

#: Measured stages, in order.
STAGES = ('ours_read', 'ours_end_to_end', 'mcap_raw', 'mcap_ros2')
#: The source tree the stages import (the code under test, not an installed copy).
ROOT = Path(__file__).resolve().parents[2]
#: Tensor of the synthetic log [kg m^2].
INERTIA = np.array([[0.8, 0.02, -0.01], [0.02, 1.1, 0.03], [-0.01, 0.03, 1.5]])
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


def build_log(path: Path, minutes: float, compression: str, seed: int = 0) -> int:
    """Write the benchmark log with the ``mcap`` package's writer; return the message count."""
    from mcap.writer import CompressionType, Writer

    from inertia_ros.io import cdr_encode as ce

    rng = np.random.default_rng(seed)
    comp = {'zstd': CompressionType.ZSTD, 'none': CompressionType.NONE,
            'lz4': CompressionType.LZ4}[compression]
    n = 0
    with open(path, 'wb') as fh:
        w = Writer(fh, compression=comp, chunk_size=1 << 20)
        w.start(profile='ros2', library='inertia_ros bench')
        chans = []
        for topic, typ in (('/imu', ce.IMU), ('/torque', ce.WRENCH_STAMPED)):
            sid = w.register_schema(typ, 'ros2msg', ce.schema_text(typ).encode())
            chans.append(w.register_channel(topic, 'cdr', sid))
        k = 0
        while k * 10.0 < minutes * 60.0:
            ns_g, pay_g, ns_t, pay_t = _block(k * 10.0, rng, 1_704_067_200_000_000_000)
            allt = np.concatenate((ns_g, ns_t))
            ng = ns_g.size
            for i in np.argsort(allt, kind='stable').tolist():
                c, j, pay = (0, i, pay_g) if i < ng else (1, i - ng, pay_t)
                w.add_message(chans[c], int(allt[i]), pay[j], int(allt[i]), j)
            n += allt.size
            k += 1
        w.finish()
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
    env = dict(os.environ)
    if blas_threads is not None:
        for var in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS'):
            env[var] = str(blas_threads)
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          check=False, env=env)
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
        blas_threads: int | None = None) -> int:
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
    """
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
