"""Figures of runs (matplotlib, PNG by default, SVG on request): the thesis's set per run, and
comparisons of controllers on the same axes.

Per run (:func:`plot_run`), each figure one file ``<name>_<figure>.<fmt>``:

- ``path_2d`` — the executed end-effector path and the reference path in the trajectory's
  plane (the two axes of the trajectory's reference frame along which the path spreads
  most; without a trajectory, the path's two principal directions);
- ``path_3d`` — the same in 3-D (world frame);
- ``translation`` and ``rotation`` — the elements of the measured translation ``t`` [m] and
  rotation quaternion ``r`` against the phase σ, with the target's dashed;
- ``joint_velocities`` — commanded and measured ``qd`` [rad/s] per joint, with the bound
  if the run's ``meta`` holds ``velocity_limits``;
- ``joint_positions`` — ``q`` [rad];
- ``joint_torques`` — the applied torques [N·m] (MuJoCo runs only: the kinematic loop has
  none, and the figure is then not drawn);
- ``scaling`` — the time scaling ``s(t)`` and the phase ``σ(t)`` (with ``σ = t`` dashed).

:func:`plot_comparison` overlays two or more runs: path, translation error, ``s(t)`` and
``σ(t)``. Every function returns the paths it wrote; files are written atomically.

Only matplotlib's object-oriented API is used (``Figure`` with the Agg canvas, no
``pyplot``), so no global backend is set and nothing is shown on screen.
"""

from __future__ import annotations

import io
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dqcontrol.dq.algebra import dq_to_matrix, pose_error, translation
from dqcontrol.errors import ParameterError
from dqcontrol.extras import missing_extra
from dqcontrol.runs.log import RunLog
from dqcontrol.runs.storage import atomic_write_bytes
from dqcontrol.trajectories import Trajectory
from dqcontrol.viz.stop_marks import mark_stop_on_path, shade_stop

try:
    from matplotlib.figure import Figure
except ImportError as exc:
    raise missing_extra(
        "matplotlib", extra="viz", purpose="dqcontrol.viz.figures", reason=str(exc)
    ) from None

__all__ = ["FIGURES", "path_plane", "plot_comparison", "plot_run"]

#: The per-run figures, in the order :func:`plot_run` writes them.
FIGURES = (
    "path_2d",
    "path_3d",
    "translation",
    "rotation",
    "joint_velocities",
    "joint_positions",
    "joint_torques",
    "scaling",
)
_FORMATS = ("png", "svg")
_REF_STYLE: dict[str, Any] = {"color": "0.15", "linestyle": "--", "linewidth": 1.2}


# ---------------------------------------------------------------------- helpers
def _check_format(fmt: str) -> str:
    f = str(fmt).lower().lstrip(".")
    if f not in _FORMATS:
        raise ParameterError(f"figure format must be one of {_FORMATS}, got {fmt!r}")
    return f


def _save(fig: Figure, path: Path, dpi: float) -> Path:
    buffer = io.BytesIO()
    fig.savefig(buffer, format=path.suffix[1:], dpi=dpi)
    return atomic_write_bytes(path, buffer.getvalue())


def _reference_points(log: RunLog, trajectory: Trajectory | None) -> np.ndarray:
    """World positions [m] of the reference path: the trajectory's, else the run's targets."""
    if trajectory is not None and trajectory.reference is not None:
        return trajectory.path_positions(2000)
    return translation(log.target)


def path_plane(
    reference_m: np.ndarray, trajectory: Trajectory | None = None
) -> tuple[np.ndarray, np.ndarray, tuple[str, str]]:
    """The plane in which to draw a path: ``(origin (3,), axes (2, 3), axis labels)``.

    With an anchored ``trajectory``: two axes of its reference frame, those along which the
    reference path spreads most (in axis order), origin at the frame's origin — the circle's
    plane is the frame's xy, the sinusoid's its xz. Otherwise the path's two principal
    directions about its centroid.
    """
    pts = np.asarray(reference_m, dtype=float).reshape(-1, 3)
    if trajectory is not None and trajectory.reference is not None:
        frame = dq_to_matrix(trajectory.reference)
        rot, origin = frame[:3, :3], frame[:3, 3]
        spread = np.ptp((pts - origin) @ rot, axis=0)
        pick = np.sort(np.argsort(spread)[-2:])
        names = ("x", "y", "z")
        labels = tuple(f"{names[i]} in the trajectory frame [m]" for i in pick)
        return origin, rot[:, pick].T, labels  # type: ignore[return-value]
    centre = pts.mean(axis=0)
    if pts.shape[0] < 3:
        return centre, np.eye(3)[:2], ("x [m]", "y [m]")
    _, _, vt = np.linalg.svd(pts - centre, full_matrices=False)
    return centre, vt[:2], ("first principal axis [m]", "second principal axis [m]")


