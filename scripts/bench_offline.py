#!/usr/bin/env python3
"""Offline speed benchmark: our read/decode/align/estimate path vs mcap and mcap_ros2.

Builds a log of 200 Hz ``sensor_msgs/Imu`` and 50 Hz ``geometry_msgs/WrenchStamped`` (one
hour by default: 720k + 180k = 900k messages) in a temporary directory, then measures, each
stage in a fresh subprocess so that peak memory (ru_maxrss) belongs to that stage alone:

``ours_read``
    :func:`inertia_ros.io.logs.read_log` (read, decode, clean, align to windows).
``ours_end_to_end``
    ``read_log`` + :func:`inertia_ros.core.estimation.estimate` (the estimate command's path).
``mcap_raw``
    ``mcap.reader.make_reader(...).iter_messages()`` (no decoding).
``mcap_ros2``
    ``make_reader(..., decoder_factories=[mcap_ros2 DecoderFactory()]).iter_decoded_messages()``.

Usage::

    .venv/bin/python scripts/bench_offline.py [--minutes 60] [--compression zstd|none]
        [--skip-slow] [--repeat N] [--json FILE] [--blas-threads N]

``--skip-slow`` leaves out the mcap_ros2 decode (about a minute per hour of log).
``--blas-threads 1`` pins BLAS to one thread: on a loaded 2-core machine OpenBLAS's own
threads can make the estimator's Gram products tens of times slower.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

STAGES = ('ours_read', 'ours_end_to_end', 'mcap_raw', 'mcap_ros2')


def build_log(path: Path, minutes: float, compression: str, seed: int = 0) -> int:
    """Write the benchmark log; return the number of messages."""
    from mcap.writer import CompressionType, Writer

    from inertia_ros.io import cdr_encode as ce

    rng = np.random.default_rng(seed)
    inertia = np.array([[0.8, 0.02, -0.01], [0.02, 1.1, 0.03], [-0.01, 0.03, 1.5]])
    t0 = 1_704_067_200_000_000_000
    total_s = minutes * 60.0
    comp = {'zstd': CompressionType.ZSTD, 'none': CompressionType.NONE,
            'lz4': CompressionType.LZ4}[compression]
    n = 0
    with open(path, 'wb') as fh:
        w = Writer(fh, compression=comp, chunk_size=1 << 20)
        w.start(profile='ros2', library='inertia_ros bench')
        s_imu = w.register_schema(ce.IMU, 'ros2msg', ce.schema_text(ce.IMU).encode())
        s_wr = w.register_schema(ce.WRENCH_STAMPED, 'ros2msg',
                                 ce.schema_text(ce.WRENCH_STAMPED).encode())
        c_imu = w.register_channel('/imu', 'cdr', s_imu)
        c_wr = w.register_channel('/torque', 'cdr', s_wr)
        # an analytic angular velocity exciting all axes; the torque follows from Euler's
        # equations exactly (tau = I w' + w x I w), so the estimate can be checked
        freq = np.array([[0.11, 0.23], [0.17, 0.31], [0.07, 0.19]])
        amp = np.array([[0.6, 0.3], [0.5, 0.25], [0.7, 0.2]])

        def motion(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            arg = 2 * np.pi * t[:, None, None] * freq
            w = (amp * np.sin(arg)).sum(axis=2)
            wd = (amp * 2 * np.pi * freq * np.cos(arg)).sum(axis=2)
            return w, wd

        block = 10.0
        k = 0
        while k * block < total_s:
            tb = k * block
            t_tau = tb + np.arange(0, block, 0.02)
            w_t, wd_t = motion(t_tau)
            tau = wd_t @ inertia.T + np.cross(w_t, w_t @ inertia.T)
            t_g = tb + np.arange(0, block, 0.005)
            om, _ = motion(t_g)
            om += rng.normal(scale=1e-3, size=om.shape)
            tau_m = tau + rng.normal(scale=1e-3, size=tau.shape)
            ns_g = t0 + np.rint(t_g * 1e9).astype(np.int64)
            ns_t = t0 + np.rint(t_tau * 1e9).astype(np.int64)
            pay_g = ce.encode_imu(ns_g, om, 'base_link')
            pay_t = ce.encode_wrench_stamped(ns_t, tau_m, 'base_link')
            allt = np.concatenate((ns_g, ns_t))
            order = np.argsort(allt, kind='stable')
            ng = ns_g.size
            for i in order.tolist():
                if i < ng:
                    w.add_message(c_imu, int(ns_g[i]), pay_g[i], int(ns_g[i]), i)
                else:
                    w.add_message(c_wr, int(ns_t[i - ng]), pay_t[i - ng], int(ns_t[i - ng]),
                                  i - ng)
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
if stage in ('ours_read', 'ours_end_to_end'):
    log = read_log(path)
    n = log.omega.counts.received + log.torque.counts.received
    extra = {{'used': log.omega.counts.used + log.torque.counts.used}}
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
    extra = {{}}
elif stage == 'mcap_ros2':
    with open(path, 'rb') as f:
        for _ in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            n += 1
    extra = {{}}
dt = time.perf_counter() - t0
rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
print(json.dumps(dict(stage=stage, messages=n, seconds=dt, msg_per_s=n / dt,
                      peak_rss_mb=rss, **extra)))
'''


def run_stage(path: Path, stage: str, blas_threads: int | None = None) -> dict:
    """Run one stage in a fresh interpreter; return its JSON result."""
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


def main(argv: list[str] | None = None) -> int:
    """Build the log, run the stages, print a table (and optionally JSON)."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--minutes', type=float, default=60.0, help='log length [min] (60)')
    ap.add_argument('--compression', choices=('zstd', 'lz4', 'none'), default='zstd')
    ap.add_argument('--skip-slow', action='store_true', help='skip the mcap_ros2 decode')
    ap.add_argument('--json', type=Path, help='also write the results here')
    ap.add_argument('--repeat', type=int, default=1,
                    help='runs per stage; the fastest is reported (timeit practice: load '
                         'from other processes only ever adds time), peak RSS is the largest')
    ap.add_argument('--blas-threads', type=int, default=None,
                    help='set OPENBLAS/OMP_NUM_THREADS for the stages (default: inherit)')
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'bench.mcap'
        t = time.perf_counter()
        n = build_log(path, args.minutes, args.compression)
        print(f'built {path.name}: {n} messages, {path.stat().st_size / 1e6:.1f} MB '
              f'({args.compression}) in {time.perf_counter() - t:.1f} s', flush=True)
        results = []
        for stage in STAGES:
            if stage == 'mcap_ros2' and args.skip_slow:
                continue
            runs = [run_stage(path, stage, args.blas_threads) for _ in range(max(1, args.repeat))]
            good = [x for x in runs if 'error' not in x]
            r = min(good, key=lambda x: x['seconds']) if good else runs[0]
            if good:
                r = dict(r, peak_rss_mb=max(x['peak_rss_mb'] for x in good),
                         all_seconds=[x['seconds'] for x in good])
            results.append(r)
            if 'error' in r:
                print(f'{stage:16s} FAILED: {r["error"]}', flush=True)
                continue
            print(f'{stage:16s} {r["messages"]:>8d} msgs {r["seconds"]:8.2f} s '
                  f'{r["msg_per_s"]:>12,.0f} msg/s  peak RSS {r["peak_rss_mb"]:6.0f} MB'
                  + (f'  (estimate {r["estimate_s"]:.2f} s, {r["status"]})'
                     if 'estimate_s' in r else ''), flush=True)
        by = {r['stage']: r for r in results if 'error' not in r}
        if 'ours_end_to_end' in by and 'mcap_ros2' in by:
            ratio = by['ours_end_to_end']['msg_per_s'] / by['mcap_ros2']['msg_per_s']
            print(f'end-to-end is {ratio:.1f}x mcap_ros2 decoding alone')
        if 'ours_end_to_end' in by and 'mcap_raw' in by:
            ratio = by['ours_end_to_end']['msg_per_s'] / by['mcap_raw']['msg_per_s']
            print(f'end-to-end is {ratio:.1f}x mcap raw iteration')
        if args.json:
            args.json.write_text(json.dumps({'messages': n, 'minutes': args.minutes,
                                             'compression': args.compression,
                                             'blas_threads': args.blas_threads,
                                             'repeat': args.repeat,
                                             'results': results}, indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
