"""Tracking: ``J_i qd_i - s_i w_i`` at every block (docs/theory.md §4.2, thesis eq. 3.4–3.21).

With the block's pose ``x̂_i`` and Jacobian ``J_i`` (sign-aligned to the target, at the
block's predicted state), the target ``x_d(σ̂_i)`` and its derivative,

    w_i = dx_d/dσ(σ̂_i) + K (x_d(σ̂_i) - x̂_i)            (vec8)

is the velocity the task asks for at full speed; the rows ``J_i qd_i - s_i w_i`` ask the
joints for it at the speed ``s_i``. They are linear in the decision because ``w_i`` is data.
In ``z_i = [qd_i, s_i]`` the rows are ``G_i z_i`` with ``G_i = [J_i, -w_i]`` (8 × (n+1)).
Without time scaling variables the rows are ``J_i qd_i - w_i``.

``tangent=True`` keeps only the six rows in the tangent space of the unit dual quaternions
at ``x̂_i`` (``E_i G_i``, ``E_i`` of :func:`~dqcontrol.controllers.terms.path_error.
tangent_projectors`): the two normal rows cannot be produced by any joint motion, and a
level that holds them at their optimum would pin ``s_i`` (docs/theory.md §7.6).
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import Residual
from dqcontrol.controllers.core.task_kernels import add_task_grams, task_matrices
from dqcontrol.controllers.terms.path_error import tangent_projectors
from dqcontrol.controllers.terms.term import Term

__all__ = ["TrackingTerm"]


def _kinematics(ctx: StepContext) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The poses, Jacobians, targets and their derivatives, C-contiguous (a prediction may
    give strided views): the compiled kernels then have one form to compile."""
    contiguous = np.ascontiguousarray
    return (
        contiguous(ctx.poses), contiguous(ctx.jacobians), contiguous(ctx.targets),
        contiguous(ctx.target_derivatives),
    )  # fmt: skip


class TrackingTerm(Term):
    """``λ1 Σ_i ‖J_i qd_i - s_i w_i‖²``.

    Args:
        gain_per_s: the task-error gain ``K`` [1/s] in ``w_i``.
        weight: ``λ1`` (dimensionless).

    The fast path (:meth:`add_gram`) adds ``2 λ1 G_iᵀ G_i`` to each Hessian block in one
    compiled call (``qp_cost.add_task_grams``).
    """

    name = "tracking"

    def __init__(self, gain_per_s: float, weight: float = 1.0, *, tangent: bool = False) -> None:
        self.gain_per_s = float(gain_per_s)
        self.weight = float(weight)
        self.tangent = bool(tangent)

    def residual(self, ctx: StepContext) -> Residual:
        """The task rows of every block (docs/theory.md §4)."""
        xs, jacs, xd, dxd = _kinematics(ctx)
        g = task_matrices(xs, jacs, xd, dxd, self.gain_per_s)
        if self.tangent:
            g = np.einsum("pak,pkm->pam", tangent_projectors(ctx.poses), g)
        rows = g.shape[1]
        if ctx.layout.with_scaling:
            return Residual(self.name, self.weight, np.zeros(g.shape[0] * rows), blocks=g)
        n = ctx.layout.num_joints
        return Residual(self.name, self.weight, g[:, :, n].ravel() * -1.0, blocks=g[:, :, :n])

    def add_gram(self, ctx: StepContext, hessian: np.ndarray) -> bool:
        """Add the task's Gram blocks in place (compiled), for the untangled, scaled task."""
        if self.tangent or not ctx.layout.with_scaling:
            return False
        xs, jacs, xd, dxd = _kinematics(ctx)
        add_task_grams(xs, jacs, xd, dxd, self.gain_per_s, 2.0 * self.weight, hessian)
        return True
