"""``python -m inertia_ros plan --prior-inertia ... --max-torque ... --max-rate ... --out DIR``.

The actuator limits are ``--max-torque`` per axis and/or ``--wheels FILE`` (per wheel
``max_torque`` and ``max_speed``) or ``--rotors FILE`` (per rotor ``min_speed`` and
``max_speed``, hovering at ``--hover-thrust``): :mod:`inertia_ros.core.excitation.actuators`.

Designs an excitation (:mod:`inertia_ros.core.excitation`) and writes to ``DIR``:

* ``scene.yaml``: a scene the simulator plays (``python -m inertia_ros simulate``);
* ``torque.csv``: the torque schedule ``t, tau_x, tau_y, tau_z`` [s, N m] at the torque rate;
* ``sigma.png``: the predicted std of each element and principal moment against time;
* ``plan.json`` and ``plan.txt``: the predicted time to target and the comparison with the
  standard profiles at the same limits (the text is also printed).
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from inertia_ros.cli import UserError, bounded

__all__ = ['add_parser', 'run']

_THETA = ('ixx', 'iyy', 'izz', 'ixy', 'ixz', 'iyz')


def _real(text: str) -> float:
    """An argparse type: any finite real number."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'must be a number; got {text!r}') from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f'must be finite; got {text}')
    return v


def add_parser(sub: Any) -> argparse.ArgumentParser:
    """Register the ``plan`` sub-command on ``sub`` (an argparse subparsers object)."""
    p = sub.add_parser(
        'plan', help='design an excitation: torque profile, predicted sigma, time to target',
        description='Design a torque excitation within actuator and body-rate limits that '
                    'reaches a target precision soonest, robust over a prior tensor; write a '
                    'scene, a torque schedule, the predicted sigma against time and a '
                    'comparison with standard profiles to --out DIR.')
    prior = p.add_mutually_exclusive_group(required=True)
    prior.add_argument('--prior-inertia', nargs=6, type=_real, metavar='X',
                       help='prior ixx iyy izz ixy ixz iyz [kg m^2]')
    prior.add_argument('--prior-report', metavar='REPORT.json',
                       help='a previous estimate\'s JSON report (inertia and inertia_std)')
    p.add_argument('--prior-rel-std', type=bounded(1e-6, 10, ''), default=0.2,
                   help='relative prior sigma with --prior-inertia (default 0.2 = 20 %%)')
    p.add_argument('--max-torque', nargs='+', type=_real, metavar='N_M',
                   help='peak torque per axis [N m]: one value or x y z (needed unless '
                        '--wheels gives every wheel a max_torque)')
    p.add_argument('--wheels', metavar='WHEELS.yaml',
                   help='reaction wheels (config/wheels/ schema with max_torque [N m] and '
                        'max_speed [rad/s] per wheel): the design keeps every wheel\'s torque '
                        'and speed within them')
    p.add_argument('--rotors', metavar='ROTORS.yaml',
                   help='a hovering multirotor\'s rotors (config/rotors/ schema with min_speed '
                        'and max_speed [rad/s] per rotor): the design keeps every rotor\'s '
                        'speed in range; needs --hover-thrust')
    p.add_argument('--hover-thrust', type=_real, metavar='N',
                   help='total thrust held while exciting, with --rotors [N]')
    p.add_argument('--initial-wheel-speed', nargs='+', type=_real, metavar='W',
                   help='wheel speeds at the start [rad/s], one per wheel in file order (0)')
    p.add_argument('--max-rate', type=_real, required=True, help='body-rate limit |omega| '
                   '[rad/s]')
    p.add_argument('--gyro-rate', type=_real, default=200.0, help='gyro rate [Hz] (200)')
    p.add_argument('--torque-rate', type=_real, default=50.0,
                   help='torque command and measurement rate [Hz] (50)')
    p.add_argument('--gyro-noise', type=_real, default=0.002, help='gyro std [rad/s] (0.002)')
    p.add_argument('--torque-noise', type=_real, default=0.001,
                   help='torque-sample std [N m] (0.001)')
    p.add_argument('--torque-noise-rel', type=_real, default=0.0,
                   help='extra torque std as a share of the profile RMS (0)')
    p.add_argument('--initial-omega', nargs=3, type=_real, default=[0.0, 0.0, 0.0],
                   metavar='W', help='body rate at the start [rad/s] (0 0 0)')
    goal = p.add_mutually_exclusive_group()
    goal.add_argument('--target-rel-std', type=_real, default=None,
                      help='target relative sigma of every targeted quantity (default 0.01)')
    goal.add_argument('--duration', type=_real, default=None,
                      help='a fixed manoeuvre length [s] instead of a precision target')
    p.add_argument('--target-elements', nargs='+', default=['principal'], metavar='NAME',
                   help='principal (the principal moments; default) and/or ixx ... iyz')
    p.add_argument('--max-duration', type=_real, default=300.0,
                   help='longest acceptable manoeuvre [s] (300)')
    p.add_argument('--bodies', type=bounded(1, 20, '', integer=True), default=3,
                   help='prior bodies the design must work for (3)')
    p.add_argument('--seed', type=bounded(0, 2**32 - 1, '', integer=True), default=0,
                   help='seed of the prior draws and random profiles (0)')
    p.add_argument('--out', required=True, metavar='DIR', help='output directory')
    p.add_argument('--force', action='store_true', help='write into a non-empty DIR')
    p.add_argument('--format', choices=('text', 'json'), default='text',
                   help='what to print (text)')
    p.set_defaults(func=run)
    return p


