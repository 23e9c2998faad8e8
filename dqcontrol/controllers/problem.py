"""The contracts of the composable QP core (docs/theory.md §7).

A controller's QP at one step is *built* first and *solved* second:

- a :class:`DecisionLayout` says what the decision vector ``z`` holds: per block ``i`` of the
  horizon (an instant or an interval) the joint velocities ``qd_i`` and, optionally, the
  time scaling ``s_i``, stored block by block ``z = [qd_0, s_0, qd_1, s_1, …]``;
- a *term* gives residual rows ``A z - b`` with a weight (its cost is
  ``weight ‖A z - b‖²``), a :class:`Residual`;
- a *limit* gives inequality rows, :class:`Bounds` on single variables or
  :class:`Inequality` rows ``lower ≤ C z ≤ upper``, or nothing when inactive;
- a controller is an ordered list of levels (:class:`Level`); level ``k`` minimises its
  terms subject to the limits and to every higher level held at its optimum.

:class:`Problem` is what was built at one step (inspectable: every term and limit by name
with its rows and bounds) and :class:`Solution` what a backend returned.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from dqcontrol.errors import ParameterError

if TYPE_CHECKING:  # pragma: no cover
    from dqcontrol.controllers.context import StepContext

__all__ = [
    "Bounds",
    "BuiltLevel",
    "DecisionLayout",
    "DenseQP",
    "Inequality",
    "Level",
    "Limit",
    "Problem",
    "Residual",
    "Solution",
    "Term",
]


@dataclass(frozen=True)
class DecisionLayout:
    """Where each quantity sits in the decision vector ``z``.

    Attributes:
        num_joints: ``n``.
        instants_s: start time of each block relative to now ``(p,)`` [s] (``0`` first).
        durations_s: how long each block's command is held ``(p,)`` [s]: the interval
            lengths ``Δ_i`` (consistent prediction) or the spacing ``τ_{i+1} - τ_i`` of the
            thesis's instants (the last one repeats the previous spacing).
        with_scaling: each block carries ``s_i`` after its ``qd_i``.
    """

    num_joints: int
    instants_s: np.ndarray
    durations_s: np.ndarray
    with_scaling: bool = True

    def __post_init__(self) -> None:
        tau = np.asarray(self.instants_s, dtype=float)
        dur = np.asarray(self.durations_s, dtype=float)
        if tau.ndim != 1 or tau.size < 1 or tau[0] != 0.0 or np.any(np.diff(tau) <= 0.0):
            raise ParameterError(f"instants_s must start at 0 and increase [s], got {tau}")
        if dur.shape != tau.shape or not np.all(dur > 0.0):
            raise ParameterError(f"durations_s must be {tau.size} values > 0 [s], got {dur}")
        if int(self.num_joints) < 1:
            raise ParameterError(f"num_joints must be ≥ 1, got {self.num_joints}")
        object.__setattr__(self, "instants_s", tau)
        object.__setattr__(self, "durations_s", dur)

    @property
    def num_blocks(self) -> int:
        """``p``: instants or intervals of the horizon."""
        return int(self.instants_s.size)

    @property
    def block_size(self) -> int:
        """Variables per block: ``n + 1`` with scaling, ``n`` without."""
        return self.num_joints + (1 if self.with_scaling else 0)

    @property
    def num_vars(self) -> int:
        """Length of ``z``."""
        return self.num_blocks * self.block_size

    def qd_index(self) -> np.ndarray:
        """Indices of ``qd_i`` in ``z`` as a ``(p, n)`` array."""
        m, n = self.block_size, self.num_joints
        return np.arange(self.num_blocks)[:, None] * m + np.arange(n)[None, :]

    def s_index(self) -> np.ndarray:
        """Indices of ``s_i`` in ``z`` ``(p,)``; :class:`ParameterError` without scaling."""
        if not self.with_scaling:
            raise ParameterError("this layout has no time scaling variables")
        return np.arange(self.num_blocks) * self.block_size + self.num_joints

    def split(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """``(qd (p, n), s (p,) or None)`` views of a decision vector."""
        blocks = np.asarray(z).reshape(self.num_blocks, self.block_size)
        n = self.num_joints
        return blocks[:, :n], (blocks[:, n] if self.with_scaling else None)


class Residual(NamedTuple):
    """Residual rows of a term: its cost is ``weight ‖A z - b‖²``.

    ``A`` is dense ``(r, len(z))``; a term whose rows each touch one block may give
    ``blocks`` ``(p, r_i, block_size)`` instead (``A`` block diagonal, rows ordered block by
    block), which the backends exploit. ``held`` says whether lower levels hold these rows
    at their optimum (a regularisation is not held).
    """

    name: str
    weight: float
    b: np.ndarray
    A: np.ndarray | None = None
    blocks: np.ndarray | None = None
    held: bool = True
    row_weights: np.ndarray | None = None

    def dense(self, layout: DecisionLayout) -> np.ndarray:
        """``A`` as a dense ``(r, len(z))`` array."""
        if self.A is not None:
            return self.A
        p, r, m = self.blocks.shape
        out = np.zeros((p * r, layout.num_vars))
        for i in range(p):
            out[i * r : (i + 1) * r, i * m : (i + 1) * m] = self.blocks[i]
        return out

    def value(self, layout: DecisionLayout, z: np.ndarray) -> np.ndarray:
        """``A z - b`` (unweighted)."""
        return self.dense(layout) @ z - self.b


class Bounds(NamedTuple):
    """``lower ≤ z[index] ≤ upper`` from one limit.

    ``hard`` bounds (the acceleration bound) win a conflict: where their interval misses the
    others', the merged bound is the point of the hard interval closest to them
    (FORMULATION §6 conflict rule).
    """

    name: str
    index: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    hard: bool = False


class Inequality(NamedTuple):
    """General rows ``lower ≤ C z ≤ upper`` from one limit (``C`` dense)."""

    name: str
    C: np.ndarray
    lower: np.ndarray
    upper: np.ndarray


class Term(ABC):
    """A cost term: residual rows with a weight.

    Subclasses set ``name`` and ``weight`` and implement :meth:`residual`. ``constant``
    terms (rows independent of the step) are evaluated once per layout and cached.
    """

    name: str = "term"
    weight: float = 1.0
    constant: bool = False

    @abstractmethod
    def residual(self, ctx: StepContext) -> Residual:
        """The rows ``A z - b`` of this step."""

    def reset(self) -> None:  # noqa: B027 - optional hook
        """Forget any memory (called by the controller's reset)."""

    def observe(self, z: np.ndarray | None, s_applied: float) -> None:  # noqa: B027
        """Called after every step with the solution (``None`` on a fallback)."""


class Limit(ABC):
    """A constraint: rows, or nothing when inactive.

    Subclasses set ``name`` and implement :meth:`rows`, returning :class:`Bounds`,
    :class:`Inequality`, a tuple of them, or ``None``.
    """

    name: str = "limit"

    @abstractmethod
    def rows(self, ctx: StepContext) -> Bounds | Inequality | tuple | None:
        """This step's rows, or ``None`` when the limit is inactive."""


@dataclass(frozen=True)
class Level:
    """One priority level: its terms and the tolerance to which lower levels hold them.

    Attributes:
        terms: the terms minimised at this level (their weighted sum).
        tolerance: lower levels keep each held residual row of this level within this
            absolute distance of its optimum (in the row's own unit).
        name: label for diagnostics.
    """

    terms: tuple[Term, ...]
    tolerance: float = 1e-7
    name: str = ""

    def __post_init__(self) -> None:
        if not self.terms:
            raise ParameterError("a level needs at least one term")
        if not (np.isfinite(self.tolerance) and self.tolerance > 0.0):
            raise ParameterError(f"level tolerance must be > 0, got {self.tolerance!r}")


@dataclass(frozen=True)
class BuiltLevel:
    """The residuals of one level at one step."""

    name: str
    tolerance: float
    residuals: tuple[Residual, ...]


class DenseQP(NamedTuple):
    """``minimize ½ zᵀ P z + cᵀ z  s.t.  lower ≤ A z ≤ upper`` (dense; ``A = [I; C]``)."""

    P: np.ndarray
    c: np.ndarray
    A: np.ndarray
    lower: np.ndarray
    upper: np.ndarray


@dataclass(frozen=True)
class Problem:
    """Everything built at one step: the layout, the levels, the limits' rows.

    ``lower``/``upper`` are the merged variable bounds (every :class:`Bounds`, with the
    conflict rule) and ``conflict`` marks the variables where a hard bound won.
    """

    layout: DecisionLayout
    levels: tuple[BuiltLevel, ...]
    bounds: tuple[Bounds, ...]
    inequalities: tuple[Inequality, ...]
    lower: np.ndarray
    upper: np.ndarray
    conflict: np.ndarray

    def general_rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(C, lower, upper)`` of every :class:`Inequality` stacked."""
        nv = self.layout.num_vars
        if not self.inequalities:
            return np.zeros((0, nv)), np.zeros(0), np.zeros(0)
        return (
            np.vstack([g.C for g in self.inequalities]),
            np.concatenate([g.lower for g in self.inequalities]),
            np.concatenate([g.upper for g in self.inequalities]),
        )

    def objective(self, level: int) -> tuple[np.ndarray, np.ndarray]:
        """``(P, c)`` of level ``level``: ``½ zᵀ P z + cᵀ z = Σ w ‖A z - b‖² - const``."""
        return objective(self.layout, self.levels[level].residuals)

    def dense(self, level: int = 0) -> DenseQP:
        """Level ``level``'s QP without the rows that hold the higher levels."""
        p_mat, c = self.objective(level)
        c_rows, lo, up = self.general_rows()
        nv = self.layout.num_vars
        return DenseQP(
            p_mat,
            c,
            np.vstack([np.eye(nv), c_rows]),
            np.concatenate([self.lower, lo]),
            np.concatenate([self.upper, up]),
        )

    def describe(self) -> str:
        """One line per level, term and limit with its row count."""
        lines = []
        for k, lev in enumerate(self.levels):
            lines.append(f"level {k + 1} {lev.name} (tolerance {lev.tolerance:g})")
            for r in lev.residuals:
                lines.append(f"  term {r.name}: {r.b.size} rows, weight {r.weight:g}")
        for b in self.bounds:
            lines.append(f"limit {b.name}: bounds on {b.index.size} variables")
        for g in self.inequalities:
            lines.append(f"limit {g.name}: {g.lower.size} rows")
        return "\n".join(lines)


def objective(layout: DecisionLayout, residuals: tuple[Residual, ...]) -> tuple:
    """``(P, c)`` with ``½ zᵀ P z + cᵀ z = Σ w ‖A z - b‖²`` up to a constant."""
    nv = layout.num_vars
    p_mat = np.zeros((nv, nv))
    c = np.zeros(nv)
    m = layout.block_size
    for r in residuals:
        w2 = 2.0 * r.weight
        if r.blocks is not None:
            gram = np.einsum("pri,prj->pij", r.blocks, r.blocks)
            bb = r.b.reshape(r.blocks.shape[0], r.blocks.shape[1])
            lin = np.einsum("pri,pr->pi", r.blocks, bb)
            for i in range(layout.num_blocks):
                sl = slice(i * m, (i + 1) * m)
                p_mat[sl, sl] += w2 * gram[i]
                c[sl] -= w2 * lin[i]
        else:
            a_w = r.A if r.row_weights is None else r.A * r.row_weights[:, None]
            p_mat += w2 * (a_w.T @ r.A)
            c -= w2 * (a_w.T @ r.b)
    return p_mat, c


def merge_bounds(
    layout: DecisionLayout, bounds: tuple[Bounds, ...]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Intersect every :class:`Bounds`; hard bounds are applied last with the conflict rule
    (where the hard interval misses the others, the point of it closest to them)."""
    nv = layout.num_vars
    lo = np.full(nv, -np.inf)
    up = np.full(nv, np.inf)
    for b in bounds:
        if not b.hard:
            np.maximum.at(lo, b.index, b.lower)
            np.minimum.at(up, b.index, b.upper)
    conflict = np.zeros(nv, dtype=bool)
    for b in bounds:
        if b.hard:
            soft_lo, soft_up = lo[b.index], up[b.index]
            new_lo = np.maximum(soft_lo, b.lower)
            new_up = np.minimum(soft_up, b.upper)
            clash = new_lo > new_up
            if clash.any():
                target = np.where(b.upper < soft_lo, b.upper, b.lower)
                new_lo = np.where(clash, target, new_lo)
                new_up = np.where(clash, target, new_up)
                conflict[b.index[clash]] = True
            lo[b.index] = new_lo
            up[b.index] = new_up
    return lo, up, conflict


@dataclass(frozen=True)
class Solution:
    """What a backend returned for one QP.

    Attributes:
        ok: a verified optimum was found (``x`` is not ``None``).
        status: the solver's status (``"solved"``, ``"primal_infeasible"`` …).
        iterations: solver iterations.
        solve_time_s: wall time of the solve [s].
        x: the primal solution.
        duals: multipliers of the rows (``[bounds; general]``) where the backend gives them.
    """

    ok: bool
    status: str
    iterations: int = 0
    solve_time_s: float = 0.0
    x: np.ndarray | None = field(default=None, repr=False)
    duals: np.ndarray | None = field(default=None, repr=False)
