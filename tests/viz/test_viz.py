"""Viewing runs (``dqcontrol.viz``): the figures, the Meshcat viewer (offline replay and live
server), and — when Chromium is installed — that a real browser draws the robot.

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

import dqcontrol
from dqcontrol.controllers import LocalController, PredictiveController
from dqcontrol.errors import ParameterError
from dqcontrol.model import LBR4P_Q0
from dqcontrol.runs.log import RunLog
from dqcontrol.sim import run_kinematic, run_mujoco
from dqcontrol.trajectories import Circle
from dqcontrol.viz import meshcat_viewer
from dqcontrol.viz.figures import FIGURES, path_plane, plot_comparison, plot_run
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


# ---------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def mujoco_run(lbr4p):
    """A short MuJoCo run of the local controller on the circle (T_tot = 1 s)."""
    controller = LocalController(lbr4p, Circle(1.0), 0.05)
    result = run_mujoco(controller, LBR4P_Q0, meta={"velocity_limits": 3.0})
    return result, controller.trajectory


@pytest.fixture(scope="module")
def kinematic_run(lbr4p):
    controller = PredictiveController(lbr4p, Circle(1.0), 0.05, num_instants=4)
    return run_kinematic(controller, LBR4P_Q0), controller.trajectory


def _assert_image_not_blank(path: Path, min_bytes: int = 5000) -> None:
    assert path.is_file(), path
    assert path.stat().st_size > min_bytes, f"{path.name} is only {path.stat().st_size} bytes"
    rgb = imread(path)[..., :3]
    assert rgb.std() > 0.05, f"{path.name} looks blank (pixel std {rgb.std():.4f})"
    ink = np.mean(np.any(rgb < 0.9, axis=-1))
    assert ink > 0.01, f"{path.name} has almost nothing drawn ({100 * ink:.2f} % of pixels)"


# ---------------------------------------------------------------------- figures
def test_every_figure_of_a_mujoco_run_is_written_and_not_blank(mujoco_run, tmp_path):
    result, trajectory = mujoco_run
    paths = plot_run(result.log, tmp_path, name="local", trajectory=trajectory, dpi=60)
    assert [p.name for p in paths] == [f"local_{f}.png" for f in FIGURES]
    for path in paths:
        _assert_image_not_blank(path)


def test_kinematic_run_has_no_torque_figure_and_svg_on_request(kinematic_run, tmp_path):
    result, trajectory = kinematic_run
    paths = plot_run(result.log, tmp_path, trajectory=trajectory, fmt="svg",
                     figures=("path_2d", "joint_torques"))  # fmt: skip
    assert [p.name for p in paths] == ["run_path_2d.svg"]  # no torques in the kinematic loop
    text = paths[0].read_text()
    assert "<svg" in text and text.count("<path") > 5


def test_figures_without_trajectory_use_the_targets(mujoco_run, tmp_path):
    result, _ = mujoco_run
    (path,) = plot_run(result.log, tmp_path, figures=("path_2d",), dpi=60)
    _assert_image_not_blank(path)


def test_comparison_figure_overlays_runs(mujoco_run, kinematic_run, tmp_path):
    (a, trajectory), (b, _) = mujoco_run, kinematic_run
    path = plot_comparison(
        {"local (MuJoCo)": a.log, "p = 4 (kinematic)": b.log},
        tmp_path / "cmp.png",
        trajectory=trajectory,
        dpi=60,
    )
    _assert_image_not_blank(path, min_bytes=20000)
    # logs without labels are named after their controller
    path = plot_comparison([a.log, b.log], tmp_path / "cmp.svg")
    assert "local" in path.read_text()


def test_path_plane_is_the_circle_plane(mujoco_run):
    _, trajectory = mujoco_run
    ref = trajectory.path_positions(400)
    origin, axes, labels = path_plane(ref, trajectory)
    flat = (ref - origin) @ axes.T  # the circle is centred on the trajectory frame's origin
    np.testing.assert_allclose(np.linalg.norm(flat, axis=1), 0.1, atol=1e-9)
    assert labels[0].startswith("x") and labels[1].startswith("y")
    # without the trajectory: principal axes span the same plane
    origin2, axes2, _ = path_plane(ref)
    assert np.linalg.matrix_rank(np.vstack((axes, axes2)), tol=1e-6) == 2


def test_figure_errors(mujoco_run, tmp_path):
    result, _ = mujoco_run
    with pytest.raises(ParameterError, match="format"):
        plot_run(result.log, tmp_path, fmt="jpg")
    with pytest.raises(ParameterError, match="unknown figures"):
        plot_run(result.log, tmp_path, figures=("path_4d",))
    empty = RunLog.from_arrays({k: v[:0] for k, v in result.log.arrays().items()})
    with pytest.raises(ParameterError, match="empty"):
        plot_run(empty, tmp_path)
    with pytest.raises(ParameterError, match="at least one"):
        plot_comparison({}, tmp_path / "x.png")


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
