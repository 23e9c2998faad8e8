"""ROS 2 scenarios for tests/ros2/test_nodes.py, run INSIDE a network namespace that has only
the loopback interface (the test starts this file through ``unshare -n``; it refuses to run
elsewhere). Each scenario starts ``dqcontrol ros2 sim`` and ``dqcontrol ros2 control`` as
separate processes, plays its part with a node of its own (paths, bad joint states,
``~/stop``, a kill) and prints one JSON object on its last line.

    python tests/ros2_scenarios.py SCENARIO OUT_DIR
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PERIOD_S = 0.01
#: Stepped: how long a command waits for its state [s]; a loaded host can hold an answer
#: back for a second, and a command without its answer is a stale sample, not the same run.
STATE_TIMEOUT_S = 5.0
#: Longest wait for a node process [s] (a hang, not a timing requirement).
PROCESS_TIMEOUT_S = 180.0


def _only_loopback() -> None:
    names = sorted(name for _index, name in socket.if_nameindex())
    if names != ["lo"] or os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE") != "LOCALHOST":
        raise SystemExit(f"refusing to start ROS 2 outside a loopback-only namespace: {names}")


def _dqcontrol(node: str, params: dict, out: Path, name: str) -> subprocess.Popen:
    code = "from dqcontrol.cli import main; raise SystemExit(main())"
    args = []
    for key, value in params.items():
        text = json.dumps(value) if not isinstance(value, str) else value
        args += ["-p", f"{key}:={text}"]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    log = open(out / f"{name}.log", "w")  # noqa: SIM115 - closed with the process
    return subprocess.Popen(
        [sys.executable, "-c", code, "ros2", node, "--ros-args", *args],
        stdout=log, stderr=subprocess.STDOUT, env=env,
    )  # fmt: skip


def _finish(proc: subprocess.Popen, sig: int | None = None) -> int:
    if sig is not None and proc.poll() is None:
        proc.send_signal(sig)
    try:
        return proc.wait(timeout=PROCESS_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        proc.kill()
        return -999


def _sim(out: Path, mode: str = "stepped", **extra) -> subprocess.Popen:
    params = {"mode": mode, "period_s": PERIOD_S, "report_file": str(out / "sim.json"), **extra}
    return _dqcontrol("sim", params, out, "sim")


def _control(out: Path, mode: str = "stepped", **extra) -> subprocess.Popen:
    params = {
        "mode": mode, "period_s": PERIOD_S, "ee_frame": "lbr4p_flange", "exit_when_done": True,
        "save_run": str(out / "run"), "status_every": 10, "state_timeout_s": STATE_TIMEOUT_S,
        **extra,
    }  # fmt: skip
    return _dqcontrol("control", params, out, "control")


class Probe:
    """The test's own node: statuses and commands heard, publishers for the faults."""

    def __init__(self) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticStatus
        from std_msgs.msg import Float64MultiArray

        rclpy.init()
        self.rclpy = rclpy
        self.node = rclpy.create_node("dqcontrol_test_probe")
        self.statuses: list[dict] = []
        self.commands: list[tuple[float, list[float]]] = []
        self.node.create_subscription(
            DiagnosticStatus, "/dqcontrol_control/status", self._status, 100
        )
        self.node.create_subscription(
            Float64MultiArray, "/forward_velocity_controller/commands", self._command, 1000
        )
        self.executor = rclpy.executors.SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.spinner = threading.Thread(target=self.executor.spin, daemon=True)
        self.spinner.start()

    def _status(self, msg) -> None:
        self.statuses.append({kv.key: kv.value for kv in msg.values})

    def _command(self, msg) -> None:
        self.commands.append((time.monotonic(), list(msg.data)))

    def sigma(self) -> float:
        running = [s for s in self.statuses if s.get("phase") == "running"]
        return float(running[-1]["sigma_s"]) if running else 0.0

    def wait_for(self, condition, timeout_s: float = 120.0) -> bool:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if condition():
                return True
            time.sleep(0.005)
        return False

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        self.spinner.join(timeout=5.0)
        self.node.destroy_node()
        self.rclpy.try_shutdown()


def _bad_states(probe: Probe, stop: threading.Event) -> None:
    """Publish a NaN, a short and a misnamed JointState every 20 ms until ``stop``."""
    from sensor_msgs.msg import JointState

    pub = probe.node.create_publisher(JointState, "/joint_states", 10)
    names = [f"lbr4p_joint_{i}" for i in range(1, 8)]
    bad = [
        JointState(name=names, position=[0.1, float("nan"), 0, 0, 0, 0, 0]),
        JointState(name=names, position=[0.1] * 6),
        JointState(name=[*names[:6], "elbow_renamed"], position=[0.1] * 7),
    ]
    while not stop.is_set():
        for msg in bad:
            pub.publish(msg)
        stop.wait(0.02)


