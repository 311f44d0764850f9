"""The benchmark home: ``bench`` subcommands, one colour and name per method, start-up."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

from conftest import ROOT
from inertia_ros.bench.methods import method_of, method_specs
from inertia_ros.bench.plots import METHOD_STYLE, method_colour, setting_markers
from inertia_ros.cli import build_parser, main
from inertia_ros.core.estimation.options import METHODS

BASELINES = ('recursive', 'hand_fd', 'pinocchio')


def test_every_setting_is_named_after_its_method() -> None:
    """Setting names are ``METHOD`` or ``METHOD/VARIANT`` with METHOD a --method name or a
    baseline; the table gives each method one colour and a legend name equal to it."""
    specs, _ = method_specs(include_pinocchio=False)
    names = [s.name for s in specs]
    assert len(set(names)) == len(names)
    for s in specs:
        assert s.method in METHODS or s.method in BASELINES, s.name
        assert s.method in METHOD_STYLE, s.name
        assert method_colour(s.name) == METHOD_STYLE[s.method][0]
    for key, (_colour, label) in METHOD_STYLE.items():
        assert label == key
    colours = [c for c, _ in METHOD_STYLE.values()]
    assert len(set(colours)) == len(colours), 'two methods share a colour'
    assert {'ml', 'integral', 'integral_ls', 'integral_sliding', 'differential_fd',
            'differential_sg'} <= set(METHOD_STYLE)


def test_variants_share_the_colour_but_not_the_marker() -> None:
    """Within one method each setting gets its own marker; the plain setting gets 'o'."""
    names = ['integral', 'integral/full', 'integral/seg5s', 'ml', 'integral_sliding/1s',
             'integral_sliding/4s']
    m = setting_markers(names)
    assert m['integral'] == 'o' and m['ml'] == 'o'
    assert len({m[n] for n in names if method_of(n) == 'integral'}) == 3
    assert m['integral_sliding/1s'] != m['integral_sliding/4s']


@pytest.mark.parametrize('argv, attrs', [
    (['bench', '--quick', '--out', 'x'], {'kind': None, 'quick': True, 'out': 'x'}),
    (['bench', 'offline', '--minutes', '2', '--skip-slow'],
     {'kind': 'offline', 'minutes': 2.0, 'skip_slow': True}),
    (['bench', 'node', '--rate', '500'], {'kind': 'node', 'rate': 500.0}),
    (['bench', 'node', '--rate', '8000', '--torque-rate', '1000'],
     {'kind': 'node', 'rate': 8000.0, 'torque_rate': 1000.0}),
    (['bench', 'recursive', '--duration', '5'], {'kind': 'recursive', 'duration': 5.0}),
    (['bench', 'estimators', '--quick', '--seeds', '2'], {'kind': 'estimators', 'seeds': 2}),
    (['bench', 'simulate', '--repeat', '1'], {'kind': 'simulate', 'repeat': 1}),
    (['bench', 'startup', '--repeat', '3'], {'kind': 'startup', 'repeat': 3}),
    (['bench', 'honesty', '--seeds', '2', '--paths', 'api'],
     {'kind': 'honesty', 'seeds': 2, 'paths': 'api'}),
])
def test_bench_subcommands_parse(argv: list[str], attrs: dict) -> None:
    """Each focused benchmark is a subcommand of ``bench``; the suite needs none."""
    args = build_parser('bench').parse_args(argv)
    for k, v in attrs.items():
        assert getattr(args, k) == v


@pytest.mark.parametrize('argv, piece', [
    (['bench', 'offline', '--minutes', '1e9'], '--minutes: must be within [0.5, 600] min'),
    (['bench', 'node', '--rate', '0'], '--rate: must be within [1, 20000] Hz'),
    (['bench', 'recursive', '--duration', 'inf'], '--duration: must be within [1, 3600] s'),
    (['bench', 'startup', '--repeat', '0'], '--repeat: must be within [1, 100] runs'),
    (['bench', 'estimators', '--seeds', '1.5'], '--seeds: must be an integer'),
])
def test_bench_options_have_ranges(argv: list[str], piece: str,
                                   capsys: pytest.CaptureFixture) -> None:
    """Absurd values are one line naming the option, its range and unit; exit 2."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and piece in err, err


def test_bench_honesty_unknown_case_is_one_line(capsys: pytest.CaptureFixture) -> None:
    """An unknown honesty case is one line listing the known ones."""
    assert main(['bench', 'honesty', '--cases', 'clean,nope']) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and 'unknown nope; known: clean' in err


def test_every_status_has_a_text() -> None:
    """The text report explains every status of the contract."""
    from inertia_ros.cli.report import STATUS_TEXT
    from inertia_ros.core.estimation.options import STATUSES

    assert set(STATUS_TEXT) == set(STATUSES)


def test_bench_simulate_runs(capsys: pytest.CaptureFixture) -> None:
    """``bench simulate`` prints the three timings and the verdict."""
    assert main(['bench', 'simulate', '--repeat', '1']) == 0
    out = capsys.readouterr().out
    for piece in ('simulate        best', 'write           best', 'simulate+write  best',
                  'target simulate+write < 2 s'):
        assert piece in out


