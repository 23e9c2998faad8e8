"""One priority level's QP with a block-diagonal Hessian, built at every step from its terms
and the limits (docs/theory.md §7.5).

:class:`BlockAssembly` turns the terms and limits of a one-level controller into a
:class:`~dqcontrol.controllers.core.problem.BlockQP`:

- *terms*: the constant ones (:func:`~dqcontrol.controllers.core.problem.constant_rows`)
  are evaluated once into a constant Hessian and linear
  term; at each step the others add their blocks through their fast path
  (:meth:`~dqcontrol.controllers.terms.term.Term.add_gram`), or through their rows;
- *limits*: the constant ones are merged once into a template of the bounds; at each
  step the others tighten a copy of it, soft ones first and hard ones last (the conflict
  rule), through their fast paths (:meth:`~dqcontrol.controllers.limits.limit.Limit.tighten`,
  :meth:`~dqcontrol.controllers.limits.limit.Limit.row_bounds`) or through their rows.

The numbers are those :func:`~dqcontrol.controllers.core.levels.build_problem` gives (up to the
order of floating-point sums); its :class:`~dqcontrol.controllers.core.problem.Problem` stays the
inspectable definition. The general rows ``C`` keep their structure number while every
limit gives the same rows; a limit that changes its rows (or becomes active) starts a new
structure, and the backend sets up again.
"""

from __future__ import annotations

import itertools

import numpy as np

from dqcontrol.controllers.core.box_rules import hard_into, intersect_into
from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import (
    BlockQP,
    Bounds,
    Inequality,
    Residual,
    constant_rows,
)
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.terms.term import Term

__all__ = ["BlockAssembly", "overrides"]

_new_qp = tuple.__new__  # a NamedTuple from all its fields, without the keyword handling

#: The numbers of every new set of values of ``C`` within a structure (unique).
_VALUES = itertools.count(1)
#: The structure numbers of every assembly (unique: a backend compares the number only).
_STRUCTURES = itertools.count(1)


def overrides(obj: object, base: type, method: str) -> bool:
    """Whether ``obj``'s class defines ``method`` itself rather than inheriting ``base``'s."""
    return getattr(type(obj), method) is not getattr(base, method)


def _items(out) -> tuple:
    """A limit's :meth:`~Limit.rows` as a tuple of items."""
    if out is None:
        return ()
    return (out,) if isinstance(out, Bounds | Inequality) else tuple(out)


def add_residual(hessian: np.ndarray, c: np.ndarray, res: Residual) -> None:
    """Add ``w ‖A z - b‖²``'s Hessian blocks and linear term (block rows) in place."""
    w2 = 2.0 * res.weight
    blocks = res.blocks
    assert blocks is not None, "a block-diagonal level's residuals are blocks"
    p, r, m = blocks.shape
    bb = res.b.reshape(p, r)
    if res.row_weights is not None:
        rw = res.row_weights.reshape(p, r)
        hessian += w2 * np.einsum("pri,pr,prj->pij", blocks, rw, blocks)
        c -= w2 * np.einsum("pri,pr,pr->pi", blocks, rw, bb).ravel()
    else:
        hessian += w2 * np.einsum("pri,prj->pij", blocks, blocks)
        c -= w2 * np.einsum("pri,pr->pi", blocks, bb).ravel()


