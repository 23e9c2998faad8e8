"""The path error at every predicted state, linearised (docs/theory.md §8.2).

With ``x̄_i = f(q̄_i)`` sign-aligned to ``x_d(σ̄_i)``, ``J_i = J(q̄_i)``, ``x_d'`` the target's
derivative, and the states ``q_i(z)``, ``σ_i(z)`` of the prediction model, the residual of
block ``i`` is the 6-D tangent part of

    x̄_i* ⊗ ( x̄_i - x_d(σ̄_i) + J_i (q_i - q̄_i) - x_d'(σ̄_i) (σ_i - σ̄_i) ),

i.e. the six pure components (rows ``1, 2, 3`` and ``5, 6, 7`` of ``H+8(x̄_i*)``): about half
the rotation error [rad] and half the translation error [m], both in the tool frame. The
two scalar components are normal to the unit dual quaternions; no joint motion produces
them, so they are left out.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import DecisionLayout, Residual, StateRows
from dqcontrol.controllers.linalg.gram import frozen
from dqcontrol.controllers.terms.path_error_kernels import path_states_into, projectors_into
from dqcontrol.controllers.terms.term import Term
from dqcontrol.dq.algebra import hamiplus8

__all__ = ["PROJECTOR_BASIS", "PathErrorTerm", "tangent_projectors"]

_PURE = np.array([1, 2, 3, 5, 6, 7])
_CONJ = np.array([1.0, -1.0, -1.0, -1.0, 1.0, -1.0, -1.0, -1.0])


#: ``H+8`` is linear in its argument: ``H+8(x) = Σ_k x_k H+8(e_k)``; the pure rows of each
#: ``H+8(e_k)`` with the conjugation folded in, ``(8, 6, 8)``.
PROJECTOR_BASIS = np.array([_CONJ[k] * hamiplus8(np.eye(8)[k])[_PURE] for k in range(8)])


def tangent_projectors(poses: np.ndarray) -> np.ndarray:
    """``E_i = P_pure H+8(x_i*)`` ``(p, 6, 8)`` for poses ``(p, 8)`` (one product for the
    batch)."""
    poses = np.asarray(poses, dtype=float)
    out = np.empty((poses.shape[0], 6, 8))
    projectors_into(poses, PROJECTOR_BASIS, out)
    return out


class PathErrorTerm(Term):
    """``Σ_i ‖e_i‖²``, ``e_i`` the linearised tangent error of block ``i``'s state.

    Each state's rows are weighted by ``min(1, (t_w / t_i)²)`` (``t_i`` its time from now,
    ``t_w`` the larger of the first interval and ``full_weight_time_s``): where the later
    states cannot all be kept on the path, the error falls on them rather than on the
    states about to be reached. ``t_w`` does not shrink with the control period, so a fast
    loop still weighs the states it must brake for (docs/theory.md §8.2).

    Args:
        weight: weight of the term (dimensionless; the rows are in half-radians and
            half-metres).
        full_weight_time_s: the states up to this time from now weigh fully [s] (``0``:
            only the first interval's).
    """

    name = "path_error"

    def __init__(self, weight: float = 1.0, full_weight_time_s: float = 0.0) -> None:
        self.weight = float(weight)
        self.full_weight_time_s = float(full_weight_time_s)
        self._weights_key: DecisionLayout | None = None
        self._weights = np.ones(0)

    def _row_weights(self, layout: DecisionLayout) -> np.ndarray:
        """``min(1, (t_w / t_i)²)`` of every row, kept for the layout (read-only)."""
        if self._weights_key is not layout:
            ends = layout.instants_s + layout.durations_s
            full = max(float(ends[0]), self.full_weight_time_s)
            self._weights_key = layout
            self._weights = frozen(np.repeat(np.minimum(1.0, (full / ends) ** 2), 6))
        return self._weights

    def residual(self, ctx: StepContext) -> Residual:
        """The linearised tangent errors of the predicted states, weighted by their time."""
        pred = ctx.prediction
        layout = ctx.layout
        p, m = layout.num_blocks, layout.block_size
        # block (i, j) of A: weights[i, j] E_i J_i on qd_j, -phase_weights[i, j] E_i x_d' on s_j,
        # given as each state's rows [E_i J_i | -E_i x_d']
        b = np.empty(6 * p)
        states = np.empty((p, 6, m))
        path_states_into(
            ctx.poses, ctx.targets, ctx.target_derivatives, ctx.jacobians,
            pred.q_base, pred.q_lin, pred.sigma_base, pred.sigma_lin, PROJECTOR_BASIS, b, states,
        )  # fmt: skip
        return Residual(
            self.name, self.weight, b, row_weights=self._row_weights(layout),
            states=StateRows(states, pred.weights, pred.phase_weights),
        )  # fmt: skip
