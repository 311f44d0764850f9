"""``python -m inertia_ros demo``: the live demo over DDS (``make demo``).

Starts the scene simulator and the inertia estimator as two separate processes, subscribes
to their topics from this process, prints a small live table (estimate against truth,
status), then writes into ``--out``:

- ``demo_<scene>_<time>.mcap``: the run's topics as received (rosbag2-compatible MCAP; the
  topics whose message types the MCAP writer has schemas for),
- ``demo_<scene>_<time>.png``: the six tensor elements converging to the truth, each with
  its 2-sigma band, and each element's error in % of trace/3 of the truth with its 2-sigma
  band (zoomed onto the converged part, where a band at full scale would be invisible),
- ``demo_<scene>_<time>.log``: the two nodes' console output.

Existing files are never overwritten: a numeric suffix is added.  Errors are normalised as
in ``estimate --plot``: by trace/3 of the true tensor (the mean principal moment).  The live
table shows what the PNG plots, the six tensor elements (a ``truth`` row whenever the truth
changes), with ``max_ij |I_est - I_true| / (trace(I_true)/3)`` and the largest element error
in sigmas (element sigmas from ``~/inertia_covariance``); a row is printed only when it
differs from the previous one.  The final line gives the same error and every estimated
principal moment with its 1-sigma standard error (``~/principal_moments_std``).  Exit status
0 when the run produced an estimate, 1 when it did not.
"""
from __future__ import annotations

import argparse
import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from inertia_ros.cli import UserError

DEFAULT_RATE = 4.0  # playback speed factor: the 60 s default scene runs in 15 s
MAX_RATE = 50.0
DISCOVERY_TIMEOUT = 30.0  # [s] longest wait for the estimator's outputs to be discovered


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``demo`` on the CLI's sub-parsers."""
    p = sub.add_parser(
        'demo', help='live demo: simulator + estimator over DDS, table, MCAP and PNG',
        description='Live demo over DDS: starts the scene simulator and the inertia estimator '
                    'as separate processes, prints estimate vs truth while the scene plays at '
                    '--rate times real time, then writes an MCAP of the run, a PNG of the '
                    'convergence and the nodes\' log into --out (never overwriting a file) '
                    'and prints the final error.')
    p.add_argument('--scene', default=None,
                   help='scene YAML (default: config/scenes/default.yaml)')
    p.add_argument('--rate', type=float, default=DEFAULT_RATE,
                   help=f'playback speed factor, (0, {MAX_RATE:g}] (default {DEFAULT_RATE:g})')
    p.add_argument('--out', default='demo_out',
                   help='output directory for the MCAP, PNG and log (default demo_out/)')
    p.add_argument('--seed', type=int, default=None, help="simulation seed (default: scene's)")
    p.add_argument('--domain-id', type=int, default=None,
                   help='ROS_DOMAIN_ID for the run (default: the environment\'s)')
    p.add_argument('--quiet', action='store_true', help='no live table, only the result')
    p.set_defaults(func=run)


def stop_processes(procs: list[subprocess.Popen], timeout: float = 5.0) -> None:
    """Interrupt every process (SIGINT, a clean ROS shutdown), then kill the stragglers.

    Parameters
    ----------
    procs : list of subprocess.Popen
        Node processes started by the demo (or a test).
    timeout : float
        How long each may take to exit after SIGINT [s].
    """
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
    for p in procs:
        try:
            p.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def wait_until_matched(spin: Callable[[], None], subscriptions: list[Any],
                       proc: subprocess.Popen, timeout: float) -> str:
    """Spin until every subscription is matched to a publisher: DDS discovery is done.

    A node's first outputs are lost to a subscriber that has not yet discovered it, and
    discovery between processes can take seconds on a loaded machine; so the demo (and the
    process tests) wait for the estimator's outputs to be matched before any data flows.

    Parameters
    ----------
    spin : callable
        Spins the subscribing node(s) once, briefly.
    subscriptions : list of rclpy.subscription.Subscription
        Subscriptions to the publishing process's topics.
    proc : subprocess.Popen
        The publishing process: its early exit ends the wait.
    timeout : float
        Longest wait [s].

    Returns
    -------
    str
        '' when all are matched, else what went wrong (one line).
    """
    end = time.monotonic() + timeout
    while True:
        missing = [s.topic_name for s in subscriptions if s.get_publisher_count() == 0]
        if not missing:
            return ''
        if proc.poll() is not None:
            return f'the publishing process exited (status {proc.returncode})'
        if time.monotonic() > end:
            return f'no publisher discovered on {", ".join(missing)} within {timeout:g} s'
        spin()


