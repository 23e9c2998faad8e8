"""The Meshcat viewer (dqcontrol/viz/meshcat_viewer.py): the robot's geometry from the
controller's URDF (a continuous joint as its one angle), the offline HTML replay and the
obstacles drawn in it, the live server (paced runs, a dying server, a dying parent), and —
when Chromium is installed — that a real browser draws the robot.

The browser tests need Debian's ``chromium`` (``apt-get install -y chromium``); without it
they are skipped. Chromium renders WebGL in software (SwiftShader) with ``--disable-gpu
--enable-unsafe-swiftshader --use-angle=swiftshader``.
"""

from __future__ import annotations

import base64
import http.server
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import umsgpack
from matplotlib.image import imread
from model.test_pinocchio_model import _configurations, _first_joint_continuous

import dqcontrol
from dqcontrol import load_lbr4p
from dqcontrol.controllers import LocalController
from dqcontrol.model import LBR4P_Q0, lbr4p_urdf_path
from dqcontrol.model.collision import Box, Capsule, Cylinder, HalfSpace, Sphere
from dqcontrol.sim import run_mujoco
from dqcontrol.trajectories import Circle
from dqcontrol.viz import meshcat_viewer
from dqcontrol.viz.meshcat_viewer import (
    MeshcatServer,
    MeshcatViewer,
    export_replay_html,
    robot_visual_models,
)

CHROMIUM = shutil.which("chromium") or (
    "/usr/bin/chromium" if os.path.exists("/usr/bin/chromium") else None
)
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None,
    reason="Chromium is not installed (CI installs Debian's 'chromium' package)",
)


# ---------------------------------------------------------------------- the robot's geometry
def test_viewer_geometry_is_the_controllers_urdf():
    """Same URDF, same locked joints, same base: the viewer's model puts the end effector
    where the controller's model does."""
    base = pin.SE3(pin.rpy.rpyToMatrix(0.1, -0.2, 0.7), np.array([0.3, -0.1, 0.2]))
    robot = dqcontrol.load_panda(base=base)
    model, geom = robot_visual_models(robot)
    assert model.nq == robot.nq == 7
    assert geom.ngeoms > 5 and all(g.meshPath.endswith(".dae") for g in geom.geometryObjects)
    data = model.createData()
    q = np.array([0.3, -0.5, 0.2, -2.0, 0.1, 1.4, 0.5])
    pin.framesForwardKinematics(model, data, q)
    ee = base * data.oMf[model.getFrameId(robot.ee_frame)]
    np.testing.assert_allclose(ee.homogeneous, robot.placement(q).homogeneous, atol=1e-12)


@pytest.fixture(scope="module")
def arm(tmp_path_factory) -> dqcontrol.RobotModel:
    """The LBR4p with its first joint continuous (as in tests/model/test_pinocchio_model.py)."""
    path = tmp_path_factory.mktemp("continuous") / "lbr4p_continuous.urdf"
    path.write_text(_first_joint_continuous(lbr4p_urdf_path().read_text()))
    return dqcontrol.RobotModel.from_urdf(path, "lbr4p_flange")


def test_the_viewer_model_takes_the_angle(arm):
    model, _ = robot_visual_models(arm)
    assert model.nq == 7
    data = model.createData()
    q = _configurations(1, seed=7)[0]
    pin.framesForwardKinematics(model, data, q)
    flange = data.oMf[model.getFrameId("lbr4p_flange")]
    np.testing.assert_allclose(flange.homogeneous, arm.placement(q).homogeneous, atol=1e-12)


def _commands(html: str) -> list[dict]:
    """The meshcat commands embedded in a static HTML page."""
    blobs = re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    return [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]


def test_replay_html_is_self_contained_and_animates_the_run(lbr4p, mujoco_run, tmp_path):
    result, trajectory = mujoco_run
    path = export_replay_html(
        lbr4p, result.log, tmp_path / "replay.html", path_points=trajectory.path_positions(200)
    )
    html = path.read_text()
    assert "MeshCat.Viewer" in html and "<script src=" not in html  # JavaScript inlined
    cmds = _commands(html)
    objects = {c["path"] for c in cmds if c["type"] == "set_object"}
    visuals = [p for p in objects if "/dqcontrol/robot/visuals/" in p]
    assert len(visuals) >= 15  # the LBR4p's primitives
    assert "/meshcat/dqcontrol/path" in objects
    assert any(p.startswith("/meshcat/dqcontrol/trace/") for p in objects)
    assert any(p.startswith("/meshcat/dqcontrol/target/") for p in objects)
    (anim,) = [c for c in cmds if c["type"] == "set_animation"]
    clips = {a["path"]: a["clip"] for a in anim["animations"]}
    assert set(visuals) <= set(clips)
    # every clip spans the whole run (a shorter clip would loop on its own length)
    lengths = {max(k["time"] for t in c["tracks"] for k in t["keys"]) for c in clips.values()}
    assert len(lengths) == 1
    duration = lengths.pop() / clips["/meshcat/dqcontrol/target"]["fps"]
    assert duration == pytest.approx(result.log.t_s[-1] + 0.05, abs=0.05)


