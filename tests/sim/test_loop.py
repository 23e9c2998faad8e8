"""dqcontrol/sim/loop.py: the control loop against joint drivers (recording wrappers, hand-made
arms): joint mapping, warm-up, watchdog (stale, deadline, end, Ctrl-C), braking, the log."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from dqcontrol.controllers import LocalController, ProportionalController
from dqcontrol.errors import ParameterError
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.runs.storage import load_run, save_run
from dqcontrol.sim import (
    JointMismatchError,
    KinematicDriver,
    MujocoSimulation,
    SimulationDriver,
    VelocityFromPosition,
    run_kinematic,
    run_loop,
)
from dqcontrol.sim.mujoco_sim import Measurement
from dqcontrol.trajectories import Circle, Sinusoid

TIMING = ("solve_time_s", "step_time_s")


def _assert_same_log(a, b):
    assert len(a) == len(b)
    for name, x in a.arrays().items():
        if name not in TIMING:
            np.testing.assert_array_equal(x, b.arrays()[name], err_msg=name)


class Recording:
    """A driver wrapper that presents the joints in another order and records every call."""

    def __init__(self, inner, order=None, names=None) -> None:
        self.inner = inner
        n = len(inner.joint_names)
        self.order = np.arange(n) if order is None else np.asarray(order)
        self.joint_names = (
            tuple(inner.joint_names[i] for i in self.order) if names is None else tuple(names)
        )
        self.period_s = inner.period_s
        self.calls: list[tuple[str, np.ndarray | None]] = []
        self.meta = inner.meta
        self.freeze_after: int | None = None  # writes after which time stops advancing
        self._frozen: Measurement | None = None

    def _in(self, u):  # ours -> inner's order
        out = np.empty_like(u)
        out[self.order] = u
        return out

    def reset(self, q0):
        m = self.inner.reset(self._in(np.asarray(q0, dtype=float)))
        return self._out(m)

    def _out(self, m):
        return Measurement(m.t_s, m.q[self.order], m.qd[self.order], m.torque, m.torque_peak)

    def read(self):
        if self._frozen is not None:
            return self._frozen
        m = self._out(self.inner.read())
        writes = sum(1 for c, _ in self.calls if c == "write")
        if self.freeze_after is not None and writes >= self.freeze_after:
            self._frozen = m
        return m

    def write(self, u):
        self.calls.append(("write", np.array(u)))
        self.inner.write(self._in(np.asarray(u)))

    def hold(self):
        self.calls.append(("hold", None))
        self.inner.hold()


def test_the_driver_joint_order_is_mapped_by_name(lbr4p):
    plain = run_kinematic(LocalController(lbr4p, Circle(1.0), 0.05), LBR4P_Q0)
    order = [3, 6, 0, 5, 1, 4, 2]
    drv = Recording(KinematicDriver(lbr4p, 0.05), order)
    res = run_loop(LocalController(lbr4p, Circle(1.0), 0.05), drv, q0=LBR4P_Q0, brake=False)
    _assert_same_log(plain.log, res.log)
    first = drv.calls[0][1]
    np.testing.assert_array_equal(first, plain.log.qd_command[0][order])


@pytest.mark.parametrize(
    ("names", "fragment"),
    [
        (("a1", "a2", "a3", "a4", "a5", "a6", "a7"), "joint-name mismatch"),
        (None, "more than once"),
        ("fewer", "has 6 joints, the model 7"),
    ],
    ids=["names", "duplicate", "fewer"],
)
def test_a_joint_mismatch_stops_before_any_command(lbr4p, names, fragment):
    inner = KinematicDriver(lbr4p, 0.05)
    if names is None:
        names = tuple(lbr4p.joint_names[:6]) + (lbr4p.joint_names[0],)
    if names == "fewer":
        names = tuple(lbr4p.joint_names[:6])
    drv = Recording(inner, names=names)
    with pytest.raises(JointMismatchError, match=fragment):
        run_loop(LocalController(lbr4p, Circle(1.0), 0.05), drv, q0=LBR4P_Q0)
    assert drv.calls == []


def _task(log):
    """The samples of the task (before any stop)."""
    return int(np.count_nonzero(~log.stopping))


def test_a_stale_measurement_stops_within_the_acceleration_limit_and_holds(lbr4p):
    ctrl = LocalController(lbr4p, Circle(1.0), 0.05, acceleration_limit=10.0)
    drv = Recording(KinematicDriver(lbr4p, 0.05))
    drv.freeze_after = 8
    res = run_loop(ctrl, drv, q0=LBR4P_Q0, stale_periods=3)
    assert res.interrupted and res.reason == "stale" and "not renewed for 3" in res.note
    writes = [u for c, u in drv.calls if c == "write"]
    # samples 0-8 from fresh measurements, 9-10 from one up to 2 periods old; not 3
    task = _task(res.log)
    assert task == 11 and res.log.t_s[task - 1] == res.log.t_s[8]
    assert not res.log.stopping[:task].any() and res.log.stopping[task:].all()
    stop = res.log.meta["stop"]
    assert stop["reason"] == "stale" and stop["at_rest"] and stop["brake_periods"] == 0
    assert stop["stop_periods"] == len(res.log) - task == len(writes) - task
    steps = np.diff(np.vstack(writes[task - 1 :]), axis=0)
    assert np.abs(steps).max() <= 10.0 * 0.05 + 1e-12 and not writes[-1].any()
    assert drv.calls[-1] == ("hold", None)


def test_ctrl_c_brakes_and_holds_and_keeps_the_samples(lbr4p):
    ctrl = ProportionalController(lbr4p, Circle(1.0), 0.05, acceleration_limit=4.0)
    drv = Recording(KinematicDriver(lbr4p, 0.05))

    def interrupt(k, _driver, _result):
        if k == 6:
            raise KeyboardInterrupt

    res = run_loop(ctrl, drv, q0=LBR4P_Q0, on_sample=interrupt)
    assert res.reason == "user" and _task(res.log) == 7
    assert res.note == "interrupted by the user after 7 samples"
    writes = np.array([u for c, u in drv.calls if c == "write"])
    assert np.abs(np.diff(writes[6:], axis=0)).max() <= 4.0 * 0.05 + 1e-12
    assert not writes[-1].any() and drv.calls[-1] == ("hold", None)
    assert res.log.meta["stop"]["stop_periods"] == len(writes) - 7 == len(res.log) - 7


def _interrupt_through_compiled_code():
    """What an interrupt looks like when its signal handler ran inside a callback of
    compiled code: a ``SystemError`` whose cause is the ``KeyboardInterrupt``."""
    try:
        raise KeyboardInterrupt
    except KeyboardInterrupt as exc:
        raise SystemError("<function _numba_unpickle> returned a result with an exception") from exc


def test_an_interrupt_through_compiled_code_brakes_and_keeps_the_samples(lbr4p):
    ctrl = ProportionalController(lbr4p, Circle(1.0), 0.05, acceleration_limit=4.0)
    drv = Recording(KinematicDriver(lbr4p, 0.05))

    def interrupt(k, _driver, _result):
        if k == 6:
            _interrupt_through_compiled_code()

    res = run_loop(ctrl, drv, q0=LBR4P_Q0, on_sample=interrupt)
    assert res.reason == "user" and _task(res.log) == 7
    writes = np.array([u for c, u in drv.calls if c == "write"])
    assert not writes[-1].any() and drv.calls[-1] == ("hold", None)


def test_a_system_error_that_is_not_an_interrupt_is_raised(lbr4p):
    ctrl = ProportionalController(lbr4p, Circle(1.0), 0.05, acceleration_limit=4.0)

    def fail(k, _driver, _result):
        if k == 3:
            raise SystemError("a real one")

    with pytest.raises(SystemError, match="a real one"):
        run_loop(ctrl, KinematicDriver(lbr4p, 0.05), q0=LBR4P_Q0, on_sample=fail)


def test_the_end_of_the_task_brakes_after_the_log(lbr4p):
    free = run_kinematic(LocalController(lbr4p, Circle(1.0), 0.05), LBR4P_Q0)
    drv = Recording(KinematicDriver(lbr4p, 0.05))
    res = run_loop(LocalController(lbr4p, Circle(1.0), 0.05), drv, q0=LBR4P_Q0)
    task = _task(res.log)
    # the free run's commands until the task's end at rest is handed over, near its end
    handed = res.log.meta["stop"]["end_at_rest_from"]["sample"]
    assert 0 < handed < len(free.log) < task
    np.testing.assert_array_equal(res.log.qd_command[:handed], free.log.qd_command[:handed])
    assert res.log.meta["stop"]["reason"] == "end" and not res.interrupted
    assert res.log.meta["stop"]["stop_periods"] == len(res.log) - task >= 1
    assert res.log.meta["stop"]["at_rest"] and drv.calls[-1] == ("hold", None)
    assert not res.log.qd_command[-1].any() and res.metrics.stop_samples == len(res.log) - task
    assert free.log.meta["stop"] == {"reason": "end", "brake_periods": 0}


def kinematic_run(lbr4p, duration_s: float, period_s: float, cls=LocalController, **options):
    """``run_loop`` of a ``cls`` controller on the LBR4p's circle of ``duration_s`` against
    the ideal kinematics at ``period_s``, from ``LBR4P_Q0``, with the loop's ``options``."""
    return run_loop(
        cls(lbr4p, Circle(duration_s), period_s),
        KinematicDriver(lbr4p, period_s),
        q0=LBR4P_Q0,
        **options,
    )


