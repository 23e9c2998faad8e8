"""The check that the chosen simulator is installed (dqcontrol/cli/_extras.py): MuJoCo without
the ``[sim]`` extra is refused before any work, naming the extra; the kinematic loop needs
none."""

from __future__ import annotations

import pytest

from dqcontrol.cli import _extras
from dqcontrol.cli._extras import check_simulator
from dqcontrol.errors import MissingExtraError


def test_mujoco_without_the_sim_extra_is_refused(monkeypatch):
    monkeypatch.setattr(_extras, "has_extra", lambda extra: extra != "sim")
    with pytest.raises(MissingExtraError) as info:
        check_simulator("mujoco")
    assert str(info.value) == (
        "--simulator mujoco (the default; 'kinematic' needs no extra) needs mujoco, which "
        "comes with the [sim] extra: pip install 'dqcontrol[sim]'"
    )
    with pytest.raises(MissingExtraError, match="^the simulation server needs mujoco"):
        check_simulator("mujoco", "the simulation server")
    check_simulator("kinematic")  # needs no extra


def test_with_the_extra_nothing_is_raised(monkeypatch):
    monkeypatch.setattr(_extras, "has_extra", lambda extra: True)
    check_simulator("mujoco")