def test_bench_simulate_missing_scene_is_one_line(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture) -> None:
    """A missing scene file is a one-line error."""
    assert main(['bench', 'simulate', str(tmp_path / 'none.yaml')]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and 'no such scene file' in err


def test_startup_figures(monkeypatch: pytest.MonkeyPatch) -> None:
    """``bench startup`` times whole processes: every case exits 0 and is timed ``repeat``
    times (a smoke test; the < 0.3 s target is a measurement, not a test)."""
    from inertia_ros.bench import startup

    monkeypatch.setattr(startup, 'CASES', startup.CASES[:2] + startup.CASES[3:])
    figs = startup.measure(repeat=2)
    assert [f.name for f in figs] == ['estimate --help', '--version', 'python -c pass']
    for f in figs:
        assert f.ok and len(f.seconds) == 2 and all(0 < t < 30 for t in f.seconds)
    assert figs[0].target == 0.3 and figs[1].met is None


def test_bench_offline_small_log(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """``bench offline`` on a half-minute log: our stages read every message and the
    end-to-end estimate is ok; results go to --json."""
    import json

    out = tmp_path / 'r.json'
    assert main(['bench', 'offline', '--minutes', '0.5', '--skip-slow',
                 '--json', str(out)]) == 0
    res = {r['stage']: r for r in json.loads(out.read_text())['results']}
    assert set(res) == {'ours_read', 'ours_end_to_end', 'mcap_raw'}
    assert res['ours_read']['messages'] == 7500 == res['mcap_raw']['messages']
    assert res['ours_end_to_end']['status'] == 'ok'
    assert 'end-to-end is' in capsys.readouterr().out


def test_paired_record_timing_against_a_tree(capsys: pytest.CaptureFixture) -> None:
    """``bench.estimators --vs TREE`` times the nominal record in both trees, alternating
    (here the tree against itself: every call timed, both sides alike within 3x)."""
    from inertia_ros.bench.estimators import PAIRED_CALLS, bench_paired

    res = bench_paired(str(ROOT), runs=3, rounds=1)
    assert len(res['this']) == len(res['other']) == 1
    for label in PAIRED_CALLS:
        a, b = res['other'][0][label], res['this'][0][label]
        assert a > 0 and b > 0 and 1 / 3 < a / b < 3, (label, a, b)
    assert 'x' in capsys.readouterr().out.splitlines()[-1]


def test_paired_timing_refuses_a_non_tree_in_one_line(tmp_path: Path,
                                                      capsys: pytest.CaptureFixture) -> None:
    """``--vs`` on a directory that is no source tree: a one-line error, exit 2."""
    from inertia_ros.bench.estimators import main as est_main

    with pytest.raises(SystemExit) as exc:
        est_main(['--vs', str(tmp_path)])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert f'--vs {tmp_path}: not a source tree of inertia_ros' in err


def test_no_benchmark_scripts_left_and_no_old_issue_numbers() -> None:
    """The benchmarks live in inertia_ros/bench only; their docstrings cite no issue."""
    assert not list((ROOT / 'scripts').glob('bench_*.py'))
    for p in sorted((ROOT / 'inertia_ros' / 'bench').glob('*.py')) + [
            ROOT / 'inertia_ros' / 'cli' / 'bench.py']:
        tree = ast.parse(p.read_text())
        for node in ast.walk(tree):
            doc = (ast.get_docstring(node) if isinstance(
                node, (ast.Module, ast.FunctionDef, ast.ClassDef)) else None)
            assert doc is None or 'issue' not in doc.lower(), p


def test_functions_in_cli_and_bench_are_short() -> None:
    """No function over 80 lines in cli/ or bench/."""
    long = []
    for p in sorted((ROOT / 'inertia_ros' / 'cli').glob('*.py')) + sorted(
            (ROOT / 'inertia_ros' / 'bench').glob('*.py')):
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > 80:
                    long.append(f'{p.name}:{node.name} {n}')
    assert long == []


def test_node_bench_schedule_and_latency_at_unequal_rates():
    """bench node at 8 kHz gyro + 1 kHz torque: every message sent once in due order, and a
    latency measured from the last message carrying the estimate's stamp."""
    import numpy as np

    from inertia_ros.bench.node import latencies_ms, schedule

    due, stream, index = schedule(80, 10, 125_000, 1_000_000)
    assert due.size == 90 and np.all(np.diff(due) >= 0)
    assert sorted(index[stream == 0]) == list(range(80))
    assert sorted(index[stream == 1]) == list(range(10))
    torque_due = due[stream == 1]
    assert np.array_equal(torque_due, np.arange(10) * 1_000_000 + 62_500)
    send = np.arange(due.size, dtype=np.int64) * 1000 + 5_000_000
    epoch = 10**18
    stamps = np.array([epoch + due[7], epoch + torque_due[3], epoch + 1])  # last: no such
    lat = latencies_ms(stamps, np.full(3, 9_000_000, np.int64), epoch, due, send)
    i_t = int(np.flatnonzero((stream == 1) & (index == 3))[0])
    assert np.allclose(lat, [(9_000_000 - send[7]) * 1e-6, (9_000_000 - send[i_t]) * 1e-6])


def test_node_bench_publisher_lateness():
    """The publisher's timing in bench node: lateness quantiles [ms] and the longest run of
    consecutive sends more than one period late (a catch-up burst)."""
    import numpy as np

    from inertia_ros.bench.node import lateness_summary

    period = 125_000
    late = np.array([0, 10_000, 200_000, 300_000, 0, 130_000, 126_000, 125_001, 5, 0],
                    dtype=np.int64)
    s = lateness_summary(late, period)
    assert s['longest_late_run'] == 3                   # 130 000, 126 000, 125 001
    assert s['max_ms'] == 0.3
    assert s['median_ms'] == round(float(np.median(late)) * 1e-6, 3)
    assert lateness_summary(np.zeros(4, np.int64), period)['longest_late_run'] == 0
    assert lateness_summary(np.full(3, period + 1), period)['longest_late_run'] == 3
