"""The predictive methods (dqcontrol/controllers/thesis/predictive.py, docs/theory.md
§4.2–4.3): their instants and default gain against the integration matrix's spectral
radius, the two-period cycle the default gain avoids at 1 kHz, and the thesis's claim that
the predictive method tracks better than the local one at short periods."""

from __future__ import annotations

import numpy as np
import pytest
from controllers.thesis.test_controller import THESIS_ACC, THESIS_VEL, T, make

from dqcontrol.controllers import (
    PredictiveNoScalingController,
    integration_matrix,
    prediction_instants,
)
from dqcontrol.controllers.thesis.predictive import NOSCALE_GAIN_CAP_PER_S
from dqcontrol.errors import ParameterError
from dqcontrol.model import LBR4P_Q0
from dqcontrol.sim import run_kinematic
from dqcontrol.trajectories import Circle, Sinusoid

SOLVERS = ["osqp", "daqp"]


@pytest.mark.parametrize("gain_per_s", [None, 8.5])
def test_noscale_default_gain_stays_below_the_two_period_cycle_at_1khz(lbr4p, gain_per_s):
    """Without scaling at T = 1 ms, ``K = 0.9/ρ(W)`` (8.5 for p = 10, the former default) puts
    the applied command into a two-period cycle at the acceleration bound: ``qd`` alternates
    by ``T a_max`` every step (so |Δ²qd| = 2 |Δqd|) and the QP re-chooses dozens of active
    constraints each time. The default gain stays below it."""
    period = 1e-3
    ctrl = PredictiveNoScalingController(
        lbr4p, Circle(2.0), period, num_instants=10, gain_per_s=gain_per_s,
        velocity_limits=THESIS_VEL, acceleration_limit=THESIS_ACC,
    )  # fmt: skip
    res = run_kinematic(ctrl, LBR4P_Q0, max_time_s=1.0)
    qd = res.log.qd_command[300:]
    first = np.median(np.abs(np.diff(qd, axis=0)).max(axis=1))
    second = np.median(np.abs(np.diff(qd, 2, axis=0)).max(axis=1))
    iterations = np.median(res.log.iterations[300:])
    if gain_per_s is None:
        assert ctrl.gain_per_s == 4.0
        assert second < 0.05 * first and iterations <= 2
        assert res.metrics.e_mean < 4e-3  # tracks (2.9e-3 over the first second)
    else:  # the cycle the default avoids (what the test above would catch)
        assert second > 1.9 * first and first == pytest.approx(period * THESIS_ACC, rel=1e-6)
        assert iterations > 20


# --------------------------------------------------------------------------- the thesis's claim
@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize(
    "traj_cls,duration", [(Circle, 1.0), (Circle, 2.0), (Sinusoid, 2.0), (Sinusoid, 4.0)]
)
def test_predictive_beats_local_at_short_periods(lbr4p, traj_cls, duration, solver):
    local = run_kinematic(make("local", lbr4p, traj_cls(duration), solver=solver), LBR4P_Q0)
    mpc = run_kinematic(make("p10", lbr4p, traj_cls(duration), solver=solver), LBR4P_Q0)
    local, mpc = local.metrics, mpc.metrics
    assert local.completed and mpc.completed
    assert mpc.e_mean < local.e_mean
    assert mpc.path_deviation_mean_m < local.path_deviation_mean_m


# --------------------------------------------------------------------------- construction
def test_the_instants_are_the_parabolic_ones(lbr4p):
    ctrl = make("p6", lbr4p, Circle(1.0), horizon_s=0.5)
    np.testing.assert_array_equal(ctrl.layout.instants_s, prediction_instants(6, 0.5))
    assert (ctrl.num_instants, ctrl.horizon_s, ctrl.name) == (6, 0.5, "predictive_p6")
    assert ctrl.scaling
    noscale = make("noscale", lbr4p, Circle(1.0))
    assert noscale.name == "predictive_noscale_p6" and not noscale.scaling
    noscale.reset(LBR4P_Q0)
    assert noscale.step(LBR4P_Q0).s == 1.0  # σ = t


@pytest.mark.parametrize(
    ("num_instants", "horizon_s", "capped"), [(6, 1.0, False), (10, 1.0, True), (6, 0.1, True)]
)
def test_the_default_noscale_gain_keeps_the_horizon_contracting(
    lbr4p, num_instants, horizon_s, capped
):
    """``K = min(4, 0.9/ρ(W))``: below 1/ρ(W), where a deviation of the horizon would grow
    from one step to the next, and at most the cap."""
    ctrl = PredictiveNoScalingController(
        lbr4p, Circle(1.0), T, num_instants=num_instants, horizon_s=horizon_s,
        velocity_limits=THESIS_VEL, acceleration_limit=THESIS_ACC,
    )  # fmt: skip
    w = integration_matrix(prediction_instants(num_instants, horizon_s), T)
    rho = np.max(np.abs(np.linalg.eigvals(w)))
    if capped:
        assert ctrl.gain_per_s == NOSCALE_GAIN_CAP_PER_S < 0.9 / rho
    else:
        assert ctrl.gain_per_s == pytest.approx(0.9 / rho, rel=1e-12)
        assert ctrl.gain_per_s < NOSCALE_GAIN_CAP_PER_S
    given = PredictiveNoScalingController(lbr4p, Circle(1.0), T, gain_per_s=7.0)
    assert given.gain_per_s == 7.0


def test_the_noscale_method_checks_its_period_first(lbr4p):
    with pytest.raises(ParameterError, match="period_s"):
        PredictiveNoScalingController(lbr4p, Circle(1.0), 0.0)
