"""A C² pose spline through waypoints (positions and orientations) at given phases.

Positions: a clamped cubic spline per coordinate (zero velocity at both ends, C²).

Orientations: a *cumulative* spline of the relative rotations between consecutive keyframes,

    r(σ) = r_0 ⊗ exp(½ β_1(σ) ω_1) ⊗ exp(½ β_2(σ) ω_2) ⊗ … ⊗ exp(½ β_{N-1}(σ) ω_{N-1}),

where ``ω_i = log(r_{i-1}* r_i)`` is the rotation vector [rad] taking keyframe ``i-1`` to
keyframe ``i`` (in the frame of keyframe ``i-1``, shortest way, angle ≤ π) and ``β_i(σ)`` is
the clamped cubic spline through the step data ``β_i(t_k) = 1 if k ≥ i else 0``. This is the
cumulative form of Kim, Kim & Shin (SIGGRAPH 1995) with the interpolating cubic spline basis
instead of the B-spline one. Why this choice:

- it passes *exactly* through every keyframe (at ``t_k`` the first ``k`` factors are the
  relative rotations and the others the identity, so ``r(t_k) = r_k``);
- it is C² on SO(3): each ``β_i`` is C² and ``exp`` is smooth, so no chart is needed and
  there is no singularity at any angle (a spline of global rotation vectors would be C² too,
  but distorts large rotations and breaks at 2π);
- it uses the same interpolation as the positions: for rotations about one fixed axis it is
  exactly the clamped cubic spline of the accumulated angle, and the angular velocity is
  zero at both ends like the linear velocity, so rotation and translation start and stop
  together;
- its derivative is analytic: ``d/dσ exp(½ β ω) = ½ β' ω̂ exp(½ β ω)`` because the pure
  quaternion ``ω̂`` commutes with its own exponential, and the product rule over the factors
  gives ``dr/dσ`` in one forward sweep.

Its cost is one factor per keyframe pair with a rotation (the cubic spline basis is not
local); it is meant for tens of waypoints, not thousands (about 90 µs for a horizon of 10
phases with 6 rotating keyframes, 35 µs without rotation).

The dual quaternion is ``x = r + ε ½ t r`` (eq. 2.23), so
``dx/dσ = r' + ε ½ (t' r + t r')`` with ``t'`` from the position spline.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline

from dqcontrol.dq.algebra import haminus4, hamiplus4, qconj, qmul
from dqcontrol.errors import ParameterError
from dqcontrol.trajectories._checks import positive
from dqcontrol.trajectories.base import Trajectory

__all__ = ["WaypointTrajectory"]

#: Accepted deviation of a given orientation quaternion's norm from 1 (it is then normalised).
QUATERNION_NORM_TOL = 1e-3

#: ``q @ _PURE_LEFT[:, 4k:4k+4] = e_k ⊗ q`` for the unit pure quaternions ``e_1 = i, j, k``,
#: as one block-diagonal matrix acting on ``[q, q']`` (M, 8) → (M, 24).
_PURE_LEFT = np.zeros((8, 24))
for _k in range(3):
    _e = np.zeros(4)
    _e[_k + 1] = 1.0
    _PURE_LEFT[:4, 4 * _k : 4 * _k + 4] = hamiplus4(_e).T
    _PURE_LEFT[4:, 12 + 4 * _k : 12 + 4 * _k + 4] = hamiplus4(_e).T
del _k, _e

#: ``h ** _POWERS * _POWER_SCALE = [[h³, h², h, 1], [3h², 2h, 1, 0]]`` (value and slope rows).
_POWERS = np.array([[3.0, 2.0, 1.0, 0.0], [2.0, 1.0, 0.0, 0.0]])
_POWER_SCALE = np.array([[1.0, 1.0, 1.0, 1.0], [3.0, 2.0, 1.0, 0.0]])


class WaypointTrajectory(Trajectory):
    """Pose trajectory through ``N ≥ 2`` waypoints, C² in position and orientation.

    Args:
        positions_m: waypoint positions ``(N, 3)`` [m] in the reference frame.
        orientations: waypoint orientations ``(N, 4)`` as unit quaternions ``[w, x, y, z]``
            (norm within ``1 ± 1e-3``, normalised here; the sign of each is free), or
            ``None`` for the identity throughout. Consecutive keyframes are joined the short
            way (relative angle ≤ π): add keyframes for larger turns.
        times_s: phases ``(N,)`` [s] at which the waypoints are reached, starting at 0 and
            strictly increasing; ``T_tot = times_s[-1]``. If ``None``, ``duration_s`` is
            required and the times are proportional to the cumulative chord length of the
            positions (consecutive positions must then differ).
        duration_s: ``T_tot`` [s]; with ``times_s`` it may be omitted (or must equal
            ``times_s[-1]``).
        reference: pose ``ref`` in world (vec8) or ``None`` (anchored later).
    """

    def __init__(
        self,
        positions_m: np.ndarray,
        orientations: np.ndarray | None = None,
        times_s: np.ndarray | None = None,
        duration_s: float | None = None,
        reference: np.ndarray | None = None,
    ) -> None:
        positions = _check_positions(positions_m)
        n = positions.shape[0]
        times = _check_times(times_s, duration_s, positions)
        super().__init__(float(times[-1]), reference)
        quats = None if orientations is None else _check_orientations(orientations, n)

        self._positions = _read_only(positions)
        self._times = _read_only(times)
        self._orientations = None if quats is None else _read_only(quats)

        # Relative rotations ω_i = θ_i u_i between consecutive keyframes (identity ones dropped).
        self._r0 = np.array([1.0, 0.0, 0.0, 0.0]) if quats is None else quats[0].copy()
        half_angles: list[float] = []
        right_factor: list[np.ndarray] = []  # linear maps of [P, P'] used by _rotation
        step_data: list[np.ndarray] = []
        if quats is not None:
            rel = qmul(qconj(quats[:-1]), quats[1:])
            for i, (w, *v) in enumerate(rel, start=1):
                sin_half = math.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2)
                if sin_half < 1e-15:
                    continue
                half_angles.append(math.atan2(sin_half, w))
                axis_t = haminus4(np.concatenate(([0.0], np.asarray(v) / sin_half))).T
                # [P, P'] ↦ four 8-blocks: [P, P'], [P u, P' u], [0, P u], [0, P].
                factor = np.zeros((8, 32))
                factor[:, :8] = np.eye(8)
                factor[:4, 8:12] = axis_t
                factor[4:, 12:16] = axis_t
                factor[:4, 20:24] = axis_t
                factor[:4, 28:32] = np.eye(4)
                right_factor.append(factor)
                step_data.append((np.arange(n) >= i).astype(float))
        self._half_angles = np.array(half_angles)
        self._right_factor = right_factor

        # One clamped cubic spline for [x, y, z, β_1 … β_m]; same knots, same end conditions.
        data = np.column_stack([positions, *step_data]) if step_data else positions
        spline = CubicSpline(times, data, axis=0, bc_type="clamped")
        self._inner_knots = np.ascontiguousarray(spline.x[1:-1])
        self._knots = spline.x
        # (N-1, 4, 3 + k): per interval, coefficients of h³, h², h, 1.
        self._coef = np.ascontiguousarray(np.moveaxis(spline.c, 1, 0))

    @property
    def positions_m(self) -> np.ndarray:
        """Waypoint positions ``(N, 3)`` [m] in the reference frame (read-only)."""
        return self._positions

    @property
    def times_s(self) -> np.ndarray:
        """Waypoint phases ``(N,)`` [s], ``times_s[0] = 0``, ``times_s[-1] = T_tot``."""
        return self._times

    @property
    def orientations(self) -> np.ndarray | None:
        """Waypoint orientations ``(N, 4)``, normalised and sign-consistent, or ``None``."""
        return self._orientations

    # ------------------------------------------------------------------ evaluation
    def local_pose(self, sigma: float) -> np.ndarray:
        """``traj(σ)`` on the spline (:meth:`Trajectory.local_pose`)."""
        return self.local_poses(np.array([float(sigma)]))[0][0]

    def local_derivative(self, sigma: float) -> np.ndarray:
        """``dtraj/dσ`` on the spline (:meth:`Trajectory.local_derivative`)."""
        return self.local_poses(np.array([float(sigma)]))[1][0]

    def local_poses(self, sigmas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Vectorized :meth:`local_pose` and :meth:`local_derivative`."""
        s = np.asarray(sigmas, dtype=float)
        m = s.shape[0]
        spline = self._spline(s)  # (M, 2, 3 + k): [values; slopes] of [t, β]
        rdr = self._rotation(spline[:, 0, 3:], spline[:, 1, 3:])  # [r, r'] (M, 8)
        # d = ½ t r and d' = ½ (t' r + t r') for pure t: t ⊗ q = Σ_k t_k (e_k ⊗ q).
        e_times = (rdr @ _PURE_LEFT).reshape(m, 6, 4)  # [e_k ⊗ r (k = 1..3), e_k ⊗ r']
        coeffs = np.zeros((m, 2, 6))
        coeffs[:, :, :3] = spline[:, :, :3]  # [t; t'] against e_k ⊗ r
        coeffs[:, 1, 3:] = spline[:, 0, :3]  # t against e_k ⊗ r'
        dual = 0.5 * np.matmul(coeffs, e_times)  # (M, 2, 4): [d; d']
        poses = np.empty((m, 8))
        poses[:, :4] = rdr[:, :4]
        poses[:, 4:] = dual[:, 0]
        derivatives = np.empty((m, 8))
        derivatives[:, :4] = rdr[:, 4:]
        derivatives[:, 4:] = dual[:, 1]
        return poses, derivatives

    def _spline(self, s: np.ndarray) -> np.ndarray:
        """Values and first derivatives of the spline of ``[t, β]``: ``(M, 2, 3 + k)``.

        One batched product of the powers ``[h³, h², h, 1]`` and ``[3h², 2h, 1, 0]`` (``h``:
        phase since the start of the interval) with the interval's coefficients. Phases
        outside ``[0, T_tot]`` use the end polynomials (callers clip beforehand).
        """
        idx = np.searchsorted(self._inner_knots, s, side="right")  # interval, 0 … N-2
        h = (s - self._knots[idx])[:, None, None]
        powers = np.power(h, _POWERS) * _POWER_SCALE  # (M, 2, 4)
        return np.matmul(powers, self._coef[idx])

    def _rotation(self, beta: np.ndarray, dbeta: np.ndarray) -> np.ndarray:
        """``[r(σ), dr/dσ]`` ``(M, 8)`` from the cumulative factors (module docstring).

        With ``E_i = cos(β_i θ_i/2) + sin(β_i θ_i/2) u_i`` and
        ``dE_i/dσ = (β_i' θ_i/2) (-sin(β_i θ_i/2) + cos(β_i θ_i/2) u_i)``, the partial products
        obey ``P_i = P_{i-1} E_i`` and ``P_i' = P_{i-1}' E_i + P_{i-1} dE_i/dσ``.
        """
        m = beta.shape[0]
        out = np.zeros((m, 8))
        out[:, :4] = self._r0
        if not self._right_factor:
            return out
        half = (beta * self._half_angles).T[:, :, None]  # (factors, M, 1)
        rate = (dbeta * self._half_angles).T[:, :, None]
        cos = np.cos(half)
        sin = np.sin(half)
        # P_i = c P + s P u and P_i' = c P' + s P' u + (β'θ/2)(c P u - s P): the weights of
        # the four 8-blocks [P, P'], [P u, P' u], [0, P u], [0, P] made by each factor matrix.
        weights = np.empty((len(self._right_factor), m, 4, 8))
        weights[:, :, 0, :] = cos
        weights[:, :, 1, :] = sin
        weights[:, :, 2, :] = rate * cos
        weights[:, :, 3, :] = -rate * sin
        for factor, weight in zip(self._right_factor, weights, strict=True):
            out = np.add.reduce((out @ factor).reshape(m, 4, 8) * weight, axis=1)
        return out

    kind = "waypoints"

    def _metadata_params(self) -> dict:
        ori = None if self.orientations is None else self.orientations.tolist()
        return {
            "positions_m": self.positions_m.tolist(),
            "orientations": ori,
            "times_s": self.times_s.tolist(),
        }

    def _repr_params(self) -> list[str]:
        fmt: dict[str, Any] = {"precision": 4, "threshold": 30, "separator": ", "}
        ori = None if self.orientations is None else np.array2string(self.orientations, **fmt)
        return [
            f"positions_m={np.array2string(self.positions_m, **fmt)}",
            f"orientations={ori}",
            f"times_s={np.array2string(self.times_s, **fmt)}",
        ]


