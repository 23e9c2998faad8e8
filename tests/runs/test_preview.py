"""dqcontrol/runs/preview.py: the preview's stride for a period and its JSON messages against
the block's samples picked by hand."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dqcontrol.runs.preview import PREVIEW_SCHEMA, preview_messages, preview_stride


@pytest.mark.parametrize(
    ("period_s", "stride"), [(0.001, 20), (0.01, 2), (0.02, 1), (0.05, 1), (0.004, 5)]
)
def test_about_fifty_messages_a_second(period_s, stride):
    assert preview_stride(period_s) == stride


def _arrays(rng, count: int, n: int = 3) -> dict[str, np.ndarray]:
    torque = rng.standard_normal((count, n))
    torque[3, 0] = np.nan  # the kinematic loop has no torques
    return {
        "t_s": 0.01 * np.arange(count),
        "sigma": rng.uniform(0, 1, count),
        "s": rng.uniform(0, 1, count),
        "q": rng.standard_normal((count, n)),
        "qd_measured": rng.standard_normal((count, n)),
        "qd_command": rng.standard_normal((count, n)),
        "torque": torque,
        "pose": rng.standard_normal((count, 8)),
        "target": rng.standard_normal((count, 8)),
        "solver_status": np.array(["solved", "closed_form"] * (count // 2), dtype="U32"),
        "step_time_s": rng.uniform(0, 1e-3, count),
    }


@pytest.mark.parametrize("first_index", [0, 1, 6])
def test_the_messages_are_the_samples_at_multiples_of_the_stride(first_index):
    rng = np.random.default_rng(first_index)
    arrays = _arrays(rng, 10)
    stride = 3
    rows = [k for k in range(10) if (first_index + k) % stride == 0]
    messages = list(preview_messages(arrays, first_index, stride))
    assert len(messages) == len(rows)
    for (time_ns, data), k in zip(messages, rows, strict=True):
        message = json.loads(data)
        assert set(message) == set(PREVIEW_SCHEMA["properties"])
        assert time_ns == round(arrays["t_s"][k] * 1e9) and message["t_s"] == arrays["t_s"][k]
        assert message["q"] == arrays["q"][k].tolist()
        assert message["qd_command"] == arrays["qd_command"][k].tolist()
        error = np.sqrt(np.sum((arrays["target"][k] - arrays["pose"][k]) ** 2))
        assert message["error"] == pytest.approx(error, rel=1e-12)
        assert message["solver_status"] == arrays["solver_status"][k]
        torque = [None if np.isnan(v) else v for v in arrays["torque"][k]]
        assert message["torque"] == torque
