"""``fleet`` against hostile input (issue 29): its options, paths, output and cluster addresses.

The standard of the MCAP corpus: no traceback, no hang (each case well under 10 s), one
stderr line and exit 2 for a refusal, no user file modified.  The logs run in this process
(no Dask cluster: the client is replaced) unless a case is about the cluster itself.
"""
from __future__ import annotations

import contextlib
import os
import shutil
import socket
import threading
import time
from pathlib import Path

import pytest

import inertia_ros.cli.fleet as cli_fleet
import inertia_ros.fleet.run as fleet_run
from conftest import ROOT
from inertia_ros.cli import build_parser, main
from inertia_ros.cli.fleet import _cores, estimate_flags
from inertia_ros.fleet import table as fleet_table
from inertia_ros.fleet.run import estimate_log

pytest.importorskip('distributed')

GOOD = ROOT / 'bags' / 'default.mcap'
#: Longest a refusal or a hostile case may take [s] (the issue's bound is 10 s).
FAST_S = 10.0


def _fleet(capsys: pytest.CaptureFixture, *args: str) -> tuple[int, str, str, float]:
    t0 = time.perf_counter()
    code = main(['fleet', *args, '--no-progress'])
    dt = time.perf_counter() - t0
    out, err = capsys.readouterr()
    return code, out, err, dt


def _refused(result: tuple[int, str, str, float], *words: str) -> str:
    """Assert exit 2 with one stderr line holding ``words``, quickly; return the line."""
    code, out, err, dt = result
    assert code == 2, (out, err)
    assert err.count('\n') == 1 and err.startswith('inertia_ros fleet: error: '), err
    assert 'Traceback' not in err and dt < FAST_S
    for w in words:
        assert w in err, err
    return err


@pytest.fixture
def in_process(monkeypatch: pytest.MonkeyPatch) -> dict:
    """No cluster: the logs run here, one after the other; records what the client got."""
    seen: dict = {'runs': []}

    @contextlib.contextmanager
    def no_cluster(workers: int | None, scheduler: str | None):
        seen['workers'] = workers
        yield None

    def run_here(client, refs, flags, rule, on_row):
        seen['runs'].append([r.path for r in refs])
        rows = [estimate_log(r, flags, rule) for r in refs]
        for r in rows:
            on_row(r)
        return rows, False

    monkeypatch.setattr(fleet_run, 'open_client', no_cluster)
    monkeypatch.setattr(fleet_run, 'n_workers', lambda client: 1)
    monkeypatch.setattr(fleet_run, 'run_logs', run_here)
    return seen


# --------------------------------------------------------------------------------------------
# Options (item 1: --help, --com; item 3: per-log outputs)


def test_fleet_help_lists_every_estimate_option(capsys: pytest.CaptureFixture) -> None:
    """`fleet --help` exits 0 (it was a TypeError traceback) and shows estimate's options
    as estimate does, --com with its three values included only where usable."""
    assert main(['fleet', '--help']) == 0
    out = capsys.readouterr().out
    assert '--nuisance TERMS' in out and '--wheels FILE' in out and '--model {' in out
    assert '--urdf' not in out  # refused in a fleet, so not offered
    est = build_parser('estimate')._subparsers._group_actions[0].choices['estimate']
    passed = [a for a in est._actions if a.option_strings
              and a.dest not in (*cli_fleet._OWN, *cli_fleet._PER_LOG_OUTPUTS)]
    assert len(passed) >= 15
    for a in passed:
        assert max(a.option_strings, key=len) in out, a.dest


