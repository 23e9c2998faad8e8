"""Circle in the reference frame's xy-plane (docs/theory.md §3, thesis eq. 5.1)."""

from __future__ import annotations

import math

import numpy as np

from dqcontrol.trajectories._checks import positive
from dqcontrol.trajectories._kernels import circle_rows_into
from dqcontrol.trajectories.base import Trajectory

__all__ = ["Circle"]

_IDENTITY = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])  # copied, never written


class Circle(Trajectory):
    """One turn of a circle of radius ``R`` about the reference frame's z-axis.

    ``t(σ) = R cos(Ωσ) i + R sin(Ωσ) j`` with ``Ω = 2π / T_tot`` [rad/s], rotation = identity
    relative to ``ref`` (thesis eq. 5.1). The path starts at ``(R, 0, 0)`` in ``ref``, so with
    the default anchoring (:meth:`anchored_at`) the circle lies in the start tool frame's
    xy-plane with its centre at ``-R`` along the tool's x-axis, turning about the tool's z.

    Since the rotation is the identity, ``traj(σ) = 1 + ε ½ t(σ)`` and
    ``dtraj/dσ = ε ½ dt/dσ`` with ``dt/dσ = RΩ (-sin(Ωσ) i + cos(Ωσ) j)`` (exact).

    Args:
        duration_s: nominal duration ``T_tot`` [s], finite and ``> 0``.
        radius_m: radius ``R`` [m], finite and ``> 0``.
        reference: pose ``ref`` in world (vec8) or ``None`` (anchored later).
    """

    def __init__(
        self, duration_s: float, radius_m: float = 0.1, reference: np.ndarray | None = None
    ) -> None:
        super().__init__(duration_s, reference)
        self._radius = positive("radius_m", radius_m, "m")
        self._omega = 2.0 * math.pi / self.duration
        self._half_r = 0.5 * self._radius
        self._half_r_omega = 0.5 * self._radius * self._omega
        self._pair_buffer[0, 0] = 1.0  # the constant r = 1 of the pose row

    @property
    def radius_m(self) -> float:
        """Radius ``R`` [m]."""
        return self._radius

    @property
    def omega_rad_per_s(self) -> float:
        """Angular rate ``Ω = 2π / T_tot`` [rad/s]."""
        return self._omega

    def local_pose(self, sigma: float) -> np.ndarray:
        """``traj(σ)`` in the reference frame (:meth:`Trajectory.local_pose`)."""
        angle = self._omega * sigma
        pose = _IDENTITY.copy()
        pose[5] = self._half_r * math.cos(angle)
        pose[6] = self._half_r * math.sin(angle)
        return pose

    def local_derivative(self, sigma: float) -> np.ndarray:
        """``dtraj/dσ`` in the reference frame (:meth:`Trajectory.local_derivative`)."""
        angle = self._omega * sigma
        h = self._half_r_omega
        return np.array([0.0, 0.0, 0.0, 0.0, 0.0, -h * math.sin(angle), h * math.cos(angle), 0.0])

    def _local_pair(self, sigma: float) -> np.ndarray:
        angle = self._omega * sigma
        c, s = math.cos(angle), math.sin(angle)
        h, hw = self._half_r, self._half_r_omega
        buf = self._pair_buffer  # rows [1, 0, 0, 0, 0, x, y, 0] and [0, …, dx, dy, 0]
        buf[0, 5] = h * c
        buf[0, 6] = h * s
        buf[1, 5] = -hw * s
        buf[1, 6] = hw * c
        return buf

    def local_poses(self, sigmas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Vectorized :meth:`local_pose` and :meth:`local_derivative`."""
        angle = self._omega * np.asarray(sigmas, dtype=float)
        poses, derivatives = np.empty((angle.shape[0], 8)), np.empty((angle.shape[0], 8))
        hr, hw = self._half_r, self._half_r_omega
        circle_rows_into(np.cos(angle), np.sin(angle), hr, hw, poses, derivatives)
        return poses, derivatives

    kind = "circle"

    def _metadata_params(self) -> dict:
        return {"radius_m": self._radius}

    def _repr_params(self) -> list[str]:
        return [f"radius_m={self._radius!r}"]