def _stalled_at(sample: int, seconds: float):
    """An ``on_sample`` hook that stalls after sample ``sample`` is recorded: the stall
    falls between the next measurement and the next command, in sample ``sample + 1``'s
    work."""

    def slow(k, _driver, _result):
        if k == sample:
            threading.Event().wait(seconds)

    return slow


def test_a_sample_later_than_the_limit_stops_the_wall_clock_loop(lbr4p):
    res = kinematic_run(
        lbr4p,
        1.0,
        0.01,
        on_sample=_stalled_at(2, 0.03),
        realtime=True,
        max_lateness_s=0.01,
    )
    assert res.reason == "deadline" and _task(res.log) == 4 and "after its deadline" in res.note
    assert res.log.meta["stop"]["lateness_max_ms"] > 10.0
    assert res.log.meta["stop"]["missed_deadlines"] == 1


def test_a_short_miss_is_counted_and_the_loop_goes_on_in_the_present_slot(lbr4p):
    # sample 3 125 ms late at T = 50 ms (a period long enough that the host's own stalls do
    # not miss one): within the default five periods; the next sample starts at once in
    # the slot that holds the present, the two slots already past are skipped
    starts = []

    def record(k, driver, result):
        starts.append(time.perf_counter())
        _stalled_at(2, 0.175)(k, driver, result)

    res = kinematic_run(
        lbr4p,
        1.0,
        0.05,
        on_sample=record,
        realtime=True,
        brake=False,
    )
    stop = res.log.meta["stop"]
    assert stop["reason"] == "end" and not res.interrupted and res.metrics.completed
    assert stop["missed_deadlines"] == 1 and stop["lateness_max_ms"] > 100.0
    assert stop["skipped_periods"] == 2  # 125 ms late at 50 ms: two whole periods past
    assert stop["late_commands"] == 1  # sample 3's command, written 125 ms after its slot
    assert stop["late_command_samples"] == [3]
    assert starts[-1] - starts[0] >= 0.05 * (len(starts) + 0.5)  # on the grid, two slots on


