"""benchmarks/compare_results.py: row matching, tolerance, timing columns, extra rows."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "compare_results.py"
_spec = importlib.util.spec_from_file_location("compare_results", _PATH)
compare_results = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("compare_results", compare_results)
_spec.loader.exec_module(compare_results)

HEADER = "traj,T_tot_s,controller,e_mean,s_mean,exec_time_s,completed,step_time_median_ms\n"
OLD = (
    HEADER
    + "circle,8.0,Local,7.469795256039583e-05,0.9998924364848577,8.05,yes,0.028\n"
    + "circle,8.0,p=6,7.46979525604286e-05,0.9998924364848574,8.05,yes,0.085\n"
    + "circle,4.0,Local,0.000293,0.0,4.1,yes,0.03\n"
)


def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _run(capsys, *args) -> tuple[int, str]:
    code = compare_results.main([str(a) for a in args])
    return code, capsys.readouterr().out


def test_within_tolerance_and_extra_row(tmp_path, capsys):
    # s_mean moved by 1e-9 relative, s_mean 0 -> 1e-13 (under atol), timing column changed
    # a lot, keys written differently (8 vs 8.0), rows in another order, one new controller
    new = (
        HEADER
        + "circle,4,Local,0.000293,1e-13,4.1,yes,9.9\n"
        + "circle,8,p=6,7.46979525604286e-05,0.9998924364848574,8.05,yes,0.5\n"
        + "circle,8,Local,7.469795256039583e-05,0.9998924374847577,8.05,yes,0.01\n"
        + "circle,8,composable,7.4e-05,0.99,8.05,yes,0.01\n"
    )
    old_p, new_p = _write(tmp_path, "old.csv", OLD), _write(tmp_path, "new.csv", new)
    code, out = _run(capsys, old_p, new_p)
    assert code == 0, out
    assert "excluded (timing) columns: step_time_median_ms" in out
    assert "rows only in NEW (1, not a failure)" in out
    assert "circle/8/composable" in out
    assert "RESULT: SAME" in out
    assert "largest relative difference: 1.000e-09" in out
    # a new row fails with --strict-rows
    code, out = _run(capsys, old_p, new_p, "--strict-rows")
    assert code == 1
    assert "row(s) only in NEW" in out


def test_beyond_tolerance(tmp_path, capsys):
    new = OLD.replace("0.9998924364848574", "0.9998934364848574").replace(",yes,0.03", ",NO,0.03")
    old_p, new_p = _write(tmp_path, "old.csv", OLD), _write(tmp_path, "new.csv", new)
    code, out = _run(capsys, old_p, new_p)
    assert code == 1
    assert "RESULT: DIFFERENT" in out
    assert "2 beyond tolerance" in out
    line = next(x for x in out.splitlines() if "s_mean" in x and "0.99989" in x)
    assert "circle/8.0/p=6" in line and "1.000e-06" in line and "differs" in line
    assert any("completed" in x and "NO" in x and "inf" in x for x in out.splitlines())
    # a looser tolerance accepts the number but not the text
    code, out = _run(capsys, old_p, new_p, "--rtol", "1e-5")
    assert code == 1 and "1 beyond tolerance" in out


def test_missing_row_and_column_fail(tmp_path, capsys):
    lines = OLD.splitlines(keepends=True)
    new = "".join(x.replace(",exec_time_s", "") for x in lines[:1])
    new += "".join(",".join(x.split(",")[:5] + x.split(",")[6:]) for x in lines[1:3])
    old_p, new_p = _write(tmp_path, "old.csv", OLD), _write(tmp_path, "new.csv", new)
    code, out = _run(capsys, old_p, new_p)
    assert code == 1
    assert "rows missing from NEW (1)" in out and "circle/4.0/Local" in out
    assert "columns missing from NEW: exec_time_s" in out


def test_faults_keys_and_printed_precision(tmp_path, capsys):
    header = "fault,group,trajectory,controller,simulator,e_mean,time_s,note,wall_time_s\n"
    old = header + "nominal,none,circle,local,kinematic,0.00108518,2.05,,0.21\n"
    # one unit in the 6th significant digit: indistinguishable at 6 printed digits
    new = header + "nominal,none,circle,local,kinematic,0.00108519,2.05,,0.5\n"
    old_p, new_p = _write(tmp_path, "old.csv", old), _write(tmp_path, "new.csv", new)
    code, out = _run(capsys, old_p, new_p)
    assert code == 0, out
    assert "rows matched by fault, trajectory, controller, simulator" in out
    assert "excluded (timing) columns: wall_time_s" in out
    assert "~print" in out
    assert _run(capsys, old_p, new_p, "--strict-precision")[0] == 1
    # two units is a real difference
    new2 = header + "nominal,none,circle,local,kinematic,0.00108516,2.05,,0.5\n"
    assert _run(capsys, old_p, _write(tmp_path, "new2.csv", new2))[0] == 1


@pytest.mark.parametrize(
    ("name", "timing"),
    [
        ("step_time_median_ms", True),
        ("wall_time_s", True),
        ("solve_time_s", True),
        ("exec_time_s", False),
        ("time_s", False),
        ("e_mean", False),
    ],
)
def test_timing_columns(name, timing):
    assert compare_results.is_timing_column(name) is timing


def test_unknown_header_needs_keys(tmp_path, capsys):
    path = _write(tmp_path, "x.csv", "a,b\n1,2\n")
    assert _run(capsys, path, path)[0] == 2
    code, out = _run(capsys, path, path, "--keys", "a")
    assert code == 0 and "RESULT: SAME" in out
