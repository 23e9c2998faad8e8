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
with its rows and bounds), :class:`BlockQP` the single-level QP with a block-diagonal
Hessian that the structured backends take, and :class:`Solution` what a backend returned.

Terms and limits may offer a *fast path* beside their rows
(:meth:`~dqcontrol.controllers.terms.term.Term.add_gram`,
:meth:`~dqcontrol.controllers.limits.limit.Limit.tighten`,
:meth:`~dqcontrol.controllers.limits.limit.Limit.row_bounds`): the same numbers written
straight into the QP's arrays, for the kilohertz loop. Their rows stay the definition
(:meth:`~dqcontrol.controllers.terms.term.Term.residual`,
:meth:`~dqcontrol.controllers.limits.limit.Limit.rows`): what :class:`Problem` holds and the
tests check the fast paths against.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache, cached_property
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from dqcontrol.controllers.core.box_rules import hard_into, intersect_into
from dqcontrol.controllers.core.state_rows import state_rows_into
from dqcontrol.controllers.linalg.entries import stacked_entries
from dqcontrol.controllers.linalg.gram import (
    add_diagonal_blocks,
    add_scaled,
    block_gram,
    dense_gram,
    frozen,
    kept,
    subtract_block_lin,
    subtract_scaled,
)
from dqcontrol.errors import ParameterError

if TYPE_CHECKING:  # pragma: no cover
    from dqcontrol.controllers.terms.term import Term

