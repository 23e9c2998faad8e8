"""The contract of every term and every limit the package exports, checked on the
compositions of the QP controllers at steps of a closed loop.

Every class in ``dqcontrol.controllers.terms.__all__`` and ``limits.__all__`` must appear in
one of the compositions below (a new term or limit joins this test by being exported).
For each, at several steps:

- a term's rows are the affine map they claim: ``value(z) = A z - b`` with ``A`` formed
  here from its blocks (block diagonal) or its states (the prediction's weights), the
  weight and row weights finite and non-negative, every entry finite;
- each level's objective ``½ zᵀ P z + cᵀ z`` is the weighted sum of its residuals'
  squares, checked by finite differences of the cost computed from the rows;
- a limit gives ``None``, :class:`Bounds` (indices within the decision, as many bounds as
  indices, ``lower ≤ upper`` unless hard) or :class:`Inequality` rows (``C`` over the whole
  decision, one bound per row, keys one per row); a term or limit whose rows are constant
  (``constant_rows``: one object of read-only arrays) gives the same object and numbers at
  every step.
"""

import numpy as np
import pytest

from dqcontrol.controllers import limits as limits_pkg
from dqcontrol.controllers import terms as terms_pkg
from dqcontrol.controllers.core.problem import Bounds, Inequality, Residual, constant_rows
from dqcontrol.controllers.limits import CollisionLimit
from dqcontrol.model import LBR4P_Q0
from dqcontrol.model.collision import CollisionModel, Sphere
from dqcontrol.registry import build_controller
from dqcontrol.trajectories import Circle

THESIS = {"velocity_limits": np.pi * np.array([1, 1, 1, 1, 2.5, 2.5, 2.5]),
          "acceleration_limit": 10.0}  # fmt: skip
PERIOD_S = 0.01


def _compositions(robot):
    ball = Sphere(name="ball", position_m=(0.22446, -0.25589, 0.95194), radius_m=0.05)
    collision = CollisionLimit(CollisionModel(robot, (ball,)))
    return {
        "local": build_controller("local", robot, Circle(2.0), PERIOD_S, shared=THESIS),
        "p6": build_controller("p6", robot, Circle(2.0), PERIOD_S, shared=THESIS),
        "p6_strict": build_controller(
            "p6", robot, Circle(2.0), PERIOD_S, shared=THESIS, priority="strict"
        ),
        "noscale6": build_controller("noscale6", robot, Circle(2.0), PERIOD_S, shared=THESIS),
        "pf6": build_controller(
            "pf6",
            robot,
            Circle(2.0),
            PERIOD_S,
            torque_limit_fraction=0.9,
            extra_limits=(collision,),
        ),  # fmt: skip
    }


def _walk(ctrl, steps: int = 12):
    """``(context, problem)`` right after every fourth step of a closed loop (a context is
    refilled by the next step: read it before asking for the next)."""
    q = LBR4P_Q0.copy()
    ctrl.reset(q)
    for k in range(steps):
        res = ctrl.step(q)
        if k % 4 == 3:
            yield ctrl._last.ctx, ctrl.last_problem()
        q = q + PERIOD_S * res.qd_command


@pytest.fixture(scope="module")
def controllers(lbr4p):
    return _compositions(lbr4p)


def test_every_exported_term_and_limit_is_checked(controllers):
    ctrls = list(controllers.values())
    terms = {type(t) for ctrl in ctrls for lev in ctrl.levels for t in lev.terms}
    limits = {type(lim) for ctrl in ctrls for lim in ctrl.limits}
    for lim in [lim for ctrl in ctrls for lim in ctrl.limits]:
        limits |= {type(part) for part in vars(lim).values() if isinstance(part, limits_pkg.Limit)}
    exported_terms = {getattr(terms_pkg, n) for n in terms_pkg.__all__} - {terms_pkg.Term}
    exported_limits = {getattr(limits_pkg, n) for n in limits_pkg.__all__} - {limits_pkg.Limit}
    assert exported_terms <= terms, exported_terms - terms
    assert exported_limits <= limits, exported_limits - limits


def _dense_from_parts(res, layout) -> np.ndarray:
    """``A`` formed here from the residual's own parts, independently of ``dense``."""
    if res.A is not None:
        return np.asarray(res.A)
    if res.blocks is not None:
        p, r, m = res.blocks.shape
        a = np.zeros((p * r, layout.num_vars))
        for i in range(p):
            a[i * r : (i + 1) * r, i * m : (i + 1) * m] = res.blocks[i]
        return a
    st = res.states
    p, r, m = st.rows.shape
    n = m - 1
    a = np.zeros((p * r, layout.num_vars))
    for i in range(p):
        for j in range(st.weights.shape[1]):
            a[i * r : (i + 1) * r, j * m : j * m + n] = st.rows[i][:, :n] * st.weights[i, j]
            a[i * r : (i + 1) * r, j * m + n] = st.rows[i][:, n] * st.phase_weights[i, j]
    return a


