"""``dqcontrol bench`` (dqcontrol/cli/bench_cmd.py): where the benchmark is looked for, its
options, a clear message and exit code 1 without a source checkout, and the quick benchmark's
JSON with every figure (its figures are timings: never asserted here)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from dqcontrol.cli import bench_cmd, build_parser, main


def test_bench_needs_a_source_checkout(tmp_path, monkeypatch, capsys):
    assert bench_cmd.bench_path().is_file()  # this checkout has it
    monkeypatch.setattr(bench_cmd, "bench_path", lambda: tmp_path / "benchmarks" / "bench.py")
    monkeypatch.delitem(sys.modules, bench_cmd._MODULE, raising=False)
    assert main(["bench", "--quick", "--out", str(tmp_path / "bench.json")]) == 1
    err = capsys.readouterr().err
    assert "needs a source checkout" in err and "Traceback" not in err
    assert not (tmp_path / "bench.json").exists()


def test_the_benchmark_is_beside_the_package():
    import dqcontrol

    path = bench_cmd.bench_path()
    assert path.parent.name == "benchmarks" and path.name == "bench.py"
    assert path.parents[1] / "dqcontrol" / "__init__.py" == Path(dqcontrol.__file__).resolve()


def test_a_loaded_benchmark_is_reused(monkeypatch):
    marker = type(sys)("stand_in")
    monkeypatch.setitem(sys.modules, bench_cmd._MODULE, marker)
    monkeypatch.setattr(bench_cmd, "bench_path", lambda: (_ for _ in ()).throw(AssertionError))
    assert bench_cmd.load_bench() is marker  # not looked for, not executed again


def test_the_options_and_what_the_command_calls(monkeypatch):
    calls = []
    stand_in = type(sys)("stand_in")
    stand_in.main = lambda **kw: calls.append(kw)
    monkeypatch.setitem(sys.modules, bench_cmd._MODULE, stand_in)
    args = build_parser().parse_args(["bench"])
    assert args.out == "results/bench.json" and args.quick is False and args.progress is True
    assert main(["bench", "--quick", "--out", "b.json", "--no-progress"]) == 0
    assert calls == [{"out": "b.json", "quick": True}]


def test_quick_bench_writes_every_figure(tmp_path):
    bench = bench_cmd.load_bench()
    TARGETS, main = bench.TARGETS, bench.main

    out = tmp_path / "bench.json"
    res = main(out=out, quick=True)
    data = json.loads(out.read_text())
    assert data["quick"] is True and data["default_solver"] == "daqp"
    assert set(data["targets"]) == set(TARGETS)
    for key in ("cpu", "cores", "python", "packages"):
        assert key in data["machine"]
    for name in ("local[daqp]", "predictive_p6[daqp]", "predictive_p10[daqp]", "proportional"):
        assert data["controllers"][name]["median_us"] > 0.0
        # the host's floor: a constant workload timed after every step
        assert data["controllers"][name]["reference_p99_over_median"] >= 1.0
        # present only if the repeated closed loops ended in the same state bit for bit
        assert data["controllers"][name]["own_p99_over_median"] >= 1.0
    assert data["controllers"]["predictive_noscale_p10[daqp]"]["median_us"] > 0.0
    assert data["targets"]["p99_over_median"]["host_floor"] >= 1.0
    assert data["targets"]["p99_over_median"]["own_work"] >= 1.0
    assert data["mujoco"]["realtime_factor"] > 0.0
    pf10 = data["path_following"]["by_p"]["10"]
    # the prioritised solve holds the solver calls: never shorter than them
    assert 0.0 < pf10["solver_median_us"] <= pf10["levels_median_us"] <= pf10["median_us"]
    for key in ("path_following_p10", "path_following_step_over_solve"):
        assert data["targets"][key]["value"] > 0.0
    default = data["path_following"]["dynamics_p10"]  # the dynamics-aware bound, as shipped
    assert 0.0 < default["solver_median_us"] <= default["levels_median_us"] <= default["median_us"]
    assert data["scaling"]["by_p"] and data["scaling"]["by_joints_p10"]
    whole = data["collision"]["pf10_whole_circle"]  # the quick run: its first 20 steps
    assert whole["steps"] == 20 and not whole["completed"] and whole["fallbacks"] == 0
    assert whole["step_median_us"] <= whole["step_p99_us"] and 0.0 <= whole["over_period_share"]
    assert whole["closest_mm"] is None or whole["closest_mm"] > 20.0  # still far from the ball
    for v in data["agreement"].values():
        assert v["max_abs_qd_diff"] < 1e-8  # accuracy, not time: the backends agree
    assert res["targets"].keys() == data["targets"].keys()
    if data["dqrobotics"] is not None:  # a dev extra: the peers are measured interleaved
        assert data["dqrobotics"]["rounds"] >= 3
        assert set(data["ratios"]) == {
            "single_kinematics_vs_dqr",
            "batch10_vs_10x_dqr",
            "local_step_vs_dqr_classic_qp",
        }
        assert all(v > 0.0 for v in data["ratios"].values())
