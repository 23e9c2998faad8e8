"""DAQP, the default backend: one workspace per QP (priority level), updated in place each
step, and the paths specialised on the problem's structure (docs/theory.md §6, §7.5).

One level with a block-diagonal ``P`` (the thesis's controllers) goes to
:class:`~dqcontrol.controllers.backends.daqp.blocks.DaqpBlocks`, whose workspace is set up
for the blocks' structure once (:meth:`DaqpBackend.solve_blocks`).

A QP with a positive definite ``H`` and sparse general rows is handed to DAQP as the
equivalent least-distance problem
(:func:`~dqcontrol.controllers.backends.daqp.least_distance.dense_ldp`, compiled), so that
DAQP's ``H`` stays the identity for the workspace's life: forming
``C L⁻ᵀ`` then costs one pass over the non-zeros of ``C``, where DAQP, given the new ``H``,
would form ``A R⁻¹`` over every entry. With dense rows (a level reduced to the null space
of the levels above) DAQP's own handling costs the same and is kept.

Before DAQP, a level is solved on the active set of its last solve and the KKT conditions
are checked (:func:`~dqcontrol.controllers.backends.daqp.active_set.solve_on_active_set`): when
the set has not changed, that is the optimum, found without DAQP's update. A level reduced
to the null space of the levels above is given as its parts (:meth:`DaqpBackend.
solve_reduced`): its QP is formed and solved on the last active set in one compiled call
(:mod:`~dqcontrol.controllers.backends.daqp.reduced_active_set`), the same numbers as forming the
dense QP first. While every level's last set holds, all the levels of a problem are solved
so in one call (:meth:`DaqpBackend.solve_warm_levels`,
:mod:`~dqcontrol.controllers.backends.daqp.warm_levels`).
"""

from __future__ import annotations

import time
import weakref
from ctypes import c_int

import numpy as np
from scipy.linalg import lapack

from dqcontrol._compiled import compiled
from dqcontrol.controllers.backends.base import Backend
from dqcontrol.controllers.backends.daqp.active_set import SOLVED, solve_on_active_set
from dqcontrol.controllers.backends.daqp.blocks import DaqpBlocks
from dqcontrol.controllers.backends.daqp.least_distance import dense_ldp, ldp_solution
from dqcontrol.controllers.backends.daqp.reduced_active_set import reduced_on_active_set
from dqcontrol.controllers.backends.daqp.row_identity import carried_set
from dqcontrol.controllers.backends.daqp.state_factor import state_factor
from dqcontrol.controllers.backends.daqp.warm_levels import warm_levels
from dqcontrol.controllers.core.objective import dense_hessian
from dqcontrol.controllers.core.problem import (
    BlockQP,
    DenseQP,
    Inequality,
    Solution,
    SplitQP,
    WarmLevels,
)
from dqcontrol.controllers.core.reduced import LevelRows, ReducedQP
from dqcontrol.controllers.linalg.cholesky import cholesky_into
from dqcontrol.controllers.linalg.entries import nonzero_entries
from dqcontrol.errors import ParameterError

__all__ = ["DaqpBackend"]

#: DAQP settings of this backend: tighter primal tolerance than DAQP's 1e-6, so that the
#: rows holding a higher level are met to within 1e-9.
DEFAULT_DAQP_SETTINGS = {"primal_tol": 1e-9}

#: No entries: the rows given to :func:`solve_on_active_set` dense (``sparse`` False).
_DENSE_CHECK = np.zeros((0, 3))
_DENSE_CHECK.flags.writeable = False

_EXIT = {-1: "primal_infeasible", -2: "cycling", -3: "unbounded", -4: "iteration_limit",
         -5: "nonconvex", -6: "initial_active_set_infeasible"}  # fmt: skip
