"""The path-following limits' compiled rows and the progress term's rows against plain numpy
formations (docs/theory.md §8.3-§8.5), on seeded draws."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.core.problem import DecisionLayout
from dqcontrol.controllers.limits.predicted_position import PredictedPositionLimit
from dqcontrol.controllers.limits.trust_region import TrustRegionLimit
from dqcontrol.controllers.prediction.consistent import (
    ConsistentPrediction,
    interval_breakpoints,
)
from dqcontrol.controllers.terms.progress import ProgressTerm


def _prediction(seed: int, p: int = 5, n: int = 4):
    model = ConsistentPrediction(interval_breakpoints(p, 0.5, 0.01), n, 0.01)
    rng = np.random.default_rng(seed)
    model.commit(rng.normal(size=(p, n)), rng.uniform(0.0, 1.0, p))
    return model, model.predict(rng.uniform(-1.0, 1.0, n), 0.2), rng


class _Ctx:
    def __init__(self, prediction, a_max):
        self.prediction, self.a_max = prediction, a_max


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("terminal", [True, False])
def test_predicted_position_rows_are_the_reachable_ones(seed, terminal):
    model, pred, rng = _prediction(seed)
    p, n = pred.q_lin.shape
    q_min, q_max = -np.full(n, 1.0), np.full(n, 1.0)
    qd_max = rng.uniform(1.0, 2.0, n)
    reach = rng.uniform(0.0, 0.8, p)
    a_max = rng.uniform(2.0, 5.0, (p, n))
    limit = PredictedPositionLimit(
        model.layout, q_min, q_max, qd_max, terminal=terminal, reach_rad=reach
    )
    out = limit.rows(_Ctx(pred, a_max)) or ()
    full = {g.name: g for g in PredictedPositionLimit(
        model.layout, q_min, q_max, qd_max, terminal=terminal
    ).rows(_Ctx(pred, a_max))}  # fmt: skip
    near = (pred.q_lin + reach[:, None] >= q_max) | (pred.q_lin - reach[:, None] <= q_min)
    coeff = qd_max / (2.0 * a_max[-1])
    r_end = reach[-1] + coeff * qd_max
    near_end = (pred.q_lin[-1] + r_end >= q_max) | (pred.q_lin[-1] - r_end <= q_min)
    expected = {"predicted_position": near.ravel(), "terminal_braking": near_end}
    if not terminal:
        del expected["terminal_braking"]
    got = {g.name: g for g in out}
    assert set(got) == {k for k, mask in expected.items() if mask.any()}
    for name, g in got.items():
        mask = expected[name]
        assert np.array_equal(g.C, full[name].C[mask])
        assert np.array_equal(g.lower, full[name].lower[mask])
        assert np.array_equal(g.upper, full[name].upper[mask])


@pytest.mark.parametrize(("radius", "phase"), [(0.1, 0.05), (0.1, np.inf), (np.inf, 0.05)])
def test_trust_region_bands(radius, phase):
    model, pred, _ = _prediction(7)
    limit = TrustRegionLimit(model.layout, radius, phase, 0.2)
    got = {g.name: g for g in limit.rows(_Ctx(pred, None))}
    ends = model.layout.instants_s + model.layout.durations_s
    grow = 1.0 + ends / 0.2
    n = pred.q_lin.shape[1]
    centre_q = (pred.q_lin - pred.q_base).ravel()
    centre_s = pred.sigma_lin - pred.sigma_base
    expected = {}
    if np.isfinite(radius):
        r = np.repeat(radius * grow, n)
        expected["trust_region_q"] = (centre_q - r, centre_q + r)
    if np.isfinite(phase):
        expected["trust_region_phase"] = (centre_s - phase * grow, centre_s + phase * grow)
    assert set(got) == set(expected)
    for name, (lo, up) in expected.items():
        assert np.array_equal(got[name].lower, lo) and np.array_equal(got[name].upper, up)


def test_progress_rows_at_the_nominal_and_a_catching_up_reference():
    layout = DecisionLayout(2, np.array([0.0, 0.1, 0.3]), np.array([0.1, 0.2, 0.2]))
    term = ProgressTerm(layout, s_max=1.2)
    scale = np.sqrt(layout.durations_s * np.arange(3, 0, -1) / 0.5)
    for lag, s_ref in ((0.0, 1.0), (0.05, 1.1)):
        ctx = type("C", (), {"lag_s": lag})()
        res = term.residual(ctx)
        assert np.array_equal(res.b, -scale * s_ref)
        assert np.array_equal(res.blocks[:, 0, 2], -scale)


def test_posture_rows_pull_towards_the_reference():
    from dqcontrol.controllers.terms.posture import PostureTerm

    model, pred, rng = _prediction(8)
    term = PostureTerm(model.layout, 2.5)
    term.reference = rng.normal(size=pred.q_lin.shape[1])
    for scale in (1.0, 0.0):
        ctx = type("C", (), {"posture_scale": scale, "prediction": pred})()
        res = term.residual(ctx)
        expected = (2.5 * scale) * (term.reference - pred.q_lin)
        assert np.array_equal(res.b, expected.ravel())


def test_merged_bounds_of_scalars_lists_and_arrays_equal_numpys():
    from dqcontrol.controllers.core.problem import Bounds, merge_bounds

    layout = DecisionLayout(3, np.array([0.0, 0.1]), np.array([0.1, 0.2]))
    rng = np.random.default_rng(6)
    soft = (
        Bounds("a", np.arange(8), -rng.uniform(1, 2, 8), rng.uniform(1, 2, 8)),
        Bounds("b", [0, 1, 2], -0.5, 0.7),
        Bounds("c", np.array([[3], [7]], dtype=np.int32), 0.0, np.array([1.0, 2.0])),
    )
    hard = Bounds("h", np.arange(3), np.array([-2.0, 0.8, -0.1]), np.array([2.0, 1.0, 0.1]),
                  hard=True)  # fmt: skip
    lo, up, conflict = merge_bounds(layout, (*soft, hard))
    ref_lo, ref_up = np.full(8, -np.inf), np.full(8, np.inf)
    for b in soft:
        idx = np.asarray(b.index).ravel()
        ref_lo[idx] = np.maximum(ref_lo[idx], b.lower)
        ref_up[idx] = np.minimum(ref_up[idx], b.upper)
    clash = np.array([False, True, False])  # [-0.5, 0.7] misses [0.8, 1]: its point 0.8
    ref_lo[:3], ref_up[:3] = np.maximum(ref_lo[:3], hard.lower), np.minimum(ref_up[:3], hard.upper)
    ref_lo[1] = ref_up[1] = 0.8
    assert np.array_equal(lo, ref_lo) and np.array_equal(up, ref_up)
    assert conflict.dtype == np.bool_ and np.array_equal(conflict, np.r_[clash, np.zeros(5, bool)])
    lo[:] = 0.0  # the caller's arrays: the next merge starts open again
    empty = merge_bounds(layout, ())
    assert np.all(empty[0] == -np.inf) and np.all(empty[1] == np.inf) and not empty[2].any()