def test_options_pass_through_as_typed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The words of each option reach `estimate` as typed; file names become absolute."""
    monkeypatch.chdir(tmp_path)
    args = build_parser('fleet').parse_args(
        ['fleet', 'logs', '--out', 'r.csv', '--nuisance', 'gyro_bias,damping',
         '--torque-delay', '0.01', '--model', 'auto', '--ignore-frames', '--wheels',
         'w.yaml', '--torque-delay', '-0.02'])
    assert estimate_flags(args) == [
        '--torque-delay', '-0.02', '--nuisance', 'gyro_bias,damping', '--ignore-frames',
        '--wheels', str(tmp_path / 'w.yaml')]  # the default --model is not passed


def test_com_and_urdf_refused_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture,
                                          in_process: dict) -> None:
    """--com takes three values like estimate's (one value is argparse's one-line error,
    not a row error per log); --urdf and its options are refused: a fleet has no per-log
    file names.  No log runs and no file is written."""
    out = tmp_path / 'r.csv'
    err = _refused(_fleet(capsys, str(GOOD), '--out', str(out), '--com', '0.1'),
                   '--com', 'expected 3 arguments')
    _refused(_fleet(capsys, str(GOOD), '--out', str(out), '--com', '0', '0', '0.1'),
             '--com', 'estimate LOG --urdf')
    _refused(_fleet(capsys, str(GOOD), '--out', str(out), '--urdf', str(tmp_path / 'x.urdf'),
                    '--mass', '3'), '--urdf', 'a fleet writes no file per log')
    assert 'unrecognized' not in err
    assert in_process['runs'] == [] and sorted(os.listdir(tmp_path)) == []


def test_topic_without_its_file_refused(tmp_path: Path, capsys: pytest.CaptureFixture,
                                        in_process: dict) -> None:
    """--wheel-topic / --rotor-topic without --wheels / --rotors is one line before any log
    (it was passed to every log and did nothing there)."""
    out = tmp_path / 'r.csv'
    for opt, companion in (('--wheel-topic', '--wheels'), ('--rotor-topic', '--rotors')):
        _refused(_fleet(capsys, str(GOOD), '--out', str(out), opt, '/js'), opt,
                 f'only used with {companion} FILE')
    assert in_process['runs'] == [] and sorted(os.listdir(tmp_path)) == []


def test_workers_capped_at_the_cores(tmp_path: Path, capsys: pytest.CaptureFixture,
                                     in_process: dict) -> None:
    """--workers 1000 (or 10^30, a MemoryError before) starts one worker per core, and says
    so on stderr."""
    for n in ('1000', str(10 ** 30)):
        code, out, err, _ = _fleet(capsys, str(GOOD), '--out', str(tmp_path / f'{n[:4]}.csv'),
                                   '--workers', n)
        assert code == 0, err
        assert in_process['workers'] == _cores()
        assert f'--workers {n}: {_cores()} CPU core' in err and 'Traceback' not in err


def test_input_files_must_be_regular(tmp_path: Path, capsys: pytest.CaptureFixture,
                                     in_process: dict) -> None:
    """A FIFO as --wheels/--rotors (it hung every worker) or a missing one: one line."""
    fifo = tmp_path / 'w.yaml'
    os.mkfifo(fifo)
    out = str(tmp_path / 'r.csv')
    _refused(_fleet(capsys, str(GOOD), '--out', out, '--wheels', str(fifo)),
             '--wheels', 'not a regular file (a FIFO)')
    _refused(_fleet(capsys, str(GOOD), '--out', out, '--rotors', str(tmp_path / 'no.yaml')),
             '--rotors', 'No such file')
    assert in_process['runs'] == []


# --------------------------------------------------------------------------------------------
# Paths among the logs


@pytest.mark.parametrize('suffix', ['.csv', '.parquet'])
def test_unreadable_logs_are_rows_with_their_problem(tmp_path: Path, suffix: str,
                                                     capsys: pytest.CaptureFixture,
                                                     in_process: dict) -> None:
    """A dangling link, a link loop and a FIFO named *.mcap are rows with their error (were
    tracebacks, the FIFO a hang); a non-UTF-8 name is a row with \\xNN escapes (a
    UnicodeEncodeError in CSV and Parquet); a re-run finds every row unchanged."""
    if suffix == '.parquet':
        pytest.importorskip('pyarrow')
    logs = tmp_path / 'v1'
    logs.mkdir()
    os.symlink(tmp_path / 'gone.mcap', logs / 'dangling.mcap')
    os.symlink(logs / 'loop.mcap', logs / 'loop.mcap')
    os.mkfifo(logs / 'fifo.mcap')
    odd = os.fsencode(logs) + b'/caf\xe9.mcap'
    shutil.copyfile(GOOD, odd)
    out = tmp_path / f'fleet{suffix}'
    code, stdout, err, dt = _fleet(capsys, str(tmp_path), '--out', str(out))
    assert code == 0 and 'Traceback' not in err and dt < 3 * FAST_S, err
    rows = {Path(r['path']).name: r for r in fleet_table.read_rows(out)}
    assert set(rows) == {'dangling.mcap', 'loop.mcap', 'fifo.mcap', 'caf\\xe9.mcap'}
    assert 'dangling symbolic link' in rows['dangling.mcap']['error']
    assert 'symbolic link loop' in rows['loop.mcap']['error']
    assert 'not a regular file (a FIFO)' in rows['fifo.mcap']['error']
    assert all(rows[n]['status'] == 'error' for n in ('dangling.mcap', 'loop.mcap',
                                                       'fifo.mcap'))
    assert rows['caf\\xe9.mcap']['status'] in ('ok', 'model_mismatch')
    assert rows['caf\\xe9.mcap']['vehicle'] == 'v1'
    code, stdout, err, _ = _fleet(capsys, str(tmp_path), '--out', str(out))
    assert code == 0 and '(0 estimated, 4 unchanged)' in stdout, (stdout, err)
    assert len(in_process['runs']) == 1


# --------------------------------------------------------------------------------------------
# The output table


def test_user_file_at_out_is_refused_and_unchanged(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture,
                                                   in_process: dict) -> None:
    """A CSV of the user's own with a `path` column (it was rewritten as earlier results),
    a symbolic link and a FIFO at --out: refused in one line, nothing modified."""
    mine = tmp_path / 'mine.csv'
    mine.write_text(f'path,note\n{GOOD},keep me\n')
    before = (mine.read_bytes(), mine.stat().st_mtime_ns)
    _refused(_fleet(capsys, str(GOOD), '--out', str(mine)),
             'not a table written by inertia_ros fleet', 'choose another --out')
    assert (mine.read_bytes(), mine.stat().st_mtime_ns) == before
    link = tmp_path / 'link.csv'
    link.symlink_to(mine)
    _refused(_fleet(capsys, str(GOOD), '--out', str(link)), 'symbolic link')
    fifo = tmp_path / 'fifo.csv'
    os.mkfifo(fifo)
    _refused(_fleet(capsys, str(GOOD), '--out', str(fifo)), 'not a regular file')
    assert (mine.read_bytes(), mine.stat().st_mtime_ns) == before and in_process['runs'] == []


def test_temporary_file_is_unpredictable_and_never_followed(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture,
                                                            in_process: dict) -> None:
    """A directory planted at the old fixed temporary name (a traceback before) and a
    symbolic link planted there (it made fleet write through it) change nothing: the table
    is written, the victim file is untouched, no temporary file is left."""
    victim = tmp_path / 'victim.txt'
    victim.write_text('precious\n')
    out = tmp_path / 'fleet.csv'
    (tmp_path / '.fleet.csv.tmp').symlink_to(victim)
    (tmp_path / '.fleet.parquet.tmp').mkdir()
    for name in ('fleet.csv', 'fleet.parquet'):
        code, stdout, err, _ = _fleet(capsys, str(GOOD), '--out', str(tmp_path / name))
        assert code == 0 and 'Traceback' not in err, err
        assert len(fleet_table.read_rows(tmp_path / name)) == 1
    assert victim.read_text() == 'precious\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        '.fleet.csv.tmp', '.fleet.parquet.tmp', 'fleet.csv', 'fleet.parquet', 'victim.txt']
    assert (out.stat().st_mode & 0o777) == 0o666 & ~_umask()


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


# --------------------------------------------------------------------------------------------
# --scheduler addresses: each one line within seconds (every unreachable one took 20.5 s)


@contextlib.contextmanager
def _garbage_server() -> int:
    """A TCP server answering every connection with bytes that are not Dask's protocol."""
    srv = socket.socket()
    srv.bind(('127.0.0.1', 0))
    srv.listen()
    stop = threading.Event()

    def serve() -> None:
        srv.settimeout(0.2)
        while not stop.is_set():
            try:
                c, _ = srv.accept()
            except OSError:
                continue
            with contextlib.suppress(OSError), c:
                c.sendall(b'\xff' * 64 + b'HTTP/1.1 200 OK\r\n\r\ngarbage' * 10)

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    try:
        yield srv.getsockname()[1]
    finally:
        stop.set()
        t.join(2)
        srv.close()


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return int(s.getsockname()[1])


