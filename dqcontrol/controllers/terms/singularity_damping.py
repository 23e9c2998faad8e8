"""Damping that grows near singular configurations (docs/theory.md §8.3).

Where the smallest singular value ``σ_min`` of the tangent Jacobian ``E J`` (the 6×n map
from joint velocities to the path error's rate, §8.2) falls below ``ε``, a least-squares
path level would answer a small error in the missing direction with large joint velocities
(and chatter between neighbouring solutions). The rows ``qd_i`` with the weight

    w = c λ_max² (1 - (σ_min/ε)²)      (0 when σ_min ≥ ε)

are the damped least squares of Nakamura and Chiaverini: bounded velocities at the price of
an error in the singular direction only. ``c`` converts a damping of the Jacobian to the
level's units (the path term's weight times the square of the first interval).
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.context import StepContext
from dqcontrol.controllers.gram import frozen
from dqcontrol.controllers.problem import DecisionLayout, Residual, Term
from dqcontrol.controllers.terms.path_error import tangent_projectors

__all__ = ["SingularityDampingTerm"]


class SingularityDampingTerm(Term):
    """Rows ``qd_i`` weighted by ``c λ_max² (1 - (σ_min/ε)²)`` at the first state.

    Args:
        layout: the decision layout.
        threshold: ``ε`` (same unit as the tangent Jacobian's singular values, ≈ m/rad).
        max_damping: ``λ_max``.
        scale: ``c``.
    """

    name = "singularity_damping"

    def __init__(
        self, layout: DecisionLayout, threshold: float, max_damping: float, scale: float
    ) -> None:
        self.threshold = float(threshold)
        self.max_damping = float(max_damping)
        self.scale = float(scale)
        p, n, m = layout.num_blocks, layout.num_joints, layout.block_size
        self._blocks = np.zeros((p, n, m))
        self._blocks[:, np.arange(n), np.arange(n)] = 1.0
        frozen(self._blocks)
        self._b = frozen(np.zeros(p * n))
        self.weight = 0.0
        self.sigma_min = np.inf
        self._ctx: StepContext | None = None

    def residual(self, ctx: StepContext) -> Residual:
        """The rows ``qd_i`` weighted by the closeness to a singularity."""
        if ctx is not self._ctx:  # the same term in several levels: one SVD per step
            tangent = tangent_projectors(ctx.poses[:1])[0] @ ctx.jacobians[0]
            self.sigma_min = float(np.linalg.svd(tangent, compute_uv=False)[-1])
            ratio = self.sigma_min / self.threshold
            lam2 = self.max_damping**2 * (1.0 - ratio * ratio) if ratio < 1.0 else 0.0
            self.weight = self.scale * lam2
            self._ctx = ctx
        return Residual(self.name, self.weight, self._b, blocks=self._blocks, held=False)
