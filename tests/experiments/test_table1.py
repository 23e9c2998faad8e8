"""``dqcontrol.experiments.table1``: grid, settings, the time-optimal bound, recording between
samples, interrupts and executors; also (to move to its module's tests) a MuJoCo run per
controller."""

from __future__ import annotations

import csv
import math
import pickle

import numpy as np
import pytest

from dqcontrol.controllers import (
    LocalController,
    PredictiveController,
    PredictiveNoScalingController,
    ProportionalController,
)
from dqcontrol.errors import ParameterError
from dqcontrol.experiments import table1 as t1
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.sim import run_mujoco
from dqcontrol.trajectories import Circle

#: Metrics that measure the computer, not the control (differ between executors).
_TIMING = {"solve_time_median_s", "step_time_median_s"}
_THESIS_BOUNDS = {
    "velocity_limits": np.array(t1.THESIS_VELOCITY_LIMITS),
    "acceleration_limit": 10.0,
}


def _same_metrics(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for key in a.keys() - _TIMING:
        x, y = a[key], b[key]
        if isinstance(x, float) and isinstance(y, float):
            assert x == pytest.approx(y, rel=1e-9, abs=1e-12, nan_ok=True), key
        else:
            assert x == y, key


# ---------------------------------------------------------------------------- grid and job
def test_grid_selection():
    full = t1.table1_cases()
    assert len(full) == 32
    assert {(c.trajectory, c.duration_s) for c in full} == set(t1.THESIS_TABLE1)
    assert [c.controller for c in full[:4]] == ["local", "p6", "p10", "pf"]
    quick = t1.table1_cases(quick=True)
    assert len(quick) == 8 and len({(c.trajectory, c.duration_s) for c in quick}) == 2
    pf = t1.table1_cases(quick=True, controllers=["path-following"])
    assert [c.name for c in pf] == ["circle_T1s_pf", "sinusoid_T2s_pf"]
    assert pf[0].label == "path-following" and pf[0].thesis("e_mean") is None
    with pytest.raises(ParameterError, match="unknown controller 'mpc' for Table 1"):
        t1.table1_cases(controllers=["mpc"])
    with pytest.raises(ParameterError, match="choose from"):
        t1.Table1Case("circle", 1.0, "noscale")
    two = t1.table1_cases(periods=[2], controllers=["local"])
    assert [(c.trajectory, c.duration_s) for c in two] == [("circle", 2.0), ("sinusoid", 2.0)]
    with pytest.raises(ParameterError, match="not in the thesis's grid"):
        t1.table1_cases(periods=[3])
    with pytest.raises(ParameterError, match="empty"):
        t1.table1_cases(periods=[16], trajectories=["sinusoid"], quick=True)
    with pytest.raises(ParameterError):
        t1.Table1Case("square", 1.0, "local")
    assert t1.Table1Case("circle", 1, "p10").thesis("e_mean") == 2.6e-3


def test_job_is_picklable():
    case, settings = t1.Table1Case("sinusoid", 2.0, "p6"), t1.Table1Settings()
    for obj in (t1.run_case, case, settings):
        assert pickle.loads(pickle.dumps(obj)) == obj
    assert settings.velocity_limits == pytest.approx(
        math.pi * np.array([1, 1, 1, 1, 2.5, 2.5, 2.5])
    )
    assert settings.acceleration_limit == 10.0 and settings.period_s == 0.05
    assert settings.horizon_s == 1.0 and settings.simulator == "mujoco"
    assert settings.path_following_options == t1.PATH_FOLLOWING_OPTIONS
    with pytest.raises(ParameterError, match="bound_samples"):
        t1.Table1Settings(bound_samples=5)


def test_rows_options_and_bounds():
    """The thesis's rows keep their options; the path-following rows get the thesis's
    velocity bounds, T, τ_p and otherwise their defaults; each row's bound has its
    controller's limits."""
    settings = t1.Table1Settings()
    local, p10, pf = (t1.Table1Case("circle", 1.0, c) for c in ("local", "p10", "pf"))
    assert local.controller_options(settings)["stall_damping"] == 0.0
    assert "horizon_s" not in local.controller_options(settings)
    assert p10.controller_options(settings)["acceleration_limit"] == 10.0
    options = pf.controller_options(settings)
    assert options["horizon_s"] == 1.0 and "stall_damping" not in options
    assert options["servo_time_constant_s"] == 0.005  # MuJoCo's servos, in its prediction
    kinematic = pf.controller_options(t1.Table1Settings(simulator="kinematic"))
    assert "servo_time_constant_s" not in kinematic
    assert "acceleration_limit" not in options  # the controller's own default
    np.testing.assert_array_equal(options["velocity_limits"], t1.THESIS_VELOCITY_LIMITS)
    thesis_bound = p10.bound_constraints(settings)
    assert thesis_bound["acceleration_limit"] == 10.0 and thesis_bound["speed_cap"] == 1.0
    assert thesis_bound["posture_gain_per_s"] == 0.0
    assert pf.bound_constraints(settings)["posture_gain_per_s"] == 1.0
    own = t1.Table1Settings(path_following_options=(("torque_limit_fraction", 0.5),))
    bound = pf.bound_constraints(own)
    assert bound["acceleration_limit"] == "dynamics" and bound["torque_limits"][0] == 88.0


def _read_csv(path):
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        return reader.fieldnames, list(reader)


#: The kinematic loop without the time-optimal bound.
_NO_BOUND = t1.Table1Settings(simulator="kinematic", bound_samples=0)


def test_without_toppra_the_bound_is_nan_with_a_note(monkeypatch):
    from dqcontrol.errors import ConfigurationError
    from dqcontrol.experiments import runner, time_optimal

    def missing():
        raise ConfigurationError("the time-optimal bound needs toppra (simulated)")

    monkeypatch.setattr(time_optimal, "_import_toppra", missing)
    monkeypatch.setattr(runner, "_BOUNDS", {})
    case = t1.Table1Case("circle", 1.0, "local")
    result = t1.run_case(case, t1.Table1Settings(simulator="kinematic", bound_samples=101))
    assert math.isnan(result["toppra_bound_s"]) and "needs toppra" in result["note"]
    (row,) = t1.table_rows([result])
    assert math.isnan(row["toppra_bound_s"]) and math.isnan(row["exec_over_bound"])
    assert row["completed"] == "yes"
    skipped = t1.run_case(case, _NO_BOUND)
    assert math.isnan(skipped["toppra_bound_s"]) and skipped["note"] == ""


def test_recording_between_samples_leaves_the_mujoco_run_unchanged():
    case = t1.Table1Case("circle", 1.0, "local")
    plain = t1.run_case(case, t1.Table1Settings(bound_samples=0, between_samples=False))
    recorded = t1.run_case(case, t1.Table1Settings(bound_samples=0))
    for key in plain["metrics"].keys() - _TIMING:
        a, b = plain["metrics"][key], recorded["metrics"][key]
        assert a == b or (isinstance(a, float) and math.isnan(a) and math.isnan(b)), key
    assert math.isnan(plain["path_dev_max_between_m"])
    between = recorded["path_dev_max_between_m"]
    assert plain["metrics"]["path_deviation_max_m"] <= between < 0.1
    assert 0.0 < recorded["torque_peak_ratio"] <= 1.0


def test_interrupt_keeps_completed_cases(tmp_path, monkeypatch):
    real = t1.run_case
    calls = []

    def flaky(case, settings=None, save_dir=None):
        calls.append(case)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(case, settings, save_dir)

    monkeypatch.setattr(t1, "run_case", flaky)
    with pytest.raises(KeyboardInterrupt):
        t1.run_table1(
            tmp_path, quick=True, settings=_NO_BOUND, workers=1, progress=False, save_runs=False
        )
    _, rows = _read_csv(tmp_path / "table1.csv")
    assert len(rows) == 2
    assert "Interrupted" in (tmp_path / "table1.md").read_text()


# ---------------------------------------------------------------------------- executors
#: The kinematic loop with a coarse time-optimal bound (a fast reduced grid).
_KINEMATIC = t1.Table1Settings(simulator="kinematic", bound_samples=201)


@pytest.fixture(scope="module")
def pool_results(tmp_path_factory):
    out = tmp_path_factory.mktemp("pool")
    return t1.run_table1(
        out,
        quick=True,
        settings=_KINEMATIC,
        workers=2,
        progress=False,
        save_runs=False,
    )


def test_process_pool_matches_in_process(pool_results):
    assert pool_results.executor.startswith("process pool, 2 workers")
    for controller in ("p10", "pf"):
        case = t1.Table1Case("circle", 1.0, controller)
        local = t1.run_case(case, _KINEMATIC)
        (remote,) = [r for r in pool_results.results if r["case"] == local["case"]]
        _same_metrics(local["metrics"], remote["metrics"])
        assert local["toppra_bound_s"] == remote["toppra_bound_s"]


def test_path_following_keeps_the_path_where_the_thesis_methods_do_not(pool_results):
    """The reduced grid (circle 1 s, sinusoid 2 s) in the kinematic loop: the
    path-following rows stay within 0.5 mm of the path at every sample, complete, and
    cross no bound; the thesis's rows leave it by more (the test can fail)."""
    rows = pool_results.rows
    assert {(r["traj"], r["T_tot_s"]) for r in rows} == {("circle", 1.0), ("sinusoid", 2.0)}
    following = [r for r in rows if r["controller"] == "path-following"]
    thesis = [r for r in rows if r["controller"] != "path-following"]
    assert len(following) == 2 and len(thesis) == 6
    for r in following:
        assert r["path_dev_max_mm"] <= 0.5, r
        assert r["completed"] == "yes" and r["fallbacks"] == 0
        assert r["viol_position"] == r["viol_velocity"] == r["viol_acceleration"] == 0
        assert math.isfinite(r["exec_over_bound"])
    for r in thesis:
        assert r["path_dev_max_mm"] > 0.5, r
    md = pool_results.markdown
    assert "## The thesis's claim at the short periods" in md  # p=10 vs Local, unchanged
    assert "## The path-following rows" in md


def test_dask_cluster_matches_process_pool(tmp_path, pool_results):
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        silence_logs=50,
    ) as cluster:
        result = t1.run_table1(
            tmp_path,
            quick=True,
            settings=_KINEMATIC,
            scheduler=cluster.scheduler_address,
            progress=False,
            save_runs=True,
        )
    assert result.executor.startswith("Dask distributed at tcp://")
    assert len(result.results) == len(pool_results.results) == 8
    by_case = {str(r["case"]): r for r in pool_results.results}
    for r in result.results:
        _same_metrics(r["metrics"], by_case[str(r["case"])]["metrics"])
    for a, b in zip(result.rows, pool_results.rows, strict=True):  # same order, same table
        for key in a.keys() - {"step_time_median_ms"}:
            if isinstance(a[key], float):
                assert a[key] == pytest.approx(b[key], rel=1e-9, nan_ok=True), key
            else:
                assert a[key] == b[key], key
    assert len(list((tmp_path / "table1_runs").glob("*.json"))) == 8


