"""dqcontrol/sim/mujoco_sim.py: kinematics and mass matrix against Pinocchio, velocity servos
that track and hold, computed torque, torque limits, payload, obstacles, input checks, speed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import dqcontrol
from dqcontrol.controllers import LocalController
from dqcontrol.dq.algebra import align_sign
from dqcontrol.errors import ConfigurationError, DQControlError, ParameterError, URDFError
from dqcontrol.model.collision import Sphere
from dqcontrol.model.library import LBR4P_Q0, PANDA_Q0
from dqcontrol.sim import MujocoDriver, run_loop
from dqcontrol.sim.mujoco_sim import MujocoSimulation
from dqcontrol.trajectories import Circle

BASE = pin.SE3(pin.rpy.rpyToMatrix(0.3, -0.2, 1.0), np.array([0.5, -0.2, 0.1]))
#: LBR4p with the upper arm leaning forward: long lever arm of the flange about joint 2.
LBR4P_REACH = np.array([0.0, 1.0, 0.0, -0.6, 0.0, 0.5, 0.0])


@pytest.fixture(scope="module")
def lbr4p_sim(lbr4p) -> MujocoSimulation:
    return MujocoSimulation(lbr4p)


@pytest.fixture(scope="module")
def panda_sim(panda) -> MujocoSimulation:
    return MujocoSimulation(panda)


def _robots():
    return {
        "lbr4p": lambda: dqcontrol.load_lbr4p(),
        "panda": lambda: dqcontrol.load_panda(),
        "lbr4p_base": lambda: dqcontrol.load_lbr4p(base=BASE),
        "panda_base": lambda: dqcontrol.load_panda(base=BASE),
        "lbr4p_tool_locked": lambda: dqcontrol.load_lbr4p(
            base=BASE,
            tool=pin.SE3(pin.rpy.rpyToMatrix(0.1, 0.2, -0.3), np.array([0.01, -0.02, 0.1])),
            locked_joints={"lbr4p_joint_7": 0.7, "lbr4p_joint_3": -0.4},
        ),
        "panda_hand": lambda: dqcontrol.load_panda(ee_frame="panda_hand"),
        "panda_joint_frame": lambda: dqcontrol.load_panda(ee_frame="panda_joint7"),
    }


# --------------------------------------------------------------------------- kinematics
@pytest.mark.parametrize("name", list(_robots()))
def test_ee_pose_matches_pinocchio(name):
    robot = _robots()[name]()
    sim = MujocoSimulation(robot)
    worst = 0.0
    for q in robot.random_configurations(50, seed=7):
        sim.reset(q)
        x_mj = sim.ee_pose()
        x_pin = robot.pose(q)
        x_mj, _ = align_sign(x_mj, x_pin)
        worst = max(worst, float(np.abs(x_mj - x_pin).max()))
        np.testing.assert_allclose(sim.measure().q, q, atol=0.0)
    assert worst < 1e-9, f"{name}: MuJoCo and Pinocchio EE poses differ by {worst}"


def test_panda_loads_meshes_and_locks_fingers(panda_sim, panda):
    model = panda_sim.model
    assert model.nq == model.nv == model.nu == panda.nq == 7
    assert model.nmesh >= 9  # STL collision meshes of links 0-7 and the hand
    assert any(".dae" in d for d in panda_sim.dropped_visuals)
    assert list(panda_sim.joint_qpos_adr) == panda.joint_names


def test_mass_matrix_matches_nominal_model_plus_armature(lbr4p_sim, lbr4p):
    import mujoco

    m, d = lbr4p_sim.model, lbr4p_sim.data
    for q in lbr4p.random_configurations(5, seed=3):
        lbr4p_sim.reset(q)
        full = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, full)
        expected = lbr4p.mass_matrix(q) + np.diag(lbr4p_sim.armature)
        np.testing.assert_allclose(full, expected, atol=1e-12)


# --------------------------------------------------------------------------- servo
def _time_to_95(sim, q0, command, dt):
    sim.reset(q0)
    t95 = np.zeros_like(command)
    for _ in range(int(round(0.2 / dt))):
        meas = sim.step(command, dt)
        outside = np.abs(meas.qd - command) > 0.05 * np.abs(command)
        t95[outside] = meas.t_s + dt
    return t95


def test_velocity_step_is_tracked_within_a_few_periods(lbr4p_sim):
    command = np.full(7, 0.3)
    lbr4p_sim.reset(LBR4P_Q0)
    for k in range(3):
        meas = lbr4p_sim.step(command, 0.05)
        assert meas.t_s == pytest.approx(0.05 * (k + 1))
    assert np.abs(meas.qd - command).max() < 0.05 * 0.3
    # the step response itself, sampled every 1 ms: 95 % well within one period of 0.05 s
    t95 = _time_to_95(lbr4p_sim, LBR4P_Q0, command, 0.001)
    assert t95.max() < 0.03, t95


def test_velocity_step_does_not_overshoot(lbr4p_sim):
    command = np.full(7, 0.3)
    lbr4p_sim.reset(LBR4P_Q0)
    peak = np.zeros(7)
    for _ in range(100):
        peak = np.maximum(peak, lbr4p_sim.step(command, 0.001).qd)
    assert (peak < 1.05 * command).all(), peak


@pytest.mark.parametrize("robot_name", ["lbr4p", "panda"])
def test_zero_command_holds_against_gravity(robot_name, lbr4p_sim, panda_sim):
    sim, q0 = (lbr4p_sim, LBR4P_Q0) if robot_name == "lbr4p" else (panda_sim, PANDA_Q0)
    sim.reset(q0)
    for _ in range(20):
        meas = sim.step(np.zeros(7), 0.05)
    assert meas.t_s == pytest.approx(1.0)
    assert np.abs(meas.q - q0).max() < 1e-3


def test_unknown_payload_is_held_by_the_integral_action(lbr4p):
    sim = MujocoSimulation(lbr4p, payload_kg=3.0)
    sim.reset(LBR4P_REACH)
    q_settled = sim.step(np.zeros(7), 0.5).q
    assert np.abs(q_settled - LBR4P_REACH).max() < 0.02  # the initial sag
    meas = sim.step(np.zeros(7), 1.0)
    assert np.abs(meas.q - q_settled).max() < 1e-3


def test_servo_at_1ms_control_period_tracks_a_ramp(lbr4p_sim):
    # a smooth command changing every 1 ms: the servo lags by about τ_v
    lbr4p_sim.reset(LBR4P_Q0)
    for k in range(300):
        command = np.full(7, 0.5 * np.sin(2 * np.pi * 1.0 * k * 0.001))
        meas = lbr4p_sim.step(command, 0.001)
    lag_s = lbr4p_sim.servo_time_constant_s
    expected = 0.5 * np.sin(2 * np.pi * 1.0 * (meas.t_s - lag_s))
    assert np.abs(meas.qd - expected).max() < 0.02


# --------------------------------------------------------------------------- torques
def _peak_torque(sim, q0, amplitude=2.0, periods=20):
    sim.reset(q0)
    peak = np.zeros(sim.robot.nq)
    for k in range(periods):
        command = amplitude * (1.0 if k % 4 < 2 else -1.0) * np.ones(sim.robot.nq)
        meas = sim.step(command, 0.05)
        assert (np.abs(meas.torque) <= meas.torque_peak + 1e-12).all()
        peak = np.maximum(peak, meas.torque_peak)
    return peak


def test_torques_never_exceed_effort_limits(lbr4p_sim, lbr4p):
    peak = _peak_torque(lbr4p_sim, LBR4P_Q0)
    limit = lbr4p.limits.effort_max
    assert (peak <= limit * (1 + 1e-12)).all(), peak
    assert np.isclose(peak, limit).any(), "the demanding command should saturate a drive"


def test_effort_scale_halves_the_torque_limits(lbr4p):
    sim = MujocoSimulation(lbr4p, effort_scale=0.5)
    np.testing.assert_allclose(sim.torque_limit, 0.5 * lbr4p.limits.effort_max)
    np.testing.assert_allclose(
        sim.model.jnt_actfrcrange[:, 1], 0.5 * lbr4p.limits.effort_max, rtol=1e-12
    )
    peak = _peak_torque(sim, LBR4P_Q0)
    assert (peak <= 0.5 * lbr4p.limits.effort_max * (1 + 1e-12)).all(), peak
    assert np.isclose(peak, 0.5 * lbr4p.limits.effort_max).any()


def test_payload_changes_the_gravity_torque_at_joint_2(lbr4p):
    payload_kg = 2.0
    held = {}
    for mass in (0.0, payload_kg):
        sim = MujocoSimulation(lbr4p, payload_kg=mass)
        sim.reset(LBR4P_REACH)
        meas = sim.step(np.zeros(7), 1.0)
        held[mass] = meas.torque
        q_end = meas.q
    # static torque of a point mass at the flange: J_vᵀ (0, 0, m g)
    jac = pin.computeFrameJacobian(
        lbr4p.model,
        lbr4p.model.createData(),
        q_end,
        lbr4p.model.getFrameId(lbr4p.ee_frame),
        pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,
    )
    expected = jac[:3].T @ np.array([0.0, 0.0, payload_kg * 9.81])
    delta = held[payload_kg] - held[0.0]
    assert abs(delta[1]) > 5.0  # N·m: a real change at the shoulder
    np.testing.assert_allclose(delta, expected, atol=0.05 * abs(expected[1]))


# --------------------------------------------------------------------------- API
def test_measure_repeats_the_last_step(lbr4p_sim):
    lbr4p_sim.reset(LBR4P_Q0)
    meas = lbr4p_sim.step(np.full(7, 0.1), 0.05)
    again = lbr4p_sim.measure()
    assert again.t_s == meas.t_s
    for field in ("q", "qd", "torque", "torque_peak"):
        np.testing.assert_array_equal(getattr(again, field), getattr(meas, field))
    with pytest.raises(AttributeError):
        meas.t_s = 0.0  # frozen
    meas.q[0] = 99.0  # a copy: the simulation is not touched
    assert lbr4p_sim.measure().q[0] != 99.0


def test_reset_sets_state_and_time(lbr4p_sim):
    qd0 = np.linspace(-0.2, 0.2, 7)
    meas = lbr4p_sim.reset(LBR4P_Q0, qd0)
    assert meas.t_s == 0.0
    np.testing.assert_array_equal(meas.q, LBR4P_Q0)
    np.testing.assert_array_equal(meas.qd, qd0)
    np.testing.assert_array_equal(lbr4p_sim.command, qd0)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"physics_dt_s": 0.003},
        {"physics_dt_s": 0.0},
        {"physics_dt_s": float("nan")},
        {"effort_scale": 0.0},
        {"effort_scale": -1.0},
        {"effort_scale": float("inf")},
        {"payload_kg": -1.0},
        {"payload_offset_m": [0.0, 0.1]},
        {"motor": "current"},  # "velocity" or "torque"
        {"servo_time_constant_s": 0.001},  # < 2 physics steps
        {"integral_time_constant_s": 0.0},
        {"armature": [0.1, 0.2]},
        {"armature": -0.1},
        {"joint_damping": float("nan")},
    ],
)
def test_bad_parameters_raise(lbr4p, kwargs):
    with pytest.raises(ParameterError):
        MujocoSimulation(lbr4p, **kwargs)


def test_bad_commands_and_durations_raise(lbr4p_sim):
    lbr4p_sim.reset(LBR4P_Q0)
    with pytest.raises(ConfigurationError):
        lbr4p_sim.step(np.zeros(6), 0.05)
    with pytest.raises(ConfigurationError):
        lbr4p_sim.step(np.full(7, np.nan), 0.05)
    with pytest.raises(ConfigurationError):
        lbr4p_sim.reset(np.zeros(8))
    with pytest.raises(ConfigurationError):
        lbr4p_sim.reset(LBR4P_Q0, np.full(7, np.inf))
    for duration in (0.0015, 0.0, -0.05, float("nan"), 1e-4):
        with pytest.raises(ParameterError):
            lbr4p_sim.step(np.zeros(7), duration)
    # within 1e-9 of a multiple is accepted
    assert lbr4p_sim.step(np.zeros(7), 0.05 + 5e-10).t_s == pytest.approx(0.05)


def test_blown_up_state_raises(lbr4p):
    sim = MujocoSimulation(lbr4p)
    sim.reset(LBR4P_Q0)
    sim.data.qvel[0] = np.nan  # what an exploding simulation leaves behind
    with pytest.raises(DQControlError, match="unstable"):
        sim.step(np.zeros(7), 0.01)


_MESH_URDF = """<robot name="r">
  <link name="base"/>
  <link name="l1">
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01"
      ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><mesh filename="meshes/{mesh}"/></geometry></collision>
  </link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