def test_a_command_written_after_its_period_is_a_late_command(lbr4p):
    class Slow(LocalController):
        def step(self, q, qd=None):
            if self.sigma > 0.0 and not getattr(self, "_slowed", False):
                self._slowed = True
                threading.Event().wait(0.075)
            return super().step(q, qd)

    res = kinematic_run(
        lbr4p,
        1.0,
        0.05,
        cls=Slow,
        realtime=True,
        brake=False,
    )
    stop = res.log.meta["stop"]
    assert stop["late_commands"] == 1 and stop["missed_deadlines"] == 1
    assert 20.0 < stop["command_late_max_ms"] < stop["lateness_max_ms"] + 1e-9
    assert stop["late_command_samples"] == [int(np.argmax(res.log.sigma > 0.0))]


@pytest.mark.parametrize("bad", [-0.001, float("nan"), True])
def test_a_bad_lateness_limit_is_refused(lbr4p, bad):
    with pytest.raises(ParameterError, match="max_lateness_s"):
        kinematic_run(
            lbr4p,
            0.3,
            0.01,
            max_lateness_s=bad,
        )


def test_the_wall_clock_loop_keeps_its_period(lbr4p):
    import gc

    starts, frozen = [], []

    def record(_k, _driver, _result):
        starts.append(time.perf_counter())
        frozen.append(gc.get_freeze_count())

    start = time.perf_counter()
    res = kinematic_run(
        lbr4p,
        0.4,
        0.1,
        on_sample=record,
        realtime=True,
        brake=False,
    )
    assert not res.interrupted and res.metrics.completed
    assert time.perf_counter() - start >= 0.1 * (len(res.log) - 1)
    stop = res.log.meta["stop"]
    assert stop["lateness_max_ms"] < 0.0 and stop["missed_deadlines"] == 0
    assert 0.0 <= stop["jitter_median_ms"] <= stop["jitter_p99_ms"] <= stop["jitter_max_ms"]
    assert len(starts) == len(res.log)
    # the collector saw only the run's own objects, and everything again after it
    assert min(frozen) > 0 and gc.get_freeze_count() == 0


