"""Trajectories rebuilt from the metadata they write (:meth:`Trajectory.to_metadata`)."""

from __future__ import annotations

import inspect
from collections.abc import Mapping

from dqcontrol.errors import ParameterError
from dqcontrol.trajectories.base import Trajectory
from dqcontrol.trajectories.circle import Circle
from dqcontrol.trajectories.sinusoid import Sinusoid
from dqcontrol.trajectories.waypoints import WaypointTrajectory

__all__ = ["TRAJECTORY_KINDS", "trajectory_from_metadata"]

#: The kinds that describe themselves, by their metadata name.
TRAJECTORY_KINDS: dict[str, type[Trajectory]] = {
    cls.kind: cls for cls in (Circle, Sinusoid, WaypointTrajectory)
}
#: Keys of a run's metadata that are not the trajectory's (skipped when rebuilding it).
_COMMON_KEYS = ("trajectory", "duration_s", "reference")


def trajectory_from_metadata(meta: Mapping) -> Trajectory:
    """The trajectory that :meth:`Trajectory.to_metadata` described.

    ``meta`` may hold other keys besides (a saved run's metadata does): only ``trajectory``
    (the kind), ``duration_s``, ``reference`` and the kind's own parameters are read; a
    parameter left out takes the class's default.

    Raises:
        ParameterError: no ``trajectory`` or ``duration_s``, an unknown kind (the message
            lists the known ones), or a value the class rejects.
    """
    kind = meta.get("trajectory")
    cls = TRAJECTORY_KINDS.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise ParameterError(
            f"metadata names no known trajectory (trajectory={kind!r}); known: "
            f"{sorted(TRAJECTORY_KINDS)}"
        )
    if meta.get("duration_s") is None:
        raise ParameterError(f"the {kind} metadata has no duration_s")
    params = _parameters(cls)
    kwargs = {k: meta[k] for k in params if k in meta and k not in _COMMON_KEYS}
    return cls(duration_s=float(meta["duration_s"]), reference=meta.get("reference"), **kwargs)


def _parameters(cls: type[Trajectory]) -> tuple[str, ...]:
    return tuple(inspect.signature(cls.__init__).parameters)[1:]
