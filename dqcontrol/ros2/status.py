"""What the control node tells: ``~/status`` (a ``diagnostic_msgs/DiagnosticStatus``) and
RViz markers (``visualization_msgs/Marker``) of the path and the target.

``~/status`` holds, as key-value pairs: ``phase`` (running, done, stopped, waiting),
``sigma_s`` (the phase σ [s]), ``duration_s`` (T_tot [s]), ``s`` (the time scaling),
``path_deviation_m`` [m], ``binding_limit`` (``velocity <joint>``, ``position <joint>``,
``time scaling`` or ``none``), ``stop_reason`` (empty while running), ``rejected_states``
and ``controller``. Its level is OK while the task runs or has ended, WARN after a stop,
ERROR when the robot is gone.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from dqcontrol.dq.algebra import translation

__all__ = ["Status", "binding_limit", "marker_path", "marker_target", "status_message"]

#: How close to a bound counts as binding: 1 % of a velocity bound, 10 mrad of a joint limit.
VELOCITY_FRACTION = 0.99
POSITION_MARGIN_RAD = 0.01


@dataclass(frozen=True)
class Status:
    """One ``~/status`` (module docstring)."""

    phase: str
    sigma_s: float = 0.0
    duration_s: float = 0.0
    s: float = 0.0
    path_deviation_m: float = 0.0
    binding_limit: str = "none"
    stop_reason: str = ""
    rejected_states: int = 0
    controller: str = ""
    level: int = 0


def binding_limit(
    names: tuple[str, ...], q: np.ndarray, u: np.ndarray, s: float,
    q_min: np.ndarray, q_max: np.ndarray, qd_max: np.ndarray,
) -> str:  # fmt: skip
    """The limit that binds the command ``u`` [rad/s] at ``q`` [rad]: a joint at its
    velocity bound, a joint at its position limit moving on, the time scaling, or none."""
    at_speed = np.abs(u) >= VELOCITY_FRACTION * qd_max
    if at_speed.any():
        return f"velocity {names[int(np.argmax(np.abs(u) / qd_max))]}"
    low = (q - q_min < POSITION_MARGIN_RAD) & (u <= 0.0)
    high = (q_max - q < POSITION_MARGIN_RAD) & (u >= 0.0)
    if (low | high).any():
        return f"position {names[int(np.argmax(low | high))]}"
    return "time scaling" if s < 1.0 - 1e-9 else "none"


def status_message(ros: Any, status: Status, stamp: Any) -> Any:
    """``status`` as a ``diagnostic_msgs/DiagnosticStatus`` (``stamp`` is unused by the
    message, kept for symmetry with the markers' headers)."""
    del stamp
    diag = ros.diagnostic
    values = {
        "phase": status.phase,
        "sigma_s": f"{status.sigma_s:.6f}",
        "duration_s": f"{status.duration_s:.6f}",
        "s": f"{status.s:.6f}",
        "path_deviation_m": f"{status.path_deviation_m:.9f}",
        "binding_limit": status.binding_limit,
        "stop_reason": status.stop_reason,
        "rejected_states": str(status.rejected_states),
        "controller": status.controller,
    }
    text = status.phase if not status.stop_reason else f"{status.phase}: {status.stop_reason}"
    return diag.DiagnosticStatus(
        level=bytes([status.level]),
        name="dqcontrol",
        message=text,
        hardware_id="",
        values=[diag.KeyValue(key=k, value=v) for k, v in values.items()],
    )


def _point(ros: Any, p: np.ndarray) -> Any:
    return ros.geometry.Point(x=float(p[0]), y=float(p[1]), z=float(p[2]))


def marker_path(ros: Any, frame_id: str, points_m: np.ndarray, stamp: Any) -> Any:
    """The path as a ``LINE_STRIP`` marker (id 0, namespace ``dqcontrol``), 2 mm wide."""
    vis = ros.visualization.Marker
    marker = vis(type=vis.LINE_STRIP, action=vis.ADD, ns="dqcontrol", id=0)
    marker.header.frame_id, marker.header.stamp = frame_id, stamp
    marker.scale.x = 0.002
    marker.color.g, marker.color.a = 0.8, 1.0
    marker.pose.orientation.w = 1.0
    marker.points = [_point(ros, p) for p in points_m]
    return marker


def marker_target(ros: Any, frame_id: str, target: np.ndarray, stamp: Any) -> Any:
    """The target ``x_d(σ)`` (vec8) as a 1 cm ``SPHERE`` marker (id 1)."""
    vis = ros.visualization.Marker
    marker = vis(type=vis.SPHERE, action=vis.ADD, ns="dqcontrol", id=1)
    marker.header.frame_id, marker.header.stamp = frame_id, stamp
    marker.scale.x = marker.scale.y = marker.scale.z = 0.01
    marker.color.r, marker.color.a = 1.0, 1.0
    marker.pose.position = _point(ros, translation(target))
    marker.pose.orientation.w = 1.0
    return marker
