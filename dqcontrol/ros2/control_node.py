"""The control node: a controller of the registry against a ros2_control arm (docs/ros2.md).

:class:`ControlNode` wires a :class:`~dqcontrol.ros2.driver.Ros2JointDriver` to
:func:`~dqcontrol.sim.run_loop`: on the wall clock (the loop paces itself at the period,
rclpy's executor spins in a background thread) or stepped (lockstep with a robot that steps
one period per command). The loop's watchdog stops on stale joint states, ``~/stop``
(``std_srvs/Trigger``) stops a task, and Ctrl-C or SIGTERM stop the node; each stop brings
the arm to rest along the path and holds (:func:`~dqcontrol.sim.run_loop` ``brake=True``,
docs/theory.md §8.10); :meth:`ControlNode.stop_policy` can choose to end with the last
command instead.
"""

from __future__ import annotations

import queue
import threading
from pathlib import Path
from typing import Any

import numpy as np

from dqcontrol.controllers.base import Controller, StepResult
from dqcontrol.dq.algebra import translation
from dqcontrol.errors import DQControlError, ParameterError
from dqcontrol.registry import build_controller
from dqcontrol.ros2.driver import Ros2JointDriver, stamp_s
from dqcontrol.ros2.joint_states import JointStateCheck
from dqcontrol.ros2.params import ControlParams
from dqcontrol.ros2.paths import trajectory_from_poses
from dqcontrol.ros2.robot_source import base_frame, description_qos, load_control_robot
from dqcontrol.ros2.ros import require_ros
from dqcontrol.ros2.status import Status, binding_limit, marker_path, marker_target, status_message
from dqcontrol.sim.driver import VelocityFromPosition, joint_map
from dqcontrol.sim.loop import RunResult, run_loop
from dqcontrol.trajectories import Trajectory, trajectory_from_metadata

__all__ = ["ControlNode", "StopRequested"]

#: Wall clock: controller steps before the loop's clock starts (:meth:`ControlNode._warm`).
WARM_STEPS = 3
#: ``~/status`` levels (diagnostic_msgs/DiagnosticStatus).
OK, WARN, ERROR = 0, 1, 2


class StopRequested(KeyboardInterrupt):  # noqa: N818 - the loop's own stop signal
    """``~/stop`` was called: raised from the loop's sample callback, so that the loop ends
    the task as on Ctrl-C (brake, then hold)."""


class _PositionCommands(VelocityFromPosition):
    """Position targets ``q_target += T u`` over the ROS 2 driver, with its counters."""

    def report(self) -> dict:
        """The ROS 2 driver's counters (:meth:`Ros2JointDriver.report`)."""
        return self.inner.report()  # type: ignore[attr-defined]


