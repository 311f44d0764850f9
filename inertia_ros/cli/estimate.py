"""``python -m inertia_ros estimate PATH``: the inertia tensor from a recorded log.

Reads a single ``.mcap`` file or a rosbag2 directory (:func:`inertia_ros.io.logs.read_log`),
estimates the tensor (:func:`inertia_ros.core.estimation.estimate`) and prints a report:
``--format text`` (default) for a person, ``--format json`` the DESIGN.md contract.  Exit status
0 whenever a report was produced, whatever its status; 2 with one line on stderr for unusable
input, never a traceback.  The input is only ever read.

Every output option (``-o``, ``--plot``, ``--urdf`` with ``--mass`` and ``--link``) is checked
before the log is read, under one rule: an existing file is refused unless ``--force``
(:mod:`inertia_ros.io.outputs`).  A status without a complete tensor writes no URDF: a note on
stderr, exit 0.

This module parses the arguments and runs the command; the numbers of the report are in
:mod:`inertia_ros.cli.report`, the figure in :mod:`inertia_ros.cli.plots`.  At its top it
imports only the option vocabularies (:mod:`inertia_ros.core.estimation.options`, which
imports nothing), so ``estimate --help`` never loads numpy, scipy or matplotlib.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from inertia_ros.cli import UserError, bounded, name_arg, path_arg, path_text_arg
from inertia_ros.core.estimation.options import (
    BATCH_HOLDS,
    INERTIAL_TORQUE,
    METHODS,
    MODELS,
    NUISANCE_TERMS,
    TORQUE_BIAS,
    check_nuisance,
)

__all__ = ['MAX_TORQUE_DELAY', 'add_parser', 'run']

#: Largest ``--torque-delay`` magnitude [s]: a clock offset beyond this is a different log.
MAX_TORQUE_DELAY = 10.0


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the ``estimate`` sub-command."""
    p = sub.add_parser(
        'estimate', help='estimate the inertia tensor from a recorded MCAP log',
        description='Estimate the inertia tensor from a recorded log (a .mcap file or a '
                    'rosbag2 directory) of angular velocity and known torque.')
    p.add_argument('path', metavar='PATH', type=path_text_arg,
                   help='.mcap file or rosbag2 directory (read only)')
    p.add_argument('--omega-topic', metavar='T', type=name_arg,
                   help='angular-velocity topic (Imu, Vector3Stamped or TwistStamped); found '
                        'by type when omitted')
    p.add_argument('--torque-topic', metavar='T', type=name_arg,
                   help='torque topic (WrenchStamped or Vector3Stamped); found by type when '
                        'omitted; "none" for torque-free data (no torque stream)')
    p.add_argument('--model', choices=MODELS, default='auto',
                   help='parameter set (default auto: the smallest the data supports)')
    p.add_argument('--symmetry-axis', choices=('x', 'y', 'z'),
                   help='body symmetry axis (needed by --model axisymmetric)')
    p.add_argument('--torque-bias', choices=TORQUE_BIAS, default='auto',
                   help='estimate a constant unmeasured disturbance torque (default auto)')
    p.add_argument('--inertial-torque', choices=INERTIAL_TORQUE, default='auto',
                   help='also estimate a disturbance torque constant in inertial axes (e.g. a '
                        'steady air flow, a tether); auto (default) keeps it when the data '
                        'support it, and runs without it with --wheels/--rotors and the '
                        'sliding and differential methods; on always fits it')
    p.add_argument('--method', choices=METHODS, default='auto',
                   help='estimator (default auto: maximum likelihood (ml) up to 100k gyro '
                        'samples, integral beyond)')
    p.add_argument('--hold', choices=BATCH_HOLDS, default='auto',
                   help='torque between samples: zero-order hold, linear, or auto (both '
                        'fitted, the one the data support by a likelihood test kept; default)')
    p.add_argument('--torque-scale-std', type=bounded(0.0, 0.5, ''), default=0.0,
                   metavar='R',
                   help='relative one-sigma uncertainty of the torque scale (0.02 = 2 %%), '
                        'added to the standard errors (default 0)')
    p.add_argument('--gyro-scale-std', type=bounded(0.0, 0.5, ''), default=0.0, metavar='R',
                   help='relative one-sigma uncertainty of the gyro scale (0.01 = 1 %%), '
                        'added to the standard errors (default 0)')
    p.add_argument('--torque-delay', type=bounded(-MAX_TORQUE_DELAY, MAX_TORQUE_DELAY, 's'),
                   default=0.0, metavar='S',
                   help=f'torque stamps lag the applied torque by S seconds, |S| <= '
                        f'{MAX_TORQUE_DELAY:g} (default 0)')
    p.add_argument('--nuisance', type=_nuisance_arg, default='off', metavar='TERMS',
                   help='sensor nuisance terms: auto (each kept when the data support it), '
                        f'off (default) or a comma list of {", ".join(NUISANCE_TERMS)}')
    p.add_argument('--ignore-frames', action='store_true',
                   help='accept different header.frame_id values on the two streams')
    p.add_argument('--wheels', metavar='FILE', type=path_arg,
                   help='wheels/flywheels YAML (joint, axis, inertia[, inertia_std] per wheel): '
                        'their momentum from the JointState wheel speeds enters the momentum '
                        'form; a torque topic, if any, adds the other known torque')
    p.add_argument('--wheel-topic', metavar='T', type=name_arg,
                   help='sensor_msgs/JointState topic of the wheel speeds (velocity, rad/s); '
                        'found by type when omitted')
    p.add_argument('--rotors', metavar='FILE', type=path_arg,
                   help='multirotor rotors YAML (joint, position, spin, k_f, k_m[, '
                        'time_constant, inertia, *_std] per rotor; example '
                        'config/rotors/quadrotor.yaml): the rotor torques (and momentum) from '
                        'the JointState rotor speeds are the known torque; a torque topic, if '
                        'any, adds to it')
    p.add_argument('--rotor-topic', metavar='T', type=name_arg,
                   help='sensor_msgs/JointState topic of the rotor speeds (velocity, rad/s); '
                        'found by type when omitted')
    _add_output_options(p)
    p.add_argument('--no-progress', action='store_true', help='no progress bar on stderr')
    p.set_defaults(func=run)