</robot>"""
#: A tetrahedron as a Wavefront OBJ: 4 vertices, the fewest MuJoCo accepts.
_TETRA_OBJ = "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 0 0.1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


def _mesh_urdf(folder, mesh: str, text: str):
    (folder / "meshes").mkdir(exist_ok=True)
    (folder / "meshes" / mesh).write_text(text)
    path = folder / f"r_{mesh.replace('.', '_')}.urdf"
    path.write_text(_MESH_URDF.format(mesh=mesh))
    return path


def test_collision_mesh_mujoco_cannot_read_is_refused_by_the_simulator(tmp_path):
    """A COLLADA collision mesh (coal reads it, MuJoCo does not): the robot loads, and the
    simulator refuses to build its model, naming the link and the file, also from a source
    that skipped the load check. The same link with an OBJ mesh simulates with it."""
    from dqcontrol.model.urdf_source import URDFSource
    from dqcontrol.sim.mjcf_builder import prepare_urdf_xml

    path = _mesh_urdf(tmp_path, "l1.dae", "<COLLADA/>")
    robot = dqcontrol.RobotModel.from_urdf(path, "l1")
    pattern = r"collision mesh 'meshes/l1\.dae' of link 'l1'.*cannot read '\.dae'"
    with pytest.raises(URDFError, match=pattern):
        MujocoSimulation(robot)
    unchecked = URDFSource(path.read_text(), path, ())
    with pytest.raises(URDFError, match=r"l1\.dae.*cannot read '\.dae'"):
        prepare_urdf_xml(unchecked)
    robot = dqcontrol.RobotModel.from_urdf(_mesh_urdf(tmp_path, "l1.obj", _TETRA_OBJ), "l1")
    assert MujocoSimulation(robot).model.nmesh == 1


def test_payload_sits_at_the_end_effector(lbr4p):
    offset = np.array([0.0, 0.0, 0.05])
    sim = MujocoSimulation(lbr4p, payload_kg=1.0, payload_offset_m=offset)
    sim.reset(LBR4P_Q0)
    placement = lbr4p.placement(LBR4P_Q0)
    np.testing.assert_allclose(sim.payload_position(), placement.act(offset), atol=1e-12)
    assert MujocoSimulation(lbr4p).payload_position() is None


def test_1ms_loop_over_2s_keeps_time(lbr4p_sim):
    """2000 periods of 1 ms add up to 2 s of simulated time (its speed is measured by
    ``dqcontrol bench``, not asserted here)."""
    lbr4p_sim.reset(LBR4P_Q0)
    command = np.full(7, 0.1)
    for _ in range(2000):
        lbr4p_sim.step(command, 0.001)
    assert lbr4p_sim.time_s == pytest.approx(2.0)


# computed torque (motor="torque"): tracking, effort limits, the ramp


def _velocity_error_rms(log) -> float:
    """RMS of ``qd`` measured at sample k+1 minus the command of period k [rad/s]."""
    return float(np.sqrt(np.mean((log.qd_measured[1:] - log.qd_command[:-1]) ** 2)))


def test_computed_torque_tracks_the_velocity_better_than_the_servo_within_the_limits(lbr4p):
    runs = {}
    for motor in ("velocity", "torque"):
        driver = MujocoDriver(lbr4p, 0.05, motor=motor)
        res = run_loop(LocalController(lbr4p, Circle(1.0), 0.05), driver, q0=LBR4P_Q0)
        assert res.metrics.completed and res.log.meta["motor"] == motor
        limit = driver.simulation.torque_limit
        assert (res.log.torque_peak <= limit + 1e-9).all()
        runs[motor] = res
    servo, ct = (_velocity_error_rms(runs[m].log) for m in ("velocity", "torque"))
    assert ct < 0.1 * servo
    assert runs["torque"].metrics.torque_peak_nm < runs["velocity"].metrics.torque_peak_nm


def test_the_ramp_reaches_the_command_at_the_end_of_the_step(lbr4p):
    u = np.array([0.3, -0.2, 0.25, 0.3, -0.4, 0.5, 0.6])
    sim2 = MujocoSimulation(lbr4p, motor="torque", command_ramp_s=0.05)
    sim2.reset(LBR4P_Q0)
    mid = sim2.step(u, 0.025)  # half-way along a 50 ms ramp
    np.testing.assert_allclose(mid.qd, 0.5 * u, atol=2e-3)
    end = sim2.step(u, 0.025)  # the same command: the ramp goes on
    np.testing.assert_allclose(end.qd, u, atol=2e-3)
    later = sim2.step(u, 0.05)
    np.testing.assert_allclose(later.qd, u, atol=2e-3)


def test_an_impossible_step_is_clipped_to_the_effort_limits(lbr4p):
    sim = MujocoSimulation(lbr4p, motor="torque", effort_scale=0.5)
    sim.reset(LBR4P_Q0)
    peak = np.zeros(7)
    for _ in range(20):
        peak = np.maximum(peak, sim.step(np.full(7, 3.0), 0.01).torque_peak)
    assert (peak <= sim.torque_limit + 1e-9).all() and (peak >= sim.torque_limit - 1e-9).any()


def test_an_unknown_payload_leaves_a_velocity_error(lbr4p):
    sim = MujocoSimulation(lbr4p, motor="torque", payload_kg=3.0)
    sim.reset(LBR4P_Q0)
    for _ in range(10):
        m = sim.step(np.zeros(7), 0.05)
    assert np.abs(m.qd).max() > 1e-3  # no integral action: the payload's torque shows


def test_bad_computed_torque_options(lbr4p):
    with pytest.raises(ParameterError, match="motor must be one of"):
        MujocoSimulation(lbr4p, motor="current")
    with pytest.raises(ParameterError, match="command_ramp_s must be finite"):
        MujocoSimulation(lbr4p, motor="torque", command_ramp_s=-1.0)
    sim = MujocoSimulation(lbr4p, motor="torque", command_ramp_s=0.0015)
    sim.reset(LBR4P_Q0)
    with pytest.raises(ParameterError, match="not a whole number of physics steps"):
        sim.step(np.ones(7), 0.01)


def test_the_comparison_script_runs_short(capsys):
    import runpy

    script = Path(__file__).resolve().parents[2] / "docs" / "drivers_comparison.py"
    main = runpy.run_path(str(script), run_name="drivers_comparison")["main"]
    assert main(["--short"]) == 0
    out = capsys.readouterr().out
    assert "| circle 1 s | local | computed torque | 0 | yes |" in out


def test_the_simulation_collides_with_its_obstacles(lbr4p):
    """An obstacle given to the simulator is a body the arm hits: a ball on the flange
    stops it where the same command without the ball moves it."""
    robot = lbr4p
    flange = robot.placement(LBR4P_Q0).translation
    ball = Sphere(name="ball", position_m=tuple(flange + [0.0, 0.0, -0.08]), radius_m=0.05)
    moved = {}
    for shapes in ((), (ball,)):
        sim = MujocoSimulation(robot, obstacles=shapes)
        sim.reset(LBR4P_Q0)
        jac = pin.computeFrameJacobian(
            robot.model, robot.data, LBR4P_Q0, robot.frame_id(robot.ee_frame),
            pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,
        )  # fmt: skip
        down = np.linalg.pinv(jac[:3]) @ np.array([0.0, 0.0, -0.1])  # 0.1 m/s down [rad/s]
        for _ in range(20):
            meas = sim.step(down, 0.05)
        moved[len(shapes)] = float(robot.placement(meas.q).translation[2] - flange[2])
    assert moved[0] < -0.05  # free: the flange goes down by more than the gap
    assert moved[1] > -0.05  # with the ball: stopped by it
