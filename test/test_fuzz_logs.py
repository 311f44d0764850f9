"""Hostile input through the offline CLI: no traceback, no hang, no memory spike, no lie.

A seeded corpus (:mod:`fuzz_corpus`, generated per run, > 300 logs) of truncations, byte
flips, decompression bombs, bad ``metadata.yaml`` of every type, short records, damaged
footers, clock faults and pauses goes through ``inertia_ros.cli.main(['estimate', ...])``.
Every run must end with exit 0 and the JSON contract, or exit 2 and exactly one stderr
line; the input must be byte-for-byte unchanged; each run must take < 10 s; where the truth
is known (intact and truncated logs, byte flips, damaged footers, clock faults, pauses) a
report with status ``ok`` must lie within 5 standard deviations of it in every element.
The bombs run in a subprocess whose peak resident memory must stay below 1 GiB.
"""
from __future__ import annotations

import contextlib
import io
import json
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from fuzz_corpus import Case, bomb_cases, build_corpus, digest, write_mcap

from conftest import ROOT

CONTRACT = {'status', 'inertia', 'inertia_std', 'principal_moments', 'principal_axes',
            'ratios', 'identifiable', 'model', 'method', 'samples', 'diagnostics'}
#: Wall time allowed per case [s] (typical: 0.02-0.3 s).
MAX_SECONDS = 10.0
#: Peak resident memory allowed for a process estimating a bomb [bytes].
MAX_RSS = 1 << 30


def run_cli(path: Path) -> tuple[int, str, str, float, list[str]]:
    """``estimate PATH --format json --no-progress`` in-process.

    Returns (exit status, stdout, stderr, seconds, Python warnings raised).
    """
    from inertia_ros.cli import main

    out, err = io.StringIO(), io.StringIO()
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stdout(out), \
            contextlib.redirect_stderr(err):
        warnings.simplefilter('always')
        rc = main(['estimate', str(path), '--format', 'json', '--no-progress'])
    return (rc, out.getvalue(), err.getvalue(), time.perf_counter() - t0,
            [f'{w.category.__name__}: {w.message}' for w in caught])


def check(case: Case) -> dict | None:
    """Run one case and assert the contract; return the report (None on exit 2)."""
    before = digest(case.path)
    try:
        rc, out, err, secs, _ = run_cli(case.path)
    except BaseException as exc:  # a traceback: the failure this test exists for
        raise AssertionError(f'{case.name}: {exc.__class__.__name__}: {exc}') from exc
    assert digest(case.path) == before, f'{case.name}: the input was modified'
    assert secs < MAX_SECONDS, f'{case.name}: {secs:.1f} s'
    if rc == 2:
        lines = err.strip().splitlines()
        assert len(lines) == 1, f'{case.name}: exit 2 with {len(lines)} stderr lines: {err!r}'
        assert lines[0].startswith('inertia_ros estimate: error: ')
        return None
    assert rc == 0, f'{case.name}: exit {rc}, stderr {err!r}'
    report = json.loads(out)
    missing = CONTRACT - set(report)
    assert not missing, f'{case.name}: report misses {sorted(missing)}'
    if case.truth is not None and report['status'] == 'ok':
        err_ = np.abs(np.asarray(report['inertia']) - case.truth)
        std = np.asarray(report['inertia_std'])
        z = float(np.max(err_ / np.maximum(std, 1e-12)))
        assert z <= 5.0, (f'{case.name}: status ok but {z:.1f} sigma from the truth '
                          f'(max error {float(err_.max()):.3g} kg m^2)')
    return report


@pytest.fixture(scope='module')
def corpus(tmp_path_factory: pytest.TempPathFactory) -> list[Case]:
    cases, _ = build_corpus(tmp_path_factory.mktemp('fuzz'))
    return cases


def test_corpus_is_large_and_seeded(corpus: list[Case], tmp_path: Path) -> None:
    kinds = {c.kind for c in corpus}
    assert len(corpus) >= 300
    assert {'truncate', 'flip', 'metadata', 'short_record', 'footer', 'clock', 'pause',
            'garbage'} <= kinds
    again, _ = build_corpus(tmp_path / 'again')
    assert [digest(c.path) for c in again[:60]] == [digest(c.path) for c in corpus[:60]]


def test_every_case_ends_cleanly(corpus: list[Case]) -> None:
    """No traceback, one line or the contract, input unchanged, bounded time, no lie."""
    failures = []
    outcome: dict[str, dict[str, int]] = {}
    for case in corpus:
        try:
            report = check(case)
        except AssertionError as exc:
            failures.append(str(exc).splitlines()[0])
            continue
        key = 'error' if report is None else report['status']
        outcome.setdefault(case.kind, {}).setdefault(key, 0)
        outcome[case.kind][key] += 1
    assert not failures, f'{len(failures)} of {len(corpus)} cases failed:\n' + '\n'.join(
        failures[:40])
    # the damage the intact-data families carry must not stop an estimate
    assert outcome['intact'] == {'ok': 3}
    assert outcome['footer'].get('ok', 0) >= 12, outcome['footer']
    assert outcome['pause'].get('ok', 0) >= 6, outcome['pause']


