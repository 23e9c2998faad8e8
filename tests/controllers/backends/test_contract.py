"""The backend contract: a backend written here, outside the package, registered by name and
used by every QP controller; the dense defaults of every capability; the forwarding base of
wrappers; the registry's errors."""

import numpy as np
import pytest
import quadprog

from dqcontrol.controllers.backends import (
    Backend,
    ForwardingBackend,
    backend_names,
    make_backend,
    register_backend,
)
from dqcontrol.controllers.core.problem import DenseQP, Solution
from dqcontrol.errors import ParameterError
from dqcontrol.model import LBR4P_Q0
from dqcontrol.registry import build_controller
from dqcontrol.trajectories import Circle

BIG = 1e20


class QuadprogBackend(Backend):
    """Goldfarb–Idnani's dual method (quadprog) on the dense QP: one method, nothing else."""

    name = "quadprog_test"

    def __init__(self, settings: dict | None = None) -> None:
        if settings:
            raise ParameterError(f"quadprog_test takes no settings, got {sorted(settings)}")
        self.calls = 0

    def solve(self, key: object, qp: DenseQP) -> Solution:
        self.calls += 1
        lower, upper = qp.lower, qp.upper
        if not (lower <= upper).all():
            return Solution(False, "invalid_bounds")
        eq = np.isclose(lower, upper, rtol=0.0, atol=0.0)
        lo = ~eq & (lower > -BIG)
        up = ~eq & (upper < BIG)
        rows = np.vstack((qp.A[eq], qp.A[lo], -qp.A[up]))
        rhs = np.concatenate((lower[eq], lower[lo], -upper[up]))
        p_sym = 0.5 * (qp.P + qp.P.T)
        try:
            x = quadprog.solve_qp(p_sym, -qp.c, rows.T, rhs, int(eq.sum()))[0]
        except ValueError as exc:  # infeasible or not positive definite
            return Solution(False, f"error: {exc}")
        return Solution(True, "solved", 0, 0.0, x)


@pytest.fixture(scope="module")
def quadprog_backend():
    if QuadprogBackend.name not in backend_names():
        register_backend(QuadprogBackend.name, QuadprogBackend)
    return QuadprogBackend.name


THESIS = {"velocity_limits": np.pi * np.array([1, 1, 1, 1, 2.5, 2.5, 2.5]),
          "acceleration_limit": 10.0}  # fmt: skip


def _commands(robot, name: str, steps: int, **extra) -> np.ndarray:
    ctrl = build_controller(name, robot, Circle(2.0), 0.01, shared=THESIS, **extra)
    q = LBR4P_Q0.copy()
    ctrl.reset(q)
    out = []
    for _ in range(steps):
        res = ctrl.step(q)
        assert not res.diagnostics.fallback, res.diagnostics.message
        out.append(np.r_[res.qd_command, res.s])
        q = q + 0.01 * res.qd_command
    return np.array(out)


# One level (the thesis's weights): the optimum is unique, the commands agree to the solvers'
# tolerance. Several levels: each lower level holds the ones above within a band of their
# tolerance (1e-4 here, docs/theory.md §7.4), inside which two exact solvers may stop at
# different points.
@pytest.mark.parametrize(
    ("name", "extra", "atol"),
    [
        ("local", {}, 1e-6),
        ("p6", {}, 1e-6),
        ("noscale6", {}, 1e-6),
        ("p6", {"priority": "strict"}, 1e-4),
        ("pf6", {}, 1e-4),
    ],
)
def test_a_backend_from_outside_the_package_runs_every_qp_controller(
    lbr4p, quadprog_backend, name, extra, atol
):
    ours = _commands(lbr4p, name, 25, solver=quadprog_backend, **extra)
    daqp = _commands(lbr4p, name, 25, **extra)
    np.testing.assert_allclose(ours, daqp, atol=atol)


def test_the_new_backend_is_the_one_that_solves(lbr4p, quadprog_backend):
    ctrl = build_controller("p6", lbr4p, Circle(2.0), 0.01, shared=THESIS, solver="quadprog_test")
    ctrl.reset(LBR4P_Q0)
    ctrl.step(LBR4P_Q0)
    assert isinstance(ctrl.backend, QuadprogBackend) and ctrl.backend.calls >= 1
    assert "quadprog_test" in backend_names() and backend_names()[0] == "daqp"


def test_dense_defaults_of_every_capability():
    backend = QuadprogBackend()
    assert backend.solve_warm_levels(None, np.zeros((0, 2)), ()) is None  # type: ignore[arg-type]
    assert not backend.solves_warm_levels and not backend.uses_warm_start
    backend.set_general_rows(2, ())
    backend.reset()


def test_forwarding_backend_forwards_every_capability():
    inner = make_backend("daqp")
    wrapper = ForwardingBackend(inner)
    assert wrapper.name == "daqp" and wrapper.solves_warm_levels
    qp = DenseQP(np.eye(2), np.array([1.0, -1.0]), np.eye(2), -np.ones(2) * 0.5, np.ones(2))
    np.testing.assert_allclose(wrapper.solve(0, qp).x, inner.solve(1, qp).x)
    with pytest.raises(ParameterError, match="needs a Backend"):
        ForwardingBackend(object())  # type: ignore[arg-type]


def test_registry_errors(lbr4p):
    with pytest.raises(ParameterError, match=r"solver must be one of 'daqp', .*'osqp'.*'nope'"):
        make_backend("nope")
    with pytest.raises(ParameterError, match="already registered"):
        register_backend("daqp", QuadprogBackend)
    with pytest.raises(ParameterError, match="identifier"):
        register_backend("two words", QuadprogBackend)
    with pytest.raises(ParameterError, match="solver must be one of"):
        build_controller("local", lbr4p, Circle(2.0), 0.01, solver="cvxopt")
    with pytest.raises(ParameterError, match="solver must be one of"):
        build_controller("pf", lbr4p, Circle(2.0), 0.01, solver="cvxopt")