def _unique(path: Path) -> Path:
    """``path`` itself, or with the first free ``-N`` suffix: never overwrite a file."""
    if not path.exists():
        return path
    for k in range(1, 10000):
        cand = path.with_name(f'{path.stem}-{k}{path.suffix}')
        if not cand.exists():
            return cand
    raise UserError(f'no free file name like {path} in {path.parent}')


@dataclass
class _Run:
    """What the demo's own subscriber collected."""

    records: dict[str, list[tuple[int, bytes]]] = field(default_factory=dict)
    truth: list[tuple[int, np.ndarray]] = field(default_factory=list)
    est: list[tuple[int, np.ndarray]] = field(default_factory=list)
    #: std of [ixx, iyy, izz, ixy, ixz, iyz] [kg m^2] of the estimate stamped t [ns]
    est_std: list[tuple[int, np.ndarray]] = field(default_factory=list)
    #: principal-moment std [kg m^2] stamped t [ns]
    moments_std: list[tuple[int, np.ndarray]] = field(default_factory=list)
    status: str = 'waiting'
    message: str = ''
    counts: dict[str, str] = field(default_factory=dict)

    def gyro_span(self) -> float:
        """Header-stamp span of the gyro messages recorded so far [s] (0 before two)."""
        from inertia_ros.io import cdr_decode

        rows = self.records.get('/imu', [])
        if len(rows) < 2:
            return 0.0
        stamps = cdr_decode.decode_payloads(TOPICS['/imu'][0], [rows[0][1], rows[-1][1]],
                                            fields=()).stamp_ns
        return float(stamps[-1] - stamps[0]) * 1e-9


TOPICS = {
    # topic: (message type name, qos kind: see inertia_ros.nodes.recorder.KINDS)
    '/imu': ('sensor_msgs/msg/Imu', 'sensor_data'),
    '/torque': ('geometry_msgs/msg/WrenchStamped', 'sensor_data'),
    '/scene_simulator/truth': ('geometry_msgs/msg/InertiaStamped', 'latched'),
    '/inertia_estimator/inertia': ('geometry_msgs/msg/InertiaStamped', 'latched'),
    '/inertia_estimator/principal_moments': ('geometry_msgs/msg/Vector3Stamped', 'reliable'),
    '/inertia_estimator/principal_moments_std': ('geometry_msgs/msg/Vector3Stamped',
                                                 'reliable'),
    '/inertia_estimator/inertia_covariance': ('std_msgs/msg/Float64MultiArray', 'reliable'),
    '/inertia_estimator/principal_axes': ('geometry_msgs/msg/QuaternionStamped', 'reliable'),
    '/inertia_estimator/markers': ('visualization_msgs/msg/MarkerArray', 'reliable'),
    '/diagnostics': ('diagnostic_msgs/msg/DiagnosticArray', 'reliable'),
}
#: Name prefix of the estimator's diagnostic status ('<node name>: <task>').
ESTIMATOR_STATUS = 'inertia_estimator: '


#: Elements of the tensor in the table and the PNG: (row, column) and name.
ELEMENTS = (((0, 0), 'ixx'), ((1, 1), 'iyy'), ((2, 2), 'izz'), ((0, 1), 'ixy'),
            ((0, 2), 'ixz'), ((1, 2), 'iyz'))
#: What errors are divided by (the ``estimate --plot`` convention), as labelled.
ERROR_SCALE = 'trace/3'


def _scale(truth: np.ndarray) -> float:
    """trace(truth) / 3 [kg m^2]: the mean principal moment, the error normaliser."""
    return float(np.trace(truth)) / 3.0


