"""The stop in the figures and in ``dqcontrol view`` (dqcontrol/viz/stop_marks.py)."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.figure import Figure

from dqcontrol.controllers import LocalController
from dqcontrol.model import LBR4P_Q0
from dqcontrol.runs.log import RunLog
from dqcontrol.sim import KinematicDriver, run_loop
from dqcontrol.trajectories import Circle
from dqcontrol.viz.figures import plot_run
from dqcontrol.viz.stop_marks import mark_stop_on_path, shade_stop, stop_summary

T = 0.05


@pytest.fixture(scope="module")
def stopped(lbr4p):
    ctrl = LocalController(lbr4p, Circle(1.0), T)

    def request(_k, _driver, result) -> None:
        if result.sigma_next >= 0.5 and not ctrl.stopping:
            ctrl.request_stop()

    return run_loop(ctrl, KinematicDriver(lbr4p, T), q0=LBR4P_Q0, on_sample=request).log


def test_the_stop_is_shaded_over_its_samples(stopped):
    ax = Figure().add_subplot()
    shade_stop(ax, stopped, stopped.t_s)
    first = int(np.argmax(stopped.stopping))
    (span,) = ax.patches
    bbox = span.get_bbox()  # data x, axes y
    assert bbox.x0 == pytest.approx(stopped.t_s[first])
    assert bbox.x1 == pytest.approx(stopped.t_s[-1])
    assert ax.get_legend_handles_labels()[1] == ["stop"]


def test_a_run_without_a_stop_has_no_marks(stopped):
    arrays = stopped.arrays()
    arrays["stopping"] = np.zeros(len(stopped), dtype=bool)
    plain = RunLog.from_arrays(arrays, stopped.meta)
    ax = Figure().add_subplot()
    shade_stop(ax, plain, plain.t_s)
    mark_stop_on_path(ax, plain, np.zeros((len(plain), 2)))
    assert not ax.patches and not ax.lines and stop_summary(plain) == ""


def test_the_summary_names_the_stop(stopped):
    text = stop_summary(stopped)
    count = int(stopped.stopping.sum())
    assert text.startswith(f"stop (request): {count} samples ({count * T:.3f} s)")


def test_the_figures_are_written_with_the_stop(stopped, tmp_path):
    paths = plot_run(stopped, tmp_path, figures=("path_2d", "joint_velocities", "scaling"))
    assert [p.name for p in paths] == [
        "run_path_2d.png", "run_joint_velocities.png", "run_scaling.png",
    ]  # fmt: skip