def _add_output_options(p: argparse.ArgumentParser) -> None:
    """The report's format and the files ``estimate`` may write (report, figure, URDF)."""
    p.add_argument('--format', choices=('text', 'json'), default='text',
                   help='report format (default text)')
    p.add_argument('-o', '--output', metavar='FILE', type=path_arg,
                   help='write the report to FILE instead of stdout (an existing FILE only '
                        'with --force)')
    p.add_argument('--plot', metavar='FILE.png', type=path_arg,
                   help='also draw torque fit, convergence and principal axes to FILE.png '
                        '(.svg, .pdf: that format; an existing file only with --force)')
    p.add_argument('--urdf', metavar='FILE', type=path_arg,
                   help='also write the tensor as a URDF <inertial> block (needs --mass); '
                        'not written (a note on stderr, exit 0) when the status gives no '
                        'complete tensor')
    p.add_argument('--force', action='store_true',
                   help='replace existing -o, --plot and --urdf files (default: refuse them, '
                        'before any work); the input log is never replaced')
    p.add_argument('--mass', type=bounded(1e-9, 1e9, 'kg'), metavar='M',
                   help='body mass for --urdf [kg] (rotation data cannot tell it)')
    p.add_argument('--com', type=bounded(-1e6, 1e6, 'm'), nargs=3, metavar=('X', 'Y', 'Z'),
                   default=(0.0, 0.0, 0.0),
                   help='centre of mass in the link frame for --urdf [m] (default 0 0 0)')
    p.add_argument('--link', default='base_link', metavar='NAME',
                   help='link name for --urdf (default base_link)')


# --------------------------------------------------------------------------------------------


class _Progress:
    """The reading progress (bytes of the log) on stderr, through :mod:`inertia_ros.progress`
    (drawn only when enabled: stderr a terminal and no ``--no-progress``)."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self.bar: Any = None

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled or total <= 0:
            return
        if self.bar is None:
            from inertia_ros.progress import progress_bar
            self.bar = progress_bar(total, 'reading', enabled=True, scale=1e-6, unit='MB',
                                    fmt='{desc} [{bar:30}] {percentage:5.1f}% '
                                        '{n:7.1f}/{total:.1f} MB {postfix}')
        self.bar.update(min(done, total) - self.bar.n)
        if done >= total:
            self.bar.refresh()               # the last state is drawn, not throttled away

    def note(self, text: str) -> None:
        """Show a one-line status (e.g. while estimating)."""
        if self.bar is not None:
            self.bar.set_postfix_str(text[:60])

    def close(self) -> None:
        """Erase the bar."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None


