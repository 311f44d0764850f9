"""The estimate command: committed bags against their truth, messy variants, errors, outputs."""
from __future__ import annotations

import hashlib
import json
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_logs import write_log

from conftest import ROOT
from inertia_ros.cli import main
from inertia_ros.io import cdr_decode
from inertia_ros.io.mcap_reader import McapReader

BAGS = sorted((ROOT / 'bags').glob('*.mcap'))
CONTRACT_KEYS = {'status', 'inertia', 'inertia_std', 'principal_moments', 'principal_axes',
                 'ratios', 'ratios_std', 'identifiable', 'torque_bias', 'inertial_torque',
                 'model', 'method', 'samples', 'covariance', 'diagnostics'}
#: Expected status per committed bag (by file stem); any other bag must be 'ok'.
EXPECTED = {'torque_free': ('scale_unobservable',),
            'single_axis': ('partially_identifiable', 'insufficient_excitation'),
            # without --wheels the wheel-driven body looks torque-free, but is not
            'wheels': ('scale_unobservable', 'insufficient_excitation'),
            # likewise the rotor-driven quadrotor without --rotors (its torque topic is zeros)
            'quadrotor': ('scale_unobservable', 'insufficient_excitation'),
            # sensor nuisance samples: without --nuisance the model lacks the term
            # (a 15 ms torque delay too: at the anchored-segment length searched for the fit
            # without the bias, 5 s, the tensor moves 5 sigma when the segments are cut
            # shorter; it was ok only at the length searched with a bias the test dropped)
            **dict.fromkeys(('gyro_bias', 'damping', 'gyro_lowpass', 'torque_delay'),
                            ('model_mismatch',))}
DEFAULT_BAG = ROOT / 'bags' / 'default.mcap'
needs_default = pytest.mark.skipif(not DEFAULT_BAG.exists(), reason='bags/default.mcap absent')


def run_json(capsys: pytest.CaptureFixture, *args: str) -> tuple[int, dict | None, str]:
    """Run ``estimate ... --format json``; return (exit status, report or None, stderr)."""
    code = main(['estimate', *args, '--format', 'json', '--no-progress'])
    out, err = capsys.readouterr()
    return code, (json.loads(out) if out.strip() else None), err


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.skipif(not BAGS, reason='no committed logs in bags/')
@pytest.mark.parametrize('bag', BAGS, ids=[b.stem for b in BAGS])
def test_committed_bag_matches_its_truth(bag: Path, capsys: pytest.CaptureFixture) -> None:
    """Each bag's estimate has its expected status; 'ok' ones are within 1 % of the truth."""
    before = sha(bag)
    code, rep, err = run_json(capsys, str(bag))
    assert code == 0, err
    assert set(rep) == CONTRACT_KEYS
    truth = np.array(rep['diagnostics']['truth']['inertia'])
    want = EXPECTED.get(bag.stem, ('ok',))
    assert rep['status'] in want
    if rep['status'] == 'ok':
        est = np.array(rep['inertia'])
        assert np.linalg.norm(est - truth) / np.linalg.norm(truth) < 0.01
        std = np.array(rep['inertia_std'])
        assert np.all(np.abs(est - truth) < 6 * std + 1e-4)
        moments = np.linalg.eigvalsh(truth)
        np.testing.assert_allclose(rep['principal_moments'], moments, rtol=0.01, atol=0)
    if rep['status'] == 'scale_unobservable':
        assert rep['inertia'] is None and rep['principal_moments'] is None
        np.testing.assert_allclose(rep['ratios'], truth / np.trace(truth), rtol=0, atol=0.01)
        axes = np.array(rep['principal_axes'])
        true_axes = np.linalg.eigh(truth)[1]
        np.testing.assert_allclose(np.abs(np.sum(axes * true_axes, axis=0)), 1.0, rtol=0,
                                   atol=0.01)
    if rep['status'] == 'partially_identifiable':
        est = np.array(rep['inertia'], dtype=float)
        ident = np.isfinite(est)
        assert ident.any() and not ident.all()
        assert np.all(np.abs(est[ident] - truth[ident]) < 0.02 * np.abs(truth).max())
    assert sha(bag) == before