def test_scheduler_addresses_fail_fast_in_one_line(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture) -> None:
    """Closed port, unresolvable name, ucx://, tls:// without settings, malformed, an
    address answering garbage (a 3 EiB allocation before): one line, exit 2, < 10 s each."""
    port = _closed_port()
    out = str(tmp_path / 'r.csv')
    cases = {f'tcp://127.0.0.1:{port}': 'cannot connect',
             f'ws://127.0.0.1:{port}': 'cannot connect',
             'tcp://no-such-host.invalid:8786': 'cannot connect',
             'ucx://127.0.0.1:8786': 'protocol ucx:// is not supported',
             'tcp://127.0.0.1:99999': 'expected tcp://HOST:PORT',
             'x' * 100_000: 'expected tcp://HOST:PORT'}
    for addr, words in cases.items():
        err = _refused(_fleet(capsys, str(GOOD), '--out', out, '--scheduler', addr), words)
        assert len(err) < 500
    with _garbage_server() as garbage:
        for scheme in ('tcp', 'tls'):
            _refused(_fleet(capsys, str(GOOD), '--out', out, '--scheduler',
                            f'{scheme}://127.0.0.1:{garbage}'), 'no Dask scheduler answered')
    assert not (tmp_path / 'r.csv').exists()


# --------------------------------------------------------------------------------------------
# Ctrl-C on a local cluster of worker processes (a terminal sends it to the process group)


