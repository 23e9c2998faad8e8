"""The robot in the browser: Meshcat, live during a run or as a self-contained HTML replay.

One description of the robot feeds everything: the viewer builds Pinocchio's visual
``GeometryModel`` from the *same* URDF the controller's model and the MuJoCo simulation read
(``robot.source``, with the same locked joints and base placement) and draws it with
Pinocchio's :class:`pinocchio.visualize.MeshcatVisualizer`.

Two ways to use it:

* **Live** (:class:`MeshcatViewer` with ``live=True``): a local meshcat server is started
  as a child process (ZeroMQ on ``127.0.0.1``, no network), its URL is printed, and
  :meth:`MeshcatViewer.follow` returns the ``on_sample`` callback of
  :func:`~dqcontrol.sim.run_mujoco` that moves the robot, grows the end-effector trace and
  places the target frame, paced to real time times a speed factor. The server answers
  whether or not a browser is connected, so nothing ever waits for one; every request has
  a time-out, after which the viewer switches itself off with a warning. The server is
  stopped by :meth:`MeshcatViewer.close`, at interpreter exit, and — if this process is
  killed — by itself, when its standard input (a pipe from this process) closes.
* **Replay** (:func:`export_replay_html`, or ``live=False``): the scene is recorded in
  process by meshcat's own server code, without a server, with a meshcat ``Animation`` of
  the run (robot configurations over time, target frame, growing trace) and exported with
  ``static_html()`` as one HTML file (meshcat's JavaScript included) that plays offline in
  any browser.

Scene layout (meshcat paths under ``/meshcat/<root>``, ``root = "dqcontrol"``):
``robot`` (placed at the robot's base; Pinocchio's ``visuals`` below it), ``path`` (the
reference path, a tube), ``trace`` (the end-effector's path so far), ``target`` (the target
frame ``x_d(σ)``, an RGB triad for its x, y, z axes).
"""

from __future__ import annotations

import atexit
import contextlib
import io
import math
import os
import queue
import subprocess
import sys
import threading
import time
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from dqcontrol.dq.algebra import dq_to_matrix, translation
from dqcontrol.errors import DQControlError, ParameterError
from dqcontrol.extras import available, missing_extra, require
from dqcontrol.model.pinocchio_model import build_angle_model, lock_joints
from dqcontrol.model.robot import RobotModel

__all__ = [
    "MeshcatServer",
    "MeshcatViewer",
    "OfflineWindow",
    "SampleFollower",
    "ViewerError",
    "export_replay_html",
    "robot_visual_models",
]

#: Seconds to wait for the meshcat server to start, and for any reply of it.
SERVER_START_TIMEOUT_S = 30.0
REQUEST_TIMEOUT_S = 10.0
#: Colours (0xRRGGBB) of the reference path, the trace and the target triad's axes.
PATH_COLOR = 0x1F3A93
TRACE_COLOR = 0xD62728
AXIS_COLORS = (0xE41A1C, 0x4DAF4A, 0x377EB8)
#: Radii [m] of the path and trace tubes; length [m] of the target triad's axes.
PATH_RADIUS_M = 0.003
#: Colour and opacity of the obstacles.
OBSTACLE_COLOR = 0x8E5BC4
OBSTACLE_OPACITY = 0.55
#: A half-space is drawn as a slab this wide [m] and this thick [m], its top on the plane.
PLANE_DRAWN_SIZE_M = 2.0
PLANE_DRAWN_THICKNESS_M = 0.01
TRACE_RADIUS_M = 0.004
TRIAD_LENGTH_M = 0.08

# The server runs meshcat's own ``main()`` after starting a thread that ends the process
# when its standard input closes: the pipe from this process closes when this process exits,
# however it exits (even on SIGKILL), so the server never outlives its viewer.
_SERVER_MAIN = """
import os, sys, threading
def _watch_parent():
    try:
        sys.stdin.buffer.read()
    finally:
        os._exit(0)
threading.Thread(target=_watch_parent, daemon=True).start()
sys.argv = ["meshcat-server"]
from meshcat.servers.zmqserver import main
main()
"""


class ViewerError(DQControlError):
    """The meshcat viewer could not start or stopped answering."""


