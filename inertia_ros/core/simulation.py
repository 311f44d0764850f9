"""Scene simulation: Euler's rotational equations with quaternion attitude, and the sensors.

The body rotates under the commanded torque (a zero-order hold at ``scene.command_rate``)
plus the constant disturbance:

    I * omega_dot + omega x (I * omega) = tau_command + d          (body axes)
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

Sensors: the gyro samples the true angular velocity at its nominal instants ``k / rate`` and
adds a constant bias and white Gaussian noise.  The torque sensor reports the command in
effect at its nominal instants plus white noise of per-axis std
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

from inertia_ros.core.scene import Scene

__all__ = ['MAX_STEP_ANGLE', 'SimResult', 'command_grid', 'integrate_rigid_body', 'simulate']

#: Largest rotation [rad] of the body during one integration substep.
MAX_STEP_ANGLE = 2.0e-3

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


def _n_samples(duration: float, rate: float) -> int:
    """Number of samples ``k / rate`` with ``0 <= k / rate <= duration``."""
    return int(math.floor(duration * rate + 1e-9)) + 1


def command_grid(scene: Scene) -> np.ndarray:
    """Command update times ``k / command_rate`` [s] within the run, shape (J,)."""
    return np.arange(_n_samples(scene.duration, scene.command_rate)) / scene.command_rate


def _rk4_segment(s: list[float], tx: float, ty: float, tz: float, I: tuple[float, ...],
                 Ii: tuple[float, ...], h: float, n: int) -> list[float]:
    """Advance the state ``[wx, wy, wz, qw, qx, qy, qz]`` by ``n`` RK4 steps of ``h`` s.

    The torque ``(tx, ty, tz)`` [N m] is constant; ``I`` and ``Ii`` are the row-major
    tensor and its inverse.  Plain float arithmetic: this is the simulator's inner loop.
    """
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = I
    b00, b01, b02, b10, b11, b12, b20, b21, b22 = Ii
    wx, wy, wz, qw, qx, qy, qz = s
    h2 = 0.5 * h
    h6 = h / 6.0

    def f(wx: float, wy: float, wz: float, qw: float, qx: float, qy: float, qz: float
          ) -> tuple[float, float, float, float, float, float, float]:
        hx = a00 * wx + a01 * wy + a02 * wz
        hy = a10 * wx + a11 * wy + a12 * wz
        hz = a20 * wx + a21 * wy + a22 * wz
        rx = tx - (wy * hz - wz * hy)
        ry = ty - (wz * hx - wx * hz)
        rz = tz - (wx * hy - wy * hx)
        return (b00 * rx + b01 * ry + b02 * rz,
                b10 * rx + b11 * ry + b12 * rz,
                b20 * rx + b21 * ry + b22 * rz,
                0.5 * (-qx * wx - qy * wy - qz * wz),
                0.5 * (qw * wx + qy * wz - qz * wy),
                0.5 * (qw * wy + qz * wx - qx * wz),
                0.5 * (qw * wz + qx * wy - qy * wx))

    for _ in range(n):
        k1 = f(wx, wy, wz, qw, qx, qy, qz)
        k2 = f(wx + h2 * k1[0], wy + h2 * k1[1], wz + h2 * k1[2], qw + h2 * k1[3],
               qx + h2 * k1[4], qy + h2 * k1[5], qz + h2 * k1[6])
        k3 = f(wx + h2 * k2[0], wy + h2 * k2[1], wz + h2 * k2[2], qw + h2 * k2[3],
               qx + h2 * k2[4], qy + h2 * k2[5], qz + h2 * k2[6])
        k4 = f(wx + h * k3[0], wy + h * k3[1], wz + h * k3[2], qw + h * k3[3],
               qx + h * k3[4], qy + h * k3[5], qz + h * k3[6])
        wx += h6 * (k1[0] + 2.0 * (k2[0] + k3[0]) + k4[0])
        wy += h6 * (k1[1] + 2.0 * (k2[1] + k3[1]) + k4[1])
        wz += h6 * (k1[2] + 2.0 * (k2[2] + k3[2]) + k4[2])
        qw += h6 * (k1[3] + 2.0 * (k2[3] + k3[3]) + k4[3])
        qx += h6 * (k1[4] + 2.0 * (k2[4] + k3[4]) + k4[4])
        qy += h6 * (k1[5] + 2.0 * (k2[5] + k3[5]) + k4[5])
        qz += h6 * (k1[6] + 2.0 * (k2[6] + k3[6]) + k4[6])
    norm = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    return [wx, wy, wz, qw / norm, qx / norm, qy / norm, qz / norm]


def integrate_rigid_body(t_events: np.ndarray, torque: np.ndarray, inertia: np.ndarray,
                         omega0: np.ndarray, *, max_step_angle: float = MAX_STEP_ANGLE
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

    Returns
    -------
    omega : numpy.ndarray, shape (K, 3)
        Angular velocity [rad/s] at each event time.
    quat : numpy.ndarray, shape (K, 4)
        Attitude ``[w, x, y, z]`` (body -> inertial) at each event time.

    Raises
    ------
    ValueError
        If shapes disagree or the times are not strictly increasing.
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
    out = np.empty((k, 7))
    s = [float(omega0[0]), float(omega0[1]), float(omega0[2]), 1.0, 0.0, 0.0, 0.0]
    out[0] = s
    dts = np.diff(t_events).tolist()
    tq = torque.tolist()
    # Per segment: the tensor and its inverse as flat tuples, changing only at a change.
    cache_key: bytes | None = None
    I_t: tuple[float, ...] = ()
    Ii_t: tuple[float, ...] = ()
    inv = np.linalg.inv
    ii_norm = 0.0
    for j in range(k - 1):
        key = inertia[j].tobytes()
        if key != cache_key:
            cache_key = key
            I_t = tuple(inertia[j].ravel().tolist())
            Ii = inv(inertia[j])
            Ii_t = tuple(Ii.ravel().tolist())
            ii_norm = float(np.linalg.norm(Ii, 2))
        dt = dts[j]
        tx, ty, tz = tq[j]
        wmag = math.sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2])
        # rate bound over the segment: current spin plus what the torque can add
        wmax = wmag + ii_norm * math.sqrt(tx * tx + ty * ty + tz * tz) * dt
        n = max(1, math.ceil(wmax * dt / max_step_angle))
        s = _rk4_segment(s, tx, ty, tz, I_t, Ii_t, dt / n, n)
        out[j + 1] = s
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
    w_ev, q_ev = integrate_rigid_body(t_ev, applied, inertia_seg, scene.initial_omega)
    pick = np.clip(np.searchsorted(t_ev, t_g - _EVENT_TOL), 0, t_ev.size - 1)
    omega_true = w_ev[pick]
    attitude = q_ev[pick][:, [1, 2, 3, 0]]

    # Gyro stream.
    n_g = t_g.size
    omega = omega_true + np.asarray(scene.gyro.bias)
    if scene.gyro.noise_std > 0.0:
        omega = omega + r_gnoise.normal(0.0, scene.gyro.noise_std, size=(n_g, 3))

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

    # Imperfections on the stamps, then drops.
    im = scene.imperfections
    stamp_g = t_g.copy()
    stamp_t = t_s + im.torque_delay
    if im.timestamp_jitter > 0.0:
        lim_g = 0.45 / scene.gyro.rate
        lim_t = 0.45 / ts.rate
        stamp_g += np.clip(r_gjit.normal(0.0, im.timestamp_jitter, n_g), -lim_g, lim_g)
        stamp_t += np.clip(r_tjit.normal(0.0, im.timestamp_jitter, t_s.size), -lim_t, lim_t)
        stamp_g[0] = max(stamp_g[0], 0.0)
    keep_g = np.ones(n_g, dtype=bool)
    keep_t = np.ones(t_s.size, dtype=bool)
    if im.drop_rate > 0.0:
        keep_g = r_gdrop.random(n_g) >= im.drop_rate
        keep_t = r_tdrop.random(t_s.size) >= im.drop_rate

    return SimResult(
        t_gyro=stamp_g[keep_g], omega=omega[keep_g], omega_true=omega_true[keep_g],
        attitude_true=attitude[keep_g], t_torque=stamp_t[keep_t], torque=torque[keep_t],
        torque_command=torque_command[keep_t], inertia=np.array(scene.inertia),
        inertia_changes=changes, torque_bias_true=np.array(scene.disturbance),
        frame_id=scene.gyro.frame_id, scene=scene, seed=int(seed))