__all__ = [
    "BlockQP",
    "Bounds",
    "BuiltLevel",
    "DecisionLayout",
    "DenseQP",
    "Inequality",
    "Level",
    "Problem",
    "Residual",
    "Solution",
    "SplitQP",
    "StateHessian",
    "StateRows",
    "WarmLevels",
    "constant_rows",
    "fixed_variables",
    "merge_bounds",
    "objective",
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

    @cached_property
    def num_blocks(self) -> int:
        """``p``: instants or intervals of the horizon."""
        return int(self.instants_s.size)

    @cached_property
    def block_size(self) -> int:
        """Variables per block: ``n + 1`` with scaling, ``n`` without."""
        return self.num_joints + (1 if self.with_scaling else 0)

    @cached_property
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


def _block_diagonal(blocks: np.ndarray, num_vars: int = 0) -> np.ndarray:
    """The ``(p r, num_vars)`` matrix with ``blocks`` ``(p, r, m)`` on its diagonal
    (``num_vars`` 0: ``p m``)."""
    p, r, m = blocks.shape
    out = np.zeros((p * r, num_vars or p * m))
    for i in range(p):
        out[i * r : (i + 1) * r, i * m : (i + 1) * m] = blocks[i]
    return out


class StateRows(NamedTuple):
    """Dense rows ``A`` given through the predicted states they read (docs/theory.md §7.4).

    Row block ``i`` of ``A`` is a function of state ``i`` only, and the prediction makes
    state ``i`` a weighted sum of the decision blocks: block ``(i, j)`` of ``A`` is
    ``rows[i]`` with its first ``n`` columns times ``weights[i, j]`` (the commands
    ``qd_j``) and its last times ``phase_weights[i, j]`` (the scaling ``s_j``). A backend
    may form ``Aᵀ A`` from these ``p`` small blocks instead of the dense rows.

    Attributes:
        rows: ``(p, r, n + 1)``, the rows of each state over one decision block.
        weights: ``(p, p)``.
        phase_weights: ``(p, p)``.
    """

    rows: np.ndarray
    weights: np.ndarray
    phase_weights: np.ndarray


class Residual(NamedTuple):
    """Residual rows of a term: its cost is ``weight ‖A z - b‖²``.

    ``A`` is dense ``(r, len(z))``; a term whose rows each touch one block may give
    ``blocks`` ``(p, r_i, block_size)`` instead (``A`` block diagonal, rows ordered block by
    block), which the backends exploit. A term with dense rows that read the predicted
    states may give them as ``states`` instead (:class:`StateRows`; :meth:`dense` forms
    ``A`` from them).
    ``held`` says whether lower levels hold these rows at their optimum (a regularisation
    is not held).
    """

    name: str
    weight: float
    b: np.ndarray
    A: np.ndarray | None = None
    blocks: np.ndarray | None = None
    held: bool = True
    row_weights: np.ndarray | None = None
    states: StateRows | None = None

    def dense(self, layout: DecisionLayout) -> np.ndarray:
        """``A`` as a dense ``(r, len(z))`` array (read-only and kept for read-only
        ``blocks``; formed at each call from ``states`` where ``A`` is not given)."""
        if self.A is not None:
            return self.A
        if self.blocks is None and self.states is not None:
            rows, weights = self.states.rows, self.states.weights
            p, r, m = rows.shape
            out = np.empty((p, r, weights.shape[1], m))
            state_rows_into(rows, weights, self.states.phase_weights, out)
            return out.reshape(p * r, weights.shape[1] * m)
        blocks = self.blocks
        assert blocks is not None, "a residual has A or blocks"
        if blocks.shape[0] * blocks.shape[2] == layout.num_vars:
            return kept((blocks,), _block_diagonal)
        return _block_diagonal(blocks, layout.num_vars)

    def value(self, layout: DecisionLayout, z: np.ndarray) -> np.ndarray:
        """``A z - b`` (unweighted)."""
        return self.dense(layout) @ z - self.b


class Bounds(NamedTuple):
    """``lower ≤ z[index] ≤ upper`` from one limit.

    ``hard`` bounds (the acceleration bound) win a conflict: where their interval misses the
    others', the merged bound is the point of the hard interval closest to them (the
    conflict rule of docs/theory.md §5). ``fixed`` bounds are equalities by design
    (``lower == upper`` at every step, e.g. ``s ≡ 1`` without time scaling): a backend may
    fix them for the life of its workspace.
    """

    name: str
    index: np.ndarray  # type: ignore[assignment]  # the field's name hides tuple.index
    lower: np.ndarray
    upper: np.ndarray
    hard: bool = False
    fixed: bool = False


class Inequality(NamedTuple):
    """General rows ``lower ≤ C z ≤ upper`` from one limit (``C`` dense).

    ``keys`` names each row within the limit (integers, the same for the same row at every
    step: a collision pair at a predicted state, say) where the limit's rows come and go;
    a backend then carries its warm start to the rows that stay (docs/theory.md §7.5).
    ``None``: the rows are named by their order, for a limit whose rows keep their places.
    """

    name: str
    C: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    keys: np.ndarray | None = None


def constant_rows(rows: object, again: object) -> bool:
    """Whether a term's residual or a limit's rows never change: the same object at two
    calls (``rows`` and ``again``), made of read-only arrays only (docs/theory.md §7.3).

    This is the one mark of constancy: an array marked read-only
    (:func:`~dqcontrol.controllers.linalg.gram.frozen`) never changes, so the products of
    such arrays are computed once, and a term or limit that hands out one
    :class:`Residual`, :class:`Bounds` or :class:`Inequality` (or a tuple of them) built
    from read-only arrays is evaluated once.
    """
    if rows is None or rows is not again:
        return False
    items = rows if type(rows) is tuple else (rows,)
    for item in items:
        if not isinstance(item, Residual | Bounds | Inequality):
            return False
        for value in item:
            if isinstance(value, np.ndarray):
                if value.flags.writeable:
                    return False
            elif value is not None and not isinstance(value, str | bool | int | float):
                return False
    return True


@dataclass(frozen=True)
class Level:
    """One priority level: its terms and the tolerance to which lower levels hold them.

    Attributes:
        terms: the terms minimised at this level (their weighted sum).
        tolerance: lower levels hold each held residual row of this level at its value
            (in its null space); where that fails, within this absolute distance of its
            optimum (in the row's own unit, docs/theory.md §7.4).
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


class StateHessian(NamedTuple):
    """``P = Tᵀ blockdiag(grams) T + blockdiag(damping)``: a Hessian whose dense part comes
    from rows that read the predicted states (:class:`StateRows`; ``T`` the map from the
    decision to the states, from ``weights`` and ``phase_weights``) and whose other terms
    each touch one block (docs/theory.md §7.5).

    Attributes:
        grams: ``(p, m, m)``, each state's ``2 w Rᵢᵀ Wᵢ Rᵢ``.
        weights, phase_weights: ``(p, p)``, as in :class:`StateRows`.
        damping: ``(p, m, m)``, each block's own part.
    """

    grams: np.ndarray
    weights: np.ndarray
    phase_weights: np.ndarray
    damping: np.ndarray


class SplitQP(NamedTuple):
    """A :class:`DenseQP` with its general rows apart: ``minimize ½ zᵀ P z + cᵀ z  s.t.
    lower ≤ [I; C] z ≤ upper``, ``C`` given as its non-zero ``entries`` (row, column,
    value; row by row, columns in order, read-only:
    :attr:`Problem.general_entries`); ``states``: ``P`` in the predicted states, where it
    has that form (a backend may factorise it so; ``P`` is then ``None`` where it was not
    formed)."""

    P: np.ndarray | None
    c: np.ndarray
    entries: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    states: StateHessian | None = None


class BlockQP(NamedTuple):
    """``minimize ½ zᵀ P z + cᵀ z  s.t.  lower ≤ [I; C] z ≤ upper`` with ``P`` block diagonal.

    Attributes:
        hessian: the diagonal blocks of ``P`` ``(p, m, m)``.
        c: ``(p m,)``.
        C: the general rows ``(r, p m)``.
        lower, upper: bounds of the variables, then of the general rows ``(p m + r,)``.
        fixed: indices of the variables fixed by design (``lower == upper`` at every step).
        structure: a number naming the structure (the shapes, ``C``, ``fixed``): a backend
            sets its workspace up for a structure once and only updates values while the
            number stays the same. Whoever builds the QPs gives a new number whenever the
            structure changes
            (:class:`~dqcontrol.controllers.core.block_assembly.BlockAssembly` draws them
            from one counter, so numbers are never reused).
        warm: a guess of the solution ``(p m,)`` for solvers that take one, or ``None``.
        values: a number that changes whenever the values of ``C`` change within the same
            structure (same shapes: limits whose rows move with the state, such as a
            collision limit's): a backend then refreshes its copy of ``C`` instead of
            setting up again.
    """

    hessian: np.ndarray
    c: np.ndarray
    C: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    fixed: tuple[int, ...] = ()
    structure: int = 0
    warm: np.ndarray | None = None
    values: int = 0

    def dense(self) -> DenseQP:
        """The same QP with ``P`` and ``A`` as dense arrays."""
        p, m, _ = self.hessian.shape
        p_mat = np.zeros((p * m, p * m))
        for i in range(p):
            p_mat[i * m : (i + 1) * m, i * m : (i + 1) * m] = self.hessian[i]
        return DenseQP(p_mat, self.c, np.vstack([np.eye(p * m), self.C]), self.lower, self.upper)


def _stacked(*rows: np.ndarray) -> np.ndarray:
    """The rows one below the other."""
    return np.vstack(rows)


@cache
def _identity(size: int) -> np.ndarray:
    """The read-only identity of this size."""
    return frozen(np.eye(size))


@dataclass(frozen=True)
class Problem:
    """Everything built at one step: the layout, the levels, the limits' rows.

    ``lower``/``upper`` bound the rows of ``A = [I; C]``: first the variables (every
    :class:`Bounds` merged, with the conflict rule; ``conflict`` marks the variables where
    a hard bound won, ``fixed`` those fixed by design), then every :class:`Inequality`'s
    rows in order. The problem also reads as the dense QP of its first level,
    ``P, c, A, lower, upper`` (attributes, and iteration in that order).
    """

    layout: DecisionLayout
    levels: tuple[BuiltLevel, ...]
    bounds: tuple[Bounds, ...]
    inequalities: tuple[Inequality, ...]
    lower: np.ndarray
    upper: np.ndarray
    conflict: np.ndarray
    fixed: np.ndarray | None = None

    def general_rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(C, lower, upper)`` of every :class:`Inequality` stacked."""
        nv = self.layout.num_vars
        return self.C, self.lower[nv:], self.upper[nv:]

    @cached_property
    def C(self) -> np.ndarray:  # noqa: N802 - the matrix's name in the formulas
        """The general rows ``(r, len(z))`` (read-only)."""
        nv = self.layout.num_vars
        if not self.inequalities:
            return frozen(np.zeros((0, nv)))
        return kept(tuple(g.C for g in self.inequalities), _stacked)

    @cached_property
    def general_entries(self) -> np.ndarray:
        """The non-zero entries of ``C``, from each inequality's rows without stacking them
        (:func:`~dqcontrol.controllers.linalg.entries.stacked_entries`)."""
        return stacked_entries(tuple(g.C for g in self.inequalities))

    @cached_property
    def A(self) -> np.ndarray:  # noqa: N802
        """``[I; C]``, the rows ``lower``/``upper`` bound (read-only)."""
        return kept((_identity(self.layout.num_vars), self.C), _stacked)

    @property
    def P(self) -> np.ndarray:  # noqa: N802
        """The first level's Hessian."""
        return self.objective(0)[0]

    @property
    def c(self) -> np.ndarray:
        """The first level's linear term."""
        return self.objective(0)[1]

    def __iter__(self):
        """``P, c, A, lower, upper`` of the first level (a :class:`DenseQP`)."""
        return iter(self.dense(0))

    def __getitem__(self, index):
        return tuple(self.dense(0))[index]

    def __len__(self) -> int:
        return 5

    def objective(self, level: int) -> tuple[np.ndarray, np.ndarray]:
        """``(P, c)`` of level ``level``: ``½ zᵀ P z + cᵀ z = Σ w ‖A z - b‖² - const``."""
        return objective(self.layout, self.levels[level].residuals)

    def dense(self, level: int = 0) -> DenseQP:
        """Level ``level``'s QP without the rows that hold the higher levels."""
        p_mat, c = self.objective(level)
        return DenseQP(p_mat, c, self.A, self.lower, self.upper)

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
    """``(P, c)`` with ``½ zᵀ P z + cᵀ z = Σ w ‖A z - b‖²`` up to a constant.

    The products of read-only rows are computed once (:mod:`~dqcontrol.controllers.linalg.gram`),
    and so is ``P`` itself (read-only then) when every weighted term's rows are read-only;
    the sums are the same, in the same order, at every step."""
    nv = layout.num_vars
    live = tuple(r for r in residuals if 2.0 * r.weight != 0.0)
    operands = _read_only_rows(live)
    c = np.zeros(nv)
    if operands is None:
        p_mat = np.zeros((nv, nv))
        for r in live:
            _add_residual(layout, r, p_mat, c)
        return p_mat, c
    kinds = tuple((_kind(r), 2.0 * r.weight) for r in live)
    p_mat = kept(operands, _hessian, (nv, kinds))
    for r in live:
        _add_residual(layout, r, None, c)
    return p_mat, c


def _kind(r: Residual) -> str:
    """How ``r`` enters the objective: ``"blocks"``, ``"dense"`` or ``"weighted"`` (rows with
    row weights, blocks too, enter densely)."""
    if r.blocks is not None and r.row_weights is None:
        return "blocks"
    return "dense" if r.row_weights is None else "weighted"


def _read_only_rows(residuals: tuple[Residual, ...]) -> tuple[np.ndarray, ...] | None:
    """The arrays ``P`` is computed from (the rows, and the row weights of weighted ones),
    or ``None`` if one of them is writable."""
    out: list[np.ndarray] = []
    for r in residuals:
        kind = _kind(r)
        arrays: tuple[np.ndarray | None, ...] = (r.blocks,) if kind == "blocks" else (r.A,)
        if kind == "weighted":
            arrays = (r.A, r.row_weights)
        for a in arrays:
            if a is None or a.flags.writeable:
                return None
            out.append(a)
    return tuple(out)


def _hessian(*args) -> np.ndarray:
    """``P`` from the arrays of :func:`_read_only_rows` followed by ``(nv, kinds)``: the
    same sums, in the same order, as :func:`_add_residual`'s."""
    *arrays, nv, kinds = args
    p_mat = np.zeros((nv, nv))
    rest = iter(arrays)
    for kind, w2 in kinds:
        a = next(rest)
        if kind == "blocks":
            add_diagonal_blocks(p_mat, block_gram(a), w2)
        elif kind == "dense":
            add_scaled(p_mat, dense_gram(a), w2)
        else:
            add_scaled(p_mat, (a * next(rest)[:, None]).T @ a, w2)
    return p_mat


def _add_residual(
    layout: DecisionLayout, r: Residual, p_mat: np.ndarray | None, c: np.ndarray
) -> None:
    """Add ``2 w AᵀA`` to ``p_mat`` (``None``: not) and subtract ``2 w Aᵀ b`` from ``c``
    (each row weighted by ``row_weights`` where given), in place."""
    w2 = 2.0 * r.weight
    if r.blocks is not None and r.row_weights is None:
        if p_mat is not None:
            add_diagonal_blocks(p_mat, block_gram(r.blocks), w2)
        subtract_block_lin(c, r.blocks, r.b, w2)
        return
    a = r.dense(layout)
    if r.row_weights is None:
        if p_mat is not None:
            add_scaled(p_mat, dense_gram(a), w2)
        subtract_scaled(c, a.T @ r.b, w2)
        return
    a_w = a * r.row_weights[:, None]
    if p_mat is not None:
        add_scaled(p_mat, a_w.T @ a, w2)
    subtract_scaled(c, a_w.T @ r.b, w2)


_FLOAT = np.dtype(np.float64)
_INDEX = np.dtype(np.int64)


def _entries(values, index: np.ndarray) -> np.ndarray:
    """``values`` as one float per entry of ``index`` (a scalar is repeated)."""
    if type(values) is np.ndarray and values.dtype is _FLOAT and values.shape == index.shape:
        return values
    if isinstance(values, np.ndarray) and values.dtype == np.float64:
        if values.shape == index.shape:
            return values
    return np.broadcast_to(np.asarray(values, dtype=float), index.shape)


def _flat_index(index) -> np.ndarray:
    """``index`` as a flat ``int64`` array (itself when it is one)."""
    if type(index) is np.ndarray and index.dtype is _INDEX and index.ndim == 1:
        return index
    return np.asarray(index, dtype=np.int64).ravel()


@cache
def _open_box(nv: int) -> np.ndarray:
    """``[-inf; inf]`` ``(2, nv)`` (read-only: copied by :func:`merge_bounds`)."""
    return frozen(np.array([np.full(nv, -np.inf), np.full(nv, np.inf)]))


def merge_bounds(
    layout: DecisionLayout, bounds: tuple[Bounds, ...]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Intersect every :class:`Bounds`; hard bounds are applied last with the conflict rule
    (where the hard interval misses the others, the point of it closest to them).

    Returns ``(lower, upper, conflict)`` over the variables."""
    nv = layout.num_vars
    box = _open_box(nv).copy()
    lo, up = box[0], box[1]
    for b in bounds:
        if not b.hard:
            index = _flat_index(b.index)
            intersect_into(lo, up, index, _entries(b.lower, index), _entries(b.upper, index))
    conflict = np.zeros(nv, dtype=np.int8)
    for b in bounds:
        if b.hard:
            index = _flat_index(b.index)
            lower, upper = _entries(b.lower, index), _entries(b.upper, index)
            hard_into(lo, up, conflict, index, lower, upper)
    return lo, up, conflict.view(np.bool_)


def fixed_variables(layout: DecisionLayout, bounds: tuple[Bounds, ...]) -> np.ndarray:
    """Mask of the variables some ``fixed`` :class:`Bounds` fixes (read-only when none
    is)."""
    out = None
    for b in bounds:
        if b.fixed:
            if out is None:
                out = np.zeros(layout.num_vars, dtype=bool)
            out[b.index] = True
    return _none_fixed(layout.num_vars) if out is None else out


@cache
def _none_fixed(nv: int) -> np.ndarray:
    """The mask of no fixed variable (read-only, shared)."""
    return frozen(np.zeros(nv, dtype=bool))


class Solution(NamedTuple):
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
    x: np.ndarray | None = None
    duals: np.ndarray | None = None


class WarmLevels(NamedTuple):
    """The first levels of a problem as a backend solved them in one call
    (``solve_warm_levels``, docs/theory.md §7.5).

    Attributes:
        solutions: the levels solved, from the first; each ``x`` is the whole point.
        basis: the basis of the null space the next level moves in, where computed.
        last_basis, last_held: otherwise the basis the last level solved moved in and its
            held rows in it (``None`` after the first level), from which the next level's
            basis is narrowed.
    """

    solutions: tuple[Solution, ...]
    basis: np.ndarray | None
    last_basis: np.ndarray | None
    last_held: np.ndarray | None