#: ``--plot`` file types matplotlib writes (the suffix picks one; none: PNG).
PLOT_FORMATS = ('png', 'svg', 'svgz', 'pdf', 'eps', 'ps', 'jpg', 'jpeg', 'tif', 'tiff', 'webp')


def _inputs(args: argparse.Namespace) -> dict[Path, str]:
    """Resolved paths of everything the command reads, with what each is (never an output,
    even with --force)."""
    from inertia_ros.io.logs import log_files

    src = Path(args.path)
    inputs: dict[Path, str] = {}
    try:
        if src.exists():
            inputs = dict.fromkeys((p.resolve() for p in log_files(src)), 'the input log')
    except Exception:            # a damaged log: _read reports it; this check is best effort
        pass
    try:
        inputs[src.resolve()] = 'the input log'
        if src.is_dir():
            inputs[(src / 'metadata.yaml').resolve()] = 'the input log'
        for opt, f in (('--wheels', args.wheels), ('--rotors', args.rotors)):
            if f is not None:
                inputs[Path(f).resolve()] = f'the {opt} file'
    except (OSError, ValueError, RuntimeError):      # an unusable name: _read says so
        pass
    return inputs


def check_companions(args: argparse.Namespace) -> None:
    """Refuse an option that does nothing without its companion (it used to be ignored).

    ``--mass``, ``--com`` and ``--link`` only describe the ``--urdf`` body; ``--wheel-topic``
    and ``--rotor-topic`` only name the stream of ``--wheels`` / ``--rotors``.

    Raises
    ------
    UserError
        One line naming the option and its companion.
    """
    pairs = (('--mass', args.mass is not None, '--urdf FILE'),
             ('--com', tuple(args.com) != (0.0, 0.0, 0.0), '--urdf FILE'),
             ('--link', args.link != 'base_link', '--urdf FILE'),
             ('--wheel-topic', args.wheel_topic is not None, '--wheels FILE'),
             ('--rotor-topic', args.rotor_topic is not None, '--rotors FILE'))
    for opt, given, companion in pairs:
        dest = companion.split()[0].removeprefix('--')
        if given and getattr(args, dest) is None:
            raise UserError(f'{opt}: only used with {companion}, which is not given; add '
                            f'{companion} or leave {opt} out')


def _check_outputs(args: argparse.Namespace) -> None:
    """Refuse, before any work, every output option that cannot or must not be written.

    One rule for ``-o``, ``--plot`` and ``--urdf``: an existing file is refused unless
    ``--force``; the input, a directory, a missing or unwritable directory, a dangling link
    and two options naming one file are always refused.  ``--urdf`` also needs ``--mass``
    and a ``--link`` name of printable characters.
    """
    if args.urdf is not None:
        from inertia_ros.io.urdf import check_name  # (only then: its imports)

        if args.mass is None:
            raise UserError('--urdf needs --mass M [kg]: rotation data cannot tell the mass')
        try:
            check_name('--link', args.link)
        except ValueError as exc:
            raise UserError(str(exc)) from None
    if args.plot is not None:
        kind = args.plot.suffix.lower().removeprefix('.') or 'png'
        if kind not in PLOT_FORMATS:
            raise UserError(f'--plot {args.plot}: cannot draw a {args.plot.suffix!r} file; '
                            'give a .png (or .svg, .pdf) name')
    if args.output is None and args.plot is None and args.urdf is None:
        return                          # (nothing written: io.outputs and its imports unneeded)
    from inertia_ros.io.outputs import OutputError, check_output

    inputs = _inputs(args)
    named: dict[Path, str] = {}
    for opt, out in (('-o', args.output), ('--plot', args.plot), ('--urdf', args.urdf)):
        if out is None:
            continue
        try:
            check_output(opt, out, force=args.force, inputs=inputs)
        except OutputError as exc:
            raise UserError(str(exc)) from None
        key = out.resolve()
        if key in named and (out.is_file() or not out.exists()):
            raise UserError(f'{opt} {out}: the same file as {named[key]}; give each output its '
                            'own name')
        named[key] = opt


