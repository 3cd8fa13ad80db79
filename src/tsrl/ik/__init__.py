"""Inverse kinematics over task maps: damped least squares with adaptive damping, a null-space
posture term and restarts, in one solver (`DlsSolver`: `.step` for control loops, `.solve` for the
full solve)."""

from .dls import DlsSolver, IKOptions, IKResult

__all__ = ("DlsSolver", "IKOptions", "IKResult")
