"""Inverse kinematics over task maps: damped least squares with adaptive damping and restarts."""

from .dls import IKResult, IKStepper, dls_step, ik_step, solve_ik

__all__ = ("IKResult", "IKStepper", "dls_step", "ik_step", "solve_ik")
