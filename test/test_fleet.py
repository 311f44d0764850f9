"""``python -m inertia_ros fleet``: many logs on Dask, incremental re-runs, report.

A small simulated fleet (inertia_ros.bench.fleet.make_fleet): 3 vehicles x 3 logs of 20 s
(sat-01 releases a payload during its second log; sat-03 writes rosbag2 directories) plus 2
corrupt logs, run on a local cluster of 2 worker processes and on an external ``dask
scheduler`` + 2 ``dask worker`` processes started here.
"""
from __future__ import annotations

import contextlib
import io
import math
import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

import inertia_ros.cli.fleet as cli_fleet
import inertia_ros.fleet.run as fleet_run
from conftest import ROOT
from inertia_ros.bench.fleet import FleetSpec, make_fleet
from inertia_ros.cli import main
from inertia_ros.core.tensor import THETA_COLS, THETA_NAMES, THETA_ROWS
from inertia_ros.fleet import table as fleet_table
from inertia_ros.fleet.discover import DiscoveryError, LogRef, discover
from inertia_ros.fleet.report import compare, find_outliers
from inertia_ros.fleet.run import estimate_log

pytest.importorskip('distributed')
pytest.importorskip('pyarrow')

SPEC = FleetSpec(vehicles=3, logs_per_vehicle=3, duration=20.0, corrupt=2, seed=11)
NUMERIC = (*THETA_NAMES, *(n + '_std' for n in THETA_NAMES), 'I1', 'I2', 'I3')