_BIG = 1e30
#: Largest share of non-zero entries in the general rows for the least-distance form.
SPARSE_ROWS_SHARE = 0.25
#: Up to this many variables ``P`` is factorised by a compiled loop, beyond by LAPACK (whose
#: call costs more than the whole factorisation of a small matrix).
SMALL_FACTOR = 40
#: A multiplier of the reused active set counts as of the wrong sign beyond this share of
#: the largest one (rounding of a weakly active row stays within it).
ACTIVE_SET_DUAL_SHARE = 1e-9
#: How many rows may join or leave the last active set before DAQP takes over.
ACTIVE_SET_CHANGES = 4
#: ``P`` counts as safely positive definite when every squared pivot of its Cholesky factor
#: is above this share of its largest diagonal entry.
PIVOT_SHARE = 1e-12


class DaqpBackend(Backend):
    """DAQP (dual active set), warm-started from the previous active set per key.

    Args:
        settings: DAQP settings over :data:`DEFAULT_DAQP_SETTINGS` (the block path of
            :meth:`solve_blocks` takes them over DAQP's own defaults).
        least_distance: hand DAQP the least-distance form of QPs whose Hessian is positive
            definite and whose general rows are sparse (the same optimum, found cheaper);
            ``False`` gives DAQP every QP as it is.
        reuse_active_set: first solve a key's QP on the active set of its last solve,
            mended a few rows at a time, and keep that point when it meets the KKT
            conditions (positive definite ``P`` only); ``False`` always calls DAQP.
    """

    name = "daqp"
    solves_warm_levels = True

    def __init__(
        self,
        settings: dict | None = None,
        least_distance: bool = True,
        reuse_active_set: bool = True,
    ) -> None:
        import daqp

        self._daqp = daqp
        self.settings = dict(DEFAULT_DAQP_SETTINGS)
        self.settings.update(settings or {})
        unknown = sorted(set(self.settings) - set(daqp.Model().settings))
        if unknown:
            raise ParameterError(
                f"solver_settings: DAQP has no setting {unknown}; it knows "
                f"{sorted(daqp.Model().settings)}"
            )
        self.least_distance = bool(least_distance)
        self.reuse_active_set = bool(reuse_active_set)
        self._models: dict = {}
        self._ldp: dict = {}
        self._active: dict = {}
        self._reduced: dict = {}
        self._copies: dict = {}
        self._recent: dict = {}  # level -> the key ``(level, dim)`` it was last solved with
        self._kernel_settings: tuple = (None, np.zeros(0))
        self._rows: tuple[Inequality, ...] | None = None  # the present problem's general rows
        self._num_vars = 0  # and its number of variables
        self._blocks = DaqpBlocks(settings=settings)
        # the block path is the workspace's own (bound here: one call less at 1 kHz)
        self.solve_blocks = self._blocks.solve_blocks  # type: ignore[method-assign]

    def reset(self) -> None:
        """Forget every level's workspace and active set."""
        self._blocks.reset()
        self._models.clear()
        self._ldp.clear()
        self._active.clear()
        self._reduced.clear()
        self._copies.clear()
        self._recent.clear()
        self._rows = None

    def set_general_rows(self, num_vars: int, inequalities: tuple[Inequality, ...]) -> None:
        """Name the rows of the problem whose levels are solved next: its ``num_vars``
        variables and its limits' inequalities, in order. An active set kept for other
        general rows is then carried to these by name
        (:func:`~dqcontrol.controllers.backends.daqp.row_identity.carried_set`) instead of
        by index."""
        self._num_vars, self._rows = int(num_vars), inequalities

    def _on_rows(self, entry: tuple, extra: int, total: int) -> tuple | None:
        """``entry`` (a kept set with its QP's shape) for a QP of ``total`` rows: as it is
        where the count is the same, else carried by name to the present problem's rows
        (``extra``: rows before its ``[I; C]``, a reduced level's own variables); ``None``
        where it cannot be."""
        if entry[0][0] == total:
            return entry
        before, now = entry[3], self._rows
        first_general = extra + self._num_vars
        if before is None or now is None or first_general + _count(now) != total:
            return None  # rows not named, or named for another QP
        active, at_upper = carried_set(entry[1], entry[2], first_general, before, now)
        return ((total, entry[0][1]), active, at_upper, now)

    def solve_warm_levels(
        self, first: SplitQP, held: np.ndarray, lower: tuple[LevelRows, ...]
    ) -> WarmLevels | None:
        """The levels solved on their last active sets in one compiled call
        (:func:`~dqcontrol.controllers.backends.warm_levels.warm_levels`), as far as that
        goes: ``first`` is the first level's QP (key ``0``), ``held`` its held rows,
        ``lower`` the stacked rows of each lower level (keys ``(k, dim)``). ``None`` where
        not even the first level is solved so; the levels solved share the call's time
        equally."""
        start = time.perf_counter()
        last = self._active.get(0) if self.reuse_active_set else None
        nv, rows = first.c.size, first.lower.size
        if last is None or last[0][1] != nv:
            return None
        factor = _first_factor(first)
        if factor is None:
            return None
        actives, uppers, dims = self._last_sets(last, len(lower), rows)
        count = len(lower) + 1
        points, duals = np.empty((count, nv)), np.empty((count, rows))
        changes, has_duals = np.zeros(count, dtype=np.int64), np.zeros(count, dtype=bool)
        first_level = (factor, np.ascontiguousarray(first.c), first.lower, first.upper)
        entries, bs, scales, held_counts = zip(*lower, strict=True)
        lower_levels = (entries, bs, scales, np.array(held_counts))
        settings = self._settings_array()
        done, kept, kept_upper, counts, solved_dims, basis, ready, last_held = warm_levels(
            first_level, np.ascontiguousarray(held), lower_levels, (actives, uppers, dims),
            first.entries, settings, (points, duals, has_duals, changes),
        )  # fmt: skip
        if done == 0:
            return None
        share = _since(start) / done
        solutions, offset = [], 0
        for k, dim, size, dual, change in zip(
            range(done), solved_dims[:done].tolist(), counts[:done].tolist(),
            has_duals[:done].tolist(), changes[:done].tolist(), strict=True,
        ):  # fmt: skip
            if dual:
                key = 0 if k == 0 else (k, dim)
                shape = (rows, nv) if k == 0 else (dim + rows, dim)
                end = offset + size
                self._active[key] = (shape, kept[offset:end], kept_upper[offset:end], self._rows)
                self._recent[k] = key
            offset += size
            solutions.append(
                Solution(True, "solved", change, share, points[k], duals[k] if dual else None)
            )
        if done == count or ready:
            return WarmLevels(tuple(solutions), basis if done < count else None, None, None)
        if done == 1:  # the first level's held rows go to LAPACK: narrowed from scratch
            return WarmLevels(tuple(solutions), None, None, None)
        return WarmLevels(tuple(solutions), None, basis, last_held)

    def _last_sets(self, first: tuple, lower: int, rows: int) -> tuple[tuple, tuple, np.ndarray]:
        """The last active sets of the first level (entry ``first``) and of the ``lower``
        levels below it (the key each was last solved with), their ``at_upper`` flags,
        and the number of variables each lower set was for (``-1``: none for ``rows``
        rows). Sets kept for other rows are carried to these (:meth:`_on_rows`); the first
        level's, where that cannot be, keeps the rows that still exist."""
        active, at_upper = _on_existing_rows(self._on_rows(first, 0, rows) or first, rows)
        actives, uppers, dims = [active], [at_upper], [-1] * lower
        stored, recent = self._active, self._recent
        for k in range(1, lower + 1):
            entry = stored.get(recent.get(k))
            if entry is not None and entry[0][0] - entry[0][1] != rows:  # a limit's rows changed
                entry = self._on_rows(entry, entry[0][1], entry[0][1] + rows)
            if entry is not None and entry[0][0] - entry[0][1] == rows:
                actives.append(entry[1])
                uppers.append(entry[2])
                dims[k - 1] = entry[0][1]
            else:
                actives.append(np.zeros(0, dtype=np.int64))
                uppers.append(np.zeros(0, dtype=bool))
        return tuple(actives), tuple(uppers), np.array(dims, dtype=np.int64)

    def _settings_array(self) -> np.ndarray:
        """``(primal_tol, dual_tol, max_changes, pivot_share, max_dim)`` of the active-set
        kernels (``max_dim``: :data:`SMALL_FACTOR`, for the warm levels), the same array
        while ``primal_tol`` stays the same."""
        tol = self.settings.get("primal_tol", 1e-6)
        if self._kernel_settings[0] != tol:
            values = [tol, ACTIVE_SET_DUAL_SHARE, ACTIVE_SET_CHANGES, PIVOT_SHARE, SMALL_FACTOR]
            self._kernel_settings = (tol, np.array(values, dtype=float))
        return self._kernel_settings[1]

    def solve_reduced(self, key: object, qp: ReducedQP) -> tuple[Solution, np.ndarray]:
        """Solve level ``key`` given as a :class:`~dqcontrol.controllers.core.reduced.ReducedQP`
        (the answer in ``y``, as :meth:`solve` of its dense QP) and return it with the
        level's held rows in the basis. With a last active set of the same shape (and at
        most :data:`SMALL_FACTOR` variables) the QP is formed and solved on that set in one
        compiled call; otherwise its dense QP goes to :meth:`solve`, and where that call does
        not end with a checked optimum, to DAQP."""
        start = time.perf_counter()
        dim = qp.basis.shape[1]
        size = dim + qp.lower.size
        if isinstance(key, tuple):
            self._recent[key[0]] = key
        entry = self._active.get(key) if self.reuse_active_set else None
        if entry is not None and entry[0][1] == dim and entry[0][0] != size:
            entry = self._on_rows(entry, dim, size)  # a limit's rows changed
        if entry is None or entry[0] != (size, dim) or dim > SMALL_FACTOR:
            objective = qp.objective()
            return self.solve(key, qp.dense(objective)), objective.held
        buffers = self._reduced_buffers(key, qp.rows.b.size, size, dim)
        rows, qp_rows, qp_lower, qp_upper = buffers
        y, duals = np.empty(dim), np.empty(size)
        settings = self._settings_array()
        status, active, at_upper, changes, hessian, gradient = reduced_on_active_set(
            qp.rows.entries, qp.rows.b, qp.rows.scale, qp.basis, qp.point,
            nonzero_entries(qp.general), qp.lower, qp.upper, entry[1], entry[2], settings,
            rows, qp_rows, qp_lower, qp_upper, y, duals,
        )  # fmt: skip
        held = rows[: qp.rows.held, :-1].copy()
        if status == SOLVED and np.isfinite(y).all():
            self._active[key] = ((size, dim), active, at_upper, self._rows)
            return Solution(True, "solved", changes, _since(start), y, duals), held
        # the same guess on the same numbers would fail again: straight to DAQP
        dense = DenseQP(hessian, gradient, qp_rows.copy(), qp_lower.copy(), qp_upper.copy())
        return self._solve(key, dense, start, try_last=False), held

    def _reduced_buffers(self, key: object, count: int, size: int, dim: int) -> tuple:
        """The key's buffers of :func:`reduced_on_active_set` (its level's rows, the QP's
        rows and bounds), kept while the sizes stay the same."""
        buffers = self._reduced.get(key)
        if buffers is None or buffers[0].shape != (count, dim + 1) or buffers[1].shape[0] != size:
            buffers = (np.empty((count, dim + 1)), np.empty((size, dim)), np.empty(size),
                       np.empty(size))  # fmt: skip
            self._reduced[key] = buffers
        return buffers

    @property
    def form(self) -> str:
        """The form DAQP gets on the block path: ``"dense"`` (one block, no general row:
        the problem as it is) or ``"least_distance"``."""
        return self._blocks.form

    def solve_blocks(self, qp: BlockQP) -> Solution:
        """One level with a block-diagonal ``P``, on the workspace of its structure
        (:meth:`DaqpBlocks.solve_blocks`)."""
        return self._blocks.solve_blocks(qp)

    def solve(self, key: object, qp: DenseQP) -> Solution:
        """Solve level ``key``'s QP with DAQP (warm start: its previous active set)."""
        return self._solve(key, qp, time.perf_counter(), self.reuse_active_set)

    def _solve(self, key: object, qp: DenseQP, start: float, try_last: bool) -> Solution:
        """:meth:`solve`, first on the key's last active set where ``try_last``."""
        if not (qp.lower <= qp.upper).all():
            bad = np.flatnonzero(~(qp.lower <= qp.upper))[:5].tolist()
            return Solution(False, f"invalid_bounds: lower > upper or NaN in rows {bad}")
        factor = None
        last = self._active.get(key) if try_last else None
        if last is not None and last[0][1] == qp.A.shape[1]:
            factor = _factor(qp.P)
            kept = None if factor is None else self._on_last_active_set(key, qp, factor, start)
            if kept is not None:
                return kept
        sparse = self.least_distance and _sparse_rows(qp)
        if sparse and factor is None:
            factor = _factor(qp.P)
        buffers = self._least_distance(key, qp, factor) if factor is not None and sparse else None
        if buffers is not None:
            sol = self._solve_ldp(key, buffers, start)
        else:
            sol = self._solve_as_is(key, qp, start)
        self._remember_active_set(key, qp, sol)
        return sol

    def _on_last_active_set(
        self, key: object, qp: DenseQP, factor: np.ndarray, start: float
    ) -> Solution | None:
        """The optimum from the key's last active set (mended up to
        :data:`ACTIVE_SET_CHANGES` times), or ``None`` when it fails the KKT check (or there
        is none for this number of variables). Where a limit's row count has changed since,
        the last set carried to the present rows by name (:meth:`_on_rows`) is the guess,
        else the rows of the last set that still exist: the check decides."""
        entry = self._active.get(key)
        if entry is None or entry[0][1] != qp.A.shape[1]:
            return None
        extra = 0 if key == 0 else qp.c.size  # a reduced level's own variables come first
        moved = self._on_rows(entry, extra, qp.A.shape[0]) if _carries(key) else None
        active, at_upper = _on_existing_rows(moved or entry, qp.A.shape[0])
        a = self._writable_rows(key, np.ascontiguousarray(qp.A))
        z, duals = np.empty(qp.c.size), np.empty(a.shape[0])
        status, active, at_upper, changes = solve_on_active_set(
            (factor, _NO_BLOCKS, _NO_BLOCKS, _NO_SCALES), np.ascontiguousarray(qp.c),
            a[qp.c.size :], _DENSE_CHECK, False, qp.lower, qp.upper, active, at_upper,
            self.settings.get("primal_tol", 1e-6), ACTIVE_SET_DUAL_SHARE, ACTIVE_SET_CHANGES,
            z, duals,
        )  # fmt: skip
        if status != SOLVED or not np.isfinite(z).all():
            return None
        self._active[key] = (qp.A.shape, active, at_upper, self._rows)
        return Solution(True, "solved", changes, _since(start), z, duals)

    def _writable_rows(self, key: object, a: np.ndarray) -> np.ndarray:
        """``a``, or a writable copy of a read-only ``a`` that owns its data (such rows never
        change: the copy is kept for the key while ``a`` is the same array). The active-set
        kernel is then compiled for writable rows only, the form the reduced levels give it."""
        if a.flags.writeable or a.base is not None:
            return a
        kept = self._copies.get(key)
        if kept is None or kept[0]() is not a:
            kept = (weakref.ref(a), a.copy())
            self._copies[key] = kept
        return kept[1]

    def _remember_active_set(self, key: object, qp: DenseQP, sol: Solution) -> None:
        """Keep the rows DAQP's answer holds at a bound (non-zero multipliers) as the key's
        next guess; forget the guess after a failure."""
        if not sol.ok or sol.duals is None or sol.duals.size != qp.A.shape[0]:
            self._active.pop(key, None)
            return
        active = np.flatnonzero(sol.duals)
        self._active[key] = (qp.A.shape, active, sol.duals[active] > 0.0, self._rows)

    def _solve_as_is(self, key: object, qp: DenseQP, start: float) -> Solution:
        nv = qp.c.size
        # DAQP takes writable C-ordered buffers (the problem's rows may be read-only)
        h = np.require(qp.P, requirements=("C", "W"))
        f = np.require(qp.c, requirements=("C", "W"))
        a = np.require(qp.A[nv:], requirements=("C", "W"))
        lo = np.clip(qp.lower, -_BIG, _BIG)
        up = np.clip(qp.upper, -_BIG, _BIG)
        shape = a.shape
        entry = self._models.get(key)
        try:
            if entry is None or entry[1] != shape:
                model = self._daqp.Model()
                sense = np.zeros(lo.size, dtype=c_int)
                if model.setup(h, f, a, up, lo, sense)[0] < 0:
                    return Solution(False, "error: DAQP setup failed", 0, _since(start))
                model.settings = dict(self.settings)
            else:
                model = entry[0]
                # DAQP's update cannot take an A without rows (only bounds): leave it out
                rows = {"A": a} if a.shape[0] else {}
                if model.update(H=h, f=f, bupper=up, blower=lo, **rows) < 0:
                    self._models.pop(key, None)
                    return Solution(False, "error: DAQP refused the update", 0, _since(start))
            # DAQP keeps pointers to the arrays it was given: keep them alive with the model
            self._models[key] = (model, shape, (h, f, a, up, lo))
            x, _fval, flag, info = model.solve()
        except Exception as exc:  # noqa: BLE001 - a solver failure must not stop the loop
            self._models.pop(key, None)
            return Solution(False, f"error: {exc}", 0, _since(start))
        return self._answer(self._models, key, x, flag, info, start)

    def _least_distance(self, key: object, qp: DenseQP, factor: np.ndarray) -> dict | None:
        """The least-distance form of ``qp`` in this key's buffers (``factor``: the Cholesky
        factor of ``P``), or ``None`` when LAPACK cannot invert the factor."""
        nv = qp.c.size
        rows = qp.A.shape[0]
        entry = self._ldp.get(key)
        if entry is None or entry["m"].shape != (rows, nv):
            entry = {
                "m": np.empty((rows, nv)), "lo": np.empty(rows), "up": np.empty(rows),
                "linv_t": np.empty((1, nv, nv)), "w": np.empty(nv), "model": None,
            }  # fmt: skip
            self._ldp[key] = entry
        general = np.ascontiguousarray(qp.A[nv:])
        ok = dense_ldp(
            factor, np.ascontiguousarray(qp.c), qp.lower, qp.upper,
            general, entry["m"], entry["lo"], entry["up"], entry["linv_t"], entry["w"],
        )  # fmt: skip
        return entry if ok else None

    def _solve_ldp(self, key: object, entry: dict, start: float) -> Solution:
        """DAQP on the least-distance problem in ``entry`` (``H = I`` for the workspace's
        life: later steps update ``M`` and the bounds only)."""
        model = entry["model"]
        try:
            if model is None:
                nv = entry["w"].size
                model = self._daqp.Model()
                sense = np.zeros(entry["lo"].size, dtype=c_int)
                eye, zero = np.eye(nv), np.zeros(nv)
                if model.setup(eye, zero, entry["m"], entry["up"], entry["lo"], sense)[0] < 0:
                    return Solution(False, "error: DAQP setup failed", 0, _since(start))
                model.settings = dict(self.settings)
                entry["model"], entry["kept"] = model, (eye, zero, sense)
            elif model.update(A=entry["m"], bupper=entry["up"], blower=entry["lo"]) < 0:
                self._ldp.pop(key, None)
                return Solution(False, "error: DAQP refused the update", 0, _since(start))
            u, _fval, flag, info = model.solve()
        except Exception as exc:  # noqa: BLE001 - a solver failure must not stop the loop
            self._ldp.pop(key, None)
            return Solution(False, f"error: {exc}", 0, _since(start))
        if u is not None and flag in (1, 2):
            u = ldp_solution(entry["linv_t"], np.asarray(u), entry["w"])
        return self._answer(self._ldp, key, u, flag, info, start)

    @staticmethod
    def _answer(store: dict, key: object, x, flag: int, info, start: float) -> Solution:
        """The :class:`Solution` of DAQP's answer; a failed workspace is forgotten."""
        iterations = int(info.get("iterations", 0)) if isinstance(info, dict) else 0
        ok = flag in (1, 2) and x is not None and bool(np.isfinite(x).all())
        if not ok:
            store.pop(key, None)
            status = _EXIT.get(int(flag), f"daqp_exit_{flag}")
            return Solution(False, status, iterations, _since(start))
        duals = np.asarray(info.get("lam")) if isinstance(info, dict) and "lam" in info else None
        return Solution(True, "solved", iterations, _since(start), np.array(x), duals)


