"""``dqcontrol.studies.run``: the small study on the pool and on Dask (same tables, also through
``dqcontrol study --scheduler local``), its case files, interrupts, and the Table 1 and fault
studies' figures."""

from __future__ import annotations

import json
import textwrap

import pytest
from studies.small_study import SMALL, write_study

from dqcontrol.cli import main
from dqcontrol.experiments import table1 as t1
from dqcontrol.faults import campaign
from dqcontrol.studies import load_study, run_study, tracking


@pytest.fixture(scope="module")
def pool_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pool")
    study = load_study(write_study(folder, SMALL))
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
    study = load_study(write_study(tmp_path, SMALL))
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
    path = write_study(tmp_path, SMALL)
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
    study = load_study(write_study(tmp_path, SMALL))
    result = run_study(study, out=tmp_path / "out", workers=1, progress=False)
    assert result.interrupted and len(result.results) == 1 and result.total_cases == 2
    (record,) = (tmp_path / "out" / "small_cases").glob("*.json")
    assert json.loads(record.read_text())["case"]["trajectory"] == "circle"
    assert len(result.files["csv"].read_text().splitlines()) == 2  # header and one row
    assert "Interrupted" in result.files["md"].read_text()


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
    study = load_study(write_study(tmp_path, table1, "t1.toml"))
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
    study = load_study(write_study(tmp_path, textwrap.dedent(faults), "f1.toml"))
    result = run_study(study, out=tmp_path, workers=1, progress=False)
    reference = campaign.run_campaign(["local"], ["circle"], ["nominal", "solver_fails"],
                                      "kinematic", workers=1)  # fmt: skip
    assert [r.status for r in result.results] == ["completed", "stopped"]
    for got, want in zip(result.results, reference.rows, strict=True):
        a, b = got.row(), want.row()
        a.pop("wall_time_s"), b.pop("wall_time_s")
        assert a == pytest.approx(b, nan_ok=True)
    assert "## Checks (QP controllers)" in (tmp_path / "f1.md").read_text()
