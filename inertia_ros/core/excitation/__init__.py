"""Excitation design (issue 28): :func:`plan` designs a torque profile within actuator and
body-rate limits that reaches a target precision soonest, robust over a prior tensor, and
predicts its sigma against time (see :mod:`.design`).

``inputs``: prior, limits, target, profile; ``actuators``: reaction-wheel torque and speed
limits, rotor speed ranges; ``profiles``: the designed multisine family and the standard
profiles; ``design``: limits, information, criterion and the plan.
"""
from .actuators import (
    RotorLimits,
    WheelLimit,
    allocation,
    axis_peaks,
    wheel_speeds,
    wheel_torques,
)
from .design import (
                     Plan,
                     actuator_axis_scale,
                     choose_model,
                     criterion,
                     enforce_limits,
                     information_at,
                     limit_usage,
                     plan,
                     principal_std,
                     simulated_peak_rate,
                     targeted_rel_std,
                     theta_covariance,
                     time_to_reach,
)
from .inputs import NEAR_DIAGONAL, Limits, Prior, Profile, Target, make_prior
from .profiles import corner_frequency, design_candidates, multisine, scene_dict, standard_profiles

__all__ = ['NEAR_DIAGONAL', 'Limits', 'Plan', 'Prior', 'Profile', 'RotorLimits', 'Target',
           'WheelLimit', 'actuator_axis_scale', 'allocation', 'axis_peaks', 'choose_model',
           'corner_frequency', 'criterion', 'design_candidates', 'enforce_limits',
           'information_at', 'limit_usage', 'make_prior', 'multisine', 'plan', 'principal_std',
           'scene_dict', 'simulated_peak_rate', 'standard_profiles', 'targeted_rel_std',
           'theta_covariance', 'time_to_reach', 'wheel_speeds', 'wheel_torques']