def _error(est: np.ndarray, truth: np.ndarray) -> float:
    """max_ij |est - truth| / (trace(truth) / 3) [dimensionless]."""
    return float(np.max(np.abs(est - truth)) / _scale(truth))


def _truth_at(run: _Run, t_ns: int) -> np.ndarray | None:
    best = None
    for t, mat in run.truth:
        if t <= t_ns or best is None:
            best = mat
    return best


def run(args: argparse.Namespace) -> int:
    """Execute the demo; return the exit status."""
    from inertia_ros.nodes._ros import share_path
    from inertia_ros.nodes.scene_simulator import default_scene_path

    scene_path = Path(args.scene) if args.scene else default_scene_path()
    if not scene_path.is_file():
        raise UserError(f'--scene: no such file {scene_path}')
    if not (0 < args.rate <= MAX_RATE) or not math.isfinite(args.rate):
        raise UserError(f'--rate: must be in (0, {MAX_RATE:g}], got {args.rate}')
    if args.domain_id is not None and not 0 <= args.domain_id <= 232:
        raise UserError(f'--domain-id: must be in [0, 232], got {args.domain_id}')
    from inertia_ros.io.scene_file import load_scene
    try:
        scene = load_scene(scene_path)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UserError(f'--out: {out} exists and is not a directory')
    out.mkdir(parents=True, exist_ok=True)
    stem = f'demo_{scene.name}_{time.strftime("%Y%m%d-%H%M%S")}'
    mcap_path, png_path, log_path = (_unique(out / f'{stem}{ext}')
                                     for ext in ('.mcap', '.png', '.log'))

    env = dict(os.environ)
    if args.domain_id is not None:
        env['ROS_DOMAIN_ID'] = str(args.domain_id)
        os.environ['ROS_DOMAIN_ID'] = str(args.domain_id)
    env.setdefault('RCUTILS_LOGGING_BUFFERED_STREAM', '1')
    params = share_path('config', 'inertia_estimator.yaml')
    est_cmd = [sys.executable, '-m', 'inertia_ros.inertia_estimator_node', '--ros-args']
    if params.is_file():
        est_cmd += ['--params-file', str(params)]
    est_cmd += ['-p', 'publish_rate:=5.0']
    sim_cmd = [sys.executable, '-m', 'inertia_ros.scene_simulator_node', '--ros-args',
               '-p', f'scene:={scene_path.resolve()}', '-p', f'rate:={args.rate}',
               '-p', 'wait_for_subscribers:=2', '-p', 'start_delay:=1.0',
               '-p', 'exit_on_end:=true']
    if args.seed is not None:
        sim_cmd += ['-p', f'seed:={int(args.seed)}']
    run_data = _Run()
    with open(log_path, 'w') as log:
        _run_nodes(args, scene, run_data, est_cmd, sim_cmd, env, log, log_path)

    skipped = _write_mcap(mcap_path, run_data)
    final = _final(run_data)
    _plot(png_path, run_data, scene.name)
    print(f'wrote {mcap_path}' + (f' (not recorded, no schema: {", ".join(skipped)})'
                                  if skipped else ''))
    print(f'wrote {png_path}')
    if final is None:
        print(f'inertia_ros demo: no estimate was published (last status {run_data.status}: '
              f'{run_data.message}); see {log_path}', file=sys.stderr)
        return 1
    print(final)
    return 0


