"""Controllers by name: the one table from which the CLI, Table 1, the fault campaign and the
benchmark build their controllers.

A name resolves to a :class:`ControllerSpec`: the class, the keyword arguments that make it
this controller (e.g. ``num_instants=10``), the label the tables print, a one-line
description, and whether it is a QP controller (hard bounds as constraints) or only clips
its command. Names are case-insensitive; each family has a canonical name and the aliases
the tools have used:

============  ==================================  ===========================================
canonical     aliases                             controller
============  ==================================  ===========================================
local                                             :class:`LocalController`
pN (N ≥ 2)    predictive_pN                       :class:`PredictiveController`, ``N`` instants
noscale       noscale10, predictive_noscale_p10   :class:`PredictiveNoScalingController`, p = 10
noscaleN      predictive_noscale_pN               the same with ``N`` instants
proportional                                      :class:`ProportionalController`
pf            pf10, path-following,               :class:`PathFollowingController`, p = 10
              path_following
pfN (N ≥ 2)                                       the same with ``N`` intervals (pf6, pf20, ...)
============  ==================================  ===========================================

This module sits above :mod:`dqcontrol.controllers` (it imports them; nothing there imports
it).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

from dqcontrol.controllers import (
    LocalController,
    PredictiveController,
    PredictiveNoScalingController,
    ProportionalController,
)
from dqcontrol.controllers.base import Controller
from dqcontrol.controllers.path_following.controller import PathFollowingController
from dqcontrol.errors import ParameterError
from dqcontrol.model.robot import RobotModel
from dqcontrol.trajectories import Trajectory

__all__ = [
    "CONTROLLER_HELP",
    "KNOWN_NAMES",
    "SHARED_OPTIONS",
    "ControllerSpec",
    "build_controller",
    "controller_spec",
]

#: Settings a tool may give every controller it builds; each spec lists those it takes
#: (:attr:`ControllerSpec.takes`), the others are left to the controller's default.
SHARED_OPTIONS = (
    "velocity_limits",
    "acceleration_limit",
    "gain_per_s",
    "horizon_s",
    "solver",
    "servo_time_constant_s",
)
_TRACKING = ("velocity_limits", "acceleration_limit", "gain_per_s", "solver")


@dataclass(frozen=True)
class ControllerSpec:
    """A controller by name: how to build it and how to show it.

    Attributes:
        name: the canonical name (``local``, ``p10``, ``pf``, ...).
        cls: the controller class.
        kwargs: keyword arguments that make it this controller (besides robot, trajectory,
            period), as ``(name, value)`` pairs.
        qp: whether it is a QP controller (hard bounds as constraints); the proportional
            controller only clips its command, and is reported separately.
        label: how tables write it (``Local``, ``p=10``, ``path-following``).
        description: one line for help texts.
        takes: which of :data:`SHARED_OPTIONS` its constructor accepts.
    """

    name: str
    cls: type[Controller]
    kwargs: tuple[tuple[str, object], ...] = ()
    qp: bool = True
    label: str = ""
    description: str = ""
    takes: tuple[str, ...] = _TRACKING

    @property
    def num_instants(self) -> int:
        """``p``: prediction instants or intervals (1 for the single-instant controllers)."""
        kw: dict[str, Any] = dict(self.kwargs)
        return int(kw.get("num_instants", kw.get("num_intervals", 1)))

    @property
    def table_label(self) -> str:
        """:attr:`label`, or the name when there is none."""
        return self.label or self.name

    def options(self, shared: Mapping[str, object]) -> dict[str, object]:
        """The entries of ``shared`` this controller takes (:attr:`takes`), ``None`` values
        dropped (they mean "the controller's default")."""
        return {k: v for k, v in shared.items() if k in self.takes and v is not None}

    def build(
        self, robot: RobotModel, trajectory: Trajectory, period_s: float, **extra
    ) -> Controller:
        """The controller; ``extra`` adds or overrides keyword arguments."""
        kwargs: dict[str, Any] = dict(self.kwargs)
        kwargs.update(extra)
        return self.cls(robot, trajectory, period_s, **kwargs)

    def renamed(self, name: str) -> ControllerSpec:
        """The same controller under another name (e.g. a campaign's own naming)."""
        return replace(self, name=name)


def _predictive(p: int) -> ControllerSpec:
    return ControllerSpec(
        f"p{p}",
        PredictiveController,
        (("num_instants", p),),
        label=f"p={p}",
        description=f"the predictive method with time scaling, {p} prediction instants",
        takes=(*_TRACKING, "horizon_s"),
    )


def _noscale(p: int) -> ControllerSpec:
    return ControllerSpec(
        "noscale" if p == 10 else f"noscale{p}",
        PredictiveNoScalingController,
        (("num_instants", p),),
        label=f"no scaling, p={p}",
        description=f"the predictive method without time scaling, {p} prediction instants",
        takes=(*_TRACKING, "horizon_s"),
    )


def _path_following(p: int) -> ControllerSpec:
    return ControllerSpec(
        "pf" if p == 10 else f"pf{p}",
        PathFollowingController,
        (("num_intervals", p),),
        label="path-following" if p == 10 else f"path-following p={p}",
        description=f"path first, progress second (consistent prediction), {p} intervals",
        takes=(
            "velocity_limits",
            "acceleration_limit",
            "horizon_s",
            "solver",
            "servo_time_constant_s",
        ),  # fmt: skip
    )


_FIXED: dict[str, ControllerSpec] = {
    "local": ControllerSpec(
        "local", LocalController, label="Local", description="the local method with time scaling"
    ),
    "proportional": ControllerSpec(
        "proportional",
        ProportionalController,
        qp=False,
        label="proportional",
        description="the invariant-error proportional controller (clipped to the bounds)",
        takes=("velocity_limits", "acceleration_limit", "gain_per_s"),
    ),
}
_ALIASES = {"path-following": "pf", "path_following": "pf"}
#: Families with a count: pattern → (builder, smallest count, default count or None).
_FAMILIES = (
    (re.compile(r"^(?:p|predictive_p)(\d+)$"), _predictive, None),
    (re.compile(r"^(?:noscale|predictive_noscale_p)(\d*)$"), _noscale, 10),
    (re.compile(r"^pf(\d*)$"), _path_following, 10),
)
#: The names listed in errors and help texts (each family once).
KNOWN_NAMES = ("local", "p6", "p10", "pN", "noscale", "noscaleN", "proportional", "pf", "pfN")
#: One line per family, for the command line's help texts.
CONTROLLER_HELP = """\
  local         the local method with time scaling
  p6, p10, pN   the predictive method with N prediction instants (N >= 2)
  noscale       the predictive method without time scaling (p = 10; noscaleN for N)
  proportional  the invariant-error proportional controller (clipped to the bounds)
  pf            path following: path first, progress second, p = 10 intervals
                (aliases path-following, pf10; pf6, pf20, pfN for N intervals)"""


def _unknown(raw: str, why: str = "") -> ParameterError:
    return ParameterError(
        f"unknown controller {raw!r}{why}; known: local, p6, p10 (pN for any N >= 2), noscale "
        "(noscaleN), proportional, pf (pfN; alias path-following)"
    )


def controller_spec(name: str) -> ControllerSpec:
    """The :class:`ControllerSpec` of ``name`` (a canonical name or an alias, any case).

    Raises:
        ParameterError: an unknown name (the message lists the known ones), or a count
            below 2 (``p1``).
    """
    if not isinstance(name, str):
        raise _unknown(str(name))
    key = name.strip().lower()
    key = _ALIASES.get(key, key)
    if key in _FIXED:
        return _FIXED[key]
    for pattern, make, default in _FAMILIES:
        match = pattern.match(key)
        if match is None:
            continue
        digits = match.group(1)
        if not digits:
            if default is None:
                break
            return make(default)
        count = int(digits)
        if count < 2:
            raise _unknown(name.strip(), " (the count must be at least 2)")
        return make(count)
    raise _unknown(name.strip())


def build_controller(
    name: str | ControllerSpec,
    robot: RobotModel,
    trajectory: Trajectory,
    period_s: float,
    *,
    shared: Mapping[str, object] | None = None,
    **extra,
) -> Controller:
    """Build the controller ``name``.

    Args:
        name: a name of :func:`controller_spec` or a spec.
        robot: as for every controller.
        trajectory: as for every controller.
        period_s: as for every controller.
        shared: settings of :data:`SHARED_OPTIONS` offered to every controller; only those
            it takes are passed (:meth:`ControllerSpec.options`).
        **extra: keyword arguments passed as they are (override ``shared``).
    """
    spec = controller_spec(name) if isinstance(name, str) else name
    kwargs = spec.options(shared or {})
    kwargs.update(extra)
    return spec.build(robot, trajectory, period_s, **kwargs)