@pytest.fixture(scope='module')
def fleet(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    """The fleet directory and its manifest (11 logs: 9 good, 2 corrupt)."""
    root = tmp_path_factory.mktemp('fleet') / 'logs'
    return root, make_fleet(root, SPEC)


def _fleet(capsys: pytest.CaptureFixture, *args: str) -> tuple[int, str, str, float]:
    t0 = time.perf_counter()
    code = main(['fleet', *args, '--no-progress'])
    dt = time.perf_counter() - t0
    out, err = capsys.readouterr()
    return code, out, err, dt


@pytest.fixture(scope='module')
def local_runs(fleet: tuple[Path, dict], tmp_path_factory: pytest.TempPathFactory) -> dict:
    """Run 1 interrupted after 4 rows, run 2 finishing, 3 adding nothing, 4 the report."""
    root, _ = fleet
    out = tmp_path_factory.mktemp('out') / 'fleet.parquet'
    report = out.parent / 'report'
    mp = pytest.MonkeyPatch()
    def run(*args: str) -> tuple[int, str, str, float]:
        o, e = io.StringIO(), io.StringIO()
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(o), contextlib.redirect_stderr(e):
            code = main(['fleet', *args, '--no-progress'])
        return code, o.getvalue(), e.getvalue(), time.perf_counter() - t0

    calls = {'n': 0}
    original = cli_fleet._Bar.__call__

    def interrupting(self: cli_fleet._Bar, row: dict) -> None:
        original(self, row)
        calls['n'] += 1
        if calls['n'] == 4:
            raise KeyboardInterrupt

    mp.setattr(cli_fleet._Bar, '__call__', interrupting)
    mp.setattr(fleet_run, 'LOCAL_PROCESSES', False)  # in-process threads: no start-up cost
    try:
        first = run(str(root), '--out', str(out), '--workers', '2')
    finally:
        mp.undo()
    rows1 = fleet_table.read_rows(out)
    second = run(str(root), '--out', str(out), '--workers', '2')
    rows2 = fleet_table.read_rows(out)
    mtime2 = out.stat().st_mtime_ns
    third = run(str(root), '--out', str(out))
    rows3 = fleet_table.read_rows(out)
    fourth = run(str(root), '--out', str(out), '--report', str(report))
    return {'out': out, 'report': report, 'first': first, 'rows1': rows1, 'second': second,
            'rows2': rows2, 'third': third, 'rows3': rows3, 'fourth': fourth, 'mtime2': mtime2,
            'mtime3': out.stat().st_mtime_ns}


# --------------------------------------------------------------------------------------------
# Discovery, the per-log task, the table (no cluster)


def test_discover_finds_files_and_bag_directories(fleet: tuple[Path, dict],
                                                  tmp_path: Path) -> None:
    """Every log once: .mcap files, rosbag2 directories as one log; hidden/partial skipped."""
    root, manifest = fleet
    refs = discover([str(root)])
    paths = {r.path for r in refs}
    assert paths == set(manifest['logs']) | set(manifest['corrupt'])
    assert len(refs) == SPEC.total == 11
    bags = [r for r in refs if r.kind == 'rosbag2']
    assert len(bags) == 3 and all('sat-03' in r.path for r in bags)
    bag = Path(bags[0].path)
    assert bags[0].size == sum(f.stat().st_size for f in bag.iterdir())
    # the same log named twice, a single file, a bag directory given directly
    assert len(discover([str(root), manifest['logs'][0], str(bag)])) == 11
    assert [r.kind for r in discover([str(bag)])] == ['rosbag2']
    # hidden directories and unfinished writes are not logs
    (root / '.hidden').mkdir()
    shutil.copy(manifest['logs'][0], root / '.hidden' / 'x.mcap')
    (root / 'y.partial').mkdir()
    shutil.copy(manifest['logs'][0], root / 'y.partial' / 'y.mcap')
    try:
        assert len(discover([str(root)])) == 11
    finally:
        shutil.rmtree(root / '.hidden')
        shutil.rmtree(root / 'y.partial')
    with pytest.raises(DiscoveryError, match='no such file'):
        discover([str(tmp_path / 'missing')])


def test_estimate_log_rows(fleet: tuple[Path, dict]) -> None:
    """The task: a good log gives the estimate's numbers, a corrupt one its error line."""
    root, manifest = fleet
    refs = {r.path: r for r in discover([str(root)])}
    good = refs[manifest['logs'][3]]  # sat-02, day 1
    row = estimate_log(good, [], 'dir')
    assert row['status'] == 'ok' and row['vehicle'] == 'sat-02' and row['error'] is None
    assert row['method'] == 'ml' and row['samples_used'] == 4001
    assert row['log_start'].startswith('2026-01-01T00:10:00')
    import json

    rep = json.loads(row['report'])
    truth = rep['diagnostics']['truth']['inertia']
    for n, i, j in zip(THETA_NAMES, THETA_ROWS, THETA_COLS, strict=True):
        assert row[n] == rep['inertia'][i][j]
        # the estimate is within 5 of its own sigma of the truth
        assert abs(row[n] - truth[i][j]) < 5 * row[n + '_std']
    assert row['I1'] < row['I2'] < row['I3']
    bad = refs[manifest['corrupt'][0]]
    row = estimate_log(bad, [], 'dir')
    assert row['status'] == 'error' and row['ixx'] is None
    assert row['error'] == f'{bad.path}: not an MCAP file (empty file)'
    # vehicle from MCAP metadata, also inside a rosbag2 directory; options are passed through
    bag = next(r for r in refs.values() if r.kind == 'rosbag2')
    row = estimate_log(bag, ['--model', 'diagonal'], 'metadata:vehicle')
    assert row['vehicle'] == 'sat-03' and row['model'] == 'diagonal'
    assert row['ixy'] == 0.0  # fixed by the diagonal model
    assert row['options'] == '--model diagonal --vehicle-from metadata:vehicle'
    assert estimate_log(bag, [], 'metadata:no_such_key')['vehicle'] is None


def test_reader_thread_off_inside_a_dask_worker(fleet: tuple[Path, dict],
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """Inside a Dask worker (one core per worker thread) the MCAP reader starts no
    chunk-loading thread; outside one it does (on a machine with a spare CPU); the setting is
    restored after the log, and the row is the same either way."""
    import inertia_ros.io.mcap_reader as mr

    root, manifest = fleet
    ref = {r.path: r for r in discover([str(root)])}[manifest['logs'][0]]
    started: list[bool] = []
    real = mr._Loader

    def counting(*a: object, **k: object) -> object:
        started.append(True)
        return real(*a, **k)

    monkeypatch.setattr(mr, '_Loader', counting)
    monkeypatch.setattr(mr, '_cpus', lambda: 2)
    monkeypatch.setattr(mr.McapReader, 'THREADS', True)
    monkeypatch.setattr(fleet_run, '_worker_name', lambda: 'tcp://127.0.0.1:1')
    in_worker = estimate_log(ref, [], 'dir')
    assert started == [] and mr.McapReader.THREADS is True
    monkeypatch.setattr(fleet_run, '_worker_name', lambda: None)
    alone = estimate_log(ref, [], 'dir')
    assert started and mr.McapReader.THREADS is True
    assert in_worker['status'] == alone['status'] == 'ok'
    assert all(in_worker[n] == alone[n] for n in NUMERIC)


def test_fsspec_url(fleet: tuple[Path, dict]) -> None:
    """A fleet on an fsspec filesystem (memory://): found and estimated by the worker."""
    fsspec = pytest.importorskip('fsspec')
    root, manifest = fleet
    fs = fsspec.filesystem('memory')
    fs.put(manifest['logs'][3], '/fleet/sat-02/a.mcap')
    bag = Path(next(p for p in manifest['logs'] if 'sat-03' in p))
    for f in bag.iterdir():
        fs.put(str(f), f'/fleet/sat-03/bag/{f.name}')
    try:
        refs = discover(['memory://fleet'])
        assert [(r.path, r.kind) for r in refs] == [
            ('memory:///fleet/sat-02/a.mcap', 'mcap'), ('memory:///fleet/sat-03/bag', 'rosbag2')]
        rows = [estimate_log(r, [], 'dir') for r in refs]
        assert [r['status'] for r in rows] == ['ok', 'ok']
        assert [r['vehicle'] for r in rows] == ['sat-02', 'sat-03']
        local = estimate_log(discover([manifest['logs'][3]])[0], [], 'dir')
        assert rows[0]['ixx'] == local['ixx']
    finally:
        fs.rm('/fleet', recursive=True)


def test_table_round_trip(tmp_path: Path) -> None:
    """Parquet and CSV hold the same rows exactly (floats to the bit, nulls as nulls)."""
    ref = LogRef('/x/sat-9/a.mcap', 123, 456, 'mcap')
    from inertia_ros.fleet.run import row_from_report

    good = row_from_report(ref, {'status': 'ok', 'inertia': [[1 / 3, 0.1, 0.2], [0.1, 1.0, 0.3],
                                                             [0.2, 0.3, 2.0]],
                                 'inertia_std': None, 'principal_moments': None,
                                 'model': 'full', 'method': 'ml',
                                 'samples': {'used': 5, 'dropped': 1},
                                 'diagnostics': {'log': {'epoch_ns': 10 ** 18}}},
                           signature='--vehicle-from dir', vehicle='sat-9', wall_s=0.5)
    bad = row_from_report(LogRef('/x/b, "c".mcap', 1, 2, 'mcap'), None, signature='--x',
                          vehicle=None, error='b: not an MCAP file, "quoted"')
    for suffix in ('.parquet', '.csv'):
        path = tmp_path / f't{suffix}'
        fleet_table.write_rows(path, [good, bad])
        back = fleet_table.read_rows(path)
        assert back == [good, bad]
    with pytest.raises(fleet_table.TableError, match='.parquet or .csv'):
        fleet_table.write_rows(tmp_path / 't.xlsx', [good])


def test_outlier_rule() -> None:
    """A jump beyond 3 sigma (chi-square equivalent) is flagged, noise within is not."""
    def row(path: str, t: int, ixx: float, std: float = 0.01) -> dict:
        r = {'path': path, 'vehicle': 'v', 'status': 'ok', 'log_start_ns': t,
             'log_start': None}
        for n in THETA_NAMES:
            r[n], r[n + '_std'] = (ixx if n == 'ixx' else 0.5), std
        for k in (1, 2, 3):
            r[f'I{k}'] = None
        return r

    # one element at z = 3 among six compared: Sidak-adjusted, about 2.4 sigma
    c = compare(row('a', 0, 1.0), row('b', 1, 1.0 + 3 * math.sqrt(2) * 0.01))
    assert c is not None and c['worst'] == 'ixx' and c['k'] == 6
    assert c['z'] == pytest.approx(3.0, rel=1e-12)
    p3 = math.erfc(3 / math.sqrt(2))  # P(|Z| > 3)
    from scipy import stats

    assert c['sigma'] == pytest.approx(stats.norm.isf((1 - (1 - p3) ** 6) / 2), rel=1e-9)
    assert 2.3 < c['sigma'] < 2.5
    # far tails stay finite and ordered
    far = compare(row('a', 0, 1.0), row('b', 1, 3.0))
    assert far is not None and far['sigma'] == pytest.approx(far['z'], rel=0.05)
    rows = [row('a', 0, 1.0), row('b', 1, 1.02), row('c', 2, 1.2), row('d', 3, 1.2),
            {'path': 'e', 'vehicle': 'v', 'status': 'error', 'log_start_ns': 4}]
    flagged = find_outliers(rows)
    assert [o['path'] for o in flagged] == ['c']
    assert flagged[0]['previous'] == 'b' and flagged[0]['sigma'] > 10


# --------------------------------------------------------------------------------------------
# The command on a local cluster


def test_local_cluster_interrupt_resume_rerun(local_runs: dict) -> None:
    """Ctrl-C writes the finished rows; the next run does the rest; a third adds nothing."""
    code, out, err, _ = local_runs['first']
    assert code == 130
    assert 'interrupted: 4 of 11 logs done' in err
    assert len(local_runs['rows1']) == 4
    code, out, err, t2 = local_runs['second']
    assert code == 0, err
    assert out.startswith('fleet: 11 logs (7 estimated on 2 workers, 4 unchanged)')
    assert out.rstrip().endswith(str(local_runs['out']))
    rows = local_runs['rows2']
    assert len(rows) == 11
    assert sum(r['status'] == 'error' for r in rows) == 2
    assert sum(r['status'] == 'ok' for r in rows) + sum(
        r['status'] == 'model_mismatch' for r in rows) == 9
    first = {r['path'] for r in local_runs['rows1']}
    assert len({r['worker'] for r in rows if r['path'] not in first}) == 2
    code, out, err, t3 = local_runs['third']
    assert code == 0, err
    assert '(0 estimated, 11 unchanged)' in out
    assert local_runs['rows3'] == rows
    assert local_runs['mtime3'] == local_runs['mtime2']  # nothing new: the table is not rewritten
    assert t3 < 0.1 * t2


def test_report_flags_the_payload_change(local_runs: dict, fleet: tuple[Path, dict]) -> None:
    """The report: a PNG per vehicle, status counts, the payload vehicle's jump as outlier."""
    _, manifest = fleet
    code, out, err, _ = local_runs['fourth']
    assert code == 0 and '(0 estimated, 11 unchanged)' in out
    rep = local_runs['report']
    assert f'report: {rep}/fleet_report.md' in err
    assert sorted(p.name for p in rep.glob('*.png')) == [
        'trend_sat-01.png', 'trend_sat-02.png', 'trend_sat-03.png']
    assert all(p.stat().st_size > 10_000 for p in rep.glob('*.png'))
    md = (rep / 'fleet_report.md').read_text()
    assert '| error | 2 |' in md
    outliers = find_outliers(local_runs['rows3'])
    assert {o['vehicle'] for o in outliers} == {'sat-01'}
    flagged = {o['path'] for o in outliers}
    assert flagged & {manifest['payload']['change_log'], manifest['payload']['first_after']}
    for o in outliers:
        assert o['path'] in md and o['dI'] is not None and max(o['dI']) < 0  # lighter


def test_incremental_rerun_runs_only_changed_logs(local_runs: dict, fleet: tuple[Path, dict],
                                                  tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                  capsys: pytest.CaptureFixture) -> None:
    """Path, size, mtime and options decide what runs again (CSV table, in-process runner)."""
    root, manifest = fleet
    ran: list[list[str]] = []

    @contextlib.contextmanager
    def no_cluster(workers: int | None, scheduler: str | None):
        yield None

    def in_process(client, refs, flags, rule, on_row):
        ran.append([r.path for r in refs])
        rows = [estimate_log(r, flags, rule) for r in refs]
        for r in rows:
            on_row(r)
        return rows, False

    monkeypatch.setattr(fleet_run, 'open_client', no_cluster)
    monkeypatch.setattr(fleet_run, 'n_workers', lambda client: 1)
    monkeypatch.setattr(fleet_run, 'run_logs', in_process)
    table = tmp_path / 'fleet.csv'
    fleet_table.write_rows(table, local_runs['rows3'])
    code, out, err, _ = _fleet(capsys, str(root), '--out', str(table))
    assert code == 0 and '(0 estimated, 11 unchanged)' in out and ran == []
    assert fleet_table.read_rows(table) == local_runs['rows3']
    # a rewritten log runs again, alone
    log = manifest['logs'][4]
    st = os.stat(log)
    os.utime(log, ns=(st.st_atime_ns, st.st_mtime_ns + 10 ** 9))
    try:
        code, out, err, _ = _fleet(capsys, str(root), '--out', str(table))
    finally:
        os.utime(log, ns=(st.st_atime_ns, st.st_mtime_ns))  # other tests share the fleet
    assert code == 0 and '(1 estimated on 1 worker, 10 unchanged)' in out and ran == [[log]]
    rows = {r['path']: r for r in fleet_table.read_rows(table)}
    assert rows[log]['mtime_ns'] == st.st_mtime_ns + 10 ** 9
    assert rows[log]['ixx'] == pytest.approx(
        {r['path']: r for r in local_runs['rows3']}[log]['ixx'], rel=1e-12)
    # rows of logs outside this run's PATHs are kept; other options run every log again
    code, out, err, _ = _fleet(capsys, str(root / 'sat-02'), '--out', str(table), '--model',
                               'diagonal')
    assert code == 0 and '(5 estimated on 1 worker, 0 unchanged)' in out
    rows = fleet_table.read_rows(table)
    assert len(rows) == 11
    assert {r['options'] for r in rows if 'sat-02' in r['path']} == {
        '--model diagonal --vehicle-from dir'}
    # unusable input: one line, exit 2
    code, out, err, _ = _fleet(capsys, '/nonexistent/dir', '--out', str(table))
    assert code == 2 and err.count('\n') == 1 and 'no such file' in err
    code, out, err, _ = _fleet(capsys, str(root), '--out', str(tmp_path / 'x.txt'))
    assert code == 2 and '.parquet or .csv' in err and err.count('\n') == 1


# --------------------------------------------------------------------------------------------
# The command on an external cluster


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return int(s.getsockname()[1])


def _dask_cmd() -> list[str]:
    exe = Path(sys.executable).parent / 'dask'
    return [str(exe)] if exe.exists() else [sys.executable, '-m', 'dask']


def test_external_scheduler_gives_the_same_rows(local_runs: dict, fleet: tuple[Path, dict],
                                                tmp_path: Path,
                                                capsys: pytest.CaptureFixture) -> None:
    """`dask scheduler` + 2 `dask worker` processes started here: the same rows as locally."""
    root, _ = fleet
    port = _free_port()
    addr = f'tcp://127.0.0.1:{port}'
    procs: list[subprocess.Popen] = []
    logs = [open(tmp_path / f'dask{i}.log', 'w') for i in range(3)]
    try:
        procs.append(subprocess.Popen(
            [*_dask_cmd(), 'scheduler', '--host', '127.0.0.1', '--port', str(port),
             '--no-dashboard'], stdout=logs[0], stderr=subprocess.STDOUT, cwd=ROOT))
        for i in (1, 2):
            procs.append(subprocess.Popen(
                [*_dask_cmd(), 'worker', addr, '--nthreads', '1', '--no-dashboard',
                 '--name', f'w{i}'], stdout=logs[i], stderr=subprocess.STDOUT, cwd=ROOT))
        from distributed import Client

        with Client(addr, timeout=30) as c:
            c.wait_for_workers(2, timeout=60)
        out = tmp_path / 'ext.parquet'
        code, stdout, err, _ = _fleet(capsys, str(root), '--out', str(out), '--scheduler', addr)
        assert code == 0, err
        assert '(11 estimated on 2 workers, 0 unchanged)' in stdout
    finally:
        for p in procs[::-1]:
            p.terminate()
        for p in procs[::-1]:
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        for f in logs:
            f.close()
    ext = fleet_table.read_rows(out)
    local = local_runs['rows3']
    assert [r['path'] for r in ext] == [r['path'] for r in local]
    assert len({r['worker'] for r in ext}) == 2
    for a, b in zip(ext, local, strict=True):
        for k in ('status', 'error', 'vehicle', 'log_start_ns', 'model', 'method',
                  'samples_used', 'size', 'mtime_ns', 'options'):
            assert a[k] == b[k], (a['path'], k)
        for k in NUMERIC:
            assert (a[k] is None) == (b[k] is None)
            if a[k] is not None:
                assert a[k] == pytest.approx(b[k], rel=1e-12, abs=1e-15), (a['path'], k)



def test_benchmark_section_is_replaced_in_place(tmp_path: Path) -> None:
    """The fleet benchmark owns one marked section of BENCHMARKS.md, appended then replaced."""
    from inertia_ros.bench.fleet import BEGIN, END, update_doc

    doc = tmp_path / 'B.md'
    doc.write_text('# Benchmarks\n\nother sections\n')
    update_doc(doc, 'first figures\n')
    update_doc(doc, 'second figures\n')
    text = doc.read_text()
    assert text.startswith('# Benchmarks\n\nother sections\n\n' + BEGIN)
    assert text.count(BEGIN) == 1 and text.count(END) == 1
    assert 'second figures' in text and 'first figures' not in text
    doc.write_text(text + '\n## Later section\n')
    update_doc(doc, 'third\n')
    assert doc.read_text().endswith(f'third\n{END}\n## Later section\n')
