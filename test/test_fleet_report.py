"""The fleet report (issue 29 item 9): vehicles without a tensor, logs without an estimate,
counts in words, logs that share a start time."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from inertia_ros.core.tensor import THETA_NAMES
from inertia_ros.fleet import report as fleet_report
from inertia_ros.fleet.report import write_report

pytest.importorskip('matplotlib')

T0 = 1_704_067_200_000_000_000  # 2024-01-01T00:00:00Z, where every sample bag starts


def _row(path: str, vehicle: str, status: str = 'ok', start: int | None = T0,
         ixx: float = 1.0, std: float = 0.01, **extra: Any) -> dict[str, Any]:
    r: dict[str, Any] = {'path': path, 'vehicle': vehicle, 'status': status,
                         'log_start_ns': start, 'log_start': None, 'reason': None,
                         'error': None}
    tensor = status in ('ok', 'model_mismatch', 'partially_identifiable')
    for n in THETA_NAMES:
        r[n] = (ixx if n == 'ixx' else 2.0 if n in ('iyy', 'izz') else 0.0) if tensor else None
        r[n + '_std'] = std if tensor else None
    for k in (1, 2, 3):
        r[f'I{k}'] = (ixx if k == 1 else 2.0) if tensor else None
        r[f'I{k}_std'] = std if tensor else None
    r.update(extra)
    return r


@pytest.fixture
def figures(monkeypatch: pytest.MonkeyPatch) -> dict[str, Any]:
    """The figure of each trend PNG written, by file name (kept open for inspection)."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    seen: dict[str, Any] = {}
    real_close = plt.close

    def keep(fig: Any = None) -> None:
        if fig is not None and hasattr(fig, 'axes'):
            seen[Path(getattr(fig, '_saved_to', 'x')).name] = fig
            return
        real_close(fig)

    real_savefig = matplotlib.figure.Figure.savefig

    def savefig(self: Any, fname: Any, *a: Any, **k: Any) -> None:
        self._saved_to = str(fname)
        real_savefig(self, fname, *a, **k)

    monkeypatch.setattr(plt, 'close', keep)
    monkeypatch.setattr(matplotlib.figure.Figure, 'savefig', savefig)
    yield seen
    for fig in seen.values():
        real_close(fig)


def test_report_of_copies_and_logs_without_an_estimate(tmp_path: Path,
                                                       figures: dict[str, Any]) -> None:
    """Copies of sample bags (one start instant) are ordered by path and plotted against
    the log number (they were stacked at one instant); a vehicle with no tensor has no
    plot (it had an empty one on a 1970 axis); every log without a tensor is listed with
    why (only error rows were); "1 outlier" is singular."""
    rows = [
        _row('/f/sat-a/c.mcap', 'sat-a', ixx=1.5),  # jumps from b: the one outlier
        _row('/f/sat-a/a.mcap', 'sat-a'),
        _row('/f/sat-a/b.mcap', 'sat-a'),
        _row('/f/sat-a/d.mcap', 'sat-a', 'insufficient_excitation',
             reason='excitation too weak on axis z'),
        _row('/f/sat-b/x.mcap', 'sat-b', 'scale_unobservable',
             reason='no torque: the scale cannot be told'),
        _row('/f/sat-b/y.mcap', 'sat-b', 'error', start=None,
             error='y.mcap: not an MCAP file (empty file)'),
    ]
    md = write_report(rows, tmp_path).read_text()
    assert '6 logs, 2 vehicles, 1 outlier (' in md and '1 outliers' not in md
    assert sorted(p.name for p in tmp_path.glob('*.png')) == ['trend_sat-a.png']
    assert '| sat-b | 2 | 0 | 1 | 0 |  | none (no log with a tensor) |' in md
    assert '![sat-b]' not in md and '![sat-a](trend_sat-a.png)' in md
    without = md.split('## Logs without an estimate')[1].split('## Trends')[0]
    for line in ('| sat-a | /f/sat-a/d.mcap | insufficient_excitation | excitation too weak',
                 '| sat-b | /f/sat-b/x.mcap | scale_unobservable | no torque',
                 '| sat-b | /f/sat-b/y.mcap | error | y.mcap: not an MCAP file'):
        assert line in without, without
    assert 'Logs of sat-a share start times' in md and 'ordered by path' in md
    outlier = md.split('## Outliers')[1].split('## Vehicles')[0]
    assert '| sat-a | /f/sat-a/c.mcap |' in outlier and '| /f/sat-a/b.mcap |' in outlier
    ax = figures['trend_sat-a.png'].axes[-1]
    assert 'log number' in ax.get_xlabel()
    lo, hi = ax.get_xlim()
    assert 0 < lo < 1 and 3 < hi < 5  # logs 1-3 (4 is the one without a tensor), not 1970
    xs = sorted(ax.lines[0].get_xdata())
    assert list(xs) == [1, 2, 3]


def test_distinct_start_times_stay_on_a_time_axis(tmp_path: Path,
                                                  figures: dict[str, Any]) -> None:
    """Logs that start at different instants are plotted against the UTC start time."""
    day = 86_400 * 10 ** 9
    rows = [_row(f'/f/v/{i}.mcap', 'v', start=T0 + i * day) for i in range(3)]
    md = write_report(rows, tmp_path).read_text()
    assert '3 logs, 1 vehicle, 0 outliers' in md and 'share start times' not in md
    ax = figures['trend_v.png'].axes[-1]
    assert ax.get_xlabel() == 'log start (UTC)'
    import matplotlib.dates as mdates

    lo, hi = (mdates.num2date(x) for x in ax.get_xlim())
    assert 2023 <= lo.year <= hi.year <= 2024  # around 2024-01-01 to 03, not 1970


def test_start_times_tell_logs_apart_only_when_distinct() -> None:
    """The x axis decision: start times tell logs apart only when all known and distinct."""
    assert fleet_report._distinct_times([_row('a', 'v', start=1), _row('b', 'v', start=2)])
    assert not fleet_report._distinct_times([_row('a', 'v'), _row('b', 'v')])
    assert not fleet_report._distinct_times([_row('a', 'v', start=None)])