_NO_BLOCKS = np.zeros((0, 0, 0))
_NO_SCALES = np.zeros((0, 0))


def _count(inequalities: tuple[Inequality, ...]) -> int:
    """The number of general rows of ``inequalities``."""
    return sum(g.lower.size for g in inequalities)


def _carries(key: object) -> bool:
    """Whether the rows of a key's QP are the problem's ``[I; C]`` (the first level, ``0``)
    or a reduced level's own variables and then those (``(level, dim)``); a banded level's
    held rows come after them."""
    return key == 0 or (isinstance(key, tuple) and isinstance(key[1], int))


def _on_existing_rows(entry: tuple, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """The kept set of ``entry`` without the rows beyond the ``rows`` that exist."""
    active, at_upper = entry[1], entry[2]
    if entry[0][0] == rows:
        return active, at_upper
    keep = active < rows
    return active[keep], at_upper[keep]


def _first_factor(first: SplitQP) -> tuple | None:
    """The first level's factor tuple (:mod:`.active_set`): in the predicted states where
    ``P`` has that form and its factor is safely positive definite
    (:func:`~dqcontrol.controllers.backends.state_factor.state_factor`), else the dense
    Cholesky factor; ``None`` when neither is."""
    states, p_mat = first.states, first.P
    if states is not None:
        ok, factor = state_factor(
            states.grams, states.weights, states.phase_weights, states.damping, PIVOT_SHARE
        )
        if ok:
            return factor
        if p_mat is None:
            p_mat = dense_hessian(states)
    assert p_mat is not None, "P not formed comes with its state form"
    dense = _factor(p_mat)
    return None if dense is None else (dense, _NO_BLOCKS, _NO_BLOCKS, _NO_SCALES)


def _factor(p_mat: np.ndarray) -> np.ndarray | None:
    """The lower Cholesky factor of ``p_mat``, or ``None`` when it is not safely positive
    definite (a squared pivot at most :data:`PIVOT_SHARE` of its largest diagonal entry,
    or NaN)."""
    if p_mat.shape[0] <= SMALL_FACTOR:
        factor = np.zeros(p_mat.shape)
        return factor if cholesky_into(p_mat, factor, PIVOT_SHARE, 0.0) else None
    # the upper factor of ``p_matᵀ = p_mat`` in Fortran order is ``L`` in C order
    upper, info = lapack.dpotrf(p_mat.T, lower=0, clean=1)
    if info != 0:
        return None
    factor = upper.T
    return factor if _clear_pivots(factor, p_mat, PIVOT_SHARE) else None


@compiled
def _clear_pivots(factor: np.ndarray, p_mat: np.ndarray, share: float) -> bool:
    """The smallest pivot of ``factor`` squared above ``share`` times the largest diagonal
    entry of ``p_mat`` (neither NaN)."""
    smallest, largest = np.inf, -np.inf
    for i in range(factor.shape[0]):
        pivot, entry = factor[i, i], p_mat[i, i]
        if pivot != pivot or entry != entry:
            return False
        smallest = min(smallest, pivot)
        largest = max(largest, entry)
    return smallest * smallest > share * largest


def _sparse_rows(qp: DenseQP) -> bool:
    """Whether the general rows of ``qp`` are sparse enough for the least-distance form."""
    general = qp.A[qp.c.size :]
    return bool(np.count_nonzero(general) <= SPARSE_ROWS_SHARE * general.size)


def _since(start: float) -> float:
    return time.perf_counter() - start
