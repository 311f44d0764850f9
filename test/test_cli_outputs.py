"""estimate's outputs and messages (issue 29): one overwrite rule for -o/--plot/--urdf checked
before any work, a URDF that is always well-formed XML, --plot with wheels and rotors, the text
report's reason and remedy, and the messages a new user reads."""
from __future__ import annotations

import os
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT
from inertia_ros.cli import main, program_name

BAGS = ROOT / 'bags'
DEFAULT_BAG = BAGS / 'default.mcap'
PNG = b'\x89PNG\r\n\x1a\n'

pytestmark = pytest.mark.skipif(not DEFAULT_BAG.exists(), reason='bags/default.mcap absent')


def _estimate(capsys: pytest.CaptureFixture, *args: str) -> tuple[int, str, str]:
    """Run ``estimate ... --no-progress``; return (exit status, stdout, stderr)."""
    code = main(['estimate', *map(str, args), '--no-progress'])
    out, err = capsys.readouterr()
    return code, out, err


def _refused(code: int, out: str, err: str, *pieces: str) -> None:
    """Exit 2, no report printed (refused before the work), one stderr line with pieces."""
    assert code == 2, (out, err)
    assert out == ''
    lines = err.strip().splitlines()
    assert len(lines) == 1, lines
    for piece in pieces:
        assert piece in lines[0], (piece, lines[0])


# ------------------------------------------------------------------ outputs checked up front


@pytest.mark.parametrize('opt', ['-o', '--plot', '--urdf'])
def test_existing_output_refused_unless_force(opt: str, tmp_path: Path,
                                              capsys: pytest.CaptureFixture) -> None:
    """Each output option refuses an existing file before the log is read (no report), and
    leaves it untouched; with --force it replaces it with the new content."""
    out = tmp_path / ('out.png' if opt == '--plot' else 'out.txt')
    out.write_bytes(b'the user\'s file')
    mass = ['--mass', '10'] if opt == '--urdf' else []
    _refused(*_estimate(capsys, DEFAULT_BAG, opt, out, *mass), opt, 'exists', '--force')
    assert out.read_bytes() == b'the user\'s file'
    code, stdout, err = _estimate(capsys, DEFAULT_BAG, opt, out, *mass, '--force')
    assert code == 0, err
    data = out.read_bytes()
    if opt == '-o':
        assert stdout == '' and 'status: ok' in data.decode()
    elif opt == '--plot':
        assert data[:8] == PNG
    else:
        assert ET.fromstring(data).find('link/inertial/mass').get('value') == '10.0'


def test_urdf_refusals_come_before_the_report(tmp_path: Path,
                                              capsys: pytest.CaptureFixture) -> None:
    """--urdf into a missing directory, with a blank --link, a 100 kB one, or with control
    characters in the link name (U+0001, U+001F, U+FFFE): one line, exit 2, and no report
    printed."""
    good = tmp_path / 'body.urdf'
    cases = [
        ([tmp_path / 'missing' / 'b.urdf', '--mass', '10'], ('--urdf', 'does not exist')),
        ([good], ('--urdf needs --mass',)),
        ([good, '--mass', '10', '--link', ''], ('--link', 'non-empty')),
        ([good, '--mass', '10', '--link', '   '], ('--link', 'non-empty')),
        ([good, '--mass', '10', '--link', 'a\x01b'], ('--link', 'U+0001')),
        ([good, '--mass', '10', '--link', 'a\x1fb'], ('--link', 'U+001F')),
        ([good, '--mass', '10', '--link', 'a\ufffeb'], ('--link', 'U+FFFE')),
        ([good, '--mass', '10', '--link', 'l' * 100_000], ('--link', 'at most 256')),
    ]
    for extra, pieces in cases:
        _refused(*_estimate(capsys, DEFAULT_BAG, '--urdf', *extra), *pieces)
    assert list(tmp_path.iterdir()) == []