def test_a_wait_never_ends_before_its_deadline():
    from dqcontrol.sim.loop import SPIN_S, _sleep_until

    ends = []
    for k in range(20):
        deadline = time.perf_counter() + (k % 4) * 1e-3 + (SPIN_S if k % 2 else 0.0)
        _sleep_until(deadline)
        ends.append(time.perf_counter() - deadline)
    assert min(ends) >= 0.0


def test_a_stepped_run_has_no_wall_clock_entries(lbr4p):
    res = kinematic_run(lbr4p, 0.4, 0.1)
    assert not {"jitter_max_ms", "lateness_max_ms", "missed_deadlines"} & set(res.log.meta["stop"])


def test_progress_goes_through_the_callback(lbr4p):
    seen: list[tuple[float, float]] = []
    res = run_kinematic(
        LocalController(lbr4p, Circle(1.0), 0.05),
        LBR4P_Q0,
        on_progress=lambda s, total: seen.append((s, total)),
    )
    assert len(seen) == len(res.log) and all(t == 1.0 for _, t in seen)
    sigmas = [s for s, _ in seen]
    assert sigmas == sorted(sigmas) and sigmas[-1] >= 1.0 - 1e-12


def test_the_warm_up_does_not_touch_the_controller(lbr4p):
    cold = run_loop(
        LocalController(lbr4p, Sinusoid(2.0), 0.05),
        KinematicDriver(lbr4p, 0.05),
        q0=LBR4P_Q0,
        warm_up=False,
    )
    warm = run_loop(
        LocalController(lbr4p, Sinusoid(2.0), 0.05), KinematicDriver(lbr4p, 0.05), q0=LBR4P_Q0
    )
    _assert_same_log(cold.log, warm.log)
    assert "warm_up" not in warm.log.meta
    ctrl = LocalController(lbr4p, Circle(1.0), 0.05)
    ctrl.lock = threading.Lock()  # cannot be copied: the warm-up is skipped, with a note
    res = run_loop(ctrl, KinematicDriver(lbr4p, 0.05), q0=LBR4P_Q0)
    assert res.log.meta["warm_up"].startswith("skipped") and res.metrics.completed


