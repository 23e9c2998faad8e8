"""Studies from a file: parsing and its errors, the shipped Table 1 and fault studies against
their commands' cases, the same figures on the process pool and on a Dask cluster, and the
case results kept on an interrupt.

Runtime budget: about a minute (a two-case kinematic grid, short trajectories).
"""

from __future__ import annotations

import fnmatch
import json
import math
import os
import textwrap
import tomllib
from pathlib import Path

import pytest

from dqcontrol.cli import main
from dqcontrol.experiments import table1 as t1
from dqcontrol.experiments.executor import resolve_executor
from dqcontrol.faults import campaign
from dqcontrol.model.library import lbr4p_urdf_path
from dqcontrol.studies import (
    StudyFileError,
    load_study,
    parse_study,
    run_study,
    shipped_study_path,
    study_cases,
    tracking,
)

ROOT = Path(__file__).resolve().parents[2]

#: Two short cases in the kinematic loop: the circle at T_tot = 1 s, Local and p = 10.
SMALL = """\
[study]
name = "small"

[simulator]
kind = "kinematic"
period_s = 0.05

[grid]
controllers = ["local", "p10"]
duration_s = [1.0]

[[trajectories]]
kind = "circle"
radius_m = 0.05

[options]
acceleration_limit = 10.0

[options.p10]
horizon_s = 0.5
"""


def _write(folder: Path, text: str, name: str = "study.toml") -> Path:
    path = folder / name
    path.write_text(textwrap.dedent(text), encoding="utf-8")
    return path


def _study_text(**replace: str) -> str:
    text = SMALL
    for old, new in replace.items():
        text = text.replace(old.replace("_", " ") if " " in old else old, new)
    return text


# ---------------------------------------------------------------------------- parsing
def test_small_study_parses_to_two_cases(tmp_path):
    study = load_study(_write(tmp_path, SMALL))
    assert study.name == "small" and study.experiment == "tracking"
    assert study.simulator == "kinematic" and study.period_s == 0.05
    assert study.controllers == ("local", "p10")
    (circle,) = study.trajectories
    assert circle.name == "circle" and circle.durations_s == (1.0,)
    assert circle.metadata(1.0) == {"trajectory": "circle", "duration_s": 1.0, "radius_m": 0.05}
    assert dict(study.settings.shared) == {"acceleration_limit": 10.0}
    assert study.settings.extra("p10") == {"horizon_s": 0.5} and study.settings.extra("local") == {}
    assert [c.name for c in study_cases(study)] == ["circle_T1s_local", "circle_T1s_p10"]
    assert study.output.formats == ("md", "csv") and study.output.folder == "results"


def test_shipped_table1_study_is_the_table1_command():
    study = load_study("table1")
    assert study.settings == t1.Table1Settings()  # the thesis's settings, every field
    assert study_cases(study) == t1.table1_cases()  # 32 cases, same identities and order
    assert study.output.save_runs


def test_shipped_faults_study_is_the_fault_campaign():
    study = load_study("faults")
    cases = study_cases(study)
    assert cases == campaign.campaign_cases(simulator="mujoco")
    assert len(cases) == 228 and len({campaign_name(c) for c in cases}) == 228
    kinematic = parse_study(
        tomllib.loads(shipped_study_path("faults").read_text().replace('"mujoco"', '"kinematic"'))
    )
    assert study_cases(kinematic) == campaign.campaign_cases(simulator="kinematic")


def campaign_name(case) -> str:
    from dqcontrol.studies.kinds import experiment_kind

    return experiment_kind("faults").case_name(case)


def test_shipped_studies_are_package_data():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    patterns = config["tool"]["setuptools"]["package-data"]["dqcontrol"]
    for name in ("table1", "faults"):
        path = shipped_study_path(name)
        assert path.is_file()
        relative = path.relative_to(ROOT / "dqcontrol").as_posix()
        assert any(fnmatch.fnmatchcase(relative, p) for p in patterns), relative