def test_dangling_symlink_is_never_followed(tmp_path: Path,
                                            capsys: pytest.CaptureFixture) -> None:
    """An output that is a dangling symbolic link is refused (even with --force): the file
    it points to is not created."""
    target = tmp_path / 'elsewhere' / 'target.urdf'
    target.parent.mkdir()
    for opt, name in (('--urdf', 'b.urdf'), ('-o', 'r.txt'), ('--plot', 'p.png')):
        link = tmp_path / name
        link.symlink_to(target)
        extra = ['--mass', '10'] if opt == '--urdf' else []
        for force in ([], ['--force']):
            _refused(*_estimate(capsys, DEFAULT_BAG, opt, link, *extra, *force), opt,
                     'dangling symbolic link')
        assert not target.exists() and link.is_symlink()


def test_force_replaces_a_link_not_its_target(tmp_path: Path,
                                              capsys: pytest.CaptureFixture) -> None:
    """--force over a symbolic link to a file replaces the link with the new file; the file
    the link pointed to keeps its content."""
    target = tmp_path / 'keep.txt'
    target.write_text('keep me')
    link = tmp_path / 'report.txt'
    link.symlink_to(target)
    code, _, err = _estimate(capsys, DEFAULT_BAG, '-o', link, '--force')
    assert code == 0, err
    assert target.read_text() == 'keep me'
    assert not link.is_symlink() and 'status: ok' in link.read_text()


def test_unwritable_directory_refused_before_the_report(tmp_path: Path,
                                                        capsys: pytest.CaptureFixture) -> None:
    """A directory the process cannot write in is refused before any work (a probe file is
    created and removed, so this holds for root and read-only mounts too)."""
    if Path('/proc').is_dir():
        _refused(*_estimate(capsys, DEFAULT_BAG, '--urdf', '/proc/x.urdf', '--mass', '1'),
                 '--urdf /proc/x.urdf', 'cannot be written')
    if os.geteuid() != 0:
        ro = tmp_path / 'ro'
        ro.mkdir()
        ro.chmod(0o555)
        try:
            _refused(*_estimate(capsys, DEFAULT_BAG, '--plot', ro / 'p.png'), '--plot',
                     'cannot be written')
        finally:
            ro.chmod(0o755)


def test_two_options_one_file_and_unknown_plot_type(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture) -> None:
    """-o and --plot naming one file, and a --plot suffix matplotlib cannot write, are
    refused up front."""
    same = tmp_path / 'x.png'
    _refused(*_estimate(capsys, DEFAULT_BAG, '-o', same, '--plot', same), 'the same file')
    _refused(*_estimate(capsys, DEFAULT_BAG, '--plot', tmp_path / 'x.xyz'), '--plot',
             "'.xyz'")
    assert list(tmp_path.iterdir()) == []


def test_special_file_output_is_written(capsys: pytest.CaptureFixture) -> None:
    """An existing special file (/dev/null) is written as a stream, without --force."""
    if not Path('/dev/null').exists():
        pytest.skip('no /dev/null')
    code, out, err = _estimate(capsys, DEFAULT_BAG, '-o', '/dev/null')
    assert (code, out, err) == (0, '', '')


def test_status_without_tensor_writes_no_urdf_and_exits_0(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture
                                                          ) -> None:
    """estimate bags/torque_free.mcap --urdf tf.urdf --mass 10 prints the report, says on
    stderr (one line) that the URDF is not written, and exits 0 (a report was produced)."""
    out = tmp_path / 'tf.urdf'
    code, stdout, err = _estimate(capsys, BAGS / 'torque_free.mcap', '--urdf', out,
                                  '--mass', '10')
    assert code == 0
    assert 'status: scale_unobservable' in stdout
    lines = err.strip().splitlines()
    assert len(lines) == 1 and 'not written' in lines[0] and 'scale_unobservable' in lines[0]
    assert not out.exists()


# ------------------------------------------------------------------ URDF text