def _read(args: argparse.Namespace, progress: _Progress) -> Any:
    """Read the log; every failure is a :class:`UserError` naming the file."""
    from inertia_ros.io.logs import LogError, read_log

    act = _actuators(args)
    try:
        torque_topic = args.torque_topic
        actuated = args.wheels is not None or args.rotors is not None
        if actuated and torque_topic is None and not _has_torque_topic(args.path):
            torque_topic = 'none'       # wheels or rotors only: no other known torque
        kind = 'wheels' if args.wheels is not None else 'rotors'
        log = read_log(args.path, args.omega_topic, torque_topic,
                       ignore_frames=args.ignore_frames, torque_delay=args.torque_delay,
                       progress=progress, joints=None if act is None else act.joints,
                       joint_topic=args.wheel_topic if kind == 'wheels' else args.rotor_topic,
                       joint_what=kind)
        js = sorted(t for t, ty in log.topics.items() if ty == 'sensor_msgs/msg/JointState')
        if args.wheels is None and args.rotors is None and js:
            log.warnings.append(f'{", ".join(js)}: JointState in the log; if it carries '
                                'wheel or rotor speeds, pass --wheels WHEELS.yaml (reaction '
                                'wheels, flywheels) or --rotors ROTORS.yaml (a multirotor) to '
                                'use them')
        return log
    except LogError as exc:
        raise UserError(str(exc)) from None
    except ValueError as exc:
        text = _first_line(exc)
        raise UserError(text if str(args.path) in text else f'{args.path}: damaged or '
                        f'unreadable log ({type(exc).__name__}: {text})') from None
    except OSError as exc:
        raise UserError(f'{args.path}: cannot read: {exc.strerror or exc}') from None
    except Exception as exc:
        # a damaged file reaching a path the reader does not guard: still one line
        raise UserError(f'{args.path}: damaged or unreadable log ({type(exc).__name__}: '
                        f'{_first_line(exc)})') from None
    finally:
        progress.close()


def _actuators(args: argparse.Namespace) -> Any:
    """The wheels or rotors file of ``--wheels`` / ``--rotors`` (None without), kept in
    ``args.actuators``; an invalid file is a :class:`UserError`."""
    if not (args.wheels or args.rotors):      # (the YAML readers' imports: ~40 ms of start-up)
        args.actuators = None
        return None
    from inertia_ros.io.rotors import load_actuators

    try:
        args.actuators = load_actuators(args.wheels, args.rotors)
    except ValueError as exc:
        raise UserError(_first_line(exc)) from None
    return args.actuators


def _first_line(exc: BaseException) -> str:
    """The first line of an exception's message (or its type when it has none)."""
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _nuisance_arg(text: str) -> str | tuple[str, ...]:
    """``--nuisance``: auto, off or a comma list of terms."""
    try:
        return check_nuisance(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix('nuisance: ')) from None


def _estimate(args: argparse.Namespace, log: Any) -> Any:
    """Run the estimator on the log's streams with the command's options."""
    from inertia_ros.core.estimation import estimate

    nuisance = getattr(args, 'nuisance', 'off')
    if args.wheels is not None or args.rotors is not None:
        if nuisance != 'off':           # the capability table's line
            from inertia_ros.core.estimation.config import refusal

            kind = 'wheels' if args.wheels is not None else 'rotors'
            raise UserError(f"--nuisance: {refusal('batch', kind, 'nuisance')}")
        return _estimate_wheels(args, log)
    try:
        return estimate(log.omega.t, log.omega.values, log.torque.t, log.torque.values,
                        **_estimator_options(args), nuisance=nuisance)
    except ValueError as exc:
        raise UserError(f'{args.path}: cannot estimate: {_first_line(exc)}') from None


def _has_torque_topic(path: Any) -> bool:
    """True when the log has a topic of a torque type."""
    from inertia_ros.io.logs import TORQUE_TYPES, log_files
    from inertia_ros.io.mcap_reader import McapReader
    from inertia_ros.io.msgtypes import normalise_type

    for f in log_files(path):
        with McapReader(f) as r:
            for ch in r.channels.values():
                sc = r.schemas.get(ch.schema_id)
                if sc is not None and normalise_type(sc.name) in TORQUE_TYPES:
                    return True
    return False