def _prior_from_report(path: str) -> tuple[list[float], list[float]]:
    """``theta`` and its std from an estimate's JSON report (DESIGN.md contract)."""
    try:
        rep = json.loads(Path(path).read_text(encoding='utf-8'))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise UserError(f'{path}: cannot read a JSON report ({exc})') from None
    rows, cols = (0, 1, 2, 0, 0, 1), (0, 1, 2, 1, 2, 2)
    out = []
    for key in ('inertia', 'inertia_std'):
        m = rep.get(key) if isinstance(rep, dict) else None
        try:
            vals = [float(m[r][c]) for r, c in zip(rows, cols, strict=True)]
        except (TypeError, ValueError, IndexError, KeyError):
            raise UserError(f'{path}: field {key} must be a 3x3 matrix of numbers (an element '
                            'is null or missing: give --prior-inertia instead)') from None
        if not all(math.isfinite(v) for v in vals):
            raise UserError(f'{path}: field {key} has non-finite values')
        out.append(vals)
    return out[0], out[1]


def _inputs(args: argparse.Namespace) -> tuple[Any, Any, Any]:
    """Validated ``(prior, limits, target)``; bad values raise UserError."""
    from inertia_ros.core import excitation as ex

    mt = args.max_torque
    if mt is None and not args.wheels and not args.rotors:
        raise UserError('give the actuator limits: --max-torque (per axis) and/or --wheels FILE '
                        'or --rotors FILE')
    if args.wheels and args.rotors:
        raise UserError('--wheels and --rotors: give one of them')
    if (args.hover_thrust is None) == bool(args.rotors):
        raise UserError('--rotors FILE needs --hover-thrust N (and --hover-thrust needs '
                        '--rotors)')
    rotors = _rotors(args)
    if mt is not None and len(mt) not in (1, 3):
        raise UserError(f'--max-torque: give one value or three (x y z), got {len(mt)}')
    if args.initial_wheel_speed is not None and not args.wheels:
        raise UserError('--initial-wheel-speed needs --wheels FILE')
    wheels = _wheels(args)
    mt = [math.inf] if mt is None else mt
    try:
        if args.prior_report:
            theta, std = _prior_from_report(args.prior_report)
            prior = ex.make_prior(theta, std=std)
        else:
            prior = ex.make_prior(args.prior_inertia, args.prior_rel_std)
        lim = ex.Limits(max_torque=tuple(mt * 3 if len(mt) == 1 else mt),
                        max_rate=args.max_rate, gyro_rate=args.gyro_rate,
                        torque_rate=args.torque_rate, gyro_noise=args.gyro_noise,
                        torque_noise=args.torque_noise, torque_noise_rel=args.torque_noise_rel,
                        initial_omega=tuple(args.initial_omega), wheels=wheels,
                        rotors=rotors)
        rel = args.target_rel_std
        if rel is None and args.duration is None:
            rel = 0.01
        target = ex.Target(rel_std=rel, elements=tuple(args.target_elements),
                           duration=args.duration, max_duration=args.max_duration)
    except ValueError as exc:
        raise UserError(str(exc).replace('max_torque', '--max-torque')
                        .replace('max_rate', '--max-rate')) from None
    return prior, lim, target


