"""A trajectory given by two plain user functions ``σ ↦ traj(σ)`` and ``σ ↦ dtraj/dσ``."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from dqcontrol.errors import ParameterError
from dqcontrol.trajectories._checks import unit_dq
from dqcontrol.trajectories.base import Trajectory

__all__ = ["FunctionTrajectory"]

#: Finite-difference step as a fraction of ``T_tot``: ``∛ε_machine ≈ 6.1e-6``.
FD_STEP_FRACTION = float(np.finfo(float).eps ** (1.0 / 3.0))


class FunctionTrajectory(Trajectory):
    """Trajectory from user callables (docs/theory.md §3 contract, any path).

    ``pose_fn(σ)`` must return the unit dual quaternion ``traj(σ)`` (vec8, shape ``(8,)``)
    for ``σ ∈ [0, T_tot]`` [s]; it is only ever called inside that interval. It should be
    geometric in the sense of §3 (the caller decides how ``T_tot`` enters it).

    If ``derivative_fn`` is ``None``, ``dtraj/dσ`` is a central finite difference
    ``(x(σ+h) - x(σ-h)) / 2h`` with ``h = ∛ε · T_tot ≈ 6.1e-6 T_tot`` [s] (the step that
    balances the ``h²/6 · x'''`` truncation error against the ``ε/h`` rounding error for a
    path whose time scale is ``T_tot``; relative error ≈ 1e-10). Within ``h`` of an end it
    switches to the second-order one-sided difference ``(∓3x(σ) ± 4x(σ±h) ∓ x(σ±2h)) / 2h``
    so that ``pose_fn`` is not called outside ``[0, T_tot]``. Neighbouring samples are
    sign-aligned to ``x(σ)`` first (``x`` and ``-x`` are the same pose, docs/theory.md §1), so a
    ``pose_fn`` that flips sign does not corrupt the difference. Each derivative costs two
    extra ``pose_fn`` calls.

    Args:
        pose_fn: ``σ [s] ↦ traj(σ)`` (vec8); ``pose_fn(0)`` is checked to be a unit dual
            quaternion of shape ``(8,)``.
        derivative_fn: ``σ [s] ↦ dtraj/dσ`` (vec8, [1/s]) or ``None`` (finite difference).
        duration_s: nominal duration ``T_tot`` [s], finite and ``> 0``.
        reference: pose ``ref`` in world (vec8) or ``None`` (anchored later).
    """

    def __init__(
        self,
        pose_fn: Callable[[float], np.ndarray],
        derivative_fn: Callable[[float], np.ndarray] | None,
        duration_s: float,
        reference: np.ndarray | None = None,
    ) -> None:
        super().__init__(duration_s, reference)
        if not callable(pose_fn):
            raise ParameterError(f"pose_fn must be callable σ [s] ↦ vec8, got {pose_fn!r}")
        if derivative_fn is not None and not callable(derivative_fn):
            raise ParameterError(
                f"derivative_fn must be callable σ [s] ↦ vec8 or None, got {derivative_fn!r}"
            )
        self.pose_fn = pose_fn
        self.derivative_fn = derivative_fn
        #: Finite-difference step ``h`` [s] (used only without ``derivative_fn``).
        self.fd_step_s = FD_STEP_FRACTION * self.duration
        unit_dq("pose_fn(0)", pose_fn(0.0))
        if derivative_fn is not None:
            d0 = self.local_derivative(0.0)
            if not np.isfinite(d0).all():
                raise ParameterError(f"derivative_fn(0) must be finite, got {d0!r}")

    def local_pose(self, sigma: float) -> np.ndarray:
        """``pose_fn(σ)``, checked (:meth:`Trajectory.local_pose`)."""
        return _vec8("pose_fn", self.pose_fn(sigma))

    def local_derivative(self, sigma: float) -> np.ndarray:
        """``derivative_fn(σ)``, checked (:meth:`Trajectory.local_derivative`)."""
        if self.derivative_fn is not None:
            return _vec8("derivative_fn", self.derivative_fn(sigma))
        h = self.fd_step_s
        x0 = self.local_pose(sigma)
        if sigma - h < 0.0:
            x1 = _aligned(self.local_pose(sigma + h), x0)
            x2 = _aligned(self.local_pose(sigma + 2.0 * h), x0)
            return (-3.0 * x0 + 4.0 * x1 - x2) / (2.0 * h)
        if sigma + h > self.duration:
            x1 = _aligned(self.local_pose(sigma - h), x0)
            x2 = _aligned(self.local_pose(sigma - 2.0 * h), x0)
            return (3.0 * x0 - 4.0 * x1 + x2) / (2.0 * h)
        forward = _aligned(self.local_pose(sigma + h), x0)
        backward = _aligned(self.local_pose(sigma - h), x0)
        return (forward - backward) / (2.0 * h)

    def _repr_params(self) -> list[str]:
        deriv = "finite difference" if self.derivative_fn is None else self.derivative_fn
        return [f"pose_fn={self.pose_fn!r}", f"derivative_fn={deriv!r}"]


def _vec8(name: str, value: object) -> np.ndarray:
    x = np.asarray(value, dtype=float)
    if x.shape != (8,):
        raise ParameterError(f"{name} must return a vec8 of shape (8,), got shape {x.shape}")
    return x


def _aligned(x: np.ndarray, reference: np.ndarray) -> np.ndarray:
    return -x if np.dot(x, reference) < 0.0 else x