def test_list_prints_the_cases(capsys):
    assert main(["study", "table1", "--list"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "circle_T8s_local" and out[-1] == "32 cases (table1, mujoco)"


# ---------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("old", "new", "fragments"),
    [
        (
            '"p10"]',
            '"mpc"]',
            ["[grid] controllers", "unknown controller 'mpc'", "local, p6, p10", "pf"],
        ),
        (
            "[options.p10]",
            "[options.p10]\nhorizn_s = 1.0",
            ["unknown key 'horizn_s' in [options.p10]", "horizon_s"],
        ),
        ("[grid]", "[grdi]", ["unknown key 'grdi' at the top level", "grid"]),
        (
            "period_s = 0.05",
            'period_s = "fast"',
            ["[simulator] period_s", "expected a finite number > 0 [s]", "'fast' (str)"],
        ),
        ("radius_m = 0.05", "radius_m = -0.05", ["[[trajectories]] #1", "radius_m"]),
        ('kind = "circle"', 'kind = "square"', ["unknown trajectory 'square'", "waypoints"]),
        ('name = "small"', 'name = "small"\nexperiment = "x"', ["unknown experiment 'x'"]),
        ('kind = "kinematic"', 'kind = "gazebo"', ["[simulator] kind", "'mujoco', 'kinematic'"]),
        ("duration_s = [1.0]", "duration_s = []", ["[grid] duration_s", "non-empty list"]),
        ("[grid]", "[grid", ["not a valid TOML file"]),
        (
            "acceleration_limit = 10.0",
            "velocity_limits = [1.0, 2.0]",
            ["[options]: controller 'local' cannot be built", "shape (7,)"],
        ),
        (
            "period_s = 0.05",
            "period_s = -0.05",
            ["[simulator] period_s", "expected a finite number > 0 [s]", "-0.05"],
        ),
        (
            "[grid]",
            '[robot]\nurdf = "no_such_arm.urdf"\ntool_frame = "flange"\nq0_rad = [0.0]\n\n[grid]',
            ["[robot] urdf", "no_such_arm.urdf"],
        ),
    ],
    ids=[
        "controller",
        "option",
        "table",
        "type",
        "value",
        "trajectory",
        "experiment",
        "simulator",
        "empty",
        "toml",
        "option value",
        "negative period",
        "missing robot",
    ],
)
def test_bad_study_file_is_a_clear_error_with_exit_code_2(tmp_path, capsys, old, new, fragments):
    assert old in SMALL
    path = _write(tmp_path, SMALL.replace(old, new, 1))
    with pytest.raises(StudyFileError) as info:
        load_study(path)
    message = str(info.value)
    assert message.startswith(str(path))
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    assert main(["study", str(path), "--no-progress", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dqcontrol study: error: ") and fragments[0] in err
    assert "Traceback" not in err


def test_missing_file_names_the_shipped_studies(tmp_path, capsys):
    assert main(["study", str(tmp_path / "none.toml")]) == 2
    err = capsys.readouterr().err
    assert "no study file" in err and "none.toml" in err and "table1, faults" in err


def test_the_experiments_refuse_what_is_not_theirs(tmp_path):
    table1 = SMALL.replace('name = "small"', 'name = "t"\nexperiment = "table1"')
    with pytest.raises(StudyFileError, match="unknown key 'options' at the top level"):
        load_study(_write(tmp_path, table1))
    faults = SMALL.replace('name = "small"', 'name = "f"\nexperiment = "faults"')
    faults = faults.split("[options]")[0] + '[faults]\nnames = ["nominal", "gremlins"]\n'
    with pytest.raises(StudyFileError, match=r"unknown key 'radius_m' in \[\[trajectories\]\] #1"):
        load_study(_write(tmp_path, faults))  # the campaign's paths have no parameters
    faults = faults.replace("radius_m = 0.05\n", "")
    with pytest.raises(StudyFileError, match=r"\[faults\] names: unknown fault 'gremlins'"):
        load_study(_write(tmp_path, faults))
    robot = SMALL + '[robot]\nurdf = "arm.urdf"\n'
    with pytest.raises(StudyFileError, match=r"\[robot\] tool_frame: missing"):
        load_study(_write(tmp_path, robot))


# ---------------------------------------------------------------------------- running
@pytest.fixture(scope="module")
def pool_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pool")
    study = load_study(_write(folder, SMALL))
    return run_study(study, out=folder / "out", workers=2, progress=False)


def test_study_on_the_pool_writes_tables_and_case_files(pool_run):
    assert pool_run.executor == "process pool, 2 workers" and not pool_run.interrupted
    files = pool_run.files
    assert sorted(files) == ["csv", "md"] and files["csv"].name == "small.csv"
    lines = files["csv"].read_text().splitlines()
    assert lines[0].split(",") == [k for k, _, _ in tracking.COLUMNS] and len(lines) == 3
    md = files["md"].read_text()
    assert "| circle | 1 | Local |" in md and "| circle | 1 | p=10 |" in md
    records = sorted(pool_run.cases_dir.glob("*.json"))
    assert [p.name for p in records] == ["circle_T1s_local.json", "circle_T1s_p10.json"]
    for path, record in zip(records, pool_run.records, strict=True):
        assert json.loads(path.read_text()) == record
        m = record["metrics"]
        assert m["completed"] and m["velocity_violations"] == m["acceleration_violations"] == 0
    assert not list(pool_run.cases_dir.parent.rglob("*.tmp"))


def test_dask_cluster_gives_the_same_table_as_the_pool(tmp_path, pool_run):
    distributed = pytest.importorskip("dask.distributed")
    study = load_study(_write(tmp_path, SMALL))
    with distributed.LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None, silence_logs=50
    ) as cluster:
        result = run_study(study, out=tmp_path / "out", scheduler=cluster.scheduler_address,
                           progress=False)  # fmt: skip
    assert result.executor.startswith("Dask distributed at tcp://")
    assert result.files["csv"].read_text() == pool_run.files["csv"].read_text()
    for a, b in zip(result.records, pool_run.records, strict=True):
        assert {k: v for k, v in a["metrics"].items() if "time_median" not in k} == {
            k: v for k, v in b["metrics"].items() if "time_median" not in k
        }


def test_local_dask_option_from_the_command_line(tmp_path, capsys, pool_run):
    pytest.importorskip("dask.distributed")
    path = _write(tmp_path, SMALL)
    argv = ["study", str(path), "--scheduler", "local", "--workers", "2", "--no-progress"]
    assert main([*argv, "--out", str(tmp_path / "out")]) == 0
    assert "local cluster of 2 worker processes" in capsys.readouterr().out
    assert (tmp_path / "out" / "small.csv").read_text() == pool_run.files["csv"].read_text()


def test_interrupt_keeps_every_finished_case(tmp_path, monkeypatch):
    real = tracking.run_tracking_case
    calls = []

    def stop_at_the_second(case, study, save_dir=None):
        calls.append(case)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(case, study, save_dir)

    monkeypatch.setattr(tracking, "run_tracking_case", stop_at_the_second)
    study = load_study(_write(tmp_path, SMALL))
    result = run_study(study, out=tmp_path / "out", workers=1, progress=False)
    assert result.interrupted and len(result.results) == 1 and result.total_cases == 2
    (record,) = (tmp_path / "out" / "small_cases").glob("*.json")
    assert json.loads(record.read_text())["case"]["trajectory"] == "circle"
    assert len(result.files["csv"].read_text().splitlines()) == 2  # header and one row
    assert "Interrupted" in result.files["md"].read_text()


def test_a_urdf_and_tool_frame_give_the_shipped_robot_s_figures(tmp_path):
    """The LBR4p named by its URDF path and flange frame is the shipped LBR4p: the same
    waypoint case (positions and orientations) gives the same figures."""
    waypoints = """\
        [[trajectories]]
        name = "turn"
        kind = "waypoints"
        positions_m = [[0.0, 0.0, 0.0], [0.03, 0.02, 0.0], [0.05, 0.0, 0.02]]
        orientations = [[1.0, 0.0, 0.0, 0.0], [0.9962, 0.0872, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]]
        """
    base = SMALL.split("[[trajectories]]")[0].replace('["local", "p10"]', '["local"]')
    base += textwrap.dedent(waypoints)
    shipped = load_study(_write(tmp_path, base, "shipped.toml"))
    q0 = ", ".join(repr(float(v)) for v in tracking.start_configuration(shipped.robot))
    urdf = f'[robot]\nurdf = "{lbr4p_urdf_path()}"\ntool_frame = "lbr4p_flange"\nq0_rad = [{q0}]\n'
    named = load_study(_write(tmp_path, base + urdf, "urdf.toml"))
    assert named.robot.urdf == str(lbr4p_urdf_path().resolve())
    (case,) = study_cases(named)
    a = tracking.run_tracking_case(case, shipped)["metrics"]
    b = tracking.run_tracking_case(case, named)["metrics"]
    assert a["completed"] and a["samples"] > 10
    for key in a.keys() - {"solve_time_median_s", "step_time_median_s"}:
        assert a[key] == b[key] or (math.isnan(a[key]) and math.isnan(b[key])), key
    bad = base + urdf.replace("lbr4p_flange", "flange")
    with pytest.raises(StudyFileError, match="unknown end-effector frame 'flange'"):
        load_study(_write(tmp_path, bad, "bad.toml"))


def test_table1_and_faults_studies_give_their_commands_figures(tmp_path):
    """A reduced Table 1 study and a reduced fault study run the commands' own jobs: the same
    figures as :func:`table1.run_case` and :func:`campaign.run_campaign`."""
    table1 = """\
        [study]
        name = "t1"
        experiment = "table1"
        [simulator]
        kind = "kinematic"
        [grid]
        controllers = ["local"]
        [[trajectories]]
        kind = "circle"
        duration_s = [1.0]
        [table1]
        bound_samples = 0
        """
    study = load_study(_write(tmp_path, table1, "t1.toml"))
    result = run_study(study, out=tmp_path, workers=1, progress=False)
    settings = t1.Table1Settings(simulator="kinematic", bound_samples=0)
    direct = t1.run_case(t1.Table1Case("circle", 1.0, "local"), settings)
    (row,) = t1.table_rows(result.results)
    (expected,) = t1.table_rows([direct])
    assert {k: v for k, v in row.items() if k != "step_time_median_ms"} == pytest.approx(
        {k: v for k, v in expected.items() if k != "step_time_median_ms"}, nan_ok=True
    )
    assert (tmp_path / "t1.csv").read_text().splitlines()[0].split(",")[:3] == [
        "traj", "T_tot_s", "controller",
    ]  # fmt: skip
    assert len(list((tmp_path / "t1_runs").glob("*.npz"))) == 1
    faults = table1.replace('"table1"', '"faults"').replace('"t1"', '"f1"')
    faults = faults.replace("[1.0]", "[2.0]")  # the campaign's circle: T_tot = 2 s
    faults = faults.split("[table1]")[0] + '[faults]\nnames = ["nominal", "solver_fails"]\n'
    study = load_study(_write(tmp_path, textwrap.dedent(faults), "f1.toml"))
    result = run_study(study, out=tmp_path, workers=1, progress=False)
    reference = campaign.run_campaign(["local"], ["circle"], ["nominal", "solver_fails"],
                                      "kinematic", workers=1)  # fmt: skip
    assert [r.status for r in result.results] == ["completed", "stopped"]
    for got, want in zip(result.results, reference.rows, strict=True):
        a, b = got.row(), want.row()
        a.pop("wall_time_s"), b.pop("wall_time_s")
        assert a == pytest.approx(b, nan_ok=True)
    assert "## Checks (QP controllers)" in (tmp_path / "f1.md").read_text()


def test_fault_campaign_defaults_to_every_core():
    from dqcontrol.cli import build_parser

    args = build_parser().parse_args(["faults"])
    assert args.workers is None and args.scheduler is None
    assert resolve_executor(args.workers, None, 1000).workers == (os.cpu_count() or 1)
    assert resolve_executor(None, None, 1).label == "in-process (1 worker)"


def test_the_user_guide_s_example_study_parses():
    """The example of docs/user_guide.md is a valid study (its URDF replaced by the shipped
    LBR4p, which has the same 7 joints)."""
    import re

    text = (ROOT / "docs" / "user_guide.md").read_text(encoding="utf-8")
    (block,) = re.findall(r"^```toml\n(.*?)^```", text, flags=re.MULTILINE | re.DOTALL)
    data = tomllib.loads(block)
    assert data["robot"]["tool_frame"] == "tool0"
    del data["robot"]
    study = parse_study(data, source="user_guide.md")
    cases = study_cases(study)
    assert len(cases) == 12 and {c.trajectory for c in cases} == {"circle", "turn"}
    assert study.settings.extra("pf") == {"horizon_s": 1.0}


@pytest.mark.parametrize(
    "selection",
    [
        {"quick": True},
        {"periods": [2.0], "controllers": ["local", "path-following"]},
        {"trajectories": ["sinusoid"], "controllers": ["p6"]},
        {},
    ],
)
def test_table1_command_selects_its_cases_from_the_shipped_study(selection):
    from dqcontrol.studies.table1_study import select_table1

    study = select_table1(load_study("table1"), simulator="kinematic", **selection)
    assert study_cases(study) == t1.table1_cases(**selection)
    assert study.settings == t1.Table1Settings(simulator="kinematic")
    faster = select_table1(load_study("table1"), period_s=0.001, **selection)
    assert study_cases(faster) == t1.table1_cases(**selection)
    assert faster.period_s == 0.001
    assert faster.settings == t1.Table1Settings(period_s=0.001)


@pytest.mark.parametrize(
    "selection",
    [
        {"quick": True},
        {"controllers": ["local", "proportional"], "faults": ["nominal", "solver_fails"]},
        {"trajectories": ["sinusoid"], "seed": 3},
        {},
    ],
)
@pytest.mark.parametrize("simulator", ["kinematic", "mujoco"])
def test_faults_command_selects_its_cases_from_the_shipped_study(selection, simulator):
    from dqcontrol.studies.faults_study import select_faults

    study = select_faults(load_study("faults"), simulator=simulator, **selection)
    assert study_cases(study) == campaign.campaign_cases(simulator=simulator, **selection)


# ---------------------------------------------------------------------------- executors
@pytest.mark.parametrize("scheduler", [None, "local"])
def test_workers_run_one_blas_thread_each(monkeypatch, scheduler):
    """The pool's and the local Dask cluster's workers see one BLAS/OpenMP thread (the
    variables are set for the workers only, and restored here)."""
    import functools

    from dqcontrol.experiments.executor import THREAD_VARIABLES, Executor, run_jobs

    if scheduler:
        pytest.importorskip("dask.distributed")
    for variable in THREAD_VARIABLES:
        monkeypatch.delenv(variable, raising=False)
    seen = []
    job = functools.partial(os.getenv, default="unset")
    run_jobs(job, list(THREAD_VARIABLES), Executor(2, scheduler), seen.append)
    assert seen == ["1"] * len(THREAD_VARIABLES)
    assert all(v not in os.environ for v in THREAD_VARIABLES)


def test_a_run_stopped_early_is_exit_code_1(tmp_path, monkeypatch, capsys):
    real = tracking.run_tracking_case

    def unstable_p10(case, study, save_dir=None):
        result = real(case, study, save_dir)
        if case.controller == "p10":
            result["interrupted"], result["note"] = True, "the physics became unstable"
        return result

    monkeypatch.setattr(tracking, "run_tracking_case", unstable_p10)
    path = _write(tmp_path, SMALL)
    argv = ["study", str(path), "--workers", "1", "--no-progress", "--out", str(tmp_path)]
    assert main(argv) == 1
    assert "some runs stopped early: circle_T1s_p10" in capsys.readouterr().err
    assert "| circle | 1 | p=10 |" in (tmp_path / "small.md").read_text()