class ControlNode:
    """A controller as a ROS 2 node (module docstring).

    Args:
        node: the rclpy node to work on (its name gives ``~/status``, ``~/path``,
            ``~/stop``).
        params: the checked parameters.

    Call :meth:`start` once the node spins (the robot may come from a topic), then
    :meth:`run`.
    """

    def __init__(self, node: Any, params: ControlParams) -> None:
        self.ros = require_ros()
        self.node, self.params = node, params
        self.results: list[RunResult] = []
        self._tasks: queue.Queue = queue.Queue()
        self._stop = threading.Event()
        self._running = threading.Event()
        self._log = node.get_logger()

    # ------------------------------------------------------------------ set-up
    def start(self) -> None:
        """Load the robot, open the topics and the service, queue the parameter's task."""
        p, ros, node = self.params, self.ros, self.node
        self.robot = load_control_robot(node, ros, p)
        self.frame = base_frame(self.robot)
        names = p.joints or tuple(self.robot.joint_names)
        check = JointStateCheck(names, tuple(self.robot.locked_joints))
        self._perm = joint_map(names, self.robot.joint_names)
        self.driver = Ros2JointDriver(
            node, ros, check, states_topic=p.joint_states_topic, command_topic=p.command_topic,
            period_s=p.period_s, stepped=p.mode == "stepped", timeout_s=p.state_timeout_s,
            wait_s=p.wait_s,
        )  # fmt: skip
        self._status = node.create_publisher(ros.diagnostic.DiagnosticStatus, "~/status", 10)
        self._markers = node.create_publisher(
            ros.visualization.Marker, "~/markers", description_qos(ros)
        )
        self._target_marker = node.create_publisher(ros.visualization.Marker, "~/target", 10)
        node.create_service(ros.std_srvs.Trigger, "~/stop", self._on_stop)
        node.create_subscription(ros.nav.Path, "~/path", self._on_path, 10)
        if p.task != "path":
            self._tasks.put(p.task)
        self._publish(Status("waiting", controller=p.controller))

    def _on_stop(self, request: Any, response: Any) -> Any:
        del request
        response.success = self._running.is_set()
        if response.success:
            self._stop.set()
            response.message = "stopping: braking to rest, then holding"
        else:
            response.message = "no task is running"
        self._log.info(f"~/stop: {response.message}")
        return response

    def _on_path(self, msg: Any) -> None:
        if self._running.is_set():
            self._log.error("refused a path on ~/path: a task is running (call ~/stop first)")
            return
        frame = msg.header.frame_id
        if frame not in ("", self.frame):
            self._log.error(
                f"refused a path on ~/path in frame {frame!r}: its poses must be in the "
                f"robot's base frame {self.frame!r}"
            )
            return
        poses = msg.poses
        positions = np.array([[s.pose.position.x, s.pose.position.y, s.pose.position.z]
                              for s in poses]).reshape(-1, 3)  # fmt: skip
        orient = [s.pose.orientation for s in poses]
        quats = np.array([[o.w, o.x, o.y, o.z] for o in orient]).reshape(-1, 4)
        stamps = np.array([stamp_s(s.header.stamp) for s in poses])
        self._tasks.put((positions, quats, stamps))

    # ------------------------------------------------------------------ tasks
    def run(self) -> int:
        """Run the tasks as they come (the parameter's circle or sinusoid at once, each
        ``~/path``); with ``exit_when_done``, only the first. Returns 0 when every task
        completed, else 1. Ctrl-C ends it (a running task is braked first)."""
        self._await_command_subscriber()
        code = 0
        while True:
            try:
                task = self._tasks.get(timeout=0.1)
            except queue.Empty:
                continue
            try:
                trajectory = self._trajectory(task)
            except ParameterError as exc:
                self._log.error(f"refused the path on ~/path: {exc}")
                continue
            result = self.run_task(trajectory)
            code = max(code, 0 if result.metrics.completed else 1)
            shutdown = result.reason == "user" and not self._stop.is_set()
            if shutdown or result.reason == "simulation" or self.params.exit_when_done:
                return code

    def _await_command_subscriber(self) -> None:
        """Wait (``wait_s``) until the command topic has a subscriber, so that the first
        command is not lost."""
        done = threading.Event()
        for _ in range(int(self.params.wait_s / 0.01)):
            if self.node.count_subscribers(self.params.command_topic) > 0:
                return
            done.wait(0.01)
        raise DQControlError(
            f"nothing subscribes to {self.params.command_topic} after {self.params.wait_s:g} "
            "s: is the forward command controller loaded and active?"
        )

    def _trajectory(self, task: Any) -> Trajectory:
        if isinstance(task, str):
            kind = {"trajectory": task, "duration_s": self.params.duration_s}
            return trajectory_from_metadata(kind)
        q = self.driver.read().q
        q_model = q if self._perm is None else q[self._perm]
        start = self.robot.pose(q_model)
        positions, quats, stamps = task
        tolerance_m = self.params.path_start_tolerance_m
        return trajectory_from_poses(positions, quats, stamps, start, tolerance_m)

    def build(self, trajectory: Trajectory) -> Controller:
        """The controller of the parameters on ``trajectory`` (the registry's defaults, the
        servo time constant where the parameter gives one)."""
        p = self.params
        shared: dict[str, object] = {}
        if p.servo_time_constant_s > 0.0:
            shared["servo_time_constant_s"] = p.servo_time_constant_s
        return build_controller(p.controller, self.robot, trajectory, p.period_s, shared=shared)

    def stop_policy(self) -> str:
        """How a task is stopped: ``"brake"`` (the controller's path-maintaining stop: the
        phase slowed to rest along the path, then the hold); anything else ends a task with
        its last command (for a robot whose own controller brakes)."""
        return "brake"

    def run_task(self, trajectory: Trajectory) -> RunResult:
        """Run one task to its end (or a stop) and report it on ``~/status`` and the log."""
        p = self.params
        controller = self.build(trajectory)
        driver: Any = self.driver
        if p.command_interface == "position":
            driver = _PositionCommands(self.driver, p.period_s)
        if p.mode == "wall":
            self._warm(controller)
        self._stop.clear()
        self._running.set()
        self._log.info(f"running {p.controller} on the {self._task_name(trajectory)}")
        reports: queue.SimpleQueue = queue.SimpleQueue()
        reporter = threading.Thread(
            target=self._reporting, args=(controller, reports), name="dqcontrol status"
        )
        reporter.start()
        try:
            result = run_loop(
                controller, driver, realtime=p.mode == "wall", stale_periods=p.stale_periods,
                max_lateness_s=p.max_lateness_s or None,
                realtime_priority=p.realtime_priority or None,
                on_sample=self._sampler(controller, reports),
                brake=self.stop_policy() == "brake",
                meta={"ros2_mode": p.mode, "command_interface": p.command_interface},
            )  # fmt: skip
        finally:
            self._running.clear()
            reports.put(None)
            reporter.join()
        self.results.append(result)
        self._report(controller, result)
        return result

    def _warm(self, controller: Controller) -> None:
        """Step ``controller`` :data:`WARM_STEPS` times at rest where the arm is (the loop
        resets it at its start): the first steps build the controller's structures, which
        on the wall clock would take the first periods' time."""
        q = self.driver.read().q
        q = np.array(q if self._perm is None else q[self._perm], dtype=float)
        controller.reset(q)
        for _ in range(WARM_STEPS):
            controller.step(q, np.zeros(controller.robot.nq))

    @staticmethod
    def _task_name(trajectory: Trajectory) -> str:
        return type(trajectory).__name__

    # ------------------------------------------------------------------ reporting
    def _sampler(self, controller: Controller, reports: queue.SimpleQueue):
        """The loop's sample callback: hands every ``status_every``-th sample to the
        reporting thread (nothing slow in the control period) and raises
        :class:`StopRequested` after ``~/stop``."""
        every = self.params.status_every

        def on_sample(k: int, driver: Any, result: StepResult) -> None:
            if k % every == 0:
                reports.put((k, np.array(driver.read().q, dtype=float), result))
            if self._stop.is_set():
                raise StopRequested

        return on_sample

    def _reporting(self, controller: Controller, reports: queue.SimpleQueue) -> None:
        """The reporting thread: ``~/status`` and the markers of the samples handed over,
        until ``None``."""
        qd_max = getattr(controller, "qd_max", None)
        if qd_max is None or np.shape(qd_max) != (controller.robot.nq,):
            qd_max = controller.robot.limits.qd_max
        failed = False
        while (item := reports.get()) is not None:
            k, q, result = item
            try:
                if k == 0:
                    points = controller.trajectory.path_positions(400)
                    stamp = self._now()
                    self._markers.publish(marker_path(self.ros, self.frame, points, stamp))
                self._publish_sample(controller, q, result, np.asarray(qd_max, dtype=float))
            except Exception as exc:  # noqa: BLE001 - reporting never stops the control
                if not failed:
                    self._log.error(f"~/status: {type(exc).__name__}: {exc}")
                failed = True

    def _publish_sample(self, controller, q: np.ndarray, result: StepResult, qd_max) -> None:
        q = q if self._perm is None else q[self._perm]
        limits = controller.robot.limits
        binding = binding_limit(
            tuple(controller.robot.joint_names), q, result.qd_command, result.s,
            limits.q_min, limits.q_max, qd_max,
        )  # fmt: skip
        deviation = controller.trajectory.path_deviation(translation(result.pose), segments=2000)
        self._publish(Status(
            "running", float(result.sigma), controller.trajectory.duration, float(result.s),
            float(deviation), binding, "", sum(self.driver.rejected.values()),
            self.params.controller,
        ))  # fmt: skip
        stamp = self._now()
        self._target_marker.publish(marker_target(self.ros, self.frame, result.target, stamp))

    def _now(self) -> Any:
        return self.node.get_clock().now().to_msg()

    def _publish(self, status: Status) -> None:
        self._status.publish(status_message(self.ros, status, self._now()))

    def _report(self, controller: Controller, result: RunResult) -> None:
        phase, why, level = _outcome(result, self._stop.is_set())
        m = result.metrics
        line = (
            f"{phase}: {why or 'the task completed'}; {len(result.log)} samples, path "
            f"deviation max {m.path_deviation_max_m * 1e3:.3f} mm, rejected joint states "
            f"{dict(self.driver.rejected) or 'none'}{_timing(result.log.meta['stop'])}"
        )
        {OK: self._log.info, WARN: self._log.warning, ERROR: self._log.error}[level](line)
        sigma = float(result.log.sigma[-1]) if len(result.log) else 0.0
        self._publish(Status(
            phase, sigma, controller.trajectory.duration, 0.0, float(m.path_deviation_max_m),
            "none", why, sum(self.driver.rejected.values()), self.params.controller, level,
        ))  # fmt: skip
        if self.params.save_run:
            from dqcontrol.runs.storage import save_run

            target = Path(self.params.save_run)
            name = target.name if len(self.results) == 1 else f"{target.name}_{len(self.results)}"
            save_run(result, target.parent, name)


def _timing(stop: dict) -> str:
    """Wall clock: the start jitter and the late commands, for the task's log line."""
    if "jitter_p99_ms" not in stop:
        return ""
    return (
        f"; start jitter median {stop['jitter_median_ms']:.3f} / p99 "
        f"{stop['jitter_p99_ms']:.3f} / max {stop['jitter_max_ms']:.3f} ms, late commands "
        f"{stop['missed_deadlines']}"
    )


def _outcome(result: RunResult, stop_requested: bool) -> tuple[str, str, int]:
    """``(phase, stop reason, level)`` of a finished task."""
    if result.reason == "user":
        why = "stop requested on ~/stop" if stop_requested else "shutdown"
        return "stopped", f"{why}: braked to rest, holding", WARN
    if result.reason == "stale":
        return "stopped", f"stale joint states ({result.note}): braked, holding", WARN
    if result.reason == "simulation":
        return "stopped", f"robot gone, no more commands ({result.note})", ERROR
    if result.reason == "deadline":
        return "stopped", f"missed deadline ({result.note}): braked, holding", WARN
    if not result.metrics.completed:
        return "stopped", "time limit before the end of the task: braked, holding", WARN
    return "done", "", OK