# --------------------------------------------------------------------------------------------
# messy variants of the default bag


def load_streams(bag: Path) -> dict:
    """Header stamps [ns] and values of /imu and /torque, and the truth tensor."""
    out: dict = {}
    with McapReader(bag) as r:
        for b in r.iter_batches(lambda ch, sc: ch.topic in ('/imu', '/torque',
                                                            '/truth/inertia')):
            typ = cdr_decode.normalise_type(b.schema.name)
            d = cdr_decode.decode_batch(typ, b.buf, b.starts, b.lengths)
            key = b.channel.topic
            if key == '/truth/inertia':
                f = d.fields
                out['truth'] = np.array([[f['ixx'][0, 0], f['ixy'][0, 0], f['ixz'][0, 0]],
                                         [f['ixy'][0, 0], f['iyy'][0, 0], f['iyz'][0, 0]],
                                         [f['ixz'][0, 0], f['iyz'][0, 0], f['izz'][0, 0]]])
                continue
            field = 'angular_velocity' if key == '/imu' else 'torque'
            out.setdefault(key, []).append((d.stamp_ns, d.fields[field]))
    res = {'truth': out['truth']}
    for key, (tk, vk) in (('/imu', ('tg', 'w')), ('/torque', ('tt', 'tau'))):
        res[tk] = np.concatenate([a for a, _ in out[key]])
        res[vk] = np.concatenate([v for _, v in out[key]])
    return res