def _project(points: np.ndarray, origin: np.ndarray, axes: np.ndarray) -> np.ndarray:
    return (np.asarray(points, dtype=float).reshape(-1, 3) - origin) @ axes.T


def _label(log: RunLog, fallback: str) -> str:
    return str(log.meta.get("label") or log.meta.get("controller") or fallback)


def _title(log: RunLog, what: str) -> str:
    parts = [what]
    ctrl = log.meta.get("controller")
    if ctrl:
        parts.append(str(ctrl))
    sim = log.meta.get("simulator")
    if sim:
        parts.append(str(sim))
    return " — ".join(parts)


def _joint_grid(fig: Figure, n: int):
    cols = 2 if n > 3 else 1
    rows = int(np.ceil(n / cols))
    axes = fig.subplots(rows, cols, sharex=True, squeeze=False).ravel()
    for ax in axes[n:]:
        ax.set_visible(False)
    return axes[:n], rows, cols


def _equal_3d(ax, pts: np.ndarray) -> None:
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre, half = 0.5 * (lo + hi), 0.5 * max(float(np.max(hi - lo)), 1e-3)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)


# ---------------------------------------------------------------------- per-run figures
def _fig_path_2d(log: RunLog, ref: np.ndarray, trajectory: Trajectory | None) -> Figure:
    origin, axes, labels = path_plane(ref, trajectory)
    fig = Figure(figsize=(5.2, 4.8), layout="constrained")
    ax = fig.add_subplot()
    r2 = _project(ref, origin, axes)
    p2 = _project(translation(log.pose), origin, axes)
    ax.plot(r2[:, 0], r2[:, 1], label="reference", **_REF_STYLE)
    ax.plot(p2[:, 0], p2[:, 1], color="C3", linewidth=1.5, label="end effector")
    ax.plot(p2[:1, 0], p2[:1, 1], "o", color="C3", markersize=4)
    mark_stop_on_path(ax, log, p2)
    ax.set_xlabel(labels[0])
    ax.set_ylabel(labels[1])
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    ax.set_title(_title(log, "path"))
    return fig


def _fig_path_3d(log: RunLog, ref: np.ndarray) -> Figure:
    fig = Figure(figsize=(5.6, 5.0), layout="constrained")
    ax = fig.add_subplot(projection="3d")
    pos = translation(log.pose)
    ax.plot(ref[:, 0], ref[:, 1], ref[:, 2], label="reference", **_REF_STYLE)
    ax.plot(pos[:, 0], pos[:, 1], pos[:, 2], color="C3", linewidth=1.5, label="end effector")
    _equal_3d(ax, np.vstack((ref, pos)))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.legend(loc="upper left", fontsize="small")
    ax.set_title(_title(log, "path (world)"))
    return fig


def _fig_elements(log: RunLog, which: str) -> Figure:
    if which == "translation":
        measured, desired = translation(log.pose), translation(log.target)
        names: tuple[str, ...] = ("t_x", "t_y", "t_z")
        unit = " [m]"
    else:
        measured, desired = log.pose[:, :4], log.target[:, :4]
        names, unit = ("r_w", "r_x", "r_y", "r_z"), ""
    fig = Figure(figsize=(6.4, 1.7 * len(names) + 0.6), layout="constrained")
    axes = fig.subplots(len(names), 1, sharex=True, squeeze=False).ravel()
    for i, (ax, name) in enumerate(zip(axes, names, strict=True)):
        ax.plot(log.sigma, desired[:, i], label="target", **_REF_STYLE)
        ax.plot(log.sigma, measured[:, i], color=f"C{i}", linewidth=1.4, label="measured")
        ax.set_ylabel(f"${name[0]}_{{{name[2]}}}${unit}")
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="best", fontsize="small")
    axes[-1].set_xlabel("phase σ [s]")
    axes[0].set_title(_title(log, f"{which} against σ"))
    fig.align_ylabels(axes)
    return fig


def _fig_joint_velocities(log: RunLog) -> Figure:
    n = log.q.shape[1]
    fig = Figure(figsize=(7.6, 1.5 * int(np.ceil(n / 2)) + 0.8), layout="constrained")
    axes, rows, cols = _joint_grid(fig, n)
    limits = log.meta.get("velocity_limits")
    lim = np.broadcast_to(np.asarray(limits, dtype=float), (n,)) if limits is not None else None
    for j, ax in enumerate(axes):
        ax.plot(log.t_s, log.qd_command[:, j], color="C0", linewidth=1.2, label="commanded")
        ax.plot(
            log.t_s,
            log.qd_measured[:, j],
            color="C1",
            linewidth=1.0,
            linestyle="--",
            label="measured",
        )
        if lim is not None:
            for sign in (-1, 1):
                ax.axhline(sign * lim[j], color="0.5", linewidth=0.8, linestyle=":")
        ax.set_ylabel(f"$\\dot q_{j + 1}$ [rad/s]")
        shade_stop(ax, log, log.t_s, label=j == 0)
        ax.grid(True, alpha=0.3)
    for ax in axes[-cols:]:
        ax.set_xlabel("t [s]")
    axes[0].legend(loc="best", fontsize="x-small")
    fig.suptitle(_title(log, "joint velocities"))
    return fig


