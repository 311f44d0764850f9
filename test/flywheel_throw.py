"""The simulated flywheel throw shared by the TU Delft script tests (no data of theirs).

A noise-free tumbling body with one flywheel on ``-z`` (the authors' axis), 4 kHz gyro and
wheel speed: the shape of the TU Delft throws, for tests that must run without the real
recordings (``test_tudelft_script.py``, ``test_real_data_tudelft.py``).
"""
from __future__ import annotations

from inertia_ros.core.scene import Scene
from inertia_ros.core.simulation import simulate

#: Flywheel inertia of the simulated throw [kg m^2] (the authors' is 1.69e-6).
J = 1.7e-6
#: Whole-body tensor [kg m^2] (ixx, iyy, izz, ixy, ixz, iyz).
BODY = [2.0e-4, 1.2e-4, 2.6e-4, 5e-6, -3e-6, 4e-6]


def flywheel_throw(duration: float, amplitude: float):
    """Simulate the throw for ``duration`` [s], the flywheel at 1200 rad/s varying by
    ``amplitude`` [rad/s] at 3 Hz; returns the simulator's result (``t_gyro``, ``omega``,
    ``wheel_speed``, ``inertia``, ...)."""
    sc = Scene.from_dict({
        'duration': duration, 'body': {'inertia': BODY},
        'initial_omega': [8.0, -12.0, 15.0], 'torque': [],
        'gyro': {'rate': 4000.0, 'noise_std': 0.0},
        'wheels': {'rate': 4000.0, 'list': [
            {'joint': 'flywheel', 'axis': [0, 0, -1], 'inertia': J,
             'speed': {'offset': 1200.0, 'amplitude': amplitude, 'frequency': 3.0}}]}})
    return simulate(sc, 0)