# ---------------------------------------------------------------------- live viewer
def test_live_viewer_paces_a_run_without_a_browser_and_closes_its_server(lbr4p, capsys):
    viewer = MeshcatViewer(lbr4p, q=LBR4P_Q0)
    server = viewer.server
    try:
        assert f"Meshcat viewer: {viewer.url}" in capsys.readouterr().out
        assert viewer.url.startswith("http://127.0.0.1:")
        controller = LocalController(lbr4p, Circle(0.5), 0.05)
        start = time.perf_counter()
        result = run_mujoco(controller, LBR4P_Q0, on_sample=viewer.follow(controller, speed=1.0))
        wall = time.perf_counter() - start
        assert result.metrics.completed
        assert 0.45 <= wall < 5.0  # real time, and nothing waited for a browser
        start = time.perf_counter()
        viewer.play(result.log, speed=50.0)
        assert time.perf_counter() - start < 2.0
        assert viewer.active
        html = viewer.static_html()  # the live scene, from the server
        assert "/meshcat/dqcontrol/trace" in {c["path"] for c in _commands(html)}
    finally:
        viewer.close()
    assert not server.running
    viewer.display(LBR4P_Q0)  # a closed viewer ignores drawing calls


def test_viewer_switches_itself_off_when_the_server_dies(lbr4p, monkeypatch):
    monkeypatch.setattr(meshcat_viewer, "REQUEST_TIMEOUT_S", 0.5)
    with MeshcatServer() as server, MeshcatViewer(lbr4p, server=server, print_url=False) as v:
        os.kill(server.pid, signal.SIGKILL)
        server._proc.wait(timeout=5)
        start = time.perf_counter()
        with pytest.warns(RuntimeWarning, match="stopped answering"):
            v.display(LBR4P_Q0)
        assert not v.active
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # warned once only
            v.display(LBR4P_Q0)
            v.show_target(np.array([1.0, 0, 0, 0, 0, 0, 0, 0]))
        assert time.perf_counter() - start < 3.0


def test_server_dies_with_its_parent_process(tmp_path):
    script = (
        "import time\nfrom dqcontrol.viz.meshcat_viewer import MeshcatServer\n"
        "s = MeshcatServer()\nprint(s.pid, flush=True)\ntime.sleep(60)\n"
    )
    parent = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    try:
        pid = int(parent.stdout.readline())
        os.kill(parent.pid, signal.SIGKILL)  # no atexit, no cleanup: only the stdin watchdog
        parent.wait(timeout=5)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and _alive(pid):
            time.sleep(0.1)
        assert not _alive(pid), "the meshcat server outlived its parent"
    finally:
        if parent.poll() is None:
            parent.kill()


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split()[2] != "Z"
    except FileNotFoundError:
        return False


# ---------------------------------------------------------------------- in a real browser
def _screenshot(url: str, png: Path, *, live: bool) -> np.ndarray:
    """Headless Chromium screenshot (800×600) of ``url``; returns the RGB image in [0, 1]."""
    args = [
        CHROMIUM,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--enable-unsafe-swiftshader",
        "--use-angle=swiftshader",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={png.parent / (png.stem + '_profile')}",
        "--window-size=800,600",
        # a page with a live websocket never goes idle, so virtual time never runs out
        *([] if live else ["--virtual-time-budget=1500"]),
        f"--screenshot={png}",
        url,
    ]
    proc = subprocess.Popen(
        args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True
    )
    try:
        _, err = proc.communicate(timeout=45)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        pytest.fail(f"chromium did not finish a screenshot of {url}")
    assert png.is_file(), f"no screenshot: {err.decode(errors='replace')[-2000:]}"
    return imread(png)[..., :3]


def _orange(rgb: np.ndarray) -> np.ndarray:
    """Pixels of the LBR4p's orange (URDF material kuka_orange 0.96, 0.45, 0.05), lit."""
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return (r > 0.55) & (g > 0.12) & (g < 0.75 * r) & (b < 0.45 * g) & (r - b > 0.4)