def _fig_joint_lines(log: RunLog, values: np.ndarray, ylabel: str, what: str) -> Figure:
    fig = Figure(figsize=(6.4, 4.0), layout="constrained")
    ax = fig.add_subplot()
    for j in range(values.shape[1]):
        ax.plot(log.t_s, values[:, j], linewidth=1.3, label=f"joint {j + 1}")
    shade_stop(ax, log, log.t_s)
    ax.set_xlabel("t [s]")
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize="small")
    ax.set_title(_title(log, what))
    return fig


def _fig_scaling(log: RunLog) -> Figure:
    fig = Figure(figsize=(6.4, 4.4), layout="constrained")
    ax_s, ax_sigma = fig.subplots(2, 1, sharex=True)
    ax_s.plot(log.t_s, log.s, color="C2", linewidth=1.4, drawstyle="steps-post")
    ax_s.set_ylabel("s")
    ax_s.set_ylim(-0.05, 1.05)
    shade_stop(ax_s, log, log.t_s)
    shade_stop(ax_sigma, log, log.t_s, label=False)
    ax_s.grid(True, alpha=0.3)
    ax_sigma.plot(log.t_s, log.t_s, label="σ = t", **_REF_STYLE)
    ax_sigma.plot(log.t_s, log.sigma, color="C0", linewidth=1.4, label="σ(t)")
    ax_sigma.set_xlabel("t [s]")
    ax_sigma.set_ylabel("σ [s]")
    ax_sigma.grid(True, alpha=0.3)
    ax_sigma.legend(loc="best", fontsize="small")
    ax_s.set_title(_title(log, "time scaling s(t) and phase σ(t)"))
    return fig


def plot_run(
    log: RunLog,
    out_dir: str | os.PathLike,
    *,
    name: str = "run",
    trajectory: Trajectory | None = None,
    fmt: str = "png",
    dpi: float = 110.0,
    figures: Sequence[str] | None = None,
) -> list[Path]:
    """Write the per-run figures of ``log`` as ``out_dir/<name>_<figure>.<fmt>``.

    Args:
        log: the run.
        out_dir: folder (created if needed).
        name: file name prefix.
        trajectory: the *anchored* trajectory the controller used (``controller.trajectory``):
            gives the dense reference path and the plane of ``path_2d``; default: the run's
            targets and their principal plane.
        fmt: ``"png"`` or ``"svg"``.
        dpi: resolution of PNG files.
        figures: a subset of :data:`FIGURES` (default: all).

    Returns:
        The paths written, in :data:`FIGURES` order (``joint_torques`` is skipped when the
        run has no torques, i.e. the kinematic loop).

    Raises:
        ParameterError: empty log, unknown format or figure name.
    """
    fmt = _check_format(fmt)
    wanted = FIGURES if figures is None else tuple(figures)
    unknown = sorted(set(wanted) - set(FIGURES))
    if unknown:
        raise ParameterError(f"unknown figures {unknown}; choose from {list(FIGURES)}")
    if len(log) == 0:
        raise ParameterError("cannot plot an empty run log (no samples)")
    out = Path(out_dir)
    ref = _reference_points(log, trajectory)
    has_torque = bool(np.isfinite(log.torque).all())
    makers = {
        "path_2d": lambda: _fig_path_2d(log, ref, trajectory),
        "path_3d": lambda: _fig_path_3d(log, ref),
        "translation": lambda: _fig_elements(log, "translation"),
        "rotation": lambda: _fig_elements(log, "rotation"),
        "joint_velocities": lambda: _fig_joint_velocities(log),
        "joint_positions": lambda: _fig_joint_lines(log, log.q, "q [rad]", "joint angles"),
        "joint_torques": lambda: _fig_joint_lines(log, log.torque, "τ [N·m]", "joint torques"),
        "scaling": lambda: _fig_scaling(log),
    }
    paths = []
    for key in FIGURES:
        if key not in wanted or (key == "joint_torques" and not has_torque):
            continue
        paths.append(_save(makers[key](), out / f"{name}_{key}.{fmt}", dpi))
    return paths


