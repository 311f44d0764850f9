"""Scene simulation: Euler's rotational equations with quaternion attitude, and the sensors.

The body rotates under the commanded torque (a zero-order hold at ``scene.command_rate``)
plus the constant disturbance and the aerodynamic damping ``-D omega`` (``scene.damping``):

    I * omega_dot + omega x (I * omega) = tau_command + d - D omega  (body axes)
    q_dot = 1/2 * q (x) [0, omega]                                   (q: body -> inertial)

The applied torque is piecewise constant, so the equations are integrated segment by segment
between the merged event times (command updates, gyro samples, the inertia change) with the
classical fourth-order Runge-Kutta scheme.  Each segment is split into substeps so that the
body turns at most ``MAX_STEP_ANGLE`` rad per substep; the local error is then of order
``MAX_STEP_ANGLE**5`` and torque-free energy and angular momentum stay constant to ~1e-12
relative over minutes.  The inner loop is plain float arithmetic (faster than small numpy
calls for a 7-element state).

At an inertia change the angular velocity is continuous (a payload that detaches or a
mass that moves inside the body without impulse), so angular momentum jumps.

Sensors: the gyro samples the true angular velocity at its nominal instants ``k / rate``
(through a first-order low-pass of time constant ``gyro.time_constant`` when set), adds a
constant bias and white Gaussian noise, and rounds to multiples of ``gyro.lsb`` when set.
The torque sensor reports the command in effect at its nominal instants plus white noise of
per-axis std
``noise_std + noise_rel * rms(command on that axis)``.  Imperfections act on the recorded
stamps (jitter, torque-stream delay) and drop samples independently in both streams.

Random draws: one ``numpy.random.default_rng(seed)`` spawns independent children for the
torque profiles, the gyro noise, the torque noise, the stamp jitter and the drops, so each
scene is reproducible from its seed and changing one part of a scene does not reshuffle the
noise of the others.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from inertia_ros.core.scene import MAX_SUBSTEPS, Scene, too_many_substeps

__all__ = ['MAX_STEP_ANGLE', 'SimResult', 'command_grid', 'integrate_rigid_body', 'simulate']

#: Largest rotation [rad] of the body during one integration substep.
MAX_STEP_ANGLE = 1.0e-2

_EVENT_TOL = 1e-9  # s: event times closer than this are merged


@dataclass(frozen=True, eq=False)
class SimResult:
    """The streams a real robot would record for a scene, and the truth behind them.

    Attributes
    ----------
    t_gyro : numpy.ndarray, shape (N,)
        Gyro header stamps [s] (nominal instants plus jitter; dropped samples removed).
    omega : numpy.ndarray, shape (N, 3)
        Measured angular velocity [rad/s], body axes (truth + bias + noise).
    omega_true : numpy.ndarray, shape (N, 3)
        True angular velocity [rad/s] at the gyro's sampling instants.
    attitude_true : numpy.ndarray, shape (N, 4)
        True attitude quaternion ``[x, y, z, w]`` (body -> inertial; identity at t = 0) at
        the gyro's sampling instants.
    t_torque : numpy.ndarray, shape (M,)
        Torque header stamps [s] (nominal instants + ``torque_delay`` + jitter).
    torque : numpy.ndarray, shape (M, 3)
        Measured torque [N m], body axes (command in effect + noise; no disturbance).
    torque_command : numpy.ndarray, shape (M, 3)
        The true held command [N m] in effect at each torque sample.
    inertia : numpy.ndarray, shape (3, 3)
        True tensor about the centre of mass at t = 0 [kg m^2].
    inertia_changes : tuple of (float, numpy.ndarray (3, 3))
        Later step changes of the tensor: (time [s], new tensor [kg m^2]).
    torque_bias_true : numpy.ndarray, shape (3,)
        The disturbance torque [N m]: acts on the body, absent from the torque stream.
    frame_id : str
        Frame of both streams (the gyro's frame).
    scene : Scene
        The scene that was simulated.
    seed : int
        The seed actually used.
    """

    t_gyro: np.ndarray
    omega: np.ndarray
    omega_true: np.ndarray
    attitude_true: np.ndarray
    t_torque: np.ndarray
    torque: np.ndarray
    torque_command: np.ndarray
    inertia: np.ndarray
    inertia_changes: tuple[tuple[float, np.ndarray], ...]
    torque_bias_true: np.ndarray
    frame_id: str
    scene: Scene
    seed: int
    #: JointState stamps [s] (K,) of a scene with wheels, else None.
    t_wheel: np.ndarray | None = None
    #: Measured wheel speeds [rad/s] (K, n_wheels), columns in the scene's wheel order.
    wheel_speed: np.ndarray | None = None
    #: True wheel speeds [rad/s] (K, n_wheels).
    wheel_speed_true: np.ndarray | None = None


def _n_samples(duration: float, rate: float) -> int:
    """Number of samples ``k / rate`` with ``0 <= k / rate <= duration``."""
    return int(math.floor(duration * rate + 1e-9)) + 1


def command_grid(scene: Scene) -> np.ndarray:
    """Command update times ``k / command_rate`` [s] within the run, shape (J,)."""
    return np.arange(_n_samples(scene.duration, scene.command_rate)) / scene.command_rate


def integrate_rigid_body(t_events: np.ndarray, torque: np.ndarray, inertia: np.ndarray,
                         omega0: np.ndarray, *, max_step_angle: float = MAX_STEP_ANGLE,
                         damping: np.ndarray | None = None
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Integrate Euler's equations and the attitude over piecewise-constant torque.

    Parameters
    ----------
    t_events : numpy.ndarray, shape (K,)
        Strictly increasing times [s]; the state is reported at each of them.
    torque : numpy.ndarray, shape (K - 1, 3)
        Torque [N m], body axes, constant on ``[t_events[k], t_events[k + 1])``.
    inertia : numpy.ndarray, shape (3, 3) or (K - 1, 3, 3)
        Tensor [kg m^2], constant or per segment.
    omega0 : numpy.ndarray, shape (3,)
        Angular velocity at ``t_events[0]`` [rad/s]; the attitude starts at identity.
    max_step_angle : float, optional
        Largest body rotation per RK4 substep [rad].
    damping : numpy.ndarray, shape (3,), optional
        Diagonal damping ``D`` [N m s/rad]: the torque ``-D omega`` acts as well.

    Returns
    -------
    omega : numpy.ndarray, shape (K, 3)
        Angular velocity [rad/s] at each event time.
    quat : numpy.ndarray, shape (K, 4)
        Attitude ``[w, x, y, z]`` (body -> inertial) at each event time.

    Raises
    ------
    ValueError
        If shapes disagree or the times are not strictly increasing; a
        :class:`~inertia_ros.core.scene.SceneError` when the run would need more than
        :data:`~inertia_ros.core.scene.MAX_SUBSTEPS` substeps (a body spinning too fast).
    """
    t_events = np.asarray(t_events, dtype=float)
    torque = np.asarray(torque, dtype=float)
    inertia = np.asarray(inertia, dtype=float)
    k = t_events.size
    if t_events.ndim != 1 or k < 1:
        raise ValueError('t_events: must be a non-empty 1-D array of times [s]')
    if np.any(np.diff(t_events) <= 0.0):
        raise ValueError('t_events: must be strictly increasing')
    if torque.shape != (k - 1, 3):
        raise ValueError(f'torque: expected shape {(k - 1, 3)}, got {torque.shape}')
    if inertia.shape == (3, 3):
        inertia = np.broadcast_to(inertia, (k - 1, 3, 3))
    if inertia.shape != (k - 1, 3, 3):
        raise ValueError(f'inertia: expected shape (3, 3) or {(k - 1, 3, 3)}, '
                         f'got {inertia.shape}')
    if max_step_angle <= 0.0:
        raise ValueError(f'max_step_angle: must be positive, got {max_step_angle}')
    omega0 = np.asarray(omega0, dtype=float).reshape(3)
    dx, dy, dz = (0.0, 0.0, 0.0) if damping is None else (float(v) for v in damping)
    wx, wy, wz = (float(v) for v in omega0)
    qw, qx, qy, qz = 1.0, 0.0, 0.0, 0.0
    rows = [(wx, wy, wz, qw, qx, qy, qz)]
    dts = np.diff(t_events).tolist()
    tq = torque.tolist()
    # Blocks of segments with the same tensor (usually one; two with an inertia change).
    changes = np.flatnonzero(np.any(inertia[1:] != inertia[:-1], axis=(1, 2))) + 1
    edges = [0, *changes.tolist(), k - 1]
    sqrt, ceil = math.sqrt, math.ceil
    budget = MAX_SUBSTEPS + k      # one substep per segment, plus what the rotation needs
    # Classical RK4, written out in plain floats: this is the simulator's inner loop, and
    # function calls or small numpy operations would dominate its cost.  State: omega
    # (wx, wy, wz) and the attitude quaternion (qw, qx, qy, qz).
    for e0, e1 in zip(edges[:-1], edges[1:], strict=True):
        if e1 <= e0:
            continue
        a00, a01, a02, a10, a11, a12, a20, a21, a22 = inertia[e0].ravel().tolist()
        Ii = np.linalg.inv(inertia[e0])
        b00, b01, b02, b10, b11, b12, b20, b21, b22 = Ii.ravel().tolist()
        ii_norm = float(np.linalg.norm(Ii, 2))
        for j in range(e0, e1):
            dt = dts[j]
            tx, ty, tz = tq[j]
            # rate bound over the segment: current spin plus what the torque can add
            wmax = sqrt(wx * wx + wy * wy + wz * wz) \
                + ii_norm * sqrt(tx * tx + ty * ty + tz * tz) * dt
            steps = wmax * dt / max_step_angle
            if not steps < budget:       # also inf / nan: refused before any work
                raise too_many_substeps(t_events[j], wmax, MAX_SUBSTEPS)
            n = max(1, ceil(steps))
            budget -= n
            h = dt / n
            h2 = 0.5 * h
            h6 = h / 6.0
            for _ in range(n):
                # stage 1 at (w, q)
                hx = a00 * wx + a01 * wy + a02 * wz
                hy = a10 * wx + a11 * wy + a12 * wz
                hz = a20 * wx + a21 * wy + a22 * wz
                rx = tx - dx * wx - (wy * hz - wz * hy)
                ry = ty - dy * wy - (wz * hx - wx * hz)
                rz = tz - dz * wz - (wx * hy - wy * hx)
                k1x = b00 * rx + b01 * ry + b02 * rz
                k1y = b10 * rx + b11 * ry + b12 * rz
                k1z = b20 * rx + b21 * ry + b22 * rz
                k1w = -0.5 * (qx * wx + qy * wy + qz * wz)
                k1a = 0.5 * (qw * wx + qy * wz - qz * wy)
                k1b = 0.5 * (qw * wy + qz * wx - qx * wz)
                k1c = 0.5 * (qw * wz + qx * wy - qy * wx)
                # stage 2 at (w, q) + h/2 k1
                ux, uy, uz = wx + h2 * k1x, wy + h2 * k1y, wz + h2 * k1z
                pw, pa, pb, pc = qw + h2 * k1w, qx + h2 * k1a, qy + h2 * k1b, qz + h2 * k1c
                hx = a00 * ux + a01 * uy + a02 * uz
                hy = a10 * ux + a11 * uy + a12 * uz
                hz = a20 * ux + a21 * uy + a22 * uz
                rx = tx - dx * ux - (uy * hz - uz * hy)
                ry = ty - dy * uy - (uz * hx - ux * hz)
                rz = tz - dz * uz - (ux * hy - uy * hx)
                k2x = b00 * rx + b01 * ry + b02 * rz
                k2y = b10 * rx + b11 * ry + b12 * rz
                k2z = b20 * rx + b21 * ry + b22 * rz
                k2w = -0.5 * (pa * ux + pb * uy + pc * uz)
                k2a = 0.5 * (pw * ux + pb * uz - pc * uy)
                k2b = 0.5 * (pw * uy + pc * ux - pa * uz)
                k2c = 0.5 * (pw * uz + pa * uy - pb * ux)
                # stage 3 at (w, q) + h/2 k2
                ux, uy, uz = wx + h2 * k2x, wy + h2 * k2y, wz + h2 * k2z
                pw, pa, pb, pc = qw + h2 * k2w, qx + h2 * k2a, qy + h2 * k2b, qz + h2 * k2c
                hx = a00 * ux + a01 * uy + a02 * uz
                hy = a10 * ux + a11 * uy + a12 * uz
                hz = a20 * ux + a21 * uy + a22 * uz
                rx = tx - dx * ux - (uy * hz - uz * hy)
                ry = ty - dy * uy - (uz * hx - ux * hz)
                rz = tz - dz * uz - (ux * hy - uy * hx)
                k3x = b00 * rx + b01 * ry + b02 * rz
                k3y = b10 * rx + b11 * ry + b12 * rz
                k3z = b20 * rx + b21 * ry + b22 * rz
                k3w = -0.5 * (pa * ux + pb * uy + pc * uz)
                k3a = 0.5 * (pw * ux + pb * uz - pc * uy)
                k3b = 0.5 * (pw * uy + pc * ux - pa * uz)
                k3c = 0.5 * (pw * uz + pa * uy - pb * ux)
                # stage 4 at (w, q) + h k3
                ux, uy, uz = wx + h * k3x, wy + h * k3y, wz + h * k3z
                pw, pa, pb, pc = qw + h * k3w, qx + h * k3a, qy + h * k3b, qz + h * k3c
                hx = a00 * ux + a01 * uy + a02 * uz
                hy = a10 * ux + a11 * uy + a12 * uz
                hz = a20 * ux + a21 * uy + a22 * uz
                rx = tx - dx * ux - (uy * hz - uz * hy)
                ry = ty - dy * uy - (uz * hx - ux * hz)
                rz = tz - dz * uz - (ux * hy - uy * hx)
                k4x = b00 * rx + b01 * ry + b02 * rz
                k4y = b10 * rx + b11 * ry + b12 * rz
                k4z = b20 * rx + b21 * ry + b22 * rz
                k4w = -0.5 * (pa * ux + pb * uy + pc * uz)
                k4a = 0.5 * (pw * ux + pb * uz - pc * uy)
                k4b = 0.5 * (pw * uy + pc * ux - pa * uz)
                k4c = 0.5 * (pw * uz + pa * uy - pb * ux)
                wx += h6 * (k1x + 2.0 * (k2x + k3x) + k4x)
                wy += h6 * (k1y + 2.0 * (k2y + k3y) + k4y)
                wz += h6 * (k1z + 2.0 * (k2z + k3z) + k4z)
                qw += h6 * (k1w + 2.0 * (k2w + k3w) + k4w)
                qx += h6 * (k1a + 2.0 * (k2a + k3a) + k4a)
                qy += h6 * (k1b + 2.0 * (k2b + k3b) + k4b)
                qz += h6 * (k1c + 2.0 * (k2c + k3c) + k4c)
            norm = sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
            qw, qx, qy, qz = qw / norm, qx / norm, qy / norm, qz / norm
            rows.append((wx, wy, wz, qw, qx, qy, qz))
    out = np.array(rows, dtype=float).reshape(k, 7)
    return out[:, :3].copy(), out[:, 3:].copy()


def _merge_times(*arrays: np.ndarray) -> np.ndarray:
    """Sorted union of time arrays with values closer than ``_EVENT_TOL`` merged."""
    t = np.sort(np.concatenate(arrays))
    keep = np.concatenate([[True], np.diff(t) > _EVENT_TOL])
    return t[keep]


def simulate(scene: Scene, seed: int | None = None) -> SimResult:
    """Simulate a scene: the gyro and torque streams and the truth behind them.

    Parameters
    ----------
    scene : Scene
        A validated scene (``Scene.from_dict``).
    seed : int, optional
        Seed for every random draw; default ``scene.seed``.

    Returns
    -------
    SimResult
        Streams and truth; times in float seconds from the start of the run.

    Raises
    ------
    ValueError
        If ``scene`` is not a Scene or ``seed`` is negative.
    """
    if not isinstance(scene, Scene):
        raise ValueError(f'scene: expected a Scene, got {type(scene).__name__}')
    if seed is None:
        seed = scene.seed
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f'seed: must be a non-negative integer, got {seed!r}')
    rng = np.random.default_rng(int(seed))
    (r_torque, r_gnoise, r_tnoise, r_gjit, r_tjit, r_gdrop, r_tdrop) = rng.spawn(7)

    # Commands on the zero-order-hold grid.
    t_cmd = command_grid(scene)
    cmd = np.zeros((t_cmd.size, 3))
    for comp, r in zip(scene.torque, r_torque.spawn(len(scene.torque)), strict=True):
        cmd += comp.evaluate(t_cmd, r)
    cr = scene.command_rate

    # Events: gyro instants, command updates, the inertia change.
    t_g = np.arange(_n_samples(scene.duration, scene.gyro.rate)) / scene.gyro.rate
    extra = [np.array([scene.inertia_change.time])] if scene.inertia_change else []
    t_ev = _merge_times(t_g, t_cmd, *extra)
    t_ev = t_ev[t_ev <= scene.duration + _EVENT_TOL]
    seg_start = t_ev[:-1]
    idx = np.minimum(np.floor(seg_start * cr + 1e-6).astype(int), t_cmd.size - 1)
    applied = cmd[idx] + scene.disturbance
    inertia_seg = np.broadcast_to(scene.inertia, (seg_start.size, 3, 3)).copy()
    changes: tuple[tuple[float, np.ndarray], ...] = ()
    if scene.inertia_change is not None:
        after = seg_start >= scene.inertia_change.time - _EVENT_TOL
        inertia_seg[after] = scene.inertia_change.inertia
        changes = ((scene.inertia_change.time, np.array(scene.inertia_change.inertia)),)
    w_ev, q_ev = _integrate(scene, t_ev, applied, inertia_seg)
    pick = np.clip(np.searchsorted(t_ev, t_g - _EVENT_TOL), 0, t_ev.size - 1)
    omega_true = w_ev[pick]
    attitude = q_ev[pick][:, [1, 2, 3, 0]]

    omega = _gyro_reading(scene, omega_true, r_gnoise)

    # Torque stream.
    ts = scene.torque_sensor
    t_s = np.arange(_n_samples(scene.duration, ts.rate)) / ts.rate
    idx_s = np.minimum(np.floor(t_s * cr + 1e-6).astype(int), t_cmd.size - 1)
    torque_command = cmd[idx_s]
    rms = np.sqrt(np.mean(cmd ** 2, axis=0))
    std = ts.noise_std + ts.noise_rel * rms
    torque = torque_command.copy()
    if np.any(std > 0.0):
        torque += r_tnoise.standard_normal(size=torque.shape) * std

    stamp_g, stamp_t, keep_g, keep_t = _imperfections(scene, t_g, t_s, r_gjit, r_tjit,
                                                      r_gdrop, r_tdrop)
    return SimResult(**_wheel_result(scene, int(seed)),
        t_gyro=stamp_g[keep_g], omega=omega[keep_g], omega_true=omega_true[keep_g],
        attitude_true=attitude[keep_g], t_torque=stamp_t[keep_t], torque=torque[keep_t],
        torque_command=torque_command[keep_t], inertia=np.array(scene.inertia),
        inertia_changes=changes, torque_bias_true=np.array(scene.disturbance),
        frame_id=scene.gyro.frame_id, scene=scene, seed=int(seed))