def test_urdf_is_well_formed_whatever_the_log_name(tmp_path: Path) -> None:
    """The provenance comment carries the log's path; control characters in it are escaped,
    so the document stays well-formed XML (and names are refused in the library too)."""
    from inertia_ros.io.urdf import urdf_document, write_urdf

    text = urdf_document(np.eye(3), 1.0, comment='log a\x01b\x1f\ufffe-- end')
    assert ET.fromstring(text).find('link').get('name') == 'base_link'
    assert '\\x01' in text and '\\x1f' in text
    for bad in ('a\x01', '\x1f', 'x\ufffe', 'a\ud800', '\x7f', '\x85'):
        with pytest.raises(ValueError, match='control character'):
            urdf_document(np.eye(3), 1.0, link=bad)
    with pytest.raises(ValueError, match='control character'):
        urdf_document(np.eye(3), 1.0, robot='r\x02')
    link = tmp_path / 'dangling.urdf'
    link.symlink_to(tmp_path / 'nowhere.urdf')
    with pytest.raises(ValueError, match='dangling'):
        write_urdf(link, np.eye(3), 1.0)
    assert not (tmp_path / 'nowhere.urdf').exists()


# ------------------------------------------------------------------ --plot with wheels/rotors


@pytest.mark.parametrize('bag, opt, spec', [
    ('wheels', '--wheels', 'wheels_wheels.yaml'),
    ('quadrotor', '--rotors', 'quadrotor_rotors.yaml'),
])
def test_plot_with_wheels_and_rotors(bag: str, opt: str, spec: str, tmp_path: Path,
                                     capsys: pytest.CaptureFixture) -> None:
    """--plot is drawn for --wheels and --rotors runs, and the report is written too."""
    if not (BAGS / f'{bag}.mcap').exists():
        pytest.skip(f'bags/{bag}.mcap absent')
    png, rep = tmp_path / 'fig.png', tmp_path / 'r.txt'
    code, out, err = _estimate(capsys, BAGS / f'{bag}.mcap', opt, BAGS / spec, '--plot', png,
                               '-o', rep)
    assert code == 0, err
    assert 'status: ok' in rep.read_text()
    data = png.read_bytes()
    assert data[:8] == PNG and len(data) > 50_000


def test_momentum_view_satisfies_the_body_equation() -> None:
    """The equivalent torque the wheels figure draws is the body's own Euler torque: for a
    simulated wheel run, the window means of the model torque with the true tensor match
    the equivalent torque's to 2 % of its RMS."""
    from inertia_ros.cli.report import momentum_view, window_torques
    from inertia_ros.core.estimation.momentum import Wheel, wheels_momentum
    from inertia_ros.io.logs import LogData, Stream, StreamCounts

    I = np.diag([1.0, 1.5, 2.0])
    wheel = Wheel('w', np.array([0.0, 0.0, 1.0]), 0.05)
    t = np.arange(0.0, 20.0, 0.002)
    speed = 50.0 * np.sin(0.7 * t)[:, None]                       # wheel speed [rad/s]
    h = wheels_momentum(t, speed, [wheel])
    # body at rest in x, y; about z: (I_zz) w_z' = -h_z'  ->  w_z = -h_z / I_zz
    w = np.zeros((len(t), 3))
    w[:, 2] = -h.h[:, 2] / I[2, 2]
    empty = Stream('', '', 'base_link', np.zeros(0), np.zeros((0, 3)), StreamCounts())
    log = LogData([Path('x.mcap')], 0, Stream('/imu', 'Imu', 'base_link', t, w,
                                               StreamCounts()), empty, [(0.0, 20.0)])
    view = momentum_view(log, h)

    class Est:
        inertia, torque_bias, inertial_torque = I, None, None

    _, meas, model = window_torques(Est, view.omega.t, view.omega.values, view.torque.t,
                                    view.torque.values, 'zoh', 0.5)
    # torque-free body: the equivalent torque (-dh/dt) equals I dw/dt, both ~ 0.05*35*0.7
    assert np.sqrt(np.mean(meas[:, 2] ** 2)) > 0.5
    assert np.max(np.abs(meas - model)) < 0.02 * np.sqrt(np.mean(meas[:, 2] ** 2))