# ---------------------------------------------------------------------- comparison
def plot_comparison(
    runs: Mapping[str, RunLog] | Sequence[RunLog],
    path: str | os.PathLike,
    *,
    trajectory: Trajectory | None = None,
    dpi: float = 110.0,
    title: str | None = None,
) -> Path:
    """One figure overlaying two or more runs on the same axes: the path in the trajectory's
    plane, the translation error ‖t_d - t‖ [mm], the scaling ``s(t)`` and the phase ``σ(t)``.

    Args:
        runs: ``{label: log}`` (or logs, labelled by their controller).
        path: file to write; its suffix (``.png`` or ``.svg``) sets the format.
        trajectory: the anchored trajectory (shared by the runs) for the reference path and
            its plane; default: the first run's targets.
        dpi: resolution of a PNG [dots per inch].
        title: the figure's title (default: "comparison of controllers").

    Returns:
        ``path``.
    """
    items = _comparison_items(runs)
    out = Path(path)
    _check_format(out.suffix or ".none")
    ref = _reference_points(items[0][1], trajectory)
    origin, axes2, labels = path_plane(ref, trajectory)
    fig = Figure(figsize=(11.0, 7.6), layout="constrained")
    grid = fig.add_gridspec(3, 2, width_ratios=(1.0, 1.25))
    ax_path = fig.add_subplot(grid[:, 0])
    ax_err = fig.add_subplot(grid[0, 1])
    ax_s = fig.add_subplot(grid[1, 1], sharex=ax_err)
    ax_sigma = fig.add_subplot(grid[2, 1], sharex=ax_err)
    r2 = _project(ref, origin, axes2)
    ax_path.plot(r2[:, 0], r2[:, 1], label="reference", **_REF_STYLE)
    t_end = 0.0
    for i, (label, log) in enumerate(items):
        color = f"C{i}"
        p2 = _project(translation(log.pose), origin, axes2)
        ax_path.plot(p2[:, 0], p2[:, 1], color=color, linewidth=1.4, label=label)
        terr, _ = pose_error(log.pose, log.target)
        ax_err.plot(log.t_s, 1e3 * terr, color=color, linewidth=1.3, label=label)
        ax_s.plot(log.t_s, log.s, color=color, linewidth=1.3, drawstyle="steps-post")
        ax_sigma.plot(log.t_s, log.sigma, color=color, linewidth=1.3)
        t_end = max(t_end, float(log.t_s[-1]))
    ax_sigma.plot([0.0, t_end], [0.0, t_end], label="σ = t", **_REF_STYLE)
    _label_comparison_axes(ax_path, ax_err, ax_s, ax_sigma, labels)
    fig.suptitle(title or "comparison of controllers")
    return _save(fig, out, dpi)


def _comparison_items(runs: Mapping[str, RunLog] | Sequence[RunLog]) -> list[tuple[str, RunLog]]:
    """The ``(label, log)`` pairs of :func:`plot_comparison`'s ``runs``, in order.

    Logs given without labels are labelled by their controller (else ``run i``).

    Raises:
        ParameterError: there is no run, or a run has no samples.
    """
    items = (
        list(runs.items())
        if isinstance(runs, Mapping)
        else [(_label(log, f"run {i + 1}"), log) for i, log in enumerate(runs)]
    )
    if not items:
        raise ParameterError("plot_comparison needs at least one run")
    for label, log in items:
        if len(log) == 0:
            raise ParameterError(f"run {label!r} is empty (no samples)")
    return items


def _label_comparison_axes(ax_path, ax_err, ax_s, ax_sigma, labels: tuple[str, str]) -> None:
    """Labels, titles, legends, limits and grids of :func:`plot_comparison`'s four axes.

    Args:
        ax_path: the axes of the path, in the plane whose axis ``labels`` are given.
        ax_err: the axes of the translation error.
        ax_s: the axes of the time scaling ``s``.
        ax_sigma: the axes of the phase ``σ``.
        labels: the labels of the path plane's two axes.
    """
    ax_path.set_xlabel(labels[0])
    ax_path.set_ylabel(labels[1])
    ax_path.set_aspect("equal", adjustable="datalim")
    ax_path.legend(loc="best", fontsize="small")
    ax_path.set_title("path")
    ax_err.set_ylabel("‖t_d − t‖ [mm]")
    ax_err.legend(loc="best", fontsize="small")
    ax_s.set_ylabel("s")
    ax_s.set_ylim(-0.05, 1.05)
    ax_sigma.set_ylabel("σ [s]")
    ax_sigma.set_xlabel("t [s]")
    ax_sigma.legend(loc="best", fontsize="small")
    for ax in (ax_path, ax_err, ax_s, ax_sigma):
        ax.grid(True, alpha=0.3)
