"""dqcontrol ros2 control against dqcontrol ros2 sim, in separate processes, over ROS 2.

Every ROS 2 process runs in a network namespace that has only the loopback interface
(``unshare -n``, then the loopback brought up, ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``):
DDS discovery never leaves it. Where the namespace cannot be made (not root, no
``unshare``), the tests skip and say why; they never fall back to the host's network. No
rclpy node is made in this process: tests/ros2_scenarios.py plays each scenario inside the
namespace and prints what it saw; the in-process references run here.

The stepped scenarios run side by side, each in its own namespace; the wall-clock one runs
alone.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dqcontrol.extras import has_extra
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.registry import build_controller
from dqcontrol.runs.storage import load_run

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "tests" / "ros2_scenarios.py"
PERIOD_S = 0.01
STEPPED = (
    "circle_with_bad_states",
    "path_task",
    "stale",
    "stop_service",
    "shutdown",
    "sim_killed",
    "demo",
)
#: A scenario still running after this long [s] is stuck.
HANG_TIMEOUT_S = 240.0
#: In the namespace: the loopback up, discovery on this host only, then the command.
_IN_NAMESPACE = (
    'ip link set lo up && export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST && exec "$0" "$@"'
)

pytestmark = pytest.mark.skipif(
    not (has_extra("ros2") and has_extra("sim")), reason="needs the [ros2] and [sim] extras"
)


def namespace_problem() -> str | None:
    """Why a loopback-only network namespace cannot be made here, or ``None``."""
    for tool in ("unshare", "ip"):
        if shutil.which(tool) is None:
            return f"no '{tool}' command to make a loopback-only network namespace"
    try:
        probe = subprocess.run(
            ["unshare", "-n", "bash", "-c", _IN_NAMESPACE, "true"],
            capture_output=True, text=True, timeout=30,
        )  # fmt: skip
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"cannot make a network namespace: {exc}"
    if probe.returncode != 0:
        return f"cannot make a network namespace (unshare -n as root): {probe.stderr.strip()}"
    return None


def start_in_namespace(scenario: str, out: Path) -> subprocess.Popen:
    """``tests/ros2_scenarios.py scenario out`` in a namespace of its own (``demo``: the
    page's example, ``demos/ros2_bridge.py --short``)."""
    if scenario == "demo":
        args = [str(ROOT / "demos" / "ros2_bridge.py"), "--short"]
    else:
        args = [str(SCRIPT), scenario, str(out)]
    cmd = ["unshare", "-n", "bash", "-c", _IN_NAMESPACE, sys.executable, *args]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def finish(proc: subprocess.Popen, out: Path) -> dict:
    try:
        stdout, stderr = proc.communicate(timeout=HANG_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        proc.kill()
        stdout, stderr = proc.communicate()
    logs = "\n".join(f"--- {p.name}\n{p.read_text()}" for p in sorted(out.glob("*.log")))
    assert proc.returncode == 0 and stdout.strip(), f"{stdout}\n{stderr[-3000:]}\n{logs[-3000:]}"
    if not out.exists():  # the demo: its printed summary
        return {"stdout": stdout, "stderr": stderr}
    result = json.loads(stdout.strip().splitlines()[-1])
    result["out"], result["logs"] = out, logs
    return result


@pytest.fixture(scope="module")
def namespace():
    problem = namespace_problem()
    if problem is not None:
        pytest.skip(problem)


@pytest.fixture(scope="module")
def stepped(namespace, tmp_path_factory) -> dict[str, dict]:
    base = tmp_path_factory.mktemp("ros2")
    procs = {name: start_in_namespace(name, base / name) for name in STEPPED}
    results = {}
    for name, proc in procs.items():
        try:
            results[name] = finish(proc, base / name)
        except AssertionError as exc:  # that scenario's test fails with it, not the others
            results[name] = {"error": str(exc)}
    return results


def scenario(stepped: dict, name: str) -> dict:
    """What scenario ``name`` saw (the test fails with its error if it failed)."""
    got = stepped[name]
    if "error" in got:
        pytest.fail(f"scenario {name} failed: {got['error']}")
    return got


def _reference(robot, trajectory):
    """The same controller over the same simulator, in this process."""
    from dqcontrol.sim import MujocoSimulation, SimulationDriver, run_loop

    controller = build_controller("pf", robot, trajectory, PERIOD_S, shared={})
    driver = SimulationDriver(MujocoSimulation(robot), PERIOD_S)
    return run_loop(controller, driver, q0=LBR4P_Q0)


def _assert_same_run(log, ref) -> None:
    assert len(log) == len(ref.log)
    for name in ("q", "qd_measured", "qd_command", "sigma", "s"):
        gap = np.max(np.abs(getattr(log, name) - getattr(ref.log, name)))
        assert gap <= 1e-9, f"{name} differs by {gap}"


def test_stepped_circle_equals_the_in_process_run_and_ignores_bad_joint_states(stepped, lbr4p):
    from dqcontrol.trajectories import Circle

    got = scenario(stepped, "circle_with_bad_states")
    assert got["control"] == 0 and got["sim"] == 0, got["logs"]
    log, record = load_run(got["out"] / "run")
    ref = _reference(lbr4p, Circle(2.0))
    _assert_same_run(log, ref)
    assert record["metrics"]["completed"] and record["metrics"]["path_deviation_max_m"] <= 5e-4
    rejected = log.meta["driver_report"]["rejected"]
    assert set(rejected) == {"non-finite", "wrong length", "unknown joints"}, rejected
    assert min(rejected.values()) >= 5
    for reason in rejected:
        assert f"rejected a JointState on /joint_states ({reason}, 1 so far)" in got["logs"]
    assert got["statuses"][-1]["phase"] == "done"
    assert int(got["statuses"][-1]["rejected_states"]) >= sum(rejected.values())


def test_stepped_path_task_equals_the_in_process_run_and_meets_the_path_goals(stepped, lbr4p):
    # over the position interface: targets q + T u in, (target - last target) / T applied
    from dqcontrol.ros2.paths import trajectory_from_poses

    got = scenario(stepped, "path_task")
    assert got["control"] == 0, got["logs"]
    path = json.loads((got["out"] / "path.json").read_text())
    start = lbr4p.pose(LBR4P_Q0)
    trajectory = trajectory_from_poses(
        np.array(path["positions"]), np.array(path["quats"]), np.array(path["stamps"]),
        start, 0.01,
    )  # fmt: skip
    log, record = load_run(got["out"] / "run")
    _assert_same_run(log, _reference(lbr4p, trajectory))
    metrics = record["metrics"]
    assert metrics["completed"] and metrics["path_deviation_max_m"] <= 5e-4, metrics
    assert log.meta["command_interface"] == "position"
    assert log.meta["driver_report"]["commands"] >= len(log)


def test_stale_joint_states_stop_the_task_then_hold(stepped):
    # this control node reads its robot from the URDF file (robot_description_file)
    got = scenario(stepped, "stale")
    log, record = load_run(got["out"] / "run")
    sim = json.loads((got["out"] / "sim.json").read_text())
    assert log.meta["stop"]["reason"] == "stale" and got["control"] == 1
    assert sim["commands"] > 60 + log.meta["stop"]["brake_periods"] - 1
    assert sim["last_velocity"] == [0.0] * 7  # the hold after the brake
    assert "stale joint states" in got["statuses"][-1]["stop_reason"]


def test_stop_service_brings_the_arm_to_rest_on_the_path(stepped, lbr4p):
    from dqcontrol.dq.algebra import translation
    from dqcontrol.trajectories import Circle

    got = scenario(stepped, "stop_service")
    assert got["answer"][0] is True, got
    log, _record = load_run(got["out"] / "run")
    sim = json.loads((got["out"] / "sim.json").read_text())
    assert log.meta["stop"]["reason"] == "user" and 0.5 < log.sigma[-1] < 1.99
    assert sim["last_velocity"] == [0.0] * 7
    assert np.max(np.abs(sim["qd"])) < 0.05  # [rad/s], one period after the hold
    circle = Circle(2.0).anchored_at(lbr4p.pose(LBR4P_Q0))
    rest = translation(lbr4p.pose(np.array(sim["q"])))
    assert circle.path_deviation(rest) < 5e-4  # the stop keeps the path
    assert log.stopping.any() and not log.meta["stop"].get("ramp")
    assert "stop requested on ~/stop" in got["statuses"][-1]["stop_reason"]


def test_shutdown_mid_task_brakes_then_holds(stepped):
    got = scenario(stepped, "shutdown")
    log, _record = load_run(got["out"] / "run")
    sim = json.loads((got["out"] / "sim.json").read_text())
    assert log.meta["stop"]["reason"] == "user" and log.sigma[-1] < 1.99
    assert sim["last_velocity"] == [0.0] * 7
    assert got["statuses"][-1]["stop_reason"].startswith("shutdown")


def test_killed_sim_ends_the_commands_and_the_node_says_so(stepped):
    got = scenario(stepped, "sim_killed")
    assert got["commands_after_kill"] == 0
    assert "has left (the robot's node stopped): no more commands" in got["logs"]
    log, _record = load_run(got["out"] / "run")
    assert log.meta["stop"]["reason"] == "simulation"
    assert got["statuses"][-1]["stop_reason"].startswith("robot gone")


#: A separate process that says "ready", sleeps to absolute targets every millisecond for
#: ``argv[1]`` seconds and prints how late it woke up [ms]: the host's own scheduling
#: latency, measured while the nodes run.
CANARY = """
import json, sys, time
duration = float(sys.argv[1])
print("ready", flush=True)
late, start, k = [], time.perf_counter(), 0
while k * 1e-3 < duration:
    k += 1
    target = start + k * 1e-3
    left = target - time.perf_counter()
    if left > 0:
        time.sleep(left)
    late.append(1e3 * (time.perf_counter() - target))
late.sort()
print(json.dumps({"median_ms": late[len(late) // 2], "max_ms": late[-1]}))
"""
#: The host is "not quiet" when the canary woke up this late [ms]: a quarter of the period.
HOST_STALL_MS = 2.5


def test_wall_clock_at_100_hz_completes_and_reports_jitter(namespace, tmp_path):
    # the local controller, as the bridge's wall-clock test: the path-following
    # controller's first step after a reset (a cold solve) takes about a period at 100 Hz
    out = tmp_path / "wall"
    proc = start_in_namespace("wall_clock", out)
    canary = subprocess.Popen(
        [sys.executable, "-c", CANARY, "15"], stdout=subprocess.PIPE, text=True
    )
    try:
        got = finish(proc, out)
    finally:
        canary.kill()
    host_text = canary.communicate(timeout=30)[0].splitlines()
    log, record = load_run(out / "run")
    stop = log.meta["stop"]
    report = (
        f"100 Hz over ROS 2, {len(log)} samples: start jitter median "
        f"{stop['jitter_median_ms']:.3f} / p99 {stop['jitter_p99_ms']:.3f} / max "
        f"{stop['jitter_max_ms']:.3f} ms, lateness max {stop['lateness_max_ms']:.2f} ms, "
        f"late commands (missed deadlines) {stop['missed_deadlines']}"
    )
    print(report)
    if stop["reason"] in ("deadline", "stale"):
        stalled = "the canary did not finish" if len(host_text) < 2 else host_text[-1]
        if len(host_text) < 2 or json.loads(host_text[-1])["max_ms"] >= HOST_STALL_MS:
            pytest.skip(f"the host stalled ({stalled}): {report}")
    assert stop["reason"] == "end" and stop["missed_deadlines"] == 0, report
    assert record["metrics"]["completed"] and got["control"] == 0, got["logs"]
    assert stop["jitter_max_ms"] >= 0.0 and len(log) >= 200  # 2 s at 100 Hz


def test_the_pages_example_runs_the_circle_over_ros2(stepped):
    got = scenario(stepped, "demo")
    assert "completed=True" in got["stdout"], got


@pytest.mark.parametrize(
    ("node", "params", "message"),
    [
        ("control", ["ee_frame:=lbr4p_flange", "period_s:=-0.01"], "parameter 'period_s' must"),
        ("sim", ["mode:=fast"], "parameter 'mode' must be one of 'wall', 'stepped', got 'fast'"),
    ],
)
def test_a_bad_parameter_stops_the_node_with_one_line(namespace, node, params, message):
    code = "from dqcontrol.cli import main; raise SystemExit(main())"
    args = [arg for p in params for arg in ("-p", p)]
    cmd = ["unshare", "-n", "bash", "-c", _IN_NAMESPACE, sys.executable, "-c", code, "ros2",
           node, "--ros-args", *args]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120, cwd=ROOT)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 1 and len(lines) == 1, proc.stderr
    assert lines[0].startswith(f"dqcontrol ros2: error: {message}")
