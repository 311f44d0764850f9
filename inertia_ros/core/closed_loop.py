"""Closed-loop simulation: a scene's body driven step by step by a commanded torque.

The open-loop simulator (:func:`inertia_ros.core.simulation.simulate`) knows the whole torque
profile in advance; in closed loop the torque is whatever a controller (the ``exciter``)
commanded last, held (zero-order hold) until the next command.  :class:`ClosedLoopBody`
advances the scene's body from its current time to a later one under a commanded torque
that the actuator latches at its next update instant ``k / command_rate`` (the scene's
zero-order-hold grid, as in open loop),
with the project's integrator (:func:`~inertia_ros.core.simulation.integrate_rigid_body`:
Euler's equations, RK4, damping), and returns the sensor samples that fell in between:

- gyro at ``k / gyro.rate``: the true rate through the scene's first-order low-pass, plus
  bias and white noise, quantised to ``gyro.lsb`` (as the open-loop simulator);
- torque sensor at ``k / torque_sensor.rate``: the applied (latched) command plus white
  noise of std
  ``noise_std + noise_rel * rms(commands so far)`` per axis (the open-loop simulator uses
  the rms of the whole profile, unknown in closed loop).

The scene's disturbance acts on the body (not measured), its inertia change happens at its
time.  Not modelled in closed loop (refused or ignored, as said): wheels and rotors
(refused), stamp jitter, torque delay and drops (ignored: the stamps are nominal).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from inertia_ros.core.scene import Scene
from inertia_ros.core.simulation import integrate_rigid_body

__all__ = ['ClosedLoopBody', 'ClosedLoopSamples']

_TOL = 1e-9  # s


@dataclass(frozen=True)
class ClosedLoopSamples:
    """Sensor samples of one :meth:`ClosedLoopBody.advance`.

    Attributes
    ----------
    t_gyro : numpy.ndarray, shape (N,)
        Gyro stamps [s] from the start.
    omega : numpy.ndarray, shape (N, 3)
        Measured rate [rad/s].
    omega_true : numpy.ndarray, shape (N, 3)
        True rate [rad/s].
    t_torque : numpy.ndarray, shape (M,)
        Torque-sensor stamps [s].
    torque : numpy.ndarray, shape (M, 3)
        Measured applied torque [N m] (the command plus sensor noise).
    """

    t_gyro: np.ndarray
    omega: np.ndarray
    omega_true: np.ndarray
    t_torque: np.ndarray
    torque: np.ndarray


class ClosedLoopBody:
    """A scene's rigid body integrated forward under commanded torque.

    Parameters
    ----------
    scene : Scene
        Body, initial rate, damping, disturbance, inertia change and sensors; its own
        torque components are not used.
    seed : int, optional
        Seed of the sensor noise; default ``scene.seed``.

    Raises
    ------
    ValueError
        For a scene with wheels or rotors (not simulated in closed loop).
    """

    def __init__(self, scene: Scene, seed: int | None = None) -> None:
        if scene.wheels is not None or getattr(scene, 'rotors', None) is not None:
            raise ValueError(f'scene {scene.name!r}: closed loop (command_topic) simulates a '
                             'rigid body under a commanded torque; a scene with wheels or '
                             'rotors is not supported: use a scene without them')
        self.scene = scene
        rng = np.random.default_rng(int(scene.seed if seed is None else seed))
        self._r_gyro, self._r_torque = rng.spawn(2)
        self.t = 0.0
        self.omega = np.array(scene.initial_omega, dtype=float)
        self._filtered = self.omega.copy()
        self._k_gyro = 0
        self._k_torque = 0
        self._k_cmd = 0
        self._latched = np.zeros(3)  # command applied by the actuator [N m]
        self._sum_sq = np.zeros(3)
        self._n_cmd = 0
        #: True once the samples at the end of the run were returned.
        self.finished_sampled = False

    @property
    def duration(self) -> float:
        """Length of the run [s] (the scene's duration)."""
        return float(self.scene.duration)

    @property
    def finished(self) -> bool:
        """True once the run's last samples were returned."""
        return self.finished_sampled

    def inertia_at(self, t: float) -> np.ndarray:
        """The true tensor (3, 3) [kg m^2] at ``t`` [s]."""
        ch = self.scene.inertia_change
        if ch is not None and t >= ch.time - _TOL:
            return np.array(ch.inertia)
        return np.array(self.scene.inertia)

    def _instants(self, rate: float, k0: int, t_to: float, last: bool) -> np.ndarray:
        """Sample instants ``k / rate`` from index ``k0`` up to ``t_to`` (inclusive only when
        ``last``: the end of the run)."""
        k1 = int(math.floor(t_to * rate + 1e-9))
        if not last and k1 / rate >= t_to - _TOL:
            k1 -= 1
        return np.arange(k0, k1 + 1) / rate if k1 >= k0 else np.zeros(0)

    def advance(self, t_to: float, command: np.ndarray) -> ClosedLoopSamples:
        """Hold ``command`` (3,) [N m] from the current time to ``t_to`` [s].

        The run ends at the scene's duration (``t_to`` is capped there).  Samples at
        instants in ``[t, t_to)`` are returned (``t_to`` itself too at the end of the run).
        """
        command = np.asarray(command, dtype=float).reshape(3)
        if not np.all(np.isfinite(command)):
            raise ValueError(f'command torque must be finite, got {command.tolist()}')
        last = t_to >= self.duration - _TOL
        t_to = min(float(t_to), self.duration)
        empty = ClosedLoopSamples(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)),
                                  np.zeros(0), np.zeros((0, 3)))
        if self.finished_sampled or (t_to <= self.t + _TOL and not last):
            return empty
        sc = self.scene
        t_g = self._instants(sc.gyro.rate, self._k_gyro, t_to, last)
        t_s = self._instants(sc.torque_sensor.rate, self._k_torque, t_to, last)
        t_c = self._instants(sc.command_rate, self._k_cmd, t_to, last)
        extra = [sc.inertia_change.time] if sc.inertia_change is not None \
            and self.t < sc.inertia_change.time < t_to else []
        ev = np.unique(np.concatenate([[self.t, t_to], t_g, t_c, extra]))
        ev = ev[np.concatenate([[True], np.diff(ev) > _TOL])]
        # the actuator latches the newest command at its next update instant (zero-order
        # hold on the scene's command grid, as in open loop); the old one holds until then
        switch = float(t_c[0]) if t_c.size else np.inf
        if ev.size >= 2:
            seg = ev[:-1]
            inertia = np.stack([self.inertia_at(s) for s in seg])
            applied = np.where((seg >= switch - _TOL)[:, None], command, self._latched) \
                + np.asarray(sc.disturbance)
            w_ev, _ = integrate_rigid_body(ev, applied, inertia, self.omega,
                                           damping=sc.damping)
        else:
            w_ev = self.omega[None, :]
        pick = np.clip(np.searchsorted(ev, t_g - _TOL), 0, ev.size - 1)
        omega_true = w_ev[pick]
        held = np.where((t_s >= switch - _TOL)[:, None], command, self._latched)
        if t_c.size:
            self._latched = command.copy()
        self.omega = w_ev[-1].copy()
        self.t = t_to
        self._k_gyro += t_g.size
        self._k_torque += t_s.size
        self._k_cmd += t_c.size
        if last:
            self.finished_sampled = True
        self._sum_sq += np.sum(held ** 2, axis=0)
        self._n_cmd += t_s.size
        return ClosedLoopSamples(t_g, self._gyro(omega_true), omega_true, t_s,
                                 self._torque(held))

    def _gyro(self, omega_true: np.ndarray) -> np.ndarray:
        """Gyro readings (N, 3) [rad/s]: low-pass, bias, noise, quantisation."""
        g = self.scene.gyro
        out = omega_true.copy()
        if g.time_constant > 0.0:
            a = math.exp(-1.0 / (g.rate * g.time_constant))
            for i in range(out.shape[0]):
                self._filtered = a * self._filtered + (1.0 - a) * omega_true[i]
                out[i] = self._filtered
        out = out + np.asarray(g.bias)
        if g.noise_std > 0.0 and out.size:
            out = out + self._r_gyro.normal(0.0, g.noise_std, size=out.shape)
        if g.lsb > 0.0:
            out = g.lsb * np.round(out / g.lsb)
        return out

    def _torque(self, held: np.ndarray) -> np.ndarray:
        """Torque-sensor readings (n, 3) [N m] of the applied commands ``held`` (n, 3)."""
        ts = self.scene.torque_sensor
        out = held.copy()
        n = out.shape[0]
        rms = np.sqrt(self._sum_sq / max(self._n_cmd, 1))
        std = ts.noise_std + ts.noise_rel * rms
        if n and np.any(std > 0.0):
            out += self._r_torque.standard_normal(size=out.shape) * std
        return out