# ------------------------------------------------------------------ text report and messages


def test_text_report_reason_and_remedy(capsys: pytest.CaptureFixture) -> None:
    """model_mismatch prints diagnostics.reason and suggests --nuisance auto; with the
    nuisance terms fitted it no longer suggests them."""
    if not (BAGS / 'gyro_bias.mcap').exists():
        pytest.skip('bags/gyro_bias.mcap absent')
    code, out, _ = _estimate(capsys, BAGS / 'gyro_bias.mcap')
    assert code == 0 and 'status: model_mismatch' in out
    assert 'reason: the model does not explain the data' in out
    assert 'remedy: try --nuisance auto' in out
    code, out, _ = _estimate(capsys, BAGS / 'gyro_bias.mcap', '--nuisance', 'auto')
    assert code == 0 and 'remedy: try --nuisance auto' not in out


def test_text_report_names_undetermined_elements(capsys: pytest.CaptureFixture) -> None:
    """partially_identifiable names the undetermined elements (as the JSON does), in the
    reason and in the tensor, instead of 'n/a'."""
    import json

    if not (BAGS / 'single_axis.mcap').exists():
        pytest.skip('bags/single_axis.mcap absent')
    code, out, _ = _estimate(capsys, BAGS / 'single_axis.mcap', '--format', 'json')
    rep = json.loads(out)
    assert rep['status'] == 'partially_identifiable'
    names = rep['diagnostics']['undetermined']
    code, out, _ = _estimate(capsys, BAGS / 'single_axis.mcap')
    assert code == 0 and 'n/a' not in out
    reason = next(line for line in out.splitlines() if line.startswith('reason:'))
    assert all(n in reason for n in names)
    cells = sum(line.count('undetermined') for line in out.splitlines()
                if line.startswith('  ['))
    assert cells == sum(1 if n[1] == n[2] else 2 for n in names)   # ixy is also iyx


def test_torque_none_header_and_scale_reason(capsys: pytest.CaptureFixture) -> None:
    """--torque-topic none prints 'torque none (...)' rather than an empty topic, and the
    scale_unobservable report prints its reason."""
    code, out, _ = _estimate(capsys, BAGS / 'torque_free.mcap', '--torque-topic', 'none')
    assert code == 0
    assert '  torque none (torque-free data' in out and "torque  (," not in out
    assert 'reason: no torque excitation' in out


def test_jointstate_hint_names_rotors_too(capsys: pytest.CaptureFixture) -> None:
    """A log with JointState but neither --wheels nor --rotors hints at both options."""
    if not (BAGS / 'quadrotor.mcap').exists():
        pytest.skip('bags/quadrotor.mcap absent')
    _, out, _ = _estimate(capsys, BAGS / 'quadrotor.mcap')
    hint = next(line for line in out.splitlines() if 'JointState in the log' in line)
    assert '--wheels WHEELS.yaml' in hint and '--rotors ROTORS.yaml' in hint


def test_plot_time_axis_is_a_readable_utc_time() -> None:
    """The x-axis origin of the figure reads as a UTC date, not a nanosecond stamp."""
    from inertia_ros.cli.plots import epoch_text

    assert epoch_text(1_704_067_200_000_000_000) == '2024-01-01 00:00:00.000 UTC'
    assert epoch_text(1_704_067_200_123_456_789) == '2024-01-01 00:00:00.123 UTC'
    assert epoch_text(2_500_000_000) == 'stamp 2.500 s'            # a simulation clock
    assert epoch_text(2 ** 63 - 1).startswith('2262-')
    assert epoch_text(10 ** 30).startswith('stamp 1')           # out of the calendar