# ---------------------------------------------------------------------- the server
class MeshcatServer:
    """A local meshcat server in a child process (ZeroMQ and HTTP on ``127.0.0.1``).

    Attributes:
        zmq_url: where the Python side sends commands (``tcp://127.0.0.1:6000``...).
        web_url: what a browser opens (``http://127.0.0.1:7000/static/``...).

    Stopped by :meth:`close` (also a context manager), at interpreter exit, or by itself
    when this process dies. Raises :class:`ViewerError` if it does not start in
    ``timeout_s`` seconds.
    """

    def __init__(self, *, timeout_s: float = SERVER_START_TIMEOUT_S) -> None:
        if not available("meshcat"):
            raise missing_extra("meshcat", extra="viz", purpose="the Meshcat server")
        env = dict(os.environ)
        env.pop("PYTHONSTARTUP", None)
        try:
            self._proc: subprocess.Popen | None = subprocess.Popen(
                [sys.executable, "-u", "-c", _SERVER_MAIN],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,
                env=env,
                start_new_session=True,  # Ctrl-C in a terminal is ours to handle
            )
        except OSError as exc:
            raise ViewerError(f"cannot start the meshcat server: {exc}") from None
        atexit.register(self.close)
        lines: queue.Queue[str | None] = queue.Queue()
        # Drain the server's output for its whole life, so that it never blocks on a pipe.
        threading.Thread(target=_pump_lines, args=(self._proc.stdout, lines), daemon=True).start()
        urls: dict[str, str] = {}
        deadline = time.monotonic() + timeout_s
        while len(urls) < 2:
            remaining = deadline - time.monotonic()
            try:
                line = lines.get(timeout=max(remaining, 0.0)) if remaining > 0 else None
            except queue.Empty:
                line = None
            if line is None:
                code = self._proc.poll()
                self.close()
                why = f"exited with code {code}" if code is not None else "did not answer"
                raise ViewerError(
                    f"the meshcat server {why} within {timeout_s:g} s; run "
                    f"'{sys.executable} -m meshcat.servers.zmqserver' to see why"
                )
            key, _, value = line.strip().partition("=")
            if key in ("zmq_url", "web_url"):
                urls[key] = value
        self.zmq_url = urls["zmq_url"]
        self.web_url = urls["web_url"]

    @property
    def running(self) -> bool:
        """Whether the server process is alive."""
        return self._proc is not None and self._proc.poll() is None

    @property
    def pid(self) -> int | None:
        """Process id of the server (``None`` once closed)."""
        return None if self._proc is None else self._proc.pid

    def close(self) -> None:
        """Stop the server (idempotent)."""
        proc, self._proc = self._proc, None
        atexit.unregister(self.close)
        if proc is None:
            return
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(timeout=3.0)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=3.0)
        for pipe in (proc.stdin, proc.stdout):
            if pipe is not None:
                with contextlib.suppress(OSError):
                    pipe.close()

    def __enter__(self) -> MeshcatServer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        state = "running" if self.running else "closed"
        return f"MeshcatServer({state}, web_url={getattr(self, 'web_url', None)!r})"


def _pump_lines(stream, lines: queue.Queue) -> None:
    try:
        for raw in iter(stream.readline, b""):
            lines.put(raw.decode("utf-8", "replace"))
    except (OSError, ValueError):
        pass
    lines.put(None)


class _ReplySocket:
    """Stands in for the server's ZeroMQ reply socket: keeps the last reply."""

    def __init__(self) -> None:
        self.reply = b""

    def send(self, data: bytes) -> None:
        self.reply = data


class OfflineWindow:
    """A meshcat "window" with no server: meshcat's own server code records the scene in
    this process, so that ``Visualizer.static_html()`` works without sockets.

    It is meshcat's ``ZMQWebSocketBridge`` (the server) fed directly: every command goes
    through the server's ``handle_zmq`` exactly as if it had come over ZeroMQ, and
    ``get_scene`` returns the server's own static HTML.
    """

    def __init__(self) -> None:
        from meshcat.servers.tree import SceneTree

        with warnings.catch_warnings():  # meshcat imports pyzmq's deprecated ioloop module
            warnings.simplefilter("ignore", DeprecationWarning)
            from meshcat.servers.zmqserver import ZMQWebSocketBridge

        bridge = object.__new__(ZMQWebSocketBridge)  # no sockets, no ports, no event loop
        bridge.tree = SceneTree()
        bridge.websocket_pool = set()
        bridge.zmq_socket = _ReplySocket()
        self._bridge = bridge
        self.web_url = None

    def send(self, command) -> None:
        """Apply a meshcat command to the recorded scene."""
        import umsgpack

        data = command.lower()
        frames = [data["type"].encode(), data["path"].encode(), umsgpack.packb(data)]
        self._bridge.handle_zmq(frames)

    def get_scene(self) -> str:
        """The recorded scene as meshcat's static HTML."""
        self._bridge.handle_zmq([b"get_scene"])
        return self._bridge.zmq_socket.reply.decode("utf-8")

    def close(self) -> None:
        """Nothing to release."""