def _wheels(args: argparse.Namespace) -> tuple[Any, ...]:
    """The wheels' limits of ``--wheels`` (max_torque needed without --max-torque)."""
    if not args.wheels:
        return ()
    from inertia_ros.io.wheels import load_wheel_limits

    need = ('max_speed',) if args.max_torque is not None else ('max_torque', 'max_speed')
    try:
        wheels = load_wheel_limits(args.wheels, need=need,
                                   initial_speed=args.initial_wheel_speed)
        from inertia_ros.core.excitation.actuators import allocation

        allocation(wheels)
    except ValueError as exc:
        msg = str(exc)
        raise UserError(msg if msg.startswith(args.wheels) else f'{args.wheels}: {msg}') \
            from None
    return tuple(wheels)


def _rotors(args: argparse.Namespace) -> Any:
    """The rotors' limits of ``--rotors`` hovering at ``--hover-thrust`` (or None)."""
    if not args.rotors:
        return None
    from inertia_ros.io.rotors import load_rotor_limits

    try:
        return load_rotor_limits(args.rotors, args.hover_thrust)
    except ValueError as exc:
        msg = str(exc)
        raise UserError(msg if msg.startswith(args.rotors) else f'{args.rotors}: {msg}') \
            from None


def _out_dir(args: argparse.Namespace) -> Path:
    """The output directory, created; refuse a non-empty one without --force."""
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UserError(f'{out} exists and is not a directory: choose another --out')
    if out.is_dir() and any(out.iterdir()) and not args.force:
        raise UserError(f'{out} is not empty (use --force to write into it, or choose another '
                        '--out)')
    return out


def run(args: argparse.Namespace) -> int:
    """Run the command; bad input raises :class:`~inertia_ros.cli.UserError`."""
    from inertia_ros.core import excitation as ex

    prior, lim, target = _inputs(args)
    out = _out_dir(args)
    try:
        result = ex.plan(prior, lim, target, n_bodies=args.bodies, seed=args.seed)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    out.mkdir(parents=True, exist_ok=True)
    summary = write_all(out, result, prior, lim, target, args.seed)
    if args.format == 'json':
        print(json.dumps(summary, indent=2))
    else:
        print((out / 'plan.txt').read_text(encoding='utf-8'), end='')
    return 0


def _fmt_time(t: float) -> str:
    """A time [s] for the table: ``> max`` when not reached."""
    return f'{t:8.1f} s' if math.isfinite(t) else '   not reached'


def _summary(result: Any, prior: Any, lim: Any, target: Any) -> dict[str, Any]:
    """The JSON summary of a plan."""
    def num(v: float) -> float | None:
        return float(v) if math.isfinite(v) else None

    rows = [{**r, 'criterion': num(r['criterion']), 'criterion_at_end': num(r['criterion_at_end']),
             'time_to_target': num(r['time_to_target'])} for r in result.comparison]
    return {
        'model': result.model, 'design': result.design,
        'target': {'rel_std': target.rel_std, 'elements': list(target.elements),
                   'duration': target.duration, 'max_duration': target.max_duration},
        'time_to_target': num(result.time_to_target), 'duration': result.duration,
        'peak_rate': result.peak_rate, 'max_rate': lim.max_rate,
        'max_torque': list(lim.max_torque), 'horizon': result.horizon,
        'wheels': [{'joint': w.joint, 'axis': w.axis.tolist(), 'inertia': w.inertia,
                    'max_torque': num(w.max_torque), 'max_speed': num(w.max_speed),
                    'initial_speed': w.initial_speed} for w in lim.wheels],
        'rotors': None if lim.rotors is None else {
            'joints': list(lim.rotors.joints), 'hover_thrust': lim.rotors.hover_thrust,
            'min_speed': lim.rotors.min_speed.tolist(),
            'max_speed': lim.rotors.max_speed.tolist()},
        'limit_usage': result.usage, 'binding_limit': result.binding,
        'prior': {'theta': prior.theta.tolist(), 'std': prior.std.tolist()},
        'predicted': {'t': result.times.tolist(),
                      'element_std': dict(zip(_THETA, result.element_std.T.tolist(),
                                              strict=True)),
                      'principal_std': result.principal_std.T.tolist(),
                      'criterion': result.criterion.tolist()},
        'comparison': rows,
        'files': ['scene.yaml', 'torque.csv', 'sigma.png', 'plan.json', 'plan.txt'],
    }


