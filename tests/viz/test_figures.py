"""The figures of runs (dqcontrol/viz/figures.py): every figure of a MuJoCo run written and
not blank, SVG output, comparisons of runs, the plane of the path, and the errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

from dqcontrol.controllers import PredictiveController
from dqcontrol.errors import ParameterError
from dqcontrol.model import LBR4P_Q0
from dqcontrol.runs.log import RunLog
from dqcontrol.sim import run_kinematic
from dqcontrol.trajectories import Circle
from dqcontrol.viz.figures import FIGURES, path_plane, plot_comparison, plot_run


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
