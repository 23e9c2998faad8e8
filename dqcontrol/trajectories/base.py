"""The trajectory contract: a geometric path of poses over a phase ``σ`` (docs/theory.md §3).

A trajectory gives a unit dual quaternion ``traj(σ)`` and its derivative ``dtraj/dσ`` for
``σ ∈ [0, T_tot]``, where ``σ`` is measured in seconds of *nominal* time. It is geometric:
changing ``T_tot`` changes how fast the path is traversed, never the path itself. The
controllers advance ``σ`` with the time scaling ``σ_{k+1} = σ_k + T s_k`` (eq. 3.3).

The path is expressed in a reference frame ``ref`` (a pose in world); the world target is

    x_d(σ) = ref ⊗ traj(σ),        dx_d/dσ = ref ⊗ dtraj/dσ

(docs/theory.md §2–3, the thesis's eq. 4.1 with the base folded into the model). Both are
computed as one product with the Hamilton matrix ``H+8(ref)`` (eq. 2.18), built once per
reference.
"""

from __future__ import annotations

import copy
import math
from abc import ABC, abstractmethod

import numpy as np
from scipy.spatial import cKDTree

from dqcontrol.dq.algebra import dq_conj, dq_mul, dq_normalize, hamiplus8, translation
from dqcontrol.errors import ParameterError
from dqcontrol.trajectories._checks import positive, unit_dq
from dqcontrol.trajectories._kernels import value_range

__all__ = ["Trajectory"]

#: Nearest path vertices examined per point by the k-d tree search of :meth:`path_deviation`.
_K_NEAREST = 32
#: Its search radius, in segment lengths; points farther from the path scan every segment.
_SEARCH_RADIUS_SEGMENTS = 64


def _positions(points_m) -> tuple[np.ndarray, bool]:
    """``points_m`` as a finite ``(M, 3)`` float array, and whether it was one ``(3,)``
    point; otherwise a :class:`ParameterError`."""
    pts = np.asarray(points_m, dtype=float)
    single = pts.shape == (3,)
    if single:
        pts = pts[None, :]
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.isfinite(pts).all():
        raise ParameterError(
            f"points_m must be a finite (M, 3) array of positions [m], got shape "
            f"{np.shape(points_m)}"
        )
    return pts, single


