"""Joint positions at every predicted state, and a terminal braking condition
(docs/theory.md §8.4).

With states affine in the decision (``q_i = q_base_i + Σ_j W_ij qd_j``), the position
bounds are exact linear rows ``q_min ≤ q_i ≤ q_max`` at every breakpoint. At the last
state the arm must also be able to stop inside the limits from the last command: braking
from ``v`` at ``a`` covers ``v² / (2 a) ≤ |v| qd_max / (2 a)``, so

    q_min ≤ q_p + c qd_{p-1} ≤ q_max,     c = qd_max / (2 a_max)

is sufficient (linear and conservative), and keeps the next problem's braking plan
feasible. Under a jerk bound ``j̄`` the stop from ``v`` (the last interval holds its
velocity: no acceleration) covers ``v²/(2 a) + v a/(2 j̄)``: ``c = qd_max/(2 a) + a/(2 j̄)``
(docs/theory.md §8.11).

With ``reach_rad`` (how far each state can move from its linearisation point, e.g. a trust
region's radius), only the rows a state can reach are given; the limit is inactive (no
rows) when every state is further than that from its bounds.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import DecisionLayout, Inequality
from dqcontrol.controllers.limits.jerk import terminal_jerk_distance
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.limits.position_kernels import states_and_terminal_into
from dqcontrol.controllers.linalg.gram import frozen

__all__ = ["PredictedPositionLimit"]


class PredictedPositionLimit(Limit):
    """Position rows at every predicted state plus the terminal braking rows.

    Args:
        layout: the decision layout.
        q_min, q_max: position bounds [rad] (already shrunk by any margin).
        qd_max: velocity bound [rad/s] (for the braking coefficient).
        terminal: add the terminal braking rows.
        reach_rad: per state, how far it can move from its linearisation point [rad]
            (``None``: unknown, every row is given).
        jerk_max: the jerk bound [rad/s³] per joint for the terminal rows (``None``: none).
    """

    name = "predicted_position"

    def __init__(
        self,
        layout: DecisionLayout,
        q_min: np.ndarray,
        q_max: np.ndarray,
        qd_max: np.ndarray,
        *,
        terminal: bool = True,
        reach_rad: np.ndarray | None = None,
        jerk_max: np.ndarray | None = None,
    ) -> None:
        self.layout = layout
        self.jerk_max = jerk_max
        self.reach_rad = None if reach_rad is None else np.asarray(reach_rad, dtype=float)
        self.q_min = np.array(q_min, dtype=float)  # its own: set_bounds moves them
        self.q_max = np.array(q_max, dtype=float)
        self.qd_max = np.asarray(qd_max, dtype=float)
        self.terminal = bool(terminal)
        p = layout.num_blocks
        self._q_min_tiled = np.tile(self.q_min, p)
        self._q_max_tiled = np.tile(self.q_max, p)
        self._weights: np.ndarray | None = None
        self._c: np.ndarray | None = None
        self._terminal_key: tuple = (None, None)
        self._terminal_rows: tuple[np.ndarray, np.ndarray, np.ndarray] = (np.zeros(0),) * 3
        self._selections: dict[str, tuple[np.ndarray, bytes, tuple[np.ndarray, np.ndarray]]] = {}
        self._no_extra = np.zeros(layout.num_joints)  # the states' rows: the reach alone
        # entry (j, qd_{p-1, j}) of each terminal row, in the flat (n, len(z)) rows
        n = layout.num_joints
        self._terminal_entries = np.arange(n) * layout.num_vars + layout.qd_index()[-1]

    def widened(self, slack_rad: float) -> PredictedPositionLimit:
        """The same rows with the position bounds ``slack_rad`` [rad] looser on each side."""
        return PredictedPositionLimit(
            self.layout,
            self.q_min - slack_rad,
            self.q_max + slack_rad,
            self.qd_max,
            terminal=self.terminal,
            reach_rad=self.reach_rad,
            jerk_max=self.jerk_max,
        )

    def set_bounds(self, q_min: np.ndarray, q_max: np.ndarray) -> None:
        """Move the position bounds [rad] (the rows stay; e.g. a servo's measured lag,
        :class:`~dqcontrol.controllers.limits.servo_lag.ServoLagMargin`)."""
        self.q_min[:] = q_min
        self.q_max[:] = q_max
        p = self.layout.num_blocks
        self._q_min_tiled.reshape(p, -1)[:] = self.q_min
        self._q_max_tiled.reshape(p, -1)[:] = self.q_max

    def _matrix(self, weights: np.ndarray) -> np.ndarray:
        """Rows ``q_i = Σ_j W_ij qd_j`` as a ``(p n, len(z))`` matrix (cached per ``W``)."""
        if self._weights is not weights:
            layout = self.layout
            p, n = layout.num_blocks, layout.num_joints
            c = np.zeros((p * n, layout.num_vars))
            idx = layout.qd_index()
            for i in range(p):
                for j in range(i + 1):
                    c[i * n + np.arange(n), idx[j]] = weights[i, j]
            self._weights, self._c = weights, frozen(c)
            return self._c
        assert self._c is not None, "cached with the weights"
        return self._c

    def _terminal(
        self, c: np.ndarray, a_max: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(c, the terminal rows' matrix, c qd_max)``, ``c = qd_max / (2 a_max)`` at the last
        state (kept while ``c`` and ``a_max`` are the same arrays)."""
        key = self._terminal_key
        if key[0] is not c or key[1] is not a_max:
            n = self.layout.num_joints
            coeff = self.qd_max / (2.0 * a_max[-1])
            if self.jerk_max is not None:
                coeff = coeff + terminal_jerk_distance(a_max[-1], self.jerk_max)
            last = c[-n:].copy()
            last.ravel()[self._terminal_entries] += coeff
            self._terminal_key = (c, a_max)
            self._terminal_rows = (coeff, last, coeff * self.qd_max)  # last: _selected
        return self._terminal_rows

    def _selected(
        self, kind: str, c: np.ndarray, keep: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """``c[keep]`` and the rows' keys (their indices in ``c``: state and joint), the same
        arrays while ``c`` and ``keep`` are the same. The rows are read-only from the
        second step that reads them: what is derived from read-only rows is kept by their
        identity (:func:`~dqcontrol.controllers.linalg.gram.kept`), worth it for rows that stay,
        not for rows that change at every step (the terminal rows of a bound ``a_max`` that
        moves with the state), whose derived data is computed at each step instead."""
        mask = keep.tobytes()
        last = self._selections.get(kind)
        if last is not None and last[1] == mask:
            if last[0] is c:
                last[2][0].flags.writeable = False
                return last[2]
            keys = last[2][1]  # the same rows of other values
        else:
            keys = frozen(np.flatnonzero(keep))
        rows = (c if keys.shape[0] == c.shape[0] else c[keep], keys)
        self._selections[kind] = (c, mask, rows)
        return rows

    def rows(self, ctx: StepContext) -> tuple | None:
        """The position bounds of the predicted states, or ``None`` when none applies."""
        pred = ctx.prediction
        c = self._matrix(pred.weights)
        if self.reach_rad is not None:
            return self._reachable_rows(ctx, c)
        base = pred.q_base.ravel()
        out = [Inequality(self.name, c, self._q_min_tiled - base, self._q_max_tiled - base)]
        if self.terminal:
            last = self._terminal(c, ctx.a_max)[1]
            lo, up = self.q_min - pred.q_base[-1], self.q_max - pred.q_base[-1]
            out.append(Inequality("terminal_braking", last, lo, up))
        return tuple(out)

    def _reachable_rows(self, ctx: StepContext, c: np.ndarray) -> tuple | None:
        """The rows the states can reach (``reach_rad``), and the terminal rows the last
        state's braking can reach, in one compiled pass."""
        pred = ctx.prediction
        q_lin = pred.q_lin
        p, n = q_lin.shape
        assert self.reach_rad is not None, "called with a reach"
        keep = np.empty((p + 1, n), dtype=np.bool_)
        lower, upper = np.empty((p + 1) * n), np.empty((p + 1) * n)
        extra = self._terminal(c, ctx.a_max)[2] if self.terminal else self._no_extra
        count, last = states_and_terminal_into(
            q_lin, pred.q_base, self.q_min, self.q_max, self.reach_rad[-p:], self._no_extra,
            extra, self.terminal, keep, lower, upper,
        )  # fmt: skip
        out = []
        if count:
            rows, keys = self._selected("q", c, keep[:p].ravel())
            out.append(Inequality(self.name, rows, lower[:count], upper[:count], keys))
        if last:
            rows, keys = self._selected("terminal", self._terminal(c, ctx.a_max)[1], keep[p])
            end = p * n + last
            out.append(
                Inequality("terminal_braking", rows, lower[p * n : end], upper[p * n : end], keys)
            )
        return tuple(out) or None
