"""The core installs light: with the optional dependencies missing (MuJoCo, Meshcat,
matplotlib, Dask; each blocked in a fresh Python process by ``sys.modules[name] = None``),
the package imports, the kinematic loop runs from Python and from the command line, and
whatever needs an extra says which one to install. Also: the extras of ``pyproject.toml``
are the ones :mod:`dqcontrol.extras` names."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

import pytest

from dqcontrol.extras import EXTRAS, has_extra, missing_extra, require

ROOT = Path(__file__).resolve().parents[1]
BLOCKED = ("mujoco", "meshcat", "matplotlib", "dask", "distributed")

# Runs in a fresh interpreter with the optional modules blocked; prints one JSON object.
_SCRIPT = textwrap.dedent(
    """
    import contextlib, io, json, sys
    for name in {blocked!r}:
        sys.modules[name] = None

    out = {{}}
    import dqcontrol, dqcontrol.controllers, dqcontrol.sim, dqcontrol.cli, dqcontrol.faults
    import dqcontrol.experiments, dqcontrol.runs, dqcontrol.registry, dqcontrol.trajectories
    import dqcontrol.viz.meshcat_viewer
    from dqcontrol.extras import has_extra

    out["imported"] = True
    out["has_extra"] = {{e: has_extra(e) for e in ("sim", "viz", "dask")}}

    from dqcontrol import load_lbr4p
    from dqcontrol.controllers import LocalController
    from dqcontrol.errors import MissingExtraError
    from dqcontrol.experiments.thesis import THESIS_Q0
    from dqcontrol.sim import MujocoSimulation, run_kinematic
    from dqcontrol.trajectories import Circle

    robot = load_lbr4p()
    controller = LocalController(robot, Circle(duration_s=1.0), 0.05, acceleration_limit=10.0)
    result = run_kinematic(controller, THESIS_Q0)
    out["kinematic_completed"] = bool(result.metrics.completed)

    def error_of(call):
        try:
            call()
        except MissingExtraError as exc:
            return str(exc)
        return None

    out["mujoco_error"] = error_of(lambda: MujocoSimulation(robot))
    out["figures_error"] = error_of(lambda: __import__("dqcontrol.viz.figures"))
    out["viewer_error"] = error_of(
        lambda: dqcontrol.viz.meshcat_viewer.MeshcatViewer(robot, live=False)
    )

    from dqcontrol.cli import main

    def cli(*argv):
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = main(list(argv))
        return code, err.getvalue()

    common = ("--short", "--no-viewer", "--controllers", "local", "--duration", "1")
    out["cli_kinematic"] = cli("run", "--simulator", "kinematic", *common)
    out["cli_mujoco"] = cli("run", *common)
    out["loaded"] = sorted(n for n in {blocked!r} if sys.modules.get(n) is not None)
    print(json.dumps(out))
    """
)


@pytest.fixture(scope="module")
def light(tmp_path_factory):
    """The JSON report of the script above, run from an empty folder."""
    cwd = tmp_path_factory.mktemp("light")
    proc = subprocess.run(
        [sys.executable, "-c", _SCRIPT.format(blocked=BLOCKED)],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    report["cwd"] = cwd
    return report


def test_the_core_imports_without_the_extras(light):
    assert light["imported"]
    assert light["has_extra"] == {"sim": False, "viz": False, "dask": False}
    assert light["loaded"] == []


def test_the_kinematic_loop_runs_without_the_extras(light):
    assert light["kinematic_completed"]


def test_the_cli_runs_the_kinematic_loop_and_says_figures_need_viz(light):
    code, err = light["cli_kinematic"]
    assert code == 0, err
    assert "pip install 'dqcontrol[viz]'" in err
    run = light["cwd"] / "results" / "lbr4p_circle_T1s_kinematic"
    assert (run / "local.npz").is_file()
    assert not list(run.glob("*.png")) and not list(run.glob("*.html"))


def test_asking_for_mujoco_names_the_sim_extra(light):
    assert "pip install 'dqcontrol[sim]'" in light["mujoco_error"]
    code, err = light["cli_mujoco"]
    assert code == 1
    assert "--simulator mujoco" in err and "pip install 'dqcontrol[sim]'" in err
    assert len(err.strip().splitlines()) == 1


def test_asking_for_figures_or_the_viewer_names_the_viz_extra(light):
    assert "pip install 'dqcontrol[viz]'" in light["figures_error"]
    assert "pip install 'dqcontrol[viz]'" in light["viewer_error"]


def test_pyproject_extras_match_the_package():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    core = " ".join(project["dependencies"]).lower()
    extras = project["optional-dependencies"]
    for extra, modules in EXTRAS.items():
        assert extra in extras
        for module in modules:
            assert module not in core, f"{module} is in the core dependencies"
    assert any("dqcontrol[sim,viz,dask]" in dep for dep in extras["dev"])


def test_missing_extra_message_and_require():
    error = missing_extra("mujoco", extra="sim", purpose="the simulation", reason="gone")
    assert isinstance(error, ImportError)
    assert str(error) == (
        "the simulation needs mujoco, which comes with the [sim] extra: "
        "pip install 'dqcontrol[sim]' (gone)"
    )
    assert require("json", extra="sim", purpose="x") is json
    with pytest.raises(ImportError, match=r"dqcontrol\[viz\]"):
        require("no_such_module_here", extra="viz", purpose="x")
    assert has_extra("sim") in (True, False)