# ---------------------------------------------------------------------- robot geometry
def robot_visual_models(robot: RobotModel) -> tuple[pin.Model, pin.GeometryModel]:
    """Pinocchio model and visual ``GeometryModel`` of ``robot``, from its own URDF.

    The URDF of ``robot.source`` is read with its meshes as the files found at load, and
    the model is reduced by the same locked joints, with the same angle coordinate for
    continuous joints, so ``q`` of the robot is ``q`` of the returned model. The base
    placement is *not* applied (the viewer places the robot's root node instead).

    Raises:
        ParameterError: the robot has no URDF source, or its joints differ.
    """
    src = robot.source
    if src is None:
        raise ParameterError(
            "the robot has no URDF source; build it with RobotModel.from_urdf or a loader"
        )
    visual = pin.GeometryType.VISUAL
    model = build_angle_model(src.xml)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        geom = pin.buildGeomFromUrdfString(model, src.xml_with_mesh_paths(), visual)
    model, geom = lock_joints(model, robot.locked_joints, geom)
    names = [model.names[j] for j in range(1, model.njoints)]
    if names != robot.joint_names:
        raise ParameterError(
            f"the URDF's joints {names} differ from the robot's {robot.joint_names}"
        )
    return model, geom


# ---------------------------------------------------------------------- geometry helpers
def _tube(points: np.ndarray, radius: float, sides: int = 8):
    """A tube of ``radius`` [m] along a polyline ``(N, 3)``, as a meshcat triangle mesh."""
    import meshcat.geometry as mg

    pts = np.asarray(points, dtype=float)
    if pts.shape[0] >= 2:
        keep = np.concatenate(([True], np.linalg.norm(np.diff(pts, axis=0), axis=1) > 1e-9))
        pts = pts[keep]
    if pts.shape[0] < 2:
        pts = np.vstack((pts[:1], pts[:1] + [0.0, 0.0, 1e-6])) if pts.size else np.zeros((2, 3))
    tangents = np.gradient(pts, axis=0)
    tangents /= np.maximum(np.linalg.norm(tangents, axis=1, keepdims=True), 1e-12)
    # A normal that turns with the curve (parallel transport would be smoother; this is
    # enough for a tube of a few millimetres).
    ref = np.where(np.abs(tangents[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    n1 = np.cross(tangents, ref)
    n1 /= np.linalg.norm(n1, axis=1, keepdims=True)
    n2 = np.cross(tangents, n1)
    angles = np.linspace(0.0, 2.0 * math.pi, sides, endpoint=False)
    ring = (
        np.cos(angles)[None, :, None] * n1[:, None, :]
        + np.sin(angles)[None, :, None] * (n2[:, None, :])
    )
    vertices = (pts[:, None, :] + radius * ring).reshape(-1, 3)
    i = np.arange(pts.shape[0] - 1)[:, None] * sides
    j = np.arange(sides)[None, :]
    a, b = i + j, i + (j + 1) % sides
    c, d = a + sides, b + sides
    faces = np.concatenate((np.stack((a, b, c), -1), np.stack((b, d, c), -1)), axis=1)
    return mg.TriangularMeshGeometry(vertices.astype(np.float32), faces.reshape(-1, 3))


def _decimate(points: np.ndarray, max_points: int) -> np.ndarray:
    """At most ``max_points`` of a polyline, first and last kept."""
    if points.shape[0] <= max_points:
        return points
    idx = np.unique(np.linspace(0, points.shape[0] - 1, max_points).round().astype(int))
    return points[idx]


def _material(color: int, opacity: float = 1.0):
    import meshcat.geometry as mg

    mat = mg.MeshLambertMaterial(color=color)
    if opacity < 1.0:
        mat.transparent = True
        mat.opacity = opacity
    return mat


def _obstacle_parts(obs) -> list[tuple[object, np.ndarray]]:
    """Meshcat geometries and world transforms that draw one obstacle."""
    import meshcat.geometry as mg

    from dqcontrol.model.collision import Box, Capsule, Cylinder, HalfSpace, Sphere

    if isinstance(obs, HalfSpace):
        normal = np.array(obs.normal)
        axis = np.cross([0.0, 0.0, 1.0], normal)
        sin, cos = float(np.linalg.norm(axis)), float(normal[2])
        rot = np.eye(3)
        if sin > 1e-12:
            rot = pin.AngleAxis(math.atan2(sin, cos), axis / sin).matrix()
        elif cos < 0.0:
            rot = np.diag([1.0, -1.0, -1.0])
        matrix = np.eye(4)
        matrix[:3, :3] = rot
        matrix[:3, 3] = normal * (obs.offset_m - 0.5 * PLANE_DRAWN_THICKNESS_M)
        size = [PLANE_DRAWN_SIZE_M, PLANE_DRAWN_SIZE_M, PLANE_DRAWN_THICKNESS_M]
        return [(mg.Box(size), matrix)]
    world = obs.placement().homogeneous
    if isinstance(obs, Sphere):
        return [(mg.Sphere(obs.radius_m), world)]
    if isinstance(obs, Box):
        return [(mg.Box(list(obs.size_m)), world)]
    # meshcat's cylinder runs along its local y axis: turn it onto z
    upright = np.eye(4)
    upright[:3, :3] = pin.AngleAxis(math.pi / 2, np.array([1.0, 0.0, 0.0])).matrix()
    parts = [(mg.Cylinder(obs.length_m, obs.radius_m), world @ upright)]
    if isinstance(obs, Capsule):
        for end in (-0.5, 0.5):
            cap = np.eye(4)
            cap[2, 3] = end * obs.length_m
            parts.append((mg.Sphere(obs.radius_m), world @ cap))
    elif not isinstance(obs, Cylinder):
        raise ParameterError(f"cannot draw obstacle {obs!r}")
    return parts


# ---------------------------------------------------------------------- the viewer
class MeshcatViewer:
    """The robot of a :class:`~dqcontrol.model.RobotModel` in Meshcat, with path, trace
    and target.

    Args:
        robot: the robot; its URDF (``robot.source``) provides the geometry.
        live: start a local meshcat server and print its URL (``True``), or record the
            scene in process for :meth:`static_html` only (``False``, no server).
        server: an already running :class:`MeshcatServer` to use (live mode); it is then
            not closed by :meth:`close`.
        q: configuration [rad] to show first (default: the middle of the joint limits).
        print_url: print the URL of a live viewer on stdout.
        root: name of the scene's root node.

    Raises:
        ViewerError: the server did not start.
        ParameterError: the robot has no URDF source.
    """

    def __init__(
        self,
        robot: RobotModel,
        *,
        live: bool = True,
        server: MeshcatServer | None = None,
        q: np.ndarray | None = None,
        print_url: bool = True,
        root: str = "dqcontrol",
    ) -> None:
        with warnings.catch_warnings():  # meshcat imports pyzmq's deprecated ioloop module
            warnings.simplefilter("ignore", DeprecationWarning)
            meshcat = require("meshcat", extra="viz", purpose="the Meshcat viewer")
            from pinocchio.visualize import MeshcatVisualizer

        self.robot = robot
        self.root = root
        self._own_server = None
        self._failed = False
        model, geom = robot_visual_models(robot)
        if live:
            if server is None:
                server = self._own_server = MeshcatServer()
            self.server: MeshcatServer | None = server
            try:
                with contextlib.redirect_stdout(io.StringIO()):  # meshcat prints its URL
                    self.vis = meshcat.Visualizer(zmq_url=server.zmq_url)
            except Exception as exc:  # any failure of the client
                self.close()
                raise ViewerError(f"cannot connect to the meshcat server: {exc}") from None
            self._set_timeouts()
        else:
            self.server = None
            self.vis = meshcat.Visualizer(window=OfflineWindow())
        self.url: str | None = self.server.web_url if self.server is not None else None
        self._pin_viz = MeshcatVisualizer(model, None, geom)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # meshcat < 0.4 lacks get_image: irrelevant here
            self._pin_viz.initViewer(viewer=self.vis)
        self._robot_node = f"{root}/robot"
        self._guard(self._load_robot)
        if q is None:
            lim = robot.limits
            q = np.where(
                np.isfinite(lim.q_min) & np.isfinite(lim.q_max), 0.5 * (lim.q_min + lim.q_max), 0.0
            )
        self.q = np.asarray(q, dtype=float)
        self.display(self.q)
        self._trace_points: list[np.ndarray] = []
        self._framed_path = False
        self.frame_scene()
        if live and print_url:
            print(f"Meshcat viewer: {self.url}", flush=True)

    # ------------------------------------------------------------------ plumbing
    def _set_timeouts(self) -> None:
        import zmq

        sock = self.vis.window.zmq_socket
        timeout_ms = int(REQUEST_TIMEOUT_S * 1000)
        sock.setsockopt(zmq.RCVTIMEO, timeout_ms)
        sock.setsockopt(zmq.SNDTIMEO, timeout_ms)
        sock.setsockopt(zmq.LINGER, 0)

    def _guard(self, fn, *args, **kwargs):
        """Run a drawing call; on a dead or silent server switch the viewer off, warn once."""
        if self._failed:
            return None
        try:
            return fn(*args, **kwargs)
        except Exception as exc:  # zmq.Again (time-out), zmq.ZMQError, OSError ...
            if self.server is None:
                raise
            self._failed = True
            warnings.warn(
                f"the meshcat viewer stopped answering ({type(exc).__name__}: {exc}); "
                "continuing without it",
                RuntimeWarning,
                stacklevel=3,
            )
            return None

    @property
    def active(self) -> bool:
        """False once a live viewer has failed (drawing calls are then no-ops)."""
        return not self._failed

    def _load_robot(self) -> None:
        self._pin_viz.loadViewerModel(rootNodeName=self._robot_node)
        self.vis[self._robot_node].set_transform(self.robot.base_placement.homogeneous)

    # ------------------------------------------------------------------ drawing
    def display(self, q: np.ndarray) -> None:
        """Place the robot at ``q`` [rad]."""
        q = self.robot.check_q(q)
        self.q = q
        self._guard(self._pin_viz.display, q)

    def show_path(self, points_m: np.ndarray, *, color: int = PATH_COLOR) -> None:
        """Draw the reference path through world positions ``(N, 3)`` [m] (a thin tube)."""
        pts = _decimate(np.asarray(points_m, dtype=float).reshape(-1, 3), 2000)
        self._guard(
            self.vis[f"{self.root}/path"].set_object,
            _tube(pts, PATH_RADIUS_M),
            _material(color, 0.8),
        )

    def clear_trace(self) -> None:
        """Forget the end-effector trace."""
        self._trace_points = []
        self._guard(self.vis[f"{self.root}/trace"].delete)

    def add_trace_point(self, position_m: np.ndarray) -> None:
        """Append a world position [m] to the trace (drawn by :meth:`draw_trace`)."""
        self._trace_points.append(np.asarray(position_m, dtype=float).reshape(3))

    def draw_trace(self, *, color: int = TRACE_COLOR) -> None:
        """Draw the end-effector trace collected so far."""
        if len(self._trace_points) < 2:
            return
        pts = _decimate(np.array(self._trace_points), 1500)
        self._guard(
            self.vis[f"{self.root}/trace"].set_object, _tube(pts, TRACE_RADIUS_M), _material(color)
        )

    def show_obstacles(
        self, obstacles: Sequence, *, color: int = OBSTACLE_COLOR, opacity: float = OBSTACLE_OPACITY
    ) -> None:
        """Draw obstacles (:mod:`dqcontrol.model.collision`) at their world poses, replacing
        any drawn before; a half-space is a square slab whose top is the plane."""
        self._guard(self.vis[f"{self.root}/obstacles"].delete)
        for k, obs in enumerate(obstacles):
            node = self.vis[f"{self.root}/obstacles/{obs.name or k}"]
            for part, (geometry, matrix) in enumerate(_obstacle_parts(obs)):
                self._guard(node[str(part)].set_object, geometry, _material(color, opacity))
                self._guard(node[str(part)].set_transform, matrix)

    def show_target(self, pose: np.ndarray) -> None:
        """Place the target frame at a pose (unit dual quaternion vec8, or a 4×4 matrix)."""
        pose = np.asarray(pose, dtype=float)
        matrix = dq_to_matrix(pose) if pose.shape == (8,) else pose.reshape(4, 4)
        node = self.vis[f"{self.root}/target"]
        if not getattr(self, "_triad_loaded", False):
            self._triad_loaded = True
            self._guard(self._load_triad, node)
        self._guard(node.set_transform, matrix)

    @staticmethod
    def _load_triad(node) -> None:
        import meshcat.geometry as mg
        import meshcat.transformations as tf

        length, radius = TRIAD_LENGTH_M, 0.1 * TRIAD_LENGTH_M
        # meshcat's cylinder runs along its local y axis; turn it onto x, y and z.
        turns = (
            tf.rotation_matrix(-math.pi / 2, [0, 0, 1]),
            np.eye(4),
            tf.rotation_matrix(math.pi / 2, [1, 0, 0]),
        )
        for name, turn, color in zip("xyz", turns, AXIS_COLORS, strict=True):
            axis = node[name]
            axis.set_object(mg.Cylinder(length, radius), _material(color))
            shift = tf.translation_matrix([0.0, 0.5 * length, 0.0])
            axis.set_transform(turn @ shift)

    def set_camera(self, target_m: np.ndarray, offset_m: np.ndarray) -> None:
        """Look at world point ``target_m`` [m] from ``target_m + offset_m``.

        Meshcat's camera orbits the origin of its scene, so the scene is shifted instead:
        our root node, meshcat's grid and axes are moved by ``-target_m``.
        """
        import meshcat.transformations as tf

        shift = tf.translation_matrix(-np.asarray(target_m, dtype=float))
        for node in (self.root, "/Grid", "/Axes"):
            self._guard(self.vis[node].set_transform, shift)
        dx, dy, dz = np.asarray(offset_m, dtype=float)
        # the camera's own frame is y-up: world (x, y, z) is (x, z, -y) there
        self._guard(
            self.vis["/Cameras/default/rotated/<object>"].set_property,
            "position",
            [float(dx), float(dz), float(-dy)],
        )

    def frame_scene(
        self, points_m: np.ndarray | None = None, direction: Sequence[float] = (0.5, -1.3, 1.0)
    ) -> None:
        """Aim the camera at the whole robot (at its current ``q``) and ``points_m`` (e.g. the
        path) from ``direction`` (world, default: front-right, above)."""
        model = self._pin_viz.model
        data = self._pin_viz.data
        pin.forwardKinematics(model, data, self.q)
        base = self.robot.base_placement
        pts = [base.act(data.oMi[j].translation) for j in range(model.njoints)]
        if points_m is not None and len(points_m):
            pts.extend(np.asarray(points_m, dtype=float).reshape(-1, 3))
        points = np.array(pts)
        lo, hi = points.min(axis=0), points.max(axis=0)
        size = max(float(np.linalg.norm(hi - lo)), 0.5)
        unit = np.asarray(direction, dtype=float)
        unit /= np.linalg.norm(unit)
        self.set_camera(0.5 * (lo + hi), size * unit)

    # ------------------------------------------------------------------ live runs
    def follow(self, controller, *, speed: float = 1.0, fps: float = 30.0) -> SampleFollower:
        """The ``on_sample`` callback of :func:`~dqcontrol.sim.run_mujoco` that shows the run
        live: robot, trace, target and (at the first sample) the reference path, paced to
        ``speed`` × real time and drawn at most ``fps`` times per second of the display.
        """
        return SampleFollower(self, controller, speed=speed, fps=fps)

    def play(
        self,
        log,
        *,
        speed: float = 1.0,
        fps: float = 30.0,
        path_points: np.ndarray | None = None,
    ) -> None:
        """Play a recorded :class:`~dqcontrol.runs.RunLog` in the (live) viewer, paced to
        ``speed`` × real time (used after the kinematic loop, which has no callback)."""
        speed = _check_speed(speed)
        if len(log) == 0:
            return
        self.clear_trace()
        self.show_path(path_points if path_points is not None else translation(log.target))
        start = time.perf_counter()
        last = -math.inf
        period = 1.0 / fps
        positions = translation(log.pose)
        for k, t in enumerate(log.t_s):
            if not self.active:
                return
            self.add_trace_point(positions[k])
            due = float(t) / speed
            if due - last < period and k < len(log) - 1:
                continue
            lag = due - (time.perf_counter() - start)
            if lag > 0:
                time.sleep(lag)
            self.display(log.q[k])
            self.show_target(log.target[k])
            self.draw_trace()
            last = due

    # ------------------------------------------------------------------ replay
    def set_animation(
        self,
        log,
        *,
        fps: float = 30.0,
        speed: float = 1.0,
        loop: bool = True,
        max_trace_pieces: int = 120,
    ) -> None:
        """Load a meshcat ``Animation`` of a :class:`~dqcontrol.runs.RunLog`: the robot's
        configurations, the target frame and the growing end-effector trace, at ``fps``
        frames per second of ``speed`` × real time. The browser plays it (and loops it if
        ``loop``); its "Animations" menu has play, pause, reset and a time slider.
        """
        from meshcat.animation import Animation

        speed = _check_speed(speed)
        if len(log) == 0:
            raise ParameterError("cannot animate an empty run log")
        sample = _frame_samples(log, fps, speed)
        anim = Animation(default_framerate=fps)
        self._animate_robot(anim, log, sample)
        self._animate_trace(anim, translation(log.pose), sample, max_trace_pieces)
        self.display(log.q[0])
        repetitions = 1_000_000 if loop else 1
        self._guard(self.vis.set_animation, anim, play=True, repetitions=repetitions)

    def _animate_robot(self, anim, log, sample: np.ndarray) -> None:
        """The robot and the target frame at each frame's sample of ``log``."""
        target_node = f"{self.root}/target"
        self.show_target(log.target[0])
        viz = self._pin_viz
        viewer = viz.viewer
        try:
            for frame, k in enumerate(sample):
                with anim.at_frame(self.vis, frame) as frame_vis:
                    viz.viewer = frame_vis  # Pinocchio places the geometry into the frame
                    viz.display(log.q[k])
                    frame_vis[target_node].set_transform(dq_to_matrix(log.target[k]))
        finally:
            viz.viewer = viewer

    def _animate_trace(
        self, anim, positions: np.ndarray, sample: np.ndarray, max_trace_pieces: int
    ) -> None:
        """The end-effector trace as pieces that appear one after the other."""
        n_frames = sample.size
        self._guard(self.vis[f"{self.root}/trace"].delete)
        step = max(1, int(math.ceil((n_frames - 1) / max_trace_pieces)))
        bounds = list(range(0, n_frames - 1, step)) + [n_frames - 1]
        for piece, (f0, f1) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
            k0, k1 = int(sample[f0]), int(sample[f1])
            if k1 <= k0:
                continue
            node = f"{self.root}/trace/{piece:04d}"
            self._guard(
                self.vis[node].set_object,
                _tube(positions[k0 : k1 + 1], TRACE_RADIUS_M),
                _material(TRACE_COLOR),
            )
            with anim.at_frame(self.vis, 0) as frame_vis:
                frame_vis[node].set_property("visible", "boolean", f0 == 0)
            # every clip must last the whole animation: each one loops on its own length
            for frame in sorted({f1, n_frames - 1}):
                with anim.at_frame(self.vis, frame) as frame_vis:
                    frame_vis[node].set_property("visible", "boolean", True)

    def static_html(self) -> str:
        """The scene as one self-contained HTML page (meshcat's ``static_html``)."""
        html = self._guard(self.vis.static_html)
        if html is None:
            raise ViewerError("the meshcat server did not return the scene")
        return html

    def save_html(self, path: str | os.PathLike) -> Path:
        """Write :meth:`static_html` to ``path`` atomically; returns the path."""
        from dqcontrol.runs.storage import atomic_write_text

        return atomic_write_text(path, self.static_html())

    # ------------------------------------------------------------------ lifetime
    def close(self) -> None:
        """Disconnect, and stop the server if this viewer started it (idempotent)."""
        vis = getattr(self, "vis", None)
        if vis is not None and self.server is not None:
            with contextlib.suppress(Exception):
                vis.window.zmq_socket.close(linger=0)
        self._failed = True if self.server is not None else self._failed
        if self._own_server is not None:
            self._own_server.close()
            self._own_server = None

    def __enter__(self) -> MeshcatViewer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        mode = f"live at {self.url}" if self.url else "offline"
        return f"MeshcatViewer({self.robot.ee_frame!r}, {mode})"


def _frame_samples(log, fps: float, speed: float) -> np.ndarray:
    """For each animation frame (``fps`` frames per second of ``speed`` × real time, at
    least two), the index of the log's sample shown: the last one at or before the frame's
    time, the last sample on the last frame."""
    times = np.asarray(log.t_s, dtype=float)
    period = float(log.meta.get("period_s", np.median(np.diff(times)) if len(times) > 1 else 0))
    end_s = float(times[-1] + max(period, 0.0))
    n_frames = max(2, int(math.ceil(end_s / speed * fps)) + 1)
    frame_times = np.minimum(np.arange(n_frames) * speed / fps, times[-1])
    sample = np.clip(np.searchsorted(times, frame_times + 1e-12, side="right") - 1, 0, None)
    sample[-1] = len(log) - 1
    return sample


def _check_speed(speed: float) -> float:
    try:
        value = float(speed)
    except (TypeError, ValueError):
        raise ParameterError(f"speed must be a number > 0 (1 = real time), got {speed!r}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise ParameterError(f"speed must be finite and > 0 (1 = real time), got {speed!r}")
    return value


class SampleFollower:
    """``on_sample(k, simulation, result)`` callback that shows a MuJoCo run live.

    At the first sample it draws the reference path (the controller's trajectory, anchored
    by then) and starts the clock; at every sample it records the end-effector position;
    when ``1/fps`` seconds of display time have passed it sleeps until the simulated time
    divided by ``speed`` is reached (never when the run is slower than that) and draws the
    robot at the simulation's configuration, the target frame and the trace.
    """

    def __init__(self, viewer: MeshcatViewer, controller, *, speed: float, fps: float) -> None:
        self.viewer = viewer
        self.controller = controller
        self.speed = _check_speed(speed)
        self.frame_s = 1.0 / _check_speed(fps)
        self._start = 0.0
        self._last = -math.inf

    def __call__(self, k: int, simulation, result) -> None:
        """Show sample ``k`` of a run (the ``on_sample`` callback), paced to real time."""
        viewer = self.viewer
        if not viewer.active:  # closed or failed: no drawing, no pacing
            return
        period = self.controller.period_s
        if k == 0:
            viewer.clear_trace()
            path = self.controller.trajectory.path_positions(1000)
            viewer.show_path(path)
            if not viewer._framed_path:  # once: later runs keep the user's camera
                viewer._framed_path = True
                viewer.frame_scene(path)
            self._start = time.perf_counter()
            self._last = -math.inf
        viewer.add_trace_point(translation(result.pose))
        sim_t = (k + 1) * period
        due = sim_t / self.speed
        if due - self._last < self.frame_s and not self.controller.done:
            return
        lag = due - (time.perf_counter() - self._start)
        if lag > 0:
            time.sleep(lag)
        q = simulation.measure().q if simulation is not None else None
        if q is not None:
            viewer.display(q)
        viewer.show_target(result.target)
        viewer.draw_trace()
        self._last = due


# ---------------------------------------------------------------------- one-call export
def export_replay_html(
    robot: RobotModel,
    log,
    path: str | os.PathLike,
    *,
    path_points: np.ndarray | None = None,
    fps: float = 30.0,
    speed: float = 1.0,
    loop: bool = True,
    obstacles: Sequence = (),
) -> Path:
    """Write a self-contained HTML replay of a run: ``path`` (``.html``) is returned.

    Args:
        robot: the robot the run used (its URDF gives the geometry).
        log: the :class:`~dqcontrol.runs.RunLog`.
        path: the file to write (``.html``).
        path_points: world positions ``(N, 3)`` [m] of the reference path (e.g.
            ``controller.trajectory.path_positions()``); default: the run's targets.
        fps: frames per second of the animation (:meth:`MeshcatViewer.set_animation`).
        speed: playback speed, 1 = real time (:meth:`MeshcatViewer.set_animation`).
        loop: whether the animation loops (:meth:`MeshcatViewer.set_animation`).
        obstacles: obstacles to draw (:meth:`MeshcatViewer.show_obstacles`).

    No server is started and nothing waits for a browser.
    """
    viewer = MeshcatViewer(robot, live=False, q=log.q[0] if len(log) else None)
    pts = translation(log.target) if path_points is None else np.asarray(path_points)
    viewer.show_path(pts)
    if len(obstacles):
        viewer.show_obstacles(obstacles)
    viewer.frame_scene(np.vstack((pts.reshape(-1, 3), translation(log.pose))))
    viewer.set_animation(log, fps=fps, speed=speed, loop=loop)
    return viewer.save_html(path)
