"""Damping that grows near singular configurations (docs/theory.md §8.3).

Where the smallest singular value ``σ_min`` of the tangent Jacobian ``E J`` (the 6×n map
from joint velocities to the path error's rate, §8.2) falls below ``ε``, a least-squares
path level would answer a small error in the missing direction with large joint velocities
(and chatter between neighbouring solutions). The rows ``qd_i`` with the weight

    w = c λ_max² (1 - (σ_min/ε)²)      (0 when σ_min ≥ ε)

are the damped least squares of Nakamura and Chiaverini: bounded velocities at the price of
an error in the singular direction only. ``c`` converts a damping of the Jacobian to the
level's units (the path term's weight times the square of the first interval).

Away from singularities ``w = 0`` whatever ``σ_min`` is: a Cholesky factorisation shows
``σ_min`` clearly above ``ε`` (:func:`.singularity_kernels.clearly_regular`), and the SVD
is computed only where it is not, or when ``sigma_min`` is read.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import DecisionLayout, Residual
from dqcontrol.controllers.linalg.gram import frozen
from dqcontrol.controllers.terms.path_error import PROJECTOR_BASIS, tangent_projectors
from dqcontrol.controllers.terms.singularity_kernels import clearly_regular
from dqcontrol.controllers.terms.term import Term

__all__ = ["SingularityDampingTerm"]

#: Relative margin of the Cholesky check over ``ε²``: far above the rounding of ``E J`` and
#: of its Gram matrix, so a state it calls clear has ``σ_min > ε``.
_CLEAR_MARGIN = 1e-9


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
        self._clear_sq = self.threshold**2 * (1.0 + _CLEAR_MARGIN)
        self._sigma_min: float | None = np.inf
        self._ctx: StepContext | None = None

    @property
    def sigma_min(self) -> float:
        """``σ_min`` of ``E J`` at the last step's first state (``inf`` before a step)."""
        if self._sigma_min is None:
            ctx = self._ctx
            assert ctx is not None, "a step's context is kept with its value"
            tangent = tangent_projectors(ctx.poses[:1])[0] @ ctx.jacobians[0]
            self._sigma_min = float(np.linalg.svd(tangent, compute_uv=False)[-1])
        return self._sigma_min

    def residual(self, ctx: StepContext) -> Residual:
        """The rows ``qd_i`` weighted by the closeness to a singularity."""
        if ctx is not self._ctx:  # the same term in several levels: one check per step
            self._ctx, self._sigma_min = ctx, None
            pose, jacobian = ctx.poses[0], ctx.jacobians[0]
            if clearly_regular(pose, jacobian, PROJECTOR_BASIS, self._clear_sq):
                self.weight = 0.0
            else:
                ratio = self.sigma_min / self.threshold
                lam2 = self.max_damping**2 * (1.0 - ratio * ratio) if ratio < 1.0 else 0.0
                self.weight = self.scale * lam2
        return Residual(self.name, self.weight, self._b, blocks=self._blocks, held=False)