def _collector(run_data: _Run) -> Callable[[str, int, bytes], None]:
    """The recorder callback: keep every payload, decode what the live table shows."""
    from inertia_ros.nodes.messages import covariance_from_msg, inertia_from_msg, stamp_to_ns
    from inertia_ros.nodes.recorder import deserialize

    def on_message(topic: str, recv_ns: int, data: bytes) -> None:
        run_data.records.setdefault(topic, []).append((recv_ns, data))
        if topic in ('/scene_simulator/truth', '/inertia_estimator/inertia'):
            t_ns, mat = inertia_from_msg(deserialize(TOPICS[topic][0], data))
            (run_data.truth if topic.endswith('truth') else run_data.est).append((t_ns, mat))
        elif topic == '/inertia_estimator/inertia_covariance' and run_data.est:
            # published right after the ~/inertia it belongs to (which carries the stamp)
            cov, _ = covariance_from_msg(deserialize(TOPICS[topic][0], data))
            run_data.est_std.append((run_data.est[-1][0],
                                     np.sqrt(np.maximum(np.diag(cov), 0.0))))
        elif topic == '/inertia_estimator/principal_moments_std':
            msg = deserialize(TOPICS[topic][0], data)
            v = msg.vector
            run_data.moments_std.append((stamp_to_ns(msg.header.stamp),
                                         np.array([v.x, v.y, v.z])))
        elif topic == '/diagnostics':
            for st in deserialize(TOPICS[topic][0], data).status:
                if st.name.startswith(ESTIMATOR_STATUS):
                    vals = {kv.key: kv.value for kv in st.values}
                    run_data.status = vals.get('status', '?')
                    run_data.message = st.message
                    run_data.counts = vals
    return on_message


def _run_nodes(args: argparse.Namespace, scene: Any, run_data: _Run, est_cmd: list[str],
               sim_cmd: list[str], env: dict[str, str], log: Any, log_path: Path) -> None:
    """Start the estimator, wait for discovery, start the simulator, record until it ends."""
    from inertia_ros.nodes.recorder import Recorder

    procs: list[subprocess.Popen] = []
    recorder = Recorder('inertia_demo', TOPICS, _collector(run_data))
    try:
        procs.append(subprocess.Popen(est_cmd, env=env, stdout=log, stderr=subprocess.STDOUT))
        # The scene starts only once this process has discovered the estimator's outputs:
        # otherwise a slow discovery would lose the first (or, on a short scene, all) estimates.
        problem = wait_until_matched(
            recorder.spin_once, [recorder.subscription(t) for t in
                                 ('/inertia_estimator/inertia', '/diagnostics')],
            procs[0], DISCOVERY_TIMEOUT)
        if problem:
            raise UserError(f'the estimator did not come up: {problem}; see {log_path}')
        procs.append(subprocess.Popen(sim_cmd, env=env, stdout=log, stderr=subprocess.STDOUT))
        _follow(args, scene, run_data, recorder, procs, log_path)
    finally:
        stop_processes(procs)
        recorder.close()


def _follow(args: argparse.Namespace, scene: Any, run_data: _Run, recorder: Any,
            procs: list[subprocess.Popen], log_path: Path) -> None:
    """Spin and print the live table until the simulator has ended (or the time is up)."""
    sim = procs[1]
    wall_budget = scene.duration / args.rate + 60.0
    t_start = time.monotonic()
    if not args.quiet:
        print(f'inertia_ros demo: scene {scene.name!r} ({scene.duration:g} s) at rate '
              f'{args.rate:g}; simulator and estimator started (logs: {log_path})')
        print(_table_header())
    next_print = time.monotonic() + 1.0
    table = _Table()
    sim_done_at = None
    while True:
        recorder.spin_once(0.05)
        now = time.monotonic()
        if sim_done_at is None and sim.poll() is not None:
            sim_done_at = now
        if sim_done_at is not None and now - sim_done_at > 1.5:
            break
        if now - t_start > wall_budget:
            print('inertia_ros demo: time budget exceeded, stopping', file=sys.stderr)
            break
        if procs[0].poll() is not None:
            print('inertia_ros demo: the estimator exited early; see ' + str(log_path),
                  file=sys.stderr)
            break
        if now >= next_print and not args.quiet:
            next_print = now + 1.0
            for line in table.rows(run_data):
                print(line, flush=True)


def _table_header() -> str:
    """The live table's header: data time, status, the six elements, error, worst z."""
    names = ' '.join(f'{n:>10}' for _, n in ELEMENTS)
    return (f'{"t [s]":>7} {"status":<24} {names} [kg m^2]  {"error":>7} {"max|z|":>6}'
            f'  (error: max |I_est - I_true| in % of {ERROR_SCALE} of the truth)')