class Trajectory(ABC):
    """A geometric pose path ``traj(σ)``, ``σ ∈ [0, T_tot]``, in a reference frame ``ref``.

    Subclasses implement :meth:`local_pose` and :meth:`local_derivative` (and usually
    override :meth:`local_poses` with a vectorized version); this class turns them into world
    targets, anchors the reference frame and measures path deviation (docs/theory.md §9).

    Args:
        duration_s: nominal duration ``T_tot`` [s], finite and ``> 0``.
        reference: pose ``ref`` of the trajectory frame in world (unit dual quaternion vec8,
            renormalised), or ``None``: not yet anchored, the robot's start pose will define it (see
            :meth:`anchored_at`).
    """

    def __init__(self, duration_s: float, reference: np.ndarray | None = None) -> None:
        self._duration = positive("duration_s (T_tot)", duration_s, "s")
        self._reference: np.ndarray | None = None
        self._ref_plus_t: np.ndarray | None = None
        self._path_cache: dict[int, tuple[np.ndarray, cKDTree, float]] = {}
        # scratch rows for a subclass's fused _local_pair (each copy owns its own)
        self._pair_buffer = np.zeros((2, 8))
        if reference is not None:
            self._set_reference(dq_normalize(unit_dq("reference", reference)))

    # ------------------------------------------------------------------ properties
    @property
    def duration(self) -> float:
        """Nominal duration ``T_tot`` [s]; ``σ`` runs over ``[0, T_tot]``."""
        return self._duration

    @property
    def reference(self) -> np.ndarray | None:
        """Pose ``ref`` of the trajectory frame in world (read-only vec8), ``None`` if unset."""
        return self._reference

    # ------------------------------------------------------------------ subclass contract
    @abstractmethod
    def local_pose(self, sigma: float) -> np.ndarray:
        """``traj(σ)`` in the reference frame: unit dual quaternion vec8, shape ``(8,)``.

        Args:
            sigma: phase ``σ ∈ [0, T_tot]`` [s of nominal time].
        """

    @abstractmethod
    def local_derivative(self, sigma: float) -> np.ndarray:
        """``dtraj/dσ`` in the reference frame: vec8, shape ``(8,)`` [1/s].

        Args:
            sigma: phase ``σ ∈ [0, T_tot]`` [s of nominal time].
        """

    def local_poses(self, sigmas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Batched :meth:`local_pose` and :meth:`local_derivative`: two ``(N, 8)`` arrays.

        This default loops over ``sigmas``; subclasses override it with vectorized numpy.

        Args:
            sigmas: phases ``(N,)`` in ``[0, T_tot]`` [s].
        """
        s = np.asarray(sigmas, dtype=float)
        poses = np.empty((s.shape[0], 8))
        derivatives = np.empty((s.shape[0], 8))
        for i, si in enumerate(s):
            poses[i] = self.local_pose(float(si))
            derivatives[i] = self.local_derivative(float(si))
        return poses, derivatives

    def _repr_params(self) -> list[str]:
        """``name=value`` strings of the subclass's own parameters, for :meth:`__repr__`."""
        return []

    #: The name of the kind in saved metadata (``None``: the kind cannot describe itself).
    kind: str | None = None

    def _metadata_params(self) -> dict | None:
        """The subclass's constructor keywords besides ``duration_s`` and ``reference``, as
        plain JSON values, or ``None`` if it cannot describe itself."""
        return None

    def to_metadata(self) -> dict:
        """What rebuilds this trajectory, as plain JSON values:
        ``{"trajectory": kind, "duration_s": T_tot, <parameters>}`` and ``"reference"``
        (vec8) when it has one (:func:`~dqcontrol.trajectories.trajectory_from_metadata`).

        Raises:
            ParameterError: the trajectory is given by code (e.g. a
                :class:`~dqcontrol.trajectories.FunctionTrajectory`), not by numbers.
        """
        params = self._metadata_params()
        if self.kind is None or params is None:
            raise ParameterError(
                f"{type(self).__name__} cannot describe itself as metadata (it is defined by "
                "code, not by numbers)"
            )
        meta = {"trajectory": self.kind, "duration_s": self._duration, **params}
        if self._reference is not None:
            meta["reference"] = [float(v) for v in self._reference]
        return meta

    # ------------------------------------------------------------------ world targets
    def target(self, sigma: float) -> np.ndarray:
        """World target ``x_d(σ) = ref ⊗ traj(clip(σ, 0, T_tot))`` (vec8, docs/theory.md §3).

        Past ``T_tot`` the task holds its final pose (and before 0 its first one).

        Raises:
            ParameterError: if the trajectory has no reference yet, or ``σ`` is not finite.
        """
        h_t = self._ref_plus_t
        if h_t is None:
            raise self._not_anchored_error()
        s = self._check_sigma(sigma)
        return self.local_pose(min(max(s, 0.0), self._duration)).dot(h_t)

    def target_derivative(self, sigma: float) -> np.ndarray:
        """``dx_d/dσ = ref ⊗ dtraj/dσ`` (vec8) [1/s]; zero outside ``[0, T_tot)``.

        Zero for ``σ ≥ T_tot`` because the task holds its final pose there (and for ``σ < 0``,
        where the target is held at its start, so that this is the derivative of
        :meth:`target`). Multiply by ``s`` for ``dx_d/dt`` (docs/theory.md §3).

        Raises:
            ParameterError: if the trajectory has no reference yet, or ``σ`` is not finite.
        """
        h = self._ref_plus()
        s = self._check_sigma(sigma)
        if s < 0.0 or s >= self._duration:
            return np.zeros(8)
        return h @ self.local_derivative(s)

    def target_pair(self, sigma: float) -> np.ndarray:
        """:meth:`target` and :meth:`target_derivative` at one ``σ`` as the rows of a ``(2, 8)``
        array (one check, one ``(2, 8) @ (8, 8)`` product: the single-instant controllers'
        hot path).

        Raises:
            ParameterError: if the trajectory has no reference yet, or ``σ`` is not finite.
        """
        h_t = self._ref_plus_t
        if h_t is None:
            raise self._not_anchored_error()
        s = self._check_sigma(sigma)
        if 0.0 <= s < self._duration:
            return self._local_pair(s).dot(h_t)
        # outside the path the task holds its end pose: zero derivative (target_derivative)
        pose = self.local_pose(min(max(s, 0.0), self._duration))
        return np.array((pose, np.zeros(8))).dot(h_t)

    def _local_pair(self, sigma: float) -> np.ndarray:
        """``[traj(σ); dtraj/dσ]`` as a ``(2, 8)`` array (subclasses may fuse the two and
        fill ``self._pair_buffer``: the caller reads it before the next call)."""
        return np.array((self.local_pose(sigma), self.local_derivative(sigma)))

    def targets(self, sigmas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Batched :meth:`target` and :meth:`target_derivative`: two ``(N, 8)`` arrays.

        Called every control step with the ``p`` predicted phases ``σ̂_i`` (eq. 3.15–3.21);
        one vectorized evaluation and one ``(N, 8) @ (8, 8)`` product.

        Args:
            sigmas: phases ``(N,)`` [s of nominal time], any finite values.

        Raises:
            ParameterError: if the trajectory has no reference yet, or ``sigmas`` is not a
                finite 1-D array.
        """
        h_t = self._ref_plus_t
        if h_t is None:
            raise self._not_anchored_error()
        s = np.asarray(sigmas, dtype=float)
        if s.ndim != 1:
            raise ParameterError(f"sigmas must be a 1-D array [s], got shape {s.shape}")
        if s.shape[0] == 0:
            return np.empty((0, 8)), np.empty((0, 8))
        lo, hi = value_range(s)
        if not (math.isfinite(lo) and math.isfinite(hi)):  # NaN propagates through min/max
            raise ParameterError(f"sigmas must be finite [s], got {s!r}")
        duration = self._duration
        if lo >= 0.0 and hi < duration:  # the common case: every phase inside the path
            poses, derivatives = self.local_poses(s)
            return poses @ h_t, derivatives @ h_t
        poses, derivatives = self.local_poses(np.minimum(np.maximum(s, 0.0), duration))
        moving = (s >= 0.0) & (s < duration)
        return poses @ h_t, (derivatives * moving[:, None]) @ h_t

    # ------------------------------------------------------------------ reference frame
    def anchored_at(self, x0: np.ndarray) -> Trajectory:
        """A copy whose reference makes ``target(0) == x0``: ``ref = x0 ⊗ traj(0)*``.

        This is the default reference frame of docs/theory.md §3: the robot starts on the path
        and the tool orientation is held relative to its start orientation. ``x0`` is used as
        given (not renormalised), so ``target(0)`` reproduces it to rounding (~1e-16).

        Args:
            x0: start pose in world (unit dual quaternion vec8), e.g. the end-effector pose at
                the initial configuration ``q0``.
        """
        x0 = unit_dq("x0", x0)
        return self._copy_with(dq_mul(x0, dq_conj(self.local_pose(0.0))))

    def with_reference(self, reference: np.ndarray) -> Trajectory:
        """A copy expressed in the given reference frame ``ref`` (unit dual quaternion vec8).

        ``ref`` is checked (``| |r| - 1 | ≤ 1e-6``, ``|r·d| ≤ 1e-6``) and then renormalised.
        """
        return self._copy_with(dq_normalize(unit_dq("reference", reference)))

    # ------------------------------------------------------------------ geometry
    def path_positions(self, num: int = 4000) -> np.ndarray:
        """World positions [m] of ``num`` targets evenly spaced in ``σ ∈ [0, T_tot]``: ``(num, 3)``.

        The same ``num`` gives the same points for any ``T_tot`` (the path is geometric).
        """
        num = _check_count("num", num, 2)
        h_t = self._ref_plus_t
        if h_t is None:
            raise self._not_anchored_error()
        sigmas = np.linspace(0.0, self._duration, num)
        if type(self).local_poses is Trajectory.local_poses:  # no vectorized version:
            poses = np.array([self.local_pose(float(s)) for s in sigmas])  # skip derivatives
        else:
            poses, _ = self.local_poses(sigmas)
        return translation(poses @ h_t)

    def path_deviation(self, points_m: np.ndarray, *, segments: int = 20000) -> np.ndarray:
        """Distance [m] from each point to the nearest point of the geometric path.

        docs/theory.md §9's path deviation: how far the end effector is from the *path*, whatever
        ``σ``. The path is the polyline through ``segments + 1`` world positions evenly spaced
        in ``σ`` (cached per ``segments``); the point-to-segment distance is exact.

        Discretisation error: on a segment of phase length ``h = T_tot / segments`` a ``C²``
        curve ``p(σ)`` stays within ``h²/8 · max‖p''‖`` of its chord (linear interpolation
        error), so the polyline and the path are within that Hausdorff distance of each other,
        and the result differs from the exact distance by at most
        ``ε = h²/8 · max_σ ‖d²p/dσ²‖``. ``h²‖p''‖`` does not depend on ``T_tot``; for the
        circle (R = 0.1 m) ``ε ≈ 1.2e-9 m``, for the sinusoid (A = 0.1 m, Ω_x = 60 rad/m)
        ``ε ≈ 2e-8 m`` at the default 20000 segments.

        Nearest path vertices are found with a k-d tree; a segment can hold a point closer
        than the nearest vertex (distance ``d_v``) only if one of its endpoints lies within
        ``d_v + L_max/2`` (``L_max``: longest segment), so only those segments are examined
        and the result is exact for the polyline. Points far from the path (more than 64
        ``L_max``) or with too many candidate vertices scan all segments with two matrix
        products per chunk (1000 points × 20000 segments: about half a second).

        Args:
            points_m: world positions ``(M, 3)`` [m] (a single ``(3,)`` point is accepted).
            segments: number of polyline segments, ``≥ 1``.

        Returns:
            distances ``(M,)`` [m] (a float for a single ``(3,)`` point).
        """
        segments = _check_count("segments", segments, 1)
        pts, single = _positions(points_m)
        vertices, tree, half_len = self._polyline(segments)
        n_vert = vertices.shape[0]
        a = vertices[:-1]
        ab = vertices[1:] - a
        len2 = np.sum(ab * ab, axis=1)
        inv_len2 = np.divide(1.0, len2, out=np.zeros_like(len2), where=len2 > 0.0)

        # Near points: k nearest vertices within a search radius r0; the result is exact if
        # the ball of radius d_v + L_max/2 holds fewer than k vertices.
        k = min(_K_NEAREST, n_vert)
        search_radius = max(_SEARCH_RADIUS_SEGMENTS * 2.0 * half_len, 1e-12)
        dist_k, idx_k = tree.query(pts, k=k, distance_upper_bound=search_radius)
        radius = dist_k[:, 0] + half_len
        near = (radius < search_radius) & ((dist_k[:, -1] > radius) | (k == n_vert))
        out = np.empty(pts.shape[0])
        if near.any():
            seg = np.concatenate((idx_k[near] - 1, idx_k[near]), axis=1).clip(0, segments - 1)
            out[near] = _segment_distances(
                pts[near][:, None, :], a[seg], ab[seg], inv_len2[seg]
            ).min(axis=1)
        # Far points (or near a point equidistant from much of the path, e.g. a circle's
        # centre): scan every segment.
        if not near.all():
            out[~near] = self._scan_segments(pts[~near], vertices)
        return out[0] if single else out

    # ------------------------------------------------------------------ internals
    def _polyline(self, segments: int) -> tuple[np.ndarray, cKDTree, float]:
        """Cached world polyline (vertices, k-d tree, half the longest segment [m])."""
        cached = self._path_cache.get(segments)
        if cached is None:
            vertices = self.path_positions(segments + 1)
            lengths = np.linalg.norm(np.diff(vertices, axis=0), axis=1)
            cached = (vertices, cKDTree(vertices), 0.5 * float(lengths.max()))
            self._path_cache = {segments: cached}
        return cached

    @staticmethod
    def _scan_segments(pts: np.ndarray, vertices: np.ndarray) -> np.ndarray:
        """Distance from each point to the polyline by scanning all segments (chunked).

        The squared distance to every segment is expanded as
        ``‖p-a‖² - 2τ (p-a)·ab + τ²‖ab‖²`` so that its point-dependent parts are the products
        ``p·ab`` and ``p·a``; the best segment and its two neighbours are then measured exactly. The
        expansion rounds to about ``1e-16 ×`` the squared extent of the path (coordinates are
        centred on it), which could pick a segment up to ~1e-8 m (for a 1 m path) too far
        for a point *on* the path; points reach this scan only if they are ≳ 63 segment
        lengths from the path (where that rounding is relatively ≤ 1e-12) or where the path
        retraces itself.
        """
        centre = vertices.mean(axis=0)
        a = vertices[:-1] - centre
        ab = vertices[1:] - vertices[:-1]
        len2 = np.sum(ab * ab, axis=1)
        inv_len2 = np.divide(1.0, len2, out=np.zeros_like(len2), where=len2 > 0.0)
        a_ab = np.sum(a * ab, axis=1)
        a2 = np.sum(a * a, axis=1)
        n_seg = a.shape[0]
        # [ab | a] as (3, 2S): one einsum gives p·ab and p·a. einsum rather than a BLAS
        # product: with 3-long inner products threaded BLAS only adds contention.
        ab_a_t = np.ascontiguousarray(np.concatenate((ab, a)).T)
        p = pts - centre
        out = np.empty(p.shape[0])
        chunk = max(1, 250_000 // n_seg)
        for start in range(0, p.shape[0], chunk):
            pc = p[start : start + chunk]
            dots = np.einsum("mk,ks->ms", pc, ab_a_t)
            ap_ab = dots[:, :n_seg] - a_ab  # (p - a)·ab
            tau = np.clip(ap_ab * inv_len2, 0.0, 1.0)
            d2 = a2 - 2.0 * dots[:, n_seg:] - tau * (2.0 * ap_ab - tau * len2)  # minus ‖p‖²
            best = np.argmin(d2, axis=1)
            seg = (best[:, None] + np.array([-1, 0, 1])).clip(0, n_seg - 1)
            out[start : start + chunk] = _segment_distances(
                pc[:, None, :], a[seg], ab[seg], inv_len2[seg]
            ).min(axis=1)
        return out

    def _set_reference(self, reference: np.ndarray) -> None:
        ref = np.array(reference, dtype=float)
        ref.flags.writeable = False
        self._reference = ref
        self._ref_plus_t = np.ascontiguousarray(hamiplus8(ref).T)
        self._path_cache = {}

    def _copy_with(self, reference: np.ndarray) -> Trajectory:
        new = copy.copy(self)
        new._pair_buffer = self._pair_buffer.copy()
        new._set_reference(reference)
        return new

    def _ref_plus(self) -> np.ndarray:
        if self._ref_plus_t is None:
            raise self._not_anchored_error()
        return self._ref_plus_t.T

    def _not_anchored_error(self) -> ParameterError:
        return ParameterError(
            f"{type(self).__name__} has no reference frame yet (reference is None): call "
            "anchored_at(x0) with the start pose x0, or with_reference(ref), first"
        )

    @staticmethod
    def _check_sigma(sigma: float) -> float:
        try:
            s = float(sigma)
        except (TypeError, ValueError):
            raise ParameterError(f"sigma must be a finite number [s], got {sigma!r}") from None
        if not math.isfinite(s):
            raise ParameterError(f"sigma must be a finite number [s], got {sigma!r}")
        return s

    def __repr__(self) -> str:
        params = [f"duration_s={self._duration!r}", *self._repr_params()]
        ref = None if self._reference is None else np.array2string(self._reference, precision=6)
        params.append(f"reference={ref}")
        return f"{type(self).__name__}({', '.join(params)})"


def _check_count(name: str, value: int, minimum: int) -> int:
    """``value`` as an int ``≥ minimum`` or :class:`ParameterError`."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ParameterError(f"{name} must be an integer ≥ {minimum}, got {value!r}")
    return int(value)


def _segment_distances(
    p: np.ndarray, a: np.ndarray, ab: np.ndarray, inv_len2: np.ndarray
) -> np.ndarray:
    """Exact distance from points ``p`` to segments ``[a, a + ab]`` (broadcasts over ``...``).

    ``inv_len2 = 1/‖ab‖²`` (0 for a degenerate segment, which is then its point ``a``).
    """
    ap = p - a
    t = np.clip(np.sum(ap * ab, axis=-1) * inv_len2, 0.0, 1.0)
    diff = ap - t[..., None] * ab
    return np.sqrt(np.sum(diff * diff, axis=-1))