class BlockAssembly:
    """Builds a level's :class:`BlockQP` (see the module docstring).

    Args:
        terms: the level's terms.
        limits: every limit of the controller.

    :meth:`build` returns ``None`` when some term's rows touch several blocks (the level's
    Hessian is then not block diagonal: the caller solves the dense problem instead).
    """

    def __init__(self, terms: tuple[Term, ...], limits: tuple[Limit, ...]) -> None:
        self.terms = tuple(terms)
        self.limits = tuple(limits)
        self.relaxable = any(lim.relaxable for lim in self.limits)
        self.structure = 0
        self.values = 0
        self._ready = False
        self.conflict = np.zeros(0, dtype=np.int8)
        #: whether a hard bound won a conflict on the applied block at the last build
        self.has_conflict = False

    # ------------------------------------------------------------------ set-up
    def _setup_terms(self, ctx: StepContext) -> bool:
        layout = ctx.layout
        p, m = layout.num_blocks, layout.block_size
        const_h = np.zeros((p, m, m))
        const_c = np.zeros(layout.num_vars)
        scratch = np.zeros((p, m, m))
        fast, generic = [], []
        for term in self.terms:
            res = term.residual(ctx)
            if constant_rows(res, term.residual(ctx)):
                if res.blocks is None:
                    return False
                add_residual(const_h, const_c, res)
            elif overrides(term, Term, "add_gram") and term.add_gram(ctx, scratch):
                fast.append(term.add_gram)
            else:
                if res.blocks is None:
                    return False
                generic.append(term)
        self._const_h, self._const_c = const_h, const_c
        self._fast_terms, self._generic_terms = tuple(fast), tuple(generic)
        return True

    def _setup_limits(self, ctx: StepContext) -> None:
        layout = ctx.layout
        nv = layout.num_vars
        template_bounds: list[Bounds] = []
        rows: list[tuple[Limit, Inequality]] = []
        fixed: list[int] = []
        constant: set[int] = set()  # ids of the limits evaluated once
        for limit in self.limits:  # the general rows in the limits' order
            out = limit.rows(ctx)
            items = _items(out)
            for item in items:
                if isinstance(item, Bounds) and item.fixed:
                    fixed.extend(int(k) for k in item.index)
                if isinstance(item, Inequality):
                    rows.append((limit, item))
            if constant_rows(out, limit.rows(ctx)):
                constant.add(id(limit))
                template_bounds.extend(i for i in items if isinstance(i, Bounds))
        # the general rows: one slot (a range of rows) per limit, in order
        c_rows: list[np.ndarray] = []
        slots: dict[int, tuple[int, int]] = {}
        start = nv
        for limit, item in rows:
            c_rows.append(item.C)
            first = slots.get(id(limit), (start, start))[0]
            start += item.lower.size
            slots[id(limit)] = (first, start)
        self._C = np.vstack(c_rows) if c_rows else np.zeros((0, nv))
        lower = np.full(start, -np.inf)
        upper = np.full(start, np.inf)
        conflict = np.zeros(nv, dtype=np.int8)
        for b in sorted(template_bounds, key=lambda b: b.hard):
            merge_into(lower, upper, conflict, b)
        for limit, item in rows:
            if id(limit) in constant:
                first, stop = slots[id(limit)]
                lower[first:stop], upper[first:stop] = item.lower, item.upper
        self._bounds0 = np.array([lower, upper])
        self._fixed = tuple(sorted(set(fixed)))
        varying = [lim for lim in self.limits if id(lim) not in constant]
        self._plan(sorted(varying, key=lambda lim: lim.hard), slots)  # soft first
        self.conflict = conflict
        self._marked = True  # conflict may hold marks: cleared at the next build
        self._clash = conflict[: layout.num_joints]
        self._no_clash = bytes(layout.num_joints)
        self._no_mark = bytes(nv)

    def _plan(self, ordered: list[Limit], slots: dict) -> None:
        """What each step does per limit: the fast paths as bound methods (in the limits'
        order: soft ones first), the rest through their rows."""
        tightens, row_bounds, generic = [], [], []
        for limit in ordered:
            slot = slots.get(id(limit))
            fast_bounds = overrides(limit, Limit, "tighten")
            fast_rows = overrides(limit, Limit, "row_bounds") or (fast_bounds and slot is None)
            if not (fast_bounds and fast_rows):
                generic.append((limit, slot))
                continue
            tightens.append((limit.tighten, limit.relaxable))
            if slot is not None:
                row_bounds.append((limit.row_bounds, slot[0], slot[1], limit.relaxable))
        self._all_tightens = tuple(t for t, _ in tightens)
        self._relaxed_tightens = tuple(t for t, relaxable in tightens if not relaxable)
        self._row_bounds = tuple(row_bounds)
        self._generic = tuple(generic)

    def setup(self, ctx: StepContext) -> bool:
        """Evaluate the constant terms and limits and the rows' structure at ``ctx``."""
        if not self._setup_terms(ctx):
            return False
        self._setup_limits(ctx)
        self.structure = next(_STRUCTURES)
        self._ready = True
        return True

    # ------------------------------------------------------------------ every step
    def _bounds(self, ctx: StepContext, relaxed: bool) -> tuple | None:
        """``(lower, upper)`` of this step, or ``None`` if the rows' structure changed.

        Soft bounds are merged before hard ones: the generic limits' soft bounds first, then
        the fast paths in the limits' order (soft limits sort first), then the generic
        limits' hard bounds."""
        bounds = self._bounds0.copy()
        lower, upper = bounds[0], bounds[1]
        conflict = self.conflict
        if self._marked:
            conflict.fill(0)
        late: tuple | list = ()
        if self._generic:
            generic = self._generic_bounds(ctx, relaxed, lower, upper, conflict)
            if generic is None:
                return None
            late = generic
        for tighten in self._relaxed_tightens if relaxed else self._all_tightens:
            tighten(ctx, lower, upper, conflict)
        for row_bounds, a, b, relaxable in self._row_bounds:
            if relaxed and relaxable:
                lower[a:b], upper[a:b] = -np.inf, np.inf
            else:
                row_bounds(ctx, lower[a:b], upper[a:b])
        for item in late:
            merge_into(lower, upper, conflict, item)
        marked = self._marked = conflict.tobytes() != self._no_mark
        self.has_conflict = marked and self._clash.tobytes() != self._no_clash
        return lower, upper

    def _generic_bounds(self, ctx, relaxed: bool, lower, upper, conflict) -> list | None:
        """The limits without fast paths, through their rows: their soft bounds merged and
        their rows' bounds written in place; their hard bounds returned (merged last), or
        ``None`` if the rows' structure changed."""
        late: list[Bounds] = []
        for limit, slot in self._generic:
            items = _items(limit.rows(ctx))
            skip = relaxed and limit.relaxable
            if not skip:
                for item in items:
                    if isinstance(item, Bounds):
                        if item.hard:
                            late.append(item)
                        else:
                            merge_into(lower, upper, conflict, item)
            if slot is None:
                if any(isinstance(i, Inequality) for i in items):
                    return None  # a limit became active with rows
            elif skip:
                lower[slot[0] : slot[1]], upper[slot[0] : slot[1]] = -np.inf, np.inf
            elif not self._same_rows(items, slot, lower, upper, ctx.layout.num_vars):
                return None
        return late

    def _same_rows(self, items: tuple, slot: tuple, lower, upper, nv: int) -> bool:
        """Write the rows' bounds into ``slot``; False if their matrix is not the one set up."""
        rows = [i for i in items if isinstance(i, Inequality)]
        a, b = slot
        if sum(r.lower.size for r in rows) != b - a:
            return False
        c_mat = np.vstack([r.C for r in rows])
        current = self._C[a - nv : b - nv]
        if c_mat.shape != current.shape:
            return False
        if not np.array_equal(c_mat, current):  # same rows, new values
            current[...] = c_mat
            self.values = next(_VALUES)
        lower[a:b] = np.concatenate([r.lower for r in rows])
        upper[a:b] = np.concatenate([r.upper for r in rows])
        return True

    def build(self, ctx: StepContext, relaxed: bool = False, warm=None) -> BlockQP | None:
        """This step's QP (``relaxed``: without the relaxable limits), or ``None`` when the
        level is not block diagonal."""
        if not self._ready and not self.setup(ctx):
            return None
        bounds = self._bounds(ctx, relaxed)
        if bounds is None:  # a limit changed its rows: a new structure
            self.setup(ctx)
            bounds = self._bounds(ctx, relaxed)
            assert bounds is not None, "a fresh structure holds this step's rows"
        hessian = self._const_h.copy()
        for add in self._fast_terms:
            add(ctx, hessian)
        c = self._const_c
        if self._generic_terms:
            c = c.copy()
            for term in self._generic_terms:
                add_residual(hessian, c, term.residual(ctx))
        lower, upper = bounds
        return _new_qp(
            BlockQP,
            (hessian, c, self._C, lower, upper, self._fixed, self.structure, warm, self.values),
        )


def merge_into(lower: np.ndarray, upper: np.ndarray, conflict: np.ndarray, b: Bounds) -> None:
    """Merge one :class:`Bounds` into the variable bounds in place (compiled; hard ones with
    the conflict rule)."""
    index = np.asarray(b.index, dtype=np.int64)
    lo = np.ascontiguousarray(b.lower, dtype=float)
    up = np.ascontiguousarray(b.upper, dtype=float)
    if b.hard:
        hard_into(lower, upper, conflict, index, lo, up)
    else:
        intersect_into(lower, upper, index, lo, up)