@dataclass
class _Table:
    """The live table: one row per change (a ``truth`` row when the truth changes)."""

    last: str = ''
    truth: np.ndarray | None = None

    def rows(self, run: _Run) -> list[str]:
        """The lines to print now for ``run`` (none when nothing changed)."""
        out: list[str] = []
        est = run.est[-1] if run.est else None
        truth = _truth_at(run, est[0]) if est else (run.truth[-1][1] if run.truth else None)
        if truth is not None and (self.truth is None or not np.array_equal(truth, self.truth)):
            self.truth = truth
            out.append(f'{"":>7} {"truth":<24} {_elements(truth)}')
        cells, err, zmax = ' '.join(f'{"-":>10}' for _ in ELEMENTS), '-', '-'
        if est is not None:
            cells = _elements(est[1])
            if truth is not None:
                err = f'{100 * _error(est[1], truth):6.2f}%'
                std = _std_at(run.est_std, est[0])
                if std is not None and np.all(std > 0):
                    dev = [est[1][i, j] - truth[i, j] for (i, j), _ in ELEMENTS]
                    zmax = f'{np.max(np.abs(np.array(dev) / std)):6.1f}'
        row = f'{run.gyro_span():7.1f} {run.status:<24} {cells}           {err:>7} {zmax:>6}'
        if row != self.last:
            self.last = row
            out.append(row)
        return out


def _elements(mat: np.ndarray) -> str:
    """The six elements of ``mat`` [kg m^2], table cells."""
    return ' '.join(f'{mat[i, j]:10.5g}' for (i, j), _ in ELEMENTS)


def _std_at(rows: list[tuple[int, np.ndarray]], t_ns: int) -> np.ndarray | None:
    """The standard errors stamped ``t_ns`` (the newest such row), or None."""
    for t, std in reversed(rows):
        if t == t_ns:
            return std
        if t < t_ns:
            break
    return None


def _pm_cells(values: np.ndarray, std: np.ndarray | None) -> list[str]:
    """``'1.0123+-0.0012'`` per value (``'+-?'`` when the sigma is unknown)."""
    if std is None:
        return [f'{v:.4f}+-?' for v in values]
    return [f'{v:.4f}+-{s:.4f}' for v, s in zip(values, std, strict=True)]


def _final(run: _Run) -> str | None:
    if not run.est:
        return None
    t_ns, est = run.est[-1]
    truth = _truth_at(run, t_ns)
    if truth is None:
        return 'final estimate (no truth received):\n' + np.array2string(est, precision=5)
    m_est, m_true = np.linalg.eigvalsh(est), np.linalg.eigvalsh(truth)
    rel = (m_est - m_true) / m_true
    std = _std_at(run.moments_std, t_ns)
    cells = _pm_cells(m_est, std)
    zs = ([f', z {(a - b) / s:+.1f}' if s > 0 else '' for a, b, s in
           zip(m_est, m_true, std, strict=True)] if std is not None else [''] * 3)
    counts = run.counts
    return (f'final status {run.status}; final error max|I_est - I_true| / '
            f'({ERROR_SCALE} of the truth) = '
            f'{100 * _error(est, truth):.3f}%; principal moments [kg m^2] (+- 1 sigma) '
            + ', '.join(f'{c} (true {b:.4f}, {100 * r:+.2f}%{z})'
                        for c, b, r, z in zip(cells, m_true, rel, zs, strict=True))
            + f"; messages received by the estimator: gyro {counts.get('gyro_received', '?')}"
            f", torque {counts.get('torque_received', '?')} (recorded here: "
            f"{len(run.records.get('/imu', []))}, {len(run.records.get('/torque', []))})")


