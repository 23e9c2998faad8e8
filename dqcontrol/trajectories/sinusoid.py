"""Sinusoid along the reference frame's x-axis, oscillating in z (docs/theory.md §3, eq. 5.3)."""

from __future__ import annotations

import math

import numpy as np

from dqcontrol.trajectories._checks import positive
from dqcontrol.trajectories.base import Trajectory

__all__ = ["Sinusoid"]


class Sinusoid(Trajectory):
    """``t(σ) = vσ i + A sin(Ω_x v σ) k`` with ``v = 2π / (15 T_tot)`` (thesis eq. 5.3).

    The path always spans ``x ∈ [0, 2π/15]`` m whatever ``T_tot`` (``v`` [m/s] is the
    nominal x-speed), i.e. ``Ω_x / 15`` periods: four with the thesis's ``Ω_x = 60 rad/m``.
    The rotation is the identity relative to ``ref``, so ``traj(σ) = 1 + ε ½ t(σ)`` and
    ``dtraj/dσ = ε ½ (v i + A Ω_x v cos(Ω_x v σ) k)`` (exact).

    Args:
        duration_s: nominal duration ``T_tot`` [s], finite and ``> 0``.
        amplitude_m: amplitude ``A`` [m] along z, finite and ``> 0``.
        omega_x_rad_per_m: spatial frequency ``Ω_x`` [rad/m] along x, finite and ``> 0``.
        reference: pose ``ref`` in world (vec8) or ``None`` (anchored later).
    """

    #: Length of the path along x [m]: ``v T_tot = 2π/15``.
    LENGTH_X_M = 2.0 * math.pi / 15.0

    def __init__(
        self,
        duration_s: float,
        amplitude_m: float = 0.1,
        omega_x_rad_per_m: float = 60.0,
        reference: np.ndarray | None = None,
    ) -> None:
        super().__init__(duration_s, reference)
        self._amplitude = positive("amplitude_m", amplitude_m, "m")
        self._omega_x = positive("omega_x_rad_per_m", omega_x_rad_per_m, "rad/m")
        self._speed = self.LENGTH_X_M / self.duration
        self._rate = self._omega_x * self._speed  # Ω_x v [rad/s]
        self._pair_buffer[0, 0] = 1.0  # the constant r = 1 of the pose row

    @property
    def amplitude_m(self) -> float:
        """Amplitude ``A`` [m] along z."""
        return self._amplitude

    @property
    def omega_x_rad_per_m(self) -> float:
        """Spatial frequency ``Ω_x`` [rad/m] along x."""
        return self._omega_x

    @property
    def speed_m_per_s(self) -> float:
        """Nominal speed along x ``v = 2π / (15 T_tot)`` [m/s]."""
        return self._speed

    def local_pose(self, sigma: float) -> np.ndarray:
        """``traj(σ)`` in the reference frame (:meth:`Trajectory.local_pose`)."""
        x = self._speed * sigma
        z = self._amplitude * math.sin(self._rate * sigma)
        return np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.5 * x, 0.0, 0.5 * z])

    def local_derivative(self, sigma: float) -> np.ndarray:
        """``dtraj/dσ`` in the reference frame (:meth:`Trajectory.local_derivative`)."""
        dz = self._amplitude * self._rate * math.cos(self._rate * sigma)
        return np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.5 * self._speed, 0.0, 0.5 * dz])

    def _local_pair(self, sigma: float) -> np.ndarray:
        phase = self._rate * sigma
        a, v = self._amplitude, self._speed
        x, z = 0.5 * (v * sigma), 0.5 * (a * math.sin(phase))
        dz = 0.5 * (a * self._rate * math.cos(phase))
        buf = self._pair_buffer  # rows [1, 0, 0, 0, 0, x, 0, z] and [0, …, dx, 0, dz]
        buf[0, 5] = x
        buf[0, 7] = z
        buf[1, 5] = 0.5 * v
        buf[1, 7] = dz
        return buf

    def local_poses(self, sigmas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Vectorized :meth:`local_pose` and :meth:`local_derivative`."""
        s = np.asarray(sigmas, dtype=float)
        phase = self._rate * s
        poses = np.zeros((s.shape[0], 8))
        poses[:, 0] = 1.0
        poses[:, 5] = 0.5 * (self._speed * s)
        poses[:, 7] = 0.5 * (self._amplitude * np.sin(phase))
        derivatives = np.zeros((s.shape[0], 8))
        derivatives[:, 5] = 0.5 * self._speed
        derivatives[:, 7] = 0.5 * (self._amplitude * self._rate * np.cos(phase))
        return poses, derivatives

    kind = "sinusoid"

    def _metadata_params(self) -> dict:
        return {"amplitude_m": self._amplitude, "omega_x_rad_per_m": self._omega_x}

    def _repr_params(self) -> list[str]:
        return [
            f"amplitude_m={self.amplitude_m!r}",
            f"omega_x_rad_per_m={self.omega_x_rad_per_m!r}",
        ]