class PositionArm:
    """A position-only arm with the LBR4p's joints, reversed, reaching each target at once."""

    def __init__(self, names, q0) -> None:
        self.joint_names = tuple(names)
        self.q = np.array(q0, dtype=float)
        self.k = 0

    def read(self):
        nan = np.full(len(self.q), np.nan)
        return Measurement(0.05 * self.k, self.q.copy(), np.zeros(len(self.q)), nan, nan)

    def write_position(self, q_target):
        self.q = np.array(q_target, dtype=float)
        self.k += 1


def test_a_position_only_arm_runs_from_where_it_is(lbr4p, tmp_path):
    names = tuple(reversed(lbr4p.joint_names))
    arm = PositionArm(names, LBR4P_Q0[::-1])
    res = run_loop(LocalController(lbr4p, Circle(1.0), 0.05), VelocityFromPosition(arm, 0.05))
    ref = run_kinematic(LocalController(lbr4p, Circle(1.0), 0.05), LBR4P_Q0, brake=True)
    assert res.metrics.completed and _task(res.log) == _task(ref.log)
    np.testing.assert_allclose(res.log.q[: _task(ref.log)], ref.log.q[: _task(ref.log)], atol=1e-12)
    assert res.log.meta["interface"] == "position"
    save_run(res, tmp_path, "position")
    log, record = load_run(tmp_path / "position")
    assert log.meta["joint_names"] == list(lbr4p.joint_names)
    assert record["meta"]["stop"]["reason"] == "end"


def test_q0_needs_a_driver_that_can_be_reset(lbr4p):
    arm = VelocityFromPosition(PositionArm(lbr4p.joint_names, LBR4P_Q0), 0.05)
    with pytest.raises(ParameterError, match="cannot be reset"):
        run_loop(LocalController(lbr4p, Circle(1.0), 0.05), arm, q0=LBR4P_Q0)
    with pytest.raises(ParameterError, match="stale_periods"):
        run_loop(LocalController(lbr4p, Circle(1.0), 0.05), arm, stale_periods=0)


def test_a_lasting_simulation_error_ends_the_run_with_a_hold(lbr4p):
    sim = MujocoSimulation(lbr4p)

    class Failing(SimulationDriver):
        def write(self, u):
            if self.simulation.time_s > 0.2:
                from dqcontrol.errors import DQControlError

                raise DQControlError("the physics blew up")
            super().write(u)

    res = run_loop(LocalController(lbr4p, Circle(1.0), 0.05), Failing(sim, 0.05), q0=LBR4P_Q0)
    assert res.reason == "simulation" and "the physics blew up" in res.note
    stop = res.log.meta["stop"]
    assert stop["reason"] == "simulation" and stop["brake_periods"] == 0
    assert stop["stop_periods"] == 0 and not stop["at_rest"]
    assert stop["ramp"].startswith("driver error during the stop")


def test_wall_clock_figures_keep_bounded_memory():
    """The lateness and jitter of a run of any length: the last values in a ring of fixed
    size for the medians, the maximum and the positive count over every value."""
    from dqcontrol.sim.loop import _Window

    window = _Window(capacity=4)
    series = [0.5, -1.0, 3.0, -2.0, -0.5, 0.25, -4.0, -3.0]
    for value in series:
        window.append(value)
    assert len(window) == 8 and len(window.values) == 4
    assert sorted(window.values) == sorted(series[-4:])
    assert window.maximum == 3.0 and window.positive == 3 and window.last == -3.0