def _write_mcap(path: Path, run: _Run) -> list[str]:
    """Write the recorded topics; return the topics skipped (always empty now).

    Types the MCAP writer knows use its schemas; the others (diagnostics, markers, ...) get
    the schema text built from the installed ``.msg`` files.
    """
    from inertia_ros.io.mcap_writer import McapWriter
    from inertia_ros.io.msgtypes import schema_text_from_share

    with McapWriter(path) as w:
        for topic, rows in run.records.items():
            msgtype, kind = TOPICS[topic]
            try:
                w.add_topic(topic, msgtype, qos=kind)
            except ValueError:
                w.add_topic(topic, msgtype, qos=kind,
                            schema_text=schema_text_from_share(msgtype))
            w.write_many(topic, np.array([r[0] for r in rows], dtype=np.int64),
                         [r[1] for r in rows])
    return []


def _plot(path: Path, run: _Run, name: str) -> None:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, (ax_d, ax_p, ax2) = plt.subplots(3, 1, figsize=(9, 10), sharex=True)
    t0 = run.truth[0][0] if run.truth else (run.est[0][0] if run.est else 0)
    idx = [e[0] for e in ELEMENTS]
    names = [e[1] for e in ELEMENTS]
    colors = plt.rcParams['axes.prop_cycle'].by_key()['color']
    axes = [ax_d] * 3 + [ax_p] * 3
    zoom = 0.0
    if run.est:
        t = (np.array([e[0] for e in run.est]) - t0) * 1e-9
        mats = np.array([e[1] for e in run.est])
        std = np.array([_std_at(run.est_std, e[0]) if _std_at(run.est_std, e[0]) is not None
                        else np.full(6, np.nan) for e in run.est])
        for k, (i, j) in enumerate(idx):
            axes[k].plot(t, mats[:, i, j], color=colors[k], label=f'{names[k]} +- 2 sigma')
            axes[k].fill_between(t, mats[:, i, j] - 2 * std[:, k], mats[:, i, j] + 2 * std[:, k],
                                 color=colors[k], alpha=0.25, linewidth=0)
        truths = [_truth_at(run, e[0]) for e in run.est]
        if all(x is not None for x in truths):
            scale = np.array([_scale(tr) for tr in truths])
            late = t >= t[0] + 0.5 * (t[-1] - t[0])
            for k, (i, j) in enumerate(idx):
                err = 100 * (mats[:, i, j] - np.array([tr[i, j] for tr in truths])) / scale
                band = 100 * 2 * std[:, k] / scale
                ax2.plot(t, err, color=colors[k], label=names[k])
                ax2.fill_between(t, err - band, err + band, color=colors[k], alpha=0.2,
                                 linewidth=0)
                vals = np.abs(np.concatenate([err[late], err[late] + band[late],
                                              err[late] - band[late]]))
                vals = vals[np.isfinite(vals)]
                if vals.size:
                    zoom = max(zoom, float(np.max(vals)))
    t_end = ((run.est[-1][0] - t0) * 1e-9) if run.est else 1.0
    for k, (i, j) in enumerate(idx):
        for n, (tt, mat) in enumerate(run.truth):
            t_a = (tt - t0) * 1e-9
            t_b = (run.truth[n + 1][0] - t0) * 1e-9 if n + 1 < len(run.truth) else t_end
            axes[k].hlines(mat[i, j], t_a, max(t_b, t_a), colors=colors[k], linestyles='--')
    ax_d.set_ylabel('moments of inertia [kg m^2]')
    ax_p.set_ylabel('products of inertia [kg m^2]')
    ax_d.set_title(f'inertia_ros demo, scene {name!r}: estimate (solid) vs truth (dashed)')
    if run.est:
        ax_d.legend(ncol=3, fontsize='small')
        ax_p.legend(ncol=3, fontsize='small')
    else:
        ax_d.text(0.5, 0.5, 'no estimate was published', transform=ax_d.transAxes,
                  ha='center', va='center')
    ax2.set_ylabel(f'(I_est - I_true) / ({ERROR_SCALE} of the truth) [%]')
    ax2.set_title('element errors with their 2-sigma bands (zoomed on the second half)',
                  fontsize='medium')
    if zoom > 0:
        ax2.set_ylim(-1.5 * zoom, 1.5 * zoom)
        ax2.axhline(0.0, color='k', linewidth=0.8)
        ax2.legend(ncol=6, fontsize='small')
    ax2.set_xlabel('data time [s]')
    ax2.grid(True, which='both', alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)