@pytest.mark.parametrize("name", ["local", "p6", "p6_strict", "noscale6", "pf6"])
def test_terms_give_the_affine_rows_they_claim(controllers, name):
    rng = np.random.default_rng(7)
    for ctx, problem in _walk(controllers[name]):
        layout = ctx.layout
        for level in problem.levels:
            for res in level.residuals:
                a = _dense_from_parts(res, layout)
                assert a.shape == (res.b.size, layout.num_vars), res.name
                assert np.all(np.isfinite(a)) and np.all(np.isfinite(res.b)), res.name
                assert np.isfinite(res.weight) and res.weight >= 0.0, res.name
                if res.row_weights is not None:
                    assert res.row_weights.shape == (res.b.size,), res.name
                    assert np.all(res.row_weights >= 0.0), res.name
                z = rng.normal(size=layout.num_vars)
                np.testing.assert_allclose(
                    res.value(layout, z), a @ z - res.b, rtol=1e-12, atol=1e-12, err_msg=res.name
                )


def _cost(level, layout, z) -> float:
    total = 0.0
    for res in level.residuals:
        r = res.value(layout, z)
        w = np.ones_like(r) if res.row_weights is None else res.row_weights
        total += res.weight * float(np.sum(w * r * r))
    return total


@pytest.mark.parametrize("name", ["local", "p6_strict", "pf6"])
def test_each_level_objective_is_its_weighted_squares(controllers, name):
    """``½ zᵀ P z + cᵀ z`` and the cost from the rows differ by a constant: their finite
    differences agree (exact for quadratics, up to rounding)."""
    rng = np.random.default_rng(11)
    for ctx, problem in _walk(controllers[name]):
        layout = ctx.layout
        for k, level in enumerate(problem.levels):
            p_mat, c = problem.objective(k)
            z0, z1 = rng.normal(size=(2, layout.num_vars)) * 0.1
            quad = 0.5 * (z1 @ p_mat @ z1 - z0 @ p_mat @ z0) + c @ (z1 - z0)
            direct = _cost(level, layout, z1) - _cost(level, layout, z0)
            scale = max(1.0, abs(direct), abs(_cost(level, layout, z0)))
            assert abs(quad - direct) <= 1e-9 * scale, (name, level.name)


def _items(rows):
    if rows is None:
        return ()
    return (rows,) if isinstance(rows, (Bounds, Inequality, Residual)) else tuple(rows)


@pytest.mark.parametrize("name", ["local", "p6", "p6_strict", "noscale6", "pf6"])
def test_limits_give_well_formed_rows(controllers, name):
    ctrl = controllers[name]
    for ctx, _ in _walk(ctrl):
        nv = ctx.layout.num_vars
        for limit in ctrl.limits:
            for item in _items(limit.rows(ctx)):
                if isinstance(item, Bounds):
                    index = np.asarray(item.index).ravel()
                    assert np.all((0 <= index) & (index < nv)), limit.name
                    assert np.shape(item.lower) == np.shape(item.upper) == index.shape
                    if not item.hard:
                        assert np.all(np.asarray(item.lower) <= np.asarray(item.upper))
                else:
                    assert isinstance(item, Inequality), (limit.name, type(item))
                    rows = item.C.shape[0]
                    assert item.C.shape == (rows, nv), limit.name
                    assert item.lower.shape == item.upper.shape == (rows,), limit.name
                    assert not np.any(np.isnan(item.C)), limit.name
                    if item.keys is not None:
                        assert len(item.keys) == rows, limit.name


def _constant_rows(ctrl, ctx) -> dict:
    """The rows of every term and limit that marks them constant at ``ctx`` (the same
    object at two calls, read-only arrays only), by name."""
    out = {}
    for limit in ctrl.limits:
        rows = limit.rows(ctx)
        if constant_rows(rows, limit.rows(ctx)):
            out[limit.name] = rows
    for term in (t for lev in ctrl.levels for t in lev.terms):
        res = term.residual(ctx)
        if constant_rows(res, term.residual(ctx)):
            out[term.name] = res
    return out


def _arrays(rows) -> list:
    return [np.array(x, copy=True) for item in _items(rows) for x in item if hasattr(x, "shape")]


@pytest.mark.parametrize("name", ["local", "p6", "p6_strict", "noscale6", "pf6"])
def test_constant_limits_and_terms_do_not_change(controllers, name):
    ctrl = controllers[name]
    walk = [ctx for ctx, _ in _walk(ctrl)]
    first = _constant_rows(ctrl, walk[0])
    assert "damping" in first  # every controller here damps its joint velocities
    copies = {k: _arrays(v) for k, v in first.items()}
    for ctx in walk[1:]:
        later = _constant_rows(ctrl, ctx)
        assert later.keys() == first.keys()
        for key, rows in later.items():
            assert rows is first[key], key  # the same object at every step
            for a, b in zip(copies[key], _arrays(rows), strict=True):
                np.testing.assert_array_equal(a, b)
            for x in (x for item in _items(rows) for x in item if hasattr(x, "shape")):
                assert not x.flags.writeable, key
