"""The inertial torque's contract (issue 27, docs/dev/inertial_torque_design.md section 6):
the result field and JSON key, the model string, the CLI option, the text report and the
residual plot."""
from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import ROOT
from inertia_ros.bench.honesty import CASES
from inertia_ros.bench.truth_sim import simulate_truth
from inertia_ros.cli import main
from inertia_ros.core.estimation import estimate
from inertia_ros.core.estimation.model import model_name, model_parts
from inertia_ros.core.tensor import THETA_COLS, THETA_ROWS

BAG = ROOT / 'bags' / 'disturbance.mcap'
needs_bag = pytest.mark.skipif(not BAG.exists(), reason='bags/disturbance.mcap absent')


def _record(seed: int, scene: str = 'inertial', duration: float = 5.0):
    case = CASES['disturbance'].truth.with_(duration=duration)
    if scene == 'zero':
        case = case.with_(disturbance=(0.0, 0.0, 0.0))
    return simulate_truth(case, [seed])[0]


def _z_err(e, rec) -> tuple[np.ndarray, float]:
    z = (e.theta - rec.inertia_end[THETA_ROWS, THETA_COLS]) / e.theta_std
    err = np.linalg.norm(e.inertia - rec.inertia_end) / np.linalg.norm(rec.inertia_end)
    return z, float(err)


@pytest.mark.parametrize(('name', 'parts'), [
    ('full', ('full', False, False)), ('diagonal+bias', ('diagonal', True, False)),
    ('full+bias+inertial', ('full', True, True)), ('axisymmetric+inertial',
                                                   ('axisymmetric', False, True)),
    (None, ('full', False, False)), ('homogeneous', ('homogeneous', False, False))])
def test_model_parts_splits_every_model_string(name, parts) -> None:
    assert model_parts(name) == parts
    if name not in (None, 'homogeneous'):
        assert model_name(*parts) == name


def run_json(capsys, *args: str) -> tuple[int, dict | None, str]:
    code = main(['estimate', *args, '--format', 'json', '--no-progress'])
    out, err = capsys.readouterr()
    return code, (json.loads(out) if out.strip() else None), err


@needs_bag
def test_json_key_is_null_by_default_and_three_numbers_with_on(capsys) -> None:
    code, rep, err = run_json(capsys, str(BAG), '--method', 'integral')
    assert code == 0, err
    assert 'inertial_torque' in rep and rep['inertial_torque'] is None
    assert '+inertial' not in rep['model']
    code, rep, err = run_json(capsys, str(BAG), '--method', 'integral', '--inertial-torque', 'on')
    assert code == 0, err
    d = rep['inertial_torque']
    assert isinstance(d, list) and len(d) == 3 and all(isinstance(v, float) for v in d)
    assert rep['model'].endswith('+inertial')
    assert len(rep['diagnostics']['inertial_torque_std']) == 3
    assert rep['diagnostics']['disturbance']['chosen'] in ('inertial', 'both')
    assert 'first gyro sample of the epoch' in rep['diagnostics']['disturbance']['frame']


@needs_bag
def test_text_report_says_the_frame_in_words(capsys) -> None:
    code = main(['estimate', str(BAG), '--method', 'integral', '--inertial-torque', 'on',
                 '--no-progress'])
    out = capsys.readouterr().out
    assert code == 0
    line = [x for x in out.splitlines() if 'fixed in inertial axes' in x]
    assert len(line) == 1 and 'body axes at the first gyro sample of the epoch' in line[0]
    assert ' ± [' in line[0]


@pytest.mark.parametrize('value', ['maybe', 'ON', ''])
def test_a_bad_cli_value_is_one_line_exit_2(value: str, capsys) -> None:
    code = main(['estimate', str(BAG), '--inertial-torque', value, '--no-progress'])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count('\n') == 1 and '--inertial-torque' in err and 'invalid choice' in err


def test_the_fleet_takes_the_option_as_estimate_does() -> None:
    """fleet copies estimate's options: the option passes through to every log's run."""
    import argparse

    from inertia_ros.cli.fleet import _add_estimate_options, estimate_flags
    p = argparse.ArgumentParser()
    _add_estimate_options(p)
    args = p.parse_args(['--inertial-torque', 'auto'])
    assert estimate_flags(args) == ['--inertial-torque', 'auto']
    assert estimate_flags(p.parse_args([])) == []


def test_residual_plot_removes_the_inertial_torque() -> None:
    """The --plot residual (window means) subtracts ``R(t)' d``: its RMS drops well below
    the same estimate's residual without the term (1 s windows: the 0.25 s ones are mostly
    the differentiated gyro's noise)."""
    from dataclasses import replace

    from inertia_ros.cli.report import window_torques
    rec = _record(31)
    e = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque, method='integral',
                 inertial_torque='on', torque_bias='off')

    def rms(est) -> float:
        _, meas, model = window_torques(est, rec.t_gyro, rec.omega, rec.t_torque, rec.torque,
                                        'zoh', 1.0)
        return float(np.sqrt(np.mean((meas - model) ** 2)))
    with_term, without = rms(e), rms(replace(e, inertial_torque=None))
    # measured 1 s windows: 0.0030 N m with the term, 0.0101 without, 0.0195 with -d
    assert with_term < 0.4 * without, (with_term, without)