def _gyro_reading(scene: Scene, omega_true: np.ndarray, rng: np.random.Generator
                  ) -> np.ndarray:
    """The gyro stream (N, 3) [rad/s]: low-pass, bias, white noise, then quantisation."""
    g = scene.gyro
    omega = _lowpass(omega_true, g.time_constant, 1.0 / g.rate) + np.asarray(g.bias)
    if g.noise_std > 0.0:
        omega = omega + rng.normal(0.0, g.noise_std, size=omega.shape)
    if g.lsb > 0.0:
        omega = g.lsb * np.round(omega / g.lsb)
    return omega


def _lowpass(omega: np.ndarray, T: float, h: float) -> np.ndarray:
    """The first-order sensor filter ``y' = (omega - y) / T`` on the gyro grid (step ``h``
    [s]; exact for ``omega`` linear between samples), at rest on ``omega[0]``; ``T = 0``: none.
    """
    if T <= 0.0:
        return omega
    from scipy.signal import lfilter  # lazily: scipy.signal costs start-up time

    a = math.exp(-h / T)
    c = T / h * (1.0 - a)
    return lfilter([1.0 - c, c - a], [1.0, -a], omega - omega[0], axis=0) + omega[0]


def _integrate(scene: Scene, t_ev: np.ndarray, applied: np.ndarray,
               inertia_seg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Body rates and attitude at the events: with the scene's wheels when it has any."""
    if scene.wheels is not None:
        from inertia_ros.core.wheel_sim import integrate_with_wheels
        return integrate_with_wheels(t_ev, applied, inertia_seg, scene.initial_omega,
                                     scene.wheels)
    return integrate_rigid_body(t_ev, applied, inertia_seg, scene.initial_omega,
                                damping=scene.damping)


def _wheel_result(scene: Scene, seed: int) -> dict[str, np.ndarray]:
    """The JointState stream of a scene with wheels (``{}`` without): its own generator, so
    a scene without wheels draws exactly as before."""
    if scene.wheels is None:
        return {}
    from inertia_ros.core.wheel_sim import wheel_streams
    t_wh, sp, sp_true = wheel_streams(scene.wheels, scene.duration,
                                      np.random.default_rng([seed, 0x77686565]))
    return {'t_wheel': t_wh, 'wheel_speed': sp, 'wheel_speed_true': sp_true}


def _imperfections(scene: Scene, t_g: np.ndarray, t_s: np.ndarray, r_gjit: np.random.Generator,
                   r_tjit: np.random.Generator, r_gdrop: np.random.Generator,
                   r_tdrop: np.random.Generator
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Imperfections on the stamps (delay, jitter), then drops.

    Returns
    -------
    stamp_g, stamp_t : ndarray
        Gyro and torque stamps [s], shapes of ``t_g`` and ``t_s``.
    keep_g, keep_t : ndarray of bool
        Samples not dropped.
    """
    im = scene.imperfections
    n_g = t_g.size
    stamp_g = t_g.copy()
    stamp_t = t_s + im.torque_delay
    if im.timestamp_jitter > 0.0:
        lim_g = 0.45 / scene.gyro.rate
        lim_t = 0.45 / scene.torque_sensor.rate
        stamp_g += np.clip(r_gjit.normal(0.0, im.timestamp_jitter, n_g), -lim_g, lim_g)
        stamp_t += np.clip(r_tjit.normal(0.0, im.timestamp_jitter, t_s.size), -lim_t, lim_t)
        stamp_g[0] = max(stamp_g[0], 0.0)
    keep_g = np.ones(n_g, dtype=bool)
    keep_t = np.ones(t_s.size, dtype=bool)
    if im.drop_rate > 0.0:
        keep_g = r_gdrop.random(n_g) >= im.drop_rate
        keep_t = r_tdrop.random(t_s.size) >= im.drop_rate
    return stamp_g, stamp_t, keep_g, keep_t