def _text(s: dict[str, Any]) -> str:
    """The text summary of a plan."""
    tgt = s['target']
    what = (f"relative sigma {100 * tgt['rel_std']:g} % of {', '.join(tgt['elements'])}"
            if tgt['rel_std'] is not None else f"fixed duration {tgt['duration']:g} s")
    ttt = s['time_to_target']
    family = s['design'].get('family', 'multisine')
    chk = s['design'].get('check', {})
    lines = [f'plan: {s["comparison"][0]["name"]}'
             + ('' if family == 'multisine' else
                ' (a standard profile: the designed multisine is not sooner on every '
                'body drawn from the prior)'),
             f'  target: {what}; model {s["model"]}'
             + (' (near-diagonal prior: products not estimated)' if s['model'] == 'diagonal'
                else ''),
             f'  predicted time to target: {ttt:.1f} s on the prior value'
             + (f"; {chk['median']:.1f} s median ({chk['q10']:.1f}-{chk['q90']:.1f} s, "
                f"10-90 %) on {chk['check_bodies']} bodies drawn from the prior"
                if chk.get('median') is not None else '') if ttt is not None else
             f'  predicted criterion at {tgt["duration"]:g} s: '
             f'{100 * s["predicted"]["criterion"][-1]:.3g} %',
             f'  scene duration {s["duration"]:g} s; peak body rate {s["peak_rate"]:.3g} rad/s '
             f'(limit {s["max_rate"]:g}); peak torque limit '
             f'{[float(f"{v:.4g}") for v in s["max_torque"]]} N m'
             + (f' (with {len(s["wheels"])} wheels)' if s['wheels'] else '')
             + (f' (with {len(s["rotors"]["joints"])} rotors)' if s['rotors'] else ''),
             f'  binding limit(s): {s["binding_limit"]} (use: '
             + ', '.join(f'{k} {100 * v:.0f} %' for k, v in s['limit_usage'].items()) + ')',
             '', f'  {"profile":<56} {"criterion @ horizon":>20} {"time to target":>15}']
    for r in s['comparison']:
        crit = f"{100 * r['criterion']:.3g} %" if r['criterion'] is not None else 'inf'
        t = r['time_to_target']
        t_txt = 'n/a' if tgt['rel_std'] is None else _fmt_time(t if t is not None else math.inf)
        lines.append(f"  {r['name']:<56} {crit:>20} {t_txt:>15}")
    lines.append(f'  (criterion: largest targeted relative sigma, worst prior body, at '
                 f'{s["horizon"]:.3g} s)')
    return '\n'.join(lines) + '\n'


def _plot(path: Path, result: Any, target: Any) -> None:
    """The predicted sigma of each element and principal moment against time (PNG)."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for k, name in enumerate(_THETA):
        if result.model == 'diagonal' and k >= 3:
            continue
        ax.loglog(result.times, result.element_std[:, k], label=name)
    for k in range(3):
        ax.loglog(result.times, result.principal_std[:, k], '--', label=f'I{k + 1}')
    if math.isfinite(result.time_to_target):
        ax.axvline(result.time_to_target, color='k', lw=0.8, ls=':', label='time to target')
    ax.set_xlabel('time [s]')
    ax.set_ylabel('predicted sigma [kg m^2]')
    ax.set_title(result.profile.name)
    ax.grid(True, which='both', alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def write_all(out: Path, result: Any, prior: Any, lim: Any, target: Any, seed: int
              ) -> dict[str, Any]:
    """Write scene.yaml, torque.csv, sigma.png, plan.json and plan.txt; return the summary."""
    import numpy as np
    import yaml

    from inertia_ros.core import excitation as ex

    scene = ex.scene_dict(result.profile, lim, result.duration, prior.inertia, seed)
    (out / 'scene.yaml').write_text('# planned by python -m inertia_ros plan\n'
                                    + yaml.safe_dump(scene, sort_keys=False), encoding='utf-8')
    t = np.arange(int(math.floor(result.duration * lim.torque_rate + 1e-9)) + 1) \
        / lim.torque_rate
    tau = result.profile.torque(t, result.duration, seed)
    np.savetxt(out / 'torque.csv', np.column_stack([t, tau]), delimiter=',', fmt='%.9g',
               header='t_s,tau_x_Nm,tau_y_Nm,tau_z_Nm', comments='')
    _plot(out / 'sigma.png', result, target)
    s = _summary(result, prior, lim, target)
    (out / 'plan.json').write_text(json.dumps(s, indent=2) + '\n', encoding='utf-8')
    (out / 'plan.txt').write_text(_text(s), encoding='utf-8')
    return s