def _estimate_wheels(args: argparse.Namespace, log: Any) -> Any:
    """``--wheels`` / ``--rotors``: the wheels' (rotors') momentum and the rotors' torque from
    the JointState topic enter the momentum form
    (:func:`inertia_ros.core.estimation.momentum.estimate_with_momentum`)."""
    from inertia_ros.core.estimation.method_choice import lowest_rotation_hz
    from inertia_ros.core.estimation.momentum import estimate_with_momentum

    kind = 'wheels' if args.wheels is not None else 'rotors'
    act, js = args.actuators, log.joints      # the JointState stream, cleaned by read_log
    try:
        mom = act.record(js.t, js.values)
    except ValueError as exc:
        raise UserError(_first_line(exc)) from None
    log.warnings[:] = [w for w in log.warnings if 'torque-free data' not in w]
    args.wheel_info = {'file': str(act.file), 'topic': js.topic, 'samples': int(js.t.size),
                       'dropped': int(js.counts.dropped), 'joints': act.joints, 'kind': kind}
    args.momentum = mom                                    # for --plot
    # the lowest rotation line of the spinning joints: method auto's band edge
    options = dict(_estimator_options(args), rotation_hz=lowest_rotation_hz(js.values))
    try:
        return estimate_with_momentum(log.omega.t, log.omega.values, log.torque.t,
                                      log.torque.values, mom, **options)
    except ValueError as exc:
        raise UserError(f'{args.path}: cannot estimate: {_first_line(exc)}') from None


def _estimator_options(args: argparse.Namespace) -> dict[str, Any]:
    """The keyword arguments of ``estimate()`` the command line chose."""
    return {'method': args.method, 'model': args.model, 'torque_bias': args.torque_bias,
            'inertial_torque': args.inertial_torque, 'hold': args.hold,
            'symmetry_axis': args.symmetry_axis,
            'torque_scale_std': args.torque_scale_std, 'gyro_scale_std': args.gyro_scale_std}


def _write(args: argparse.Namespace, text: str) -> None:
    """The report to ``-o FILE`` or stdout."""
    if args.output is None:
        sys.stdout.write(text)
        return
    _save('-o', args.output, text, args.force)


def _momentum_prefix_run(mom: Any) -> Any:
    """The convergence curve's estimator for a ``--wheels``/``--rotors`` run: the momentum
    form on the prefix, with the momentum record cut at the prefix's last gyro stamp."""
    from dataclasses import replace

    from inertia_ros.core.estimation.momentum import estimate_with_momentum

    def run(tg: Any, w: Any, tt: Any, tau: Any, **options: Any) -> Any:
        keep = mom.t <= tg[-1]
        cut = replace(mom, t=mom.t[keep], h=mom.h[keep], h_std=mom.h_std[:, keep],
                      torque=None if mom.torque is None else mom.torque[keep],
                      torque_std=None if mom.torque_std is None else mom.torque_std[:, keep])
        return estimate_with_momentum(tg, w, tt, tau, cut, **options)

    return run


def _draw(args: argparse.Namespace, est: Any, log: Any) -> tuple[bytes, list[str]]:
    """The ``--plot`` image and the numerical warnings raised while computing it.

    With ``--wheels`` / ``--rotors`` the convergence curve refits the momentum form on each
    prefix, and the torque drawn is the equivalent torque on the body alone, the known
    torque minus the internal momentum's change (:func:`inertia_ros.cli.report.momentum_view`).
    """
    from inertia_ros.cli.plots import plot_report
    from inertia_ros.cli.report import convergence, momentum_view, numerical_warnings

    hold, what = est.diagnostics.get('hold', args.hold), 'torque'
    mom = getattr(args, 'momentum', None)
    with numerical_warnings() as found:
        if mom is None:
            conv = convergence(est, log, **_estimator_options(args))
        else:
            conv = convergence(est, log, _momentum_prefix_run(mom), **_estimator_options(args))
            log = momentum_view(log, mom, 'linear' if args.hold == 'linear' else 'zoh')
            hold, what = 'zoh', 'equivalent torque'
        kind = args.plot.suffix.lower().removeprefix('.') or 'png'
        image = plot_report(None, est, log, hold, conv, fmt=kind, torque_what=what)
    return image, list(found)


