"""The check, shared by the commands that simulate, that the chosen simulator is installed."""

from __future__ import annotations

from dqcontrol.extras import has_extra, missing_extra

_DEFAULT_PURPOSE = "--simulator mujoco (the default; 'kinematic' needs no extra)"


def check_simulator(simulator: str, purpose: str = _DEFAULT_PURPOSE) -> None:
    """Raise :class:`~dqcontrol.errors.MissingExtraError` before any work when
    ``simulator`` is ``"mujoco"`` and the ``sim`` extra is not installed."""
    if simulator == "mujoco" and not has_extra("sim"):
        raise missing_extra("mujoco", extra="sim", purpose=purpose)