# ---------------------------------------------------------------------- input checks
def _read_only(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


def _as_float_array(name: str, value: object, expected: str) -> np.ndarray:
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a numeric array of shape {expected}") from None


def _check_positions(positions_m: object) -> np.ndarray:
    p = _as_float_array("positions_m", positions_m, "(N, 3)")
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] < 2:
        raise ParameterError(
            f"positions_m must have shape (N, 3) with N ≥ 2 waypoints [m], got {p.shape}"
        )
    if not np.isfinite(p).all():
        raise ParameterError("positions_m must be finite [m]; it holds NaN or inf")
    return p


def _check_orientations(orientations: object, n: int) -> np.ndarray:
    q = _as_float_array("orientations", orientations, f"({n}, 4)")
    if q.shape != (n, 4):
        raise ParameterError(
            f"orientations must have shape ({n}, 4) (one unit quaternion [w, x, y, z] per "
            f"waypoint), got {q.shape}"
        )
    if not np.isfinite(q).all():
        raise ParameterError("orientations must be finite; it holds NaN or inf")
    norms = np.linalg.norm(q, axis=1)
    bad = np.flatnonzero(np.abs(norms - 1.0) > QUATERNION_NORM_TOL)
    if bad.size:
        raise ParameterError(
            f"orientations must be unit quaternions (norm within 1 ± {QUATERNION_NORM_TOL:g}); "
            f"rows {bad.tolist()} have norms {norms[bad].tolist()}"
        )
    q = q / norms[:, None]
    for k in range(1, n):  # make consecutive keyframes sign-consistent: q_{k-1}·q_k ≥ 0
        if np.dot(q[k - 1], q[k]) < 0.0:
            q[k] = -q[k]
    return q