def _save(opt: str, path: Path, data: bytes | str, force: bool) -> None:
    """Write a checked output file; a failure (disk full, ...) is one line."""
    from inertia_ros.io.outputs import write_output

    try:
        write_output(path, data, force=force)
    except OSError as exc:
        raise UserError(f'{opt} {path}: {exc.strerror or exc}') from None


def _run(args: argparse.Namespace) -> int:
    """The command without its last-resort handler."""
    from inertia_ros.cli.report import build_report, format_text, numerical_warnings

    if args.wheels is not None and args.rotors is not None:
        raise UserError('--wheels and --rotors: give one of them (one JointState input)')
    check_companions(args)
    _check_outputs(args)
    if args.model == 'axisymmetric' and args.symmetry_axis is None:
        raise UserError('--model axisymmetric needs --symmetry-axis x|y|z')
    progress = _Progress(sys.stderr.isatty() and not args.no_progress)
    failure = None
    with numerical_warnings() as found:
        try:
            log = _read(args, progress)
            progress.note(f'estimating ({log.omega.t.size} gyro, {log.torque.t.size} torque '
                          'samples)')
            est = _estimate(args, log)
        except UserError as exc:
            failure = exc
        finally:
            progress.close()
    if failure is not None:
        # numerical warnings on the way to a failure are its likely cause: name the first
        hint = f' ({found[0]})' if found else ''
        raise UserError(f'{failure}{hint}') from None
    report = build_report(est, log, args.torque_delay, args.hold, list(found))
    if getattr(args, 'wheel_info', None):
        report['diagnostics'][args.wheel_info.pop('kind')] = args.wheel_info
    try:
        text = (json.dumps(report, indent=2, allow_nan=False) + '\n' if args.format == 'json'
                else format_text(report))
    except ValueError as exc:      # a non-finite number escaped the contract's nulls
        raise UserError(f'{args.path}: cannot write the report: {exc}') from None
    # everything is computed before anything is written: a report, when printed, is whole
    image, notes = _draw(args, est, log) if args.plot is not None else (None, [])
    urdf = _urdf_text(args, est) if args.urdf is not None else None
    _write(args, text)
    if image is not None:
        _save('--plot', args.plot, image, args.force)
        for w in notes:
            print(f'inertia_ros estimate: --plot: {w}', file=sys.stderr)
    if urdf is not None:
        _save('--urdf', args.urdf, urdf, args.force)
    return 0


def _urdf_text(args: argparse.Namespace, est: Any) -> str | None:
    """The ``--urdf`` document: the tensor about the centre of mass, in the gyro (link) frame.

    None, with one note on stderr, when the estimate cannot give one (no complete tensor, or
    one that is not physical): the report is still the command's answer, exit status 0.
    """
    import numpy as np

    from inertia_ros.io.urdf import urdf_document

    why = None
    if est.inertia is None or not np.all(np.isfinite(est.inertia)):
        why = f'the status is {est.status!r} and the tensor is not complete (see the report)'
    else:
        comment = (f'inertia_ros estimate of {args.path}: status {est.status}, method '
                   f'{est.method}, model {est.model}')
        try:
            return urdf_document(est.inertia, args.mass, tuple(args.com), link=args.link,
                                 comment=comment)
        except ValueError as exc:
            why = _first_line(exc)
    print(f'inertia_ros estimate: --urdf {args.urdf}: not written: {why}', file=sys.stderr)
    return None


def run(args: argparse.Namespace) -> int:
    """Run the command; return the exit status (2 with one stderr line on any failure).

    Errors the user can act on arrive as :class:`UserError`.  Anything else (a damaged log
    reaching a path nobody guarded) is turned into one line naming the file and the
    exception type, never a traceback.
    """
    try:
        return _run(args)
    except (UserError, KeyboardInterrupt):
        raise
    except Exception as exc:     # the last resort: one line, the type named for a bug report
        raise UserError(f'{args.path}: unexpected {type(exc).__name__}: {_first_line(exc)} '
                        '(please report it with the log)') from None