def test_clock_fault_is_reported_and_segmented(tmp_path: Path) -> None:
    """A gyro clock set back 10 s, stored in stamp order: found, reported, not averaged."""
    from fuzz_corpus import T0, Base, simulate_base

    b = simulate_base()
    tg = b.tg.copy()
    tg[b.tg >= T0 + 10 ** 10] -= 10 ** 10
    p = write_mcap(tmp_path / 'c.mcap', Base(tg, b.w, b.tt, b.tau, b.inertia))
    report = check(Case('clock', 'clock', p, b.inertia))
    assert report is not None and report['status'] == 'ok'
    log = report['diagnostics']['log']
    assert log['clock_faults'] == 1 and log['omega']['clock_faults'] == 1
    assert log['omega']['duplicates'] == 0          # unique samples are not "duplicates"
    assert log['omega']['used'] >= 0.99 * log['omega']['received']
    assert log['windows'] == 2                       # segmented at the fault
    assert any('clock fault' in w for w in report['diagnostics']['warnings'])


def test_one_day_pause_costs_nothing(tmp_path: Path) -> None:
    """A one-day pause inside the log: the same answer as without it (to 1e-6 relative)."""
    from fuzz_corpus import T0, Base, simulate_base

    b = simulate_base()
    day = 86_400 * 10 ** 9
    cut = T0 + 10 ** 10
    paused = Base(np.where(b.tg >= cut, b.tg + day, b.tg), b.w,
                  np.where(b.tt >= cut, b.tt + day, b.tt), b.tau, b.inertia)
    split = Base(np.where(b.tg >= cut, b.tg + 10 ** 9, b.tg), b.w,
                 np.where(b.tt >= cut, b.tt + 10 ** 9, b.tt), b.tau, b.inertia)
    r_pause = check(Case('pause', 'pause', write_mcap(tmp_path / 'p.mcap', paused), b.inertia))
    r_split = check(Case('split', 'pause', write_mcap(tmp_path / 's.mcap', split), b.inertia))
    assert r_pause['status'] == r_split['status'] == 'ok'
    np.testing.assert_allclose(r_pause['inertia'], r_split['inertia'], rtol=1e-6, atol=1e-9)
    log = r_pause['diagnostics']['log']
    assert log['pauses_shortened'] == 1
    assert log['time_removed_s'] == pytest.approx(86_400.0 - 1.0, abs=0.05)  # 1 s kept


_BOMB_RUNNER = r'''
import contextlib, io, json, resource, sys, time
from inertia_ros.cli import main
out = []
for path in sys.argv[1:]:
    o, e = io.StringIO(), io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(o), contextlib.redirect_stderr(e):
        rc = main(['estimate', path, '--format', 'json', '--no-progress'])
    rep = json.loads(o.getvalue()) if rc == 0 else None
    out.append({'path': path, 'rc': rc, 'seconds': time.perf_counter() - t0,
                'stderr': e.getvalue(),
                'damage': rep['diagnostics']['log']['damage'] if rep else None,
                'rss': resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024})
print(json.dumps(out))
'''


def test_bombs_bounded_memory_and_time(tmp_path: Path) -> None:
    """Each bomb is a counted damaged chunk; peak memory < 1 GiB, wall time bounded."""
    from fuzz_corpus import simulate_base

    base = write_mcap(tmp_path / 'base.mcap', simulate_base())
    cases = bomb_cases(tmp_path, base)
    before = {c.name: digest(c.path) for c in cases}
    proc = subprocess.run([sys.executable, '-c', _BOMB_RUNNER, *map(str, (c.path for c in
                                                                          cases))],
                          capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    results = json.loads(proc.stdout)
    for case, r in zip(cases, results, strict=True):
        assert digest(case.path) == before[case.name]
        assert r['rc'] == 0, f'{case.name}: {r["stderr"]}'
        assert r['seconds'] < MAX_SECONDS, f'{case.name}: {r["seconds"]:.1f} s'
        assert r['rss'] < MAX_RSS, f'{case.name}: peak {r["rss"] / 2 ** 20:.0f} MiB'
        dmg = r['damage']
        if 'unknown_records' in case.name or 'empty_messages' in case.name:
            continue  # legal (if odd) records: read, nothing usable in them
        assert dmg['corrupt_chunks'] == 1, f'{case.name}: {dmg}'