def _messy(kind: str, s: dict, rng: np.random.Generator) -> dict:
    """Damage the streams in one way; returns write_log keyword arguments."""
    tg, w, tt, tau = s['tg'].copy(), s['w'].copy(), s['tt'].copy(), s['tau'].copy()
    kw: dict = {}
    if kind == 'reordered':  # 3 per mille of messages arrive up to 4 samples late
        log_g = tg.copy()
        late = rng.choice(tg.size, tg.size * 3 // 1000, replace=False)
        log_g[late] += rng.integers(1, 5, late.size) * 5_000_000 + 1
        kw['log_g'] = log_g
    elif kind == 'duplicated':  # 5 per mille of gyro and torque messages recorded twice
        for a, v, n in ((tg, w, 'g'), (tt, tau, 't')):
            d = np.sort(rng.choice(a.size - 1, a.size * 5 // 1000, replace=False))
            a2, v2 = np.insert(a, d + 1, a[d]), np.insert(v, d + 1, v[d], axis=0)
            if n == 'g':
                tg, w = a2, v2
            else:
                tt, tau = a2, v2
    elif kind == 'looped':  # the clock restarts half way (stamps jump back 30 s)
        kw['log_g'], kw['log_t'] = tg.copy(), tt.copy()
        mid = tg[0] + (tg[-1] - tg[0]) // 2
        tg = np.where(tg > mid, tg - 30_000_000_000, tg)
        tt = np.where(tt > mid, tt - 30_000_000_000, tt)
    elif kind == 'gap':  # 2 s missing from both streams
        mid = tg[0] + (tg[-1] - tg[0]) // 2
        kg = (tg < mid) | (tg > mid + 2_000_000_000)
        kt = (tt < mid) | (tt > mid + 2_000_000_000)
        tg, w, tt, tau = tg[kg], w[kg], tt[kt], tau[kt]
    elif kind == 'nan':  # 3 per mille NaN / Inf samples
        w[rng.choice(tg.size, tg.size * 3 // 1000, replace=False), rng.integers(0, 3)] = np.nan
        tau[rng.choice(tt.size, tt.size * 3 // 1000, replace=False), 0] = np.inf
    return {'s': {'tg': tg, 'w': w, 'tt': tt, 'tau': tau}, **kw}


@needs_default
@pytest.mark.parametrize('kind', ['reordered', 'duplicated', 'nan', 'truncated', 'looped',
                                  'gap'])
def test_messy_variants_still_estimate(kind: str, tmp_path: Path,
                                       capsys: pytest.CaptureFixture) -> None:
    """Reordered, duplicated, NaN, truncated, looped and gapped copies: ok and accurate."""
    rng = np.random.default_rng(11)
    s = load_streams(DEFAULT_BAG)
    path = tmp_path / f'{kind}.mcap'
    if kind == 'truncated':
        write_log(path, s, truth=s['truth'], compression='none', chunk_size=256 * 1024)
        data = path.read_bytes()
        path.write_bytes(data[:int(0.7 * len(data))])
    else:
        m = _messy(kind, s, rng)
        write_log(path, m.pop('s'), truth=s['truth'], **m)
    code, rep, err = run_json(capsys, str(path))
    assert code == 0, err
    assert rep['status'] == 'ok'
    est, truth = np.array(rep['inertia']), s['truth']
    assert np.linalg.norm(est - truth) / np.linalg.norm(truth) < 0.02
    log = rep['diagnostics']['log']
    n_g, n_t = s['tg'].size, s['tt'].size
    if kind == 'reordered':
        assert log['omega']['out_of_order'] > 0
        assert log['omega']['duplicates'] == 0
    if kind == 'duplicated':
        assert log['omega']['duplicates'] == n_g * 5 // 1000
        assert log['torque']['duplicates'] == n_t * 5 // 1000
    if kind == 'nan':
        assert log['omega']['nonfinite'] == n_g * 3 // 1000
        assert log['torque']['nonfinite'] == n_t * 3 // 1000
    if kind == 'looped':
        assert log['clock_jumps'] == 1 and log['windows'] == 2
    if kind == 'gap':
        assert log['omega']['gaps'] == 1 and log['windows'] == 2
    if kind == 'truncated':
        assert log['damage']['truncated']
        assert any('damaged log' in w for w in rep['diagnostics']['warnings'])
        assert 0.6 * n_g < log['omega']['received'] < 0.75 * n_g


# --------------------------------------------------------------------------------------------
# errors and outputs


def _one_line_error(code: int, err: str, pattern: str) -> None:
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert 'Traceback' not in err
    assert pattern in lines[0], lines[0]


@pytest.mark.parametrize('bag, option, kind', [
    ('wheels.mcap', ('--wheels', 'bags/wheels_wheels.yaml'), 'wheels'),
    ('quadrotor.mcap', ('--rotors', 'bags/quadrotor_rotors.yaml'), 'rotors')])
def test_nuisance_with_actuators_is_the_table_refusal(bag: str, option: tuple[str, str],
                                                      kind: str,
                                                      capsys: pytest.CaptureFixture) -> None:
    """``--nuisance`` with ``--wheels``/``--rotors`` is refused with the capability table's
    one line (issue 26: one refusal, from the table), exit 2; it was the CLI's own wording."""
    from inertia_ros.core.estimation.config import refusal

    code, _, err = run_json(capsys, str(ROOT / 'bags' / bag), option[0], str(ROOT / option[1]),
                            '--nuisance', 'auto')
    _one_line_error(code, err, f"--nuisance: {refusal('batch', kind, 'nuisance')}")


def test_unusable_inputs_give_one_line(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """Missing file, not an MCAP, no topics, wrong type, empty stream: exit 2, one line."""
    code, rep, err = run_json(capsys, str(tmp_path / 'nope.mcap'))
    _one_line_error(code, err, 'no such file or directory')
    junk = tmp_path / 'junk.mcap'
    junk.write_text('not an mcap')
    _one_line_error(*run_json(capsys, str(junk))[::2], 'not an MCAP file')
    s = {'tg': np.arange(50, dtype=np.int64) * 5_000_000 + 10**18, 'w': np.ones((50, 3)),
         'tt': np.arange(10, dtype=np.int64) * 20_000_000 + 10**18, 'tau': np.ones((10, 3))}
    path = write_log(tmp_path / 'a.mcap', s, truth=np.eye(3))
    _one_line_error(*run_json(capsys, str(path), '--torque-topic', '/truth/inertia')[::2],
                    'has type geometry_msgs/msg/InertiaStamped, not a torque type')
    _one_line_error(*run_json(capsys, str(path), '--omega-topic', '/gyro')[::2],
                    'topics in the log: /imu (sensor_msgs/msg/Imu)')
    empty = write_log(tmp_path / 'empty.mcap', {'tg': s['tg'][:0], 'w': s['w'][:0],
                                                'tt': s['tt'], 'tau': s['tau']})
    _one_line_error(*run_json(capsys, str(empty))[::2],
                    '/imu: no messages of type sensor_msgs/msg/Imu in the log (empty stream)')


@pytest.mark.skipif(not (ROOT / 'bags' / 'torque_free.mcap').exists(),
                    reason='bags/torque_free.mcap absent')
def test_torque_topic_none_on_torque_free_bag(capsys: pytest.CaptureFixture) -> None:
    """Ignoring the (zero) torque stream still gives scale_unobservable with the right ratios."""
    code, rep, err = run_json(capsys, str(ROOT / 'bags' / 'torque_free.mcap'),
                              '--torque-topic', 'none')
    assert code == 0, err
    assert rep['status'] == 'scale_unobservable'
    truth = np.array(rep['diagnostics']['truth']['inertia'])
    np.testing.assert_allclose(rep['ratios'], truth / np.trace(truth), rtol=0, atol=0.01)


def test_too_little_data_is_a_report_not_an_error(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture) -> None:
    """A short but valid log produces a report (exit 0) whose status says so."""
    rng = np.random.default_rng(1)
    s = {'tg': np.arange(40, dtype=np.int64) * 5_000_000 + 10**18,
         'w': rng.normal(size=(40, 3)),
         'tt': np.arange(10, dtype=np.int64) * 20_000_000 + 10**18,
         'tau': rng.normal(size=(10, 3))}
    code, rep, err = run_json(capsys, str(write_log(tmp_path / 's.mcap', s)))
    assert code == 0, err
    assert rep['status'] in ('insufficient_data', 'insufficient_excitation')


@needs_default
def test_text_report_output_file_and_input_untouched(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture) -> None:
    """Text report names status, tensor and data counts; -o writes it; -o input is refused."""
    before = sha(DEFAULT_BAG)
    out = tmp_path / 'report.txt'
    code = main(['estimate', str(DEFAULT_BAG), '-o', str(out), '--no-progress'])
    stdout, err = capsys.readouterr()
    assert code == 0, err
    assert stdout == ''
    text = out.read_text()
    for piece in ('status: ok', 'inertia tensor about the centre of mass', 'principal moments',
                  'principal axes', '/imu (sensor_msgs/msg/Imu', 'received', 'used',
                  'recorded truth: relative error'):
        assert piece in text
    code = main(['estimate', str(DEFAULT_BAG), '-o', str(DEFAULT_BAG)])
    _, err = capsys.readouterr()
    _one_line_error(code, err, 'refusing to overwrite the input log')
    assert sha(DEFAULT_BAG) == before


@needs_default
def test_json_to_file_equals_stdout(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """-o FILE with --format json writes the same contract object that stdout would show."""
    code, rep, _ = run_json(capsys, str(DEFAULT_BAG))
    out = tmp_path / 'r.json'
    assert main(['estimate', str(DEFAULT_BAG), '--format', 'json', '-o', str(out)]) == 0
    assert json.loads(out.read_text()) == rep
    assert rep['samples']['used'] > 0
    assert set(rep['identifiable']) == {'ixx', 'iyy', 'izz', 'ixy', 'ixz', 'iyz'}


@pytest.mark.skipif(not BAGS, reason='no committed logs in bags/')
@pytest.mark.parametrize('bag', BAGS, ids=[b.stem for b in BAGS])
def test_plot_is_written(bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """--plot writes a PNG figure for every committed bag, whatever its status."""
    png = tmp_path / 'fig.png'
    code = main(['estimate', str(bag), '--plot', str(png), '--no-progress'])
    capsys.readouterr()
    assert code == 0
    data = png.read_bytes()
    assert data[:8] == b'\x89PNG\r\n\x1a\n' and len(data) > 50_000


def test_process_exit_status_and_stderr(tmp_path: Path) -> None:
    """As a process: exit 2 and exactly one stderr line for a missing file."""
    proc = subprocess.run([sys.executable, '-m', 'inertia_ros', 'estimate',
                           str(tmp_path / 'missing.mcap')], capture_output=True, text=True,
                          cwd=ROOT, check=False)
    assert proc.returncode == 2
    assert proc.stdout == ''
    assert len(proc.stderr.strip().splitlines()) == 1
    assert proc.stderr.startswith('inertia_ros estimate: error: ')


def test_progress_bar_only_when_enabled(capsys: pytest.CaptureFixture) -> None:
    """The progress bar draws on stderr when enabled (a TTY) and stays silent otherwise."""
    from inertia_ros.cli.estimate import _Progress

    bar = _Progress(True)
    bar(50, 100)
    bar(100, 100)
    bar.close()
    err = capsys.readouterr().err
    assert 'reading [' in err and '100.0%' in err
    quiet = _Progress(False)
    quiet(50, 100)
    quiet.close()
    assert capsys.readouterr().err == ''


# --------------------------------------------------------------------------------------------
# Hostile options and damaged logs: one line, exit 2, never a traceback


@pytest.mark.parametrize('value', ['1e300', '-1e300', '10.5', '-11', 'nan', 'inf', '-inf',
                                   'abc', ''])
def test_torque_delay_out_of_range_is_one_line(value: str, capsys: pytest.CaptureFixture
                                               ) -> None:
    """--torque-delay outside [-10, 10] s (or not a finite number) is refused at parse time
    with the range and the unit, before the log is opened."""
    code = main(['estimate', 'never-opened.mcap', f'--torque-delay={value}'])
    err = capsys.readouterr().err
    _one_line_error(code, err, 'argument --torque-delay: must be')
    assert '[-10, 10] s' in err


def test_torque_delay_within_range_is_used(capsys: pytest.CaptureFixture) -> None:
    """The limits themselves parse; a delay in range is reported back in the diagnostics."""
    from inertia_ros.cli import build_parser

    for v in ('-10', '10', '0'):
        args = build_parser('estimate').parse_args(['estimate', 'x.mcap', '--torque-delay', v])
        assert args.torque_delay == float(v)
    if not DEFAULT_BAG.exists():
        pytest.skip('bags/default.mcap absent')
    code, rep, err = run_json(capsys, str(DEFAULT_BAG), '--torque-delay', '0.004')
    assert code == 0, err
    assert rep['diagnostics']['torque_delay_s'] == 0.004


def test_torque_delay_1e300_as_a_process() -> None:
    """The case that raised OverflowError: as a process, exit 2 and one stderr line."""
    proc = subprocess.run([sys.executable, '-m', 'inertia_ros', 'estimate', 'x.mcap',
                           '--torque-delay', '1e300'], capture_output=True, text=True,
                          cwd=ROOT, check=False)
    assert proc.returncode == 2
    assert proc.stderr == ('inertia_ros estimate: error: argument --torque-delay: must be '
                           'within [-10, 10] s; got 1e300 (see --help)\n')


@pytest.fixture(scope='module')
def bag_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small rosbag2 directory written by the simulate command."""
    text = (ROOT / 'config' / 'scenes' / 'default.yaml').read_text()
    tmp = tmp_path_factory.mktemp('bagdir')
    scene = tmp / 'short.yaml'
    scene.write_text(text.replace('duration: 60.0', 'duration: 10.0'))
    assert main(['simulate', str(scene), '-o', str(tmp / 'run'), '-q']) == 0
    return tmp / 'run'


@pytest.mark.parametrize('metadata', [
    b'rosbag2_bagfile_information: 5\n',
    b'rosbag2_bagfile_information:\n  relative_file_paths: [null]\n',
    b'rosbag2_bagfile_information:\n  relative_file_paths: 7\n',
    b'\xff\xfe\x00 not utf-8',
    b'[1, 2',
], ids=['info-number', 'paths-null', 'paths-number', 'not-utf8', 'bad-yaml'])
def test_damaged_metadata_never_a_traceback(metadata: bytes, bag_dir: Path, tmp_path: Path,
                                            capsys: pytest.CaptureFixture) -> None:
    """A rosbag2 directory whose metadata.yaml is damaged: a report (the reader recovered) or
    exit 2 with one line naming the bag; never a traceback."""
    bag = tmp_path / 'run'
    bag.mkdir()
    (bag / 'run_0.mcap').write_bytes((bag_dir / 'run_0.mcap').read_bytes())
    (bag / 'metadata.yaml').write_bytes(metadata)
    code, rep, err = run_json(capsys, str(bag))
    assert 'Traceback' not in err
    if code == 0:
        assert set(rep) >= CONTRACT_KEYS
    else:
        _one_line_error(code, err, str(bag))


@pytest.mark.parametrize('exc', [struct.error('unpack requires a buffer of 9 bytes'),
                                 ZeroDivisionError('float division by zero'),
                                 KeyError('records'), RuntimeError('')],
                         ids=lambda e: type(e).__name__)
def test_unexpected_reader_failure_is_one_line(exc: Exception, monkeypatch: pytest.MonkeyPatch,
                                               capsys: pytest.CaptureFixture) -> None:
    """Whatever a damaged log makes the reader raise becomes one line naming the file and
    the exception type (the last-resort handler)."""
    from inertia_ros.io import logs

    def broken(*args: object, **kwargs: object) -> None:
        raise exc

    monkeypatch.setattr(logs, 'read_log', broken)
    code, _, err = run_json(capsys, 'some/damaged.mcap')
    _one_line_error(code, err, 'some/damaged.mcap: damaged or unreadable log')
    assert type(exc).__name__ in err


def test_unexpected_failure_after_reading_is_one_line(monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture) -> None:
    """A failure past the reader (here the report) is still one line with its type."""
    if not DEFAULT_BAG.exists():
        pytest.skip('bags/default.mcap absent')
    from inertia_ros.cli import report

    def broken(*args: object, **kwargs: object) -> None:
        raise IndexError('list index out of range')

    monkeypatch.setattr(report, 'build_report', broken)
    code, _, err = run_json(capsys, str(DEFAULT_BAG))
    _one_line_error(code, err, 'unexpected IndexError: list index out of range')
    assert str(DEFAULT_BAG) in err


def test_overflowing_gyro_samples_give_one_line_not_numpy_noise(
        tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """Three 1e300 gyro samples among 6000: no numpy warning reaches stderr; the outcome is
    a report or one error line, and a failure names the numerical warning behind it."""
    from test_logs import streams

    s = streams(6000, 1500, seed=3)
    s['w'][[100, 2000, 4000], 1] = 1e300
    path = write_log(tmp_path / 'big.mcap', s)
    code, rep, err = run_json(capsys, str(path))
    assert 'Warning:' not in err and 'Traceback' not in err
    if code == 0:
        assert err == ''
        assert set(rep) >= CONTRACT_KEYS
    else:
        _one_line_error(code, err, str(path))


def test_numerical_warnings_go_into_the_report(monkeypatch: pytest.MonkeyPatch,
                                               capsys: pytest.CaptureFixture) -> None:
    """A warning raised while estimating is listed once, with its count, under
    diagnostics.warnings, and stderr stays empty."""
    if not DEFAULT_BAG.exists():
        pytest.skip('bags/default.mcap absent')
    from inertia_ros.core import estimation

    real = estimation.estimate

    def noisy(*args: object, **kwargs: object) -> object:
        for _ in range(3):
            np.float64(1e308) * np.float64(10.0)      # RuntimeWarning: overflow
        return real(*args, **kwargs)

    monkeypatch.setattr(estimation, 'estimate', noisy)
    code, rep, err = run_json(capsys, str(DEFAULT_BAG))
    assert code == 0 and err == ''
    found = [w for w in rep['diagnostics']['warnings'] if w.startswith('numerical warning')]
    assert found == ['numerical warning: overflow encountered in scalar multiply '
                     '(RuntimeWarning, 3x)']