def test_usage_names_the_invoked_program() -> None:
    """``inertia-ros --help`` says ``usage: inertia-ros``; ``python -m inertia_ros`` keeps
    its name."""
    assert program_name('/usr/local/bin/inertia-ros') == 'inertia-ros'
    assert program_name(str(ROOT / 'inertia_ros' / '__main__.py')) == 'python -m inertia_ros'
    assert program_name('') == 'python -m inertia_ros'
    script = Path(sys.executable).parent / 'inertia-ros'
    if script.exists():
        import subprocess

        proc = subprocess.run([str(script), 'estimate', '--help'], capture_output=True,
                              text=True, check=False, timeout=60)
        assert proc.returncode == 0 and proc.stdout.startswith('usage: inertia-ros estimate')


def test_remedy_never_suggests_an_option_that_would_be_refused() -> None:
    """A model_mismatch of a --wheels/--rotors run does not suggest --nuisance (refused with
    them); a torque run that already fitted nuisance terms is not told to fit them."""
    from inertia_ros.cli.report import remedy

    reason = ('the model does not explain the data: window estimates disagree (chi2 99 on 18 '
              'dof, p = 1e-12): a drifting tensor, a gyro bias or an unmodelled torque')
    base = {'status': 'model_mismatch', 'diagnostics': {'reason': reason}}
    assert '--nuisance auto' in remedy(base)
    wheels = {'status': 'model_mismatch',
              'diagnostics': {'reason': reason + '; or wheel inertias / rotor coefficients off',
                              'wheels': {'file': 'w.yaml'}}}
    assert '--nuisance auto' not in remedy(wheels) and 'wheel inertias' in remedy(wheels)
    fitted = {'status': 'model_mismatch',
              'diagnostics': {'reason': reason, 'nuisance': {'chosen': ['gyro_bias']}}}
    assert remedy(fitted) is None
    assert remedy({'status': 'ok', 'diagnostics': {'reason': reason}}) is None


def test_no_input_is_an_output_even_with_force(tmp_path: Path,
                                               capsys: pytest.CaptureFixture) -> None:
    """The log and the --wheels YAML are inputs: -o, --plot or --urdf naming one of them is
    refused even with --force, before any work, and the file is unchanged."""
    if not (BAGS / 'wheels.mcap').exists():
        pytest.skip('bags/wheels.mcap absent')
    spec = tmp_path / 'wheels.yaml'
    spec.write_bytes((BAGS / 'wheels_wheels.yaml').read_bytes())
    before = spec.read_bytes()
    for opt in ('-o', '--plot', '--urdf'):
        target = spec if opt != '--plot' else tmp_path / 'link.png'
        if opt == '--plot':
            target.symlink_to(spec)                     # a link to the input is the input
        extra = ['--mass', '1'] if opt == '--urdf' else []
        _refused(*_estimate(capsys, BAGS / 'wheels.mcap', '--wheels', spec, opt, target,
                            *extra, '--force'), opt, 'refusing to overwrite the --wheels file')
    assert spec.read_bytes() == before


def test_options_without_their_companion_are_refused(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture) -> None:
    """--mass, --com, --link without --urdf and --wheel-topic / --rotor-topic without
    --wheels / --rotors did nothing and said nothing; now one line naming both, exit 2, no
    report (and no file written)."""
    cases = [(['--mass', '3'], '--urdf'), (['--com', '0', '0', '0.1'], '--urdf'),
             (['--link', 'body'], '--urdf'), (['--wheel-topic', '/js'], '--wheels'),
             (['--rotor-topic', '/js'], '--rotors')]
    for extra, companion in cases:
        _refused(*_estimate(capsys, DEFAULT_BAG, *extra, '-o', str(tmp_path / 'r.txt')),
                 extra[0], f'only used with {companion} FILE')
        assert not (tmp_path / 'r.txt').exists()
    code, out, _ = _estimate(capsys, DEFAULT_BAG, '--link', 'base_link', '--format', 'json')
    assert code == 0 and '"status"' in out       # the default, spelled out, is harmless