def _group(pgid: int) -> list[int]:
    """Live (not zombie) processes of a process group."""
    pids = []
    for d in os.listdir('/proc'):
        if not d.isdigit():
            continue
        try:
            fields = Path(f'/proc/{d}/stat').read_text().rsplit(')', 1)[1].split()
        except OSError:
            continue
        if int(fields[2]) == pgid and fields[0] != 'Z':
            pids.append(int(d))
    return pids


def _default_sigint() -> None:
    """Ctrl-C as at a terminal: a test run started in the background (``make test &``, some
    CI runners) hands its children SIGINT ignored, which fleet rightly keeps ignoring."""
    import signal
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _interrupt(tmp_path: Path, after_workers_s: float, second_s: float | None
               ) -> tuple[int, str, float]:
    """Run fleet on 400 logs with 2 worker processes in its own process group; Ctrl-C the
    group ``after_workers_s`` after the worker processes appear (and again ``second_s``
    later); return the exit status, stderr and the seconds from the first Ctrl-C to exit."""
    import signal
    import subprocess
    import sys

    logs = tmp_path / 'v1'
    logs.mkdir()
    shutil.copyfile(GOOD, logs / '0.mcap')
    for i in range(1, 400):  # far more than 2 workers finish in the test's seconds, even
        os.link(logs / '0.mcap', logs / f'{i}.mcap')   # when the machine is loaded
    p = subprocess.Popen([sys.executable, '-m', 'inertia_ros', 'fleet', str(logs), '--out',
                          str(tmp_path / 'r.csv'), '--workers', '2', '--no-progress'],
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                         start_new_session=True, cwd=ROOT, preexec_fn=_default_sigint)
    try:
        deadline = time.monotonic() + 60
        while len(_group(p.pid)) < 4 and time.monotonic() < deadline:  # + tracker, 2 workers
            time.sleep(0.05)
        time.sleep(after_workers_s)
        t0 = time.monotonic()
        os.killpg(p.pid, signal.SIGINT)
        if second_s is not None:
            time.sleep(second_s)
            os.killpg(p.pid, signal.SIGINT)
        _, err = p.communicate(timeout=60)
        dt = time.monotonic() - t0
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    deadline = time.monotonic() + 5
    while _group(p.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _group(p.pid) == [], 'worker processes left behind'
    return p.returncode, err, dt


@pytest.mark.parametrize('when, second', [(0.2, None), (4.0, 0.2)],
                         ids=['during start-up', 'twice while running'])
def test_ctrl_c_exits_130_and_stops_the_workers(tmp_path: Path, when: float,
                                                second: float | None) -> None:
    """Ctrl-C while the workers start (it was ignored) and a double Ctrl-C while logs run
    (it exited -2): exit 130 within 10 s, the one-line interruption notice and no
    traceback on stderr, no process of the run left."""
    code, err, dt = _interrupt(tmp_path, when, second)
    assert code == 130, err
    assert 'Traceback' not in err and 'KeyboardInterrupt' not in err, err
    assert err.strip().splitlines()[-1].startswith('inertia_ros fleet: interrupted'), err
    assert dt < FAST_S


def _sleep_forever() -> None:  # a child process that would outlive its parent
    time.sleep(600)


def test_shutdown_stops_the_runs_own_processes_only() -> None:
    """Whatever ended the run, the shut-down terminates the child processes the run started
    (a worker process left behind before) and no other."""
    import multiprocessing

    from inertia_ros.fleet import cluster

    ctx = multiprocessing.get_context('spawn')
    older = ctx.Process(target=_sleep_forever, daemon=True)
    older.start()
    try:
        before = set(multiprocessing.active_children())
        mine = ctx.Process(target=_sleep_forever, daemon=True)
        mine.start()
        t0 = time.monotonic()
        cluster._shutdown(None, None, before)
        assert not mine.is_alive() and time.monotonic() - t0 < FAST_S
        assert older.is_alive()
    finally:
        older.kill()
        older.join()


def test_long_empty_and_unwritable_values_are_one_short_line(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture,
                                                             in_process: dict) -> None:
    """A 130 kB PATH, --out, --report or --wheels (tracebacks: name too long), an empty
    PATH (it searched the working directory), an --out or --report where nothing can be
    made (refused only after every log had run): one line of at most a few hundred
    characters, before any log runs."""
    long = str(tmp_path / ('a' * 130_000))
    out = str(tmp_path / 'r.csv')
    cases = [((long, '--out', out), 'cannot search (File name too long)'),
             ((str(GOOD), '--out', long + '.csv'), 'cannot write there'),
             ((str(GOOD), '--out', out, '--report', long), 'cannot make this directory'),
             ((str(GOOD), '--out', out, '--wheels', long), '--wheels'),
             (('', '--out', out), "PATH '' is empty"),
             ((str(GOOD), '--out', '/proc/r.csv'), 'cannot write there'),
             ((str(GOOD), '--out', out, '--report', '/dev/null/x'), 'Not a directory')]
    for args, words in cases:
        err = _refused(_fleet(capsys, *args), words)
        assert len(err) < 400, err
    assert in_process['runs'] == [] and os.listdir(tmp_path) == []


def test_a_long_option_value_reaches_every_log(tmp_path: Path,
                                               capsys: pytest.CaptureFixture) -> None:
    """A 130 kB option given to Dask's map as a keyword argument made every row 'failed'
    (an AssertionError in its scheduler): the options travel inside each task, and each log
    gives its own row (threads of this process, a real Dask client)."""
    pytest.importorskip('distributed')
    logs = tmp_path / 'v1'
    logs.mkdir()
    for i in range(2):
        shutil.copyfile(GOOD, logs / f'{i}.mcap')
    mp = pytest.MonkeyPatch()
    mp.setattr(fleet_run, 'LOCAL_PROCESSES', False)
    try:
        code, out, err, _ = _fleet(capsys, str(logs), '--out', str(tmp_path / 'r.csv'),
                                   '--workers', '1', '--vehicle-from',
                                   'metadata:' + 'k' * 130_000)
    finally:
        mp.undo()
    assert code == 0, err
    rows = fleet_table.read_rows(tmp_path / 'r.csv')
    assert [r['status'] for r in rows] == ['ok', 'ok']
    assert [r['vehicle'] for r in rows] == [None, None]  # no such metadata key