def _check_times(times_s: object, duration_s: float | None, positions: np.ndarray) -> np.ndarray:
    n = positions.shape[0]
    if times_s is None:
        if duration_s is None:
            raise ParameterError(
                "give times_s (waypoint phases [s]) or duration_s (T_tot > 0 [s]); got neither"
            )
        duration = positive("duration_s (T_tot)", duration_s, "s")
        chords = np.linalg.norm(np.diff(positions, axis=0), axis=1)
        if np.any(chords <= 0.0):
            raise ParameterError(
                "with times_s=None the times follow the chord length, so consecutive "
                f"positions_m must differ; segments {np.flatnonzero(chords <= 0.0).tolist()} "
                "have zero length: pass times_s"
            )
        cumulative = np.concatenate(([0.0], np.cumsum(chords)))
        times = duration * cumulative / cumulative[-1]
        times[-1] = duration
        return times
    times = _as_float_array("times_s", times_s, f"({n},)")
    if times.shape != (n,):
        raise ParameterError(f"times_s must have shape ({n},) like positions_m, got {times.shape}")
    if not np.isfinite(times).all():
        raise ParameterError("times_s must be finite [s]; it holds NaN or inf")
    if times[0] != 0.0:
        raise ParameterError(f"times_s must start at 0 [s] (σ starts at 0), got {times[0]!r}")
    if np.any(np.diff(times) <= 0.0):
        raise ParameterError(f"times_s must be strictly increasing [s], got {times.tolist()}")
    if duration_s is not None:
        duration = positive("duration_s (T_tot)", duration_s, "s")
        if abs(duration - times[-1]) > 1e-9 * times[-1]:
            raise ParameterError(
                f"duration_s must equal times_s[-1] = {times[-1]!r} [s] when both are given "
                f"(or be omitted), got {duration_s!r}"
            )
    return times