@needs_chromium
def test_browser_draws_the_robot_of_the_replay_html(lbr4p, mujoco_run, tmp_path):
    result, trajectory = mujoco_run
    html = export_replay_html(
        lbr4p, result.log, tmp_path / "replay.html", path_points=trajectory.path_positions(200)
    )
    # the same scene without the robot
    bare = MeshcatViewer(lbr4p, live=False, q=result.log.q[0])
    bare.show_path(trajectory.path_positions(200))
    bare.frame_scene(trajectory.path_positions(200))
    bare.vis["dqcontrol/robot"].set_property("visible", False)
    bare_html = bare.save_html(tmp_path / "bare.html")

    shot = _screenshot(html.as_uri(), tmp_path / "replay.png", live=False)
    bare_shot = _screenshot(bare_html.as_uri(), tmp_path / "bare.png", live=False)
    robot_pixels = _orange(shot)
    assert robot_pixels.mean() > 0.02, f"robot covers {100 * robot_pixels.mean():.2f} % only"
    assert _orange(bare_shot).mean() < 0.001
    changed = np.any(np.abs(shot - bare_shot) > 0.1, axis=-1)
    assert changed.mean() > 0.02
    # the arm is where the pixels changed, not somewhere else
    assert (robot_pixels & changed).sum() > 0.9 * robot_pixels.sum()


class _SlowFrameHandler(http.server.BaseHTTPRequestHandler):
    """Serves a page framing ``live_url`` whose load event waits ``delay_s`` (an image that
    comes late): headless Chromium takes its screenshot at the load event, so the framed
    viewer has had that long to receive the scene over its websocket."""

    live_url = ""
    delay_s = 3.0

    def do_GET(self):  # noqa: N802 - http.server's naming
        if self.path.startswith("/late.gif"):
            time.sleep(self.delay_s)
            body, kind = base64.b64decode(_GIF_1PX), "image/gif"
        else:
            body = (
                '<html><body style="margin:0;overflow:hidden">'
                f'<iframe src="{self.live_url}" style="border:0;width:800px;height:600px">'
                '</iframe><img src="/late.gif" style="position:absolute;left:0;top:0">'
                "</body></html>"
            ).encode()
            kind = "text/html"
        self.send_response(200)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, *args):
        pass


_GIF_1PX = "R0lGODlhAQABAIAAAP///wAAACH5BAEAAAAALAAAAAABAAEAAAICRAEAOw=="


def _screenshot_live(url: str, png: Path, delay_s: float) -> np.ndarray:
    handler = type("Handler", (_SlowFrameHandler,), {"live_url": url, "delay_s": delay_s})
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        return _screenshot(f"http://127.0.0.1:{server.server_port}/", png, live=True)
    finally:
        server.shutdown()
        server.server_close()


@needs_chromium
def test_browser_draws_the_robot_of_the_live_viewer_during_a_run(lbr4p, tmp_path):
    with MeshcatViewer(lbr4p, q=LBR4P_Q0, print_url=False) as viewer:
        # A 20 s task at 0.15x is over two minutes of wall time: it cannot end by itself
        # before a browser on a loaded machine has looked; the test stops it early.
        controller = LocalController(lbr4p, Circle(20.0), 0.05)
        follow = viewer.follow(controller, speed=0.15)
        done, stop = threading.Event(), threading.Event()
        errors: list[BaseException] = []

        def on_sample(k, sim, result):
            follow(k, sim, result)
            if stop.is_set():
                raise KeyboardInterrupt  # the loop's own way to stop early

        def run():
            try:
                run_mujoco(controller, LBR4P_Q0, on_sample=on_sample)
            except BaseException as error:  # reported by the test's thread below
                errors.append(error)
            finally:
                done.set()

        thread = threading.Thread(target=run, daemon=True)
        thread.start()
        try:
            time.sleep(0.5)  # the run is under way
            # A loaded machine may take longer than 3 s to send the meshes and draw them:
            # the browser looks again, later, in a fresh profile, while the run goes on.
            for attempt, delay_s in enumerate((3.0, 10.0, 25.0)):
                shot = _screenshot_live(viewer.url, tmp_path / f"live{attempt}.png", delay_s)
                if _orange(shot).mean() > 0.01:
                    break
            still_running = not done.is_set()
        finally:
            stop.set()
            thread.join(timeout=30)
        assert not errors, f"the run failed: {errors!r}"
        assert still_running, "the run ended before the browser looked"
        assert viewer.active
    robot = _orange(shot)
    assert robot.mean() > 0.01, f"robot covers {100 * robot.mean():.2f} % only"


# ---------------------------------------------------------------------- obstacles
def _object_paths(html: str) -> set[str]:
    blobs = re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    cmds = [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]
    return {c["path"] for c in cmds if c["type"] == "set_object"}