def test_unreachable_scheduler_is_a_clear_error(monkeypatch):
    pytest.importorskip("dask.distributed")
    from dqcontrol.errors import ConfigurationError

    monkeypatch.setattr(t1, "DASK_CONNECT_TIMEOUT_S", 1.0)

    with pytest.raises(ConfigurationError, match="cannot connect"):
        t1._run_dask([], t1.Table1Settings(), None, "tcp://127.0.0.1:9", lambda r: None)


# ---------------------------------------------------------------------------- controllers
@pytest.mark.parametrize(
    "make",
    [
        lambda r, t: ProportionalController(r, t, 0.05, **_THESIS_BOUNDS),
        lambda r, t: LocalController(r, t, 0.05, **_THESIS_BOUNDS),
        lambda r, t: PredictiveController(r, t, 0.05, num_instants=6, **_THESIS_BOUNDS),
        lambda r, t: PredictiveNoScalingController(r, t, 0.05, num_instants=6, **_THESIS_BOUNDS),
    ],
    ids=["proportional", "local", "predictive", "predictive_noscale"],
)
def test_each_controller_runs_the_circle_in_mujoco(lbr4p, make):
    duration = 2.0
    result = run_mujoco(make(lbr4p, Circle(duration)), LBR4P_Q0)
    m = result.metrics
    assert not result.interrupted, result.note
    assert m.completed and m.sigma_reached_s == pytest.approx(duration, abs=1e-9)
    assert m.position_violations == m.velocity_violations == m.acceleration_violations == 0
    assert not m.nan_seen and m.fallbacks == 0
    assert np.all(np.isfinite(result.log.torque)) and np.all(np.isfinite(result.log.q))
    assert m.path_deviation_max_m < 0.02  # the circle (R = 0.1 m) is followed