def _path_message(out: Path):
    """A nav_msgs/Path from the LBR4p's start pose: 4 waypoints over 2 s in the base frame;
    its arrays also go to ``path.json`` for the in-process run."""
    from geometry_msgs.msg import PoseStamped
    from nav_msgs.msg import Path as PathMsg

    from dqcontrol.dq.algebra import rotation, translation
    from dqcontrol.model.library import LBR4P_Q0, load_lbr4p

    start = load_lbr4p().pose(LBR4P_Q0)
    p0, r0 = translation(start), rotation(start)
    offsets = np.array([[0, 0, 0], [0.03, 0.01, 0], [0.05, 0.04, -0.02], [0.02, 0.06, -0.03]])
    stamps = np.array([0.0, 0.6, 1.3, 2.0])
    msg = PathMsg()
    msg.header.frame_id = "base_link"  # the LBR4p URDF's root link
    for offset, t in zip(offsets, stamps, strict=True):
        pose = PoseStamped()
        pose.header.stamp.sec, pose.header.stamp.nanosec = int(t), int(round((t % 1) * 1e9))
        x, y, z = p0 + offset
        pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = x, y, z
        o = pose.pose.orientation
        o.w, o.x, o.y, o.z = (float(v) for v in r0)
        msg.poses.append(pose)
    from dqcontrol.ros2.driver import stamp_s

    record = {"positions": (p0 + offsets).tolist(), "quats": [list(r0)] * 4,
              "stamps": [stamp_s(pose.header.stamp) for pose in msg.poses]}  # fmt: skip
    (out / "path.json").write_text(json.dumps(record))
    return msg


# ---------------------------------------------------------------------- scenarios
def circle_with_bad_states(out: Path, probe: Probe) -> dict:
    sim, control = _sim(out), _control(out)
    stop = threading.Event()
    injector = threading.Thread(target=_bad_states, args=(probe, stop), daemon=True)
    injector.start()
    code = _finish(control)
    stop.set()
    return {"control": code, "sim": _finish(sim, signal.SIGINT)}


def path_task(out: Path, probe: Probe) -> dict:
    from nav_msgs.msg import Path as PathMsg

    # the position interface: the control node integrates, the robot differentiates
    sim = _sim(out, command_interface="position")
    control = _control(out, task="path", command_interface="position")
    pub = probe.node.create_publisher(PathMsg, "/dqcontrol_control/path", 10)
    msg = _path_message(out)
    probe.wait_for(lambda: pub.get_subscription_count() > 0)
    running = lambda: any(s.get("phase") == "running" for s in probe.statuses)  # noqa: E731
    for _ in range(10):  # a message sent just as the endpoints match may be lost: again
        pub.publish(msg)
        if probe.wait_for(running, 3.0):
            break
    code = _finish(control)
    return {"control": code, "sim": _finish(sim, signal.SIGINT)}


def stale(out: Path, probe: Probe) -> dict:
    urdf = ROOT / "dqcontrol" / "robots" / "lbr4p" / "lbr4p.urdf"  # the robot from a file
    sim, control = _sim(out, mute_after=60), _control(out, robot_description_file=str(urdf))
    code = _finish(control)
    time.sleep(0.2)
    return {"control": code, "sim": _finish(sim, signal.SIGINT)}


def stop_service(out: Path, probe: Probe) -> dict:
    from std_srvs.srv import Trigger

    sim, control = _sim(out), _control(out)
    client = probe.node.create_client(Trigger, "/dqcontrol_control/stop")
    probe.wait_for(lambda: probe.sigma() > 0.5)
    client.wait_for_service(timeout_sec=10.0)
    answer = client.call(Trigger.Request(), timeout_sec=10.0)
    code = _finish(control)
    return {
        "control": code, "sim": _finish(sim, signal.SIGINT),
        "answer": None if answer is None else [answer.success, answer.message],
    }  # fmt: skip


def shutdown(out: Path, probe: Probe) -> dict:
    sim, control = _sim(out), _control(out)
    probe.wait_for(lambda: probe.sigma() > 0.5)
    code = _finish(control, signal.SIGTERM)
    return {"control": code, "sim": _finish(sim, signal.SIGINT)}


def sim_killed(out: Path, probe: Probe) -> dict:
    sim, control = _sim(out), _control(out)
    probe.wait_for(lambda: probe.sigma() > 0.5)
    sim_code = _finish(sim, signal.SIGTERM)
    killed_at = time.monotonic()
    code = _finish(control)
    time.sleep(0.3)
    after = [c for t, c in probe.commands if t > killed_at + 0.05]
    return {"control": code, "sim": sim_code, "commands_after_kill": len(after)}


def wall_clock(out: Path, probe: Probe) -> dict:
    sim = _sim(out, mode="wall")
    control = _control(out, mode="wall", controller="local", stale_periods=10)
    code = _finish(control)
    return {"control": code, "sim": _finish(sim, signal.SIGINT)}


SCENARIOS = {f.__name__: f for f in (circle_with_bad_states, path_task, stale, stop_service,
                                     shutdown, sim_killed, wall_clock)}  # fmt: skip


def main() -> None:
    _only_loopback()
    name, out = sys.argv[1], Path(sys.argv[2])
    out.mkdir(parents=True, exist_ok=True)
    probe = Probe()
    try:
        result = SCENARIOS[name](out, probe)
    finally:
        probe.close()
    result["statuses"] = probe.statuses[-3:]
    result["commands_heard"] = len(probe.commands)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
