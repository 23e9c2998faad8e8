"""``dqcontrol.faults.figures`` without its MuJoCo runs: the distance beyond the limits it
plots, against a hand computation, and its command line with the figures stubbed out."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from dqcontrol.faults import figures


def test_the_excess_is_the_largest_signed_distance_beyond_a_limit(lbr4p):
    lim = lbr4p.limits
    inside = 0.5 * (lim.q_min + lim.q_max)
    beyond_top = lim.q_max.copy()
    beyond_top[2] += 2e-3
    beyond_bottom = lim.q_min + 0.1
    beyond_bottom[5] = lim.q_min[5] - 5e-4
    t, excess = figures._excess_mrad(
        SimpleNamespace(true_q=np.array([inside, beyond_top, beyond_bottom]))
    )
    np.testing.assert_allclose(t, [0.0, 0.05, 0.1])
    # inside: the distance to the nearest limit, negative
    assert excess[0] == -1000.0 * (0.5 * (lim.q_max - lim.q_min)).min()
    np.testing.assert_allclose(excess[1:], [2.0, 0.5], rtol=1e-9)


def test_the_command_writes_both_figures_and_the_table(tmp_path, monkeypatch, capsys):
    def fake_figure(path):
        path.write_bytes(b"x" * 3000)
        return path

    monkeypatch.setattr(figures, "unreachable_figure", fake_figure)
    monkeypatch.setattr(figures, "limits_figure", fake_figure)
    monkeypatch.setattr(figures, "mitigation_table", lambda simulator: [])
    out = tmp_path / "img"
    assert figures.main(["--out", str(out), "--mitigations"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["faults_limits.png", "faults_unreachable.png"]
    text = capsys.readouterr().out
    assert f"wrote {out / 'faults_unreachable.png'} (2 kB)" in text
    assert "| case | variant | status |" in text