def _transforms(html: str) -> dict[str, np.ndarray]:
    blobs = re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    cmds = [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]
    return {
        c["path"]: np.array(c["matrix"], dtype=float).reshape(4, 4).T
        for c in cmds
        if c["type"] == "set_transform"
    }


def test_the_viewer_draws_every_shape_where_it_is():
    shapes = (
        Sphere(name="ball", position_m=(0.5, 0.0, 0.6), radius_m=0.05),
        Box(name="crate", position_m=(0.3, -0.5, 0.4), size_m=(0.2, 0.1, 0.3)),
        Capsule(name="pole", position_m=(-0.4, 0.3, 0.8), radius_m=0.04, length_m=0.5),
        Cylinder(name="drum", position_m=(0.0, 0.6, 0.4), radius_m=0.1, length_m=0.3),
        HalfSpace(name="table", normal=(0.0, 0.0, 1.0), offset_m=0.45),
    )
    viewer = MeshcatViewer(load_lbr4p(), live=False, q=LBR4P_Q0)
    viewer.show_obstacles(shapes)
    html = viewer.static_html()
    paths = _object_paths(html)
    root = "/meshcat/dqcontrol/obstacles"
    for name, parts in (("ball", 1), ("crate", 1), ("pole", 3), ("drum", 1), ("table", 1)):
        assert {f"{root}/{name}/{k}" for k in range(parts)} <= paths
    moves = _transforms(html)
    assert np.allclose(moves[f"{root}/ball/0"][:3, 3], [0.5, 0.0, 0.6])
    # the capsule's end spheres lie on its axis, half a length from the centre
    assert np.allclose(moves[f"{root}/pole/1"][:3, 3], [-0.4, 0.3, 0.55])
    # meshcat's cylinder runs along y: drawn turned onto the world z axis
    assert np.allclose(moves[f"{root}/drum/0"][:3, :3] @ [0, 1, 0], [0, 0, 1], atol=1e-12)
    # the table's slab has its top on the plane
    assert moves[f"{root}/table/0"][2, 3] == pytest.approx(0.45 - 0.005)


# ---------------------------------------------------------------------- helpers
def test_decimate_keeps_the_ends_and_at_most_the_count():
    from dqcontrol.viz.meshcat_viewer import _decimate

    points = np.arange(3000, dtype=float).reshape(1000, 3)
    few = _decimate(points, 7)
    assert few.shape == (7, 3)
    np.testing.assert_array_equal(few[[0, -1]], points[[0, -1]])
    np.testing.assert_array_equal(_decimate(points[:5], 7), points[:5])


def test_tube_rings_lie_at_the_radius_around_the_polyline():
    from dqcontrol.viz.meshcat_viewer import _tube

    points = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.1, 0.1, 0.0]])
    tube = _tube(points, 0.003, sides=6)
    vertices = np.asarray(tube.vertices, dtype=float).reshape(3, 6, 3)
    np.testing.assert_allclose(
        np.linalg.norm(vertices - points[:, None, :], axis=2), 0.003, rtol=1e-5
    )
    assert np.asarray(tube.faces).shape == (2 * 2 * 6, 3)  # two quads of two triangles a side
    assert np.asarray(tube.faces).max() == 3 * 6 - 1


def test_frame_samples_pace_the_log_at_the_speed():
    from dqcontrol.viz.meshcat_viewer import _frame_samples

    log = _Log(np.arange(11) * 0.1, {"period_s": 0.1})
    samples = _frame_samples(log, fps=10.0, speed=1.0)
    # 1.1 s at 10 frames a second: 12 frames, one sample each, the last on the last frame
    np.testing.assert_array_equal(samples, [*range(11), 10])
    fast = _frame_samples(log, fps=10.0, speed=2.0)
    np.testing.assert_array_equal(fast, [0, 2, 4, 6, 8, 10, 10])


class _Log:
    """A log stand-in: ``t_s`` [s], ``meta`` and a length."""

    def __init__(self, t_s: np.ndarray, meta: dict) -> None:
        self.t_s, self.meta = t_s, meta

    def __len__(self) -> int:
        return len(self.t_s)


@pytest.mark.parametrize("speed", [0, -1, float("nan"), float("inf"), "fast", None])
def test_a_bad_speed_is_refused(speed):
    from dqcontrol.errors import ParameterError
    from dqcontrol.viz.meshcat_viewer import _check_speed

    assert _check_speed("0.5") == 0.5
    with pytest.raises(ParameterError, match=r"speed must be .*\(1 = real time\)"):
        _check_speed(speed)
