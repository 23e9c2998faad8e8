"""Each safeguard of the controllers switched off and on, on the campaign's worst cases.

The fault campaign found four gaps (docs/faults.md); the controllers now close them with
options, and this module measures what each option buys by running the same case with the
controller *unaware* of the fault and then with the safeguard on:

- ``position_margin_rad`` (default 5 mrad): the position bounds stop inside the URDF's
  limits, so a servo's overshoot and the measurement noise stay inside too
  (:func:`position_margin` sets it on an instance, 0 switches it off);
- ``measurement_delay_periods``: the controller predicts the present joint positions from a
  ``d``-period-old measurement and the commands sent since (:func:`compensate_delay`);
- ``stall_damping`` (default 1e-3): extra damping on ``‖qd‖²`` while ``s`` is near 0, so
  that an arm stalled on an unreachable path comes to rest instead of chattering at its
  acceleration bound (0 switches it off; a larger constant ``regularization`` ``μ``, the
  alternative first tried, is measured beside it).

(The two solver fixes — crossed bounds refused before the solver, the warm start kept after
a failed solve — have no switch; their before/after figures are in docs/faults.md.)
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import replace

from dqcontrol.controllers.base import Controller
from dqcontrol.controllers.proportional import ProportionalController
from dqcontrol.controllers.thesis.controller import TrackingController
from dqcontrol.errors import ParameterError
from dqcontrol.faults.campaign import CaseResult, CaseSpec, run_case
from dqcontrol.faults.scenarios import CONTROLLERS, TRAJECTORIES, ControllerSpec, fault_by_name

__all__ = ["compensate_delay", "mitigation_table", "position_margin", "render_mitigations"]


def compensate_delay(controller: Controller, delay_periods: int) -> Controller:
    """Set ``measurement_delay_periods`` of an existing controller (before its reset)."""
    d = int(delay_periods)
    if d < 0:
        raise ParameterError(f"delay_periods must be ≥ 0, got {delay_periods!r}")
    controller.measurement_delay_periods = d
    controller._sent = deque(maxlen=max(d, 1))
    return controller


def position_margin(controller: Controller, margin_rad: float) -> Controller:
    """Set the joint-position margin [rad] of an existing controller (0: none): one with
    joint-position bounds of its own (a tracking or proportional controller)."""
    if not isinstance(controller, TrackingController | ProportionalController):
        raise ParameterError(
            f"position_margin needs a tracking or proportional controller, got "
            f"{type(controller).__name__}"
        )
    lim = controller.robot.limits
    controller.position_margin_rad = float(margin_rad)
    controller.q_min = lim.q_min + margin_rad
    controller.q_max = lim.q_max - margin_rad
    return controller


def _spec(fault: str, traj: str, controller: str | ControllerSpec, simulator: str) -> CaseSpec:
    """The case with the controller unaware of the fault (no compensation, no wider margin)."""
    ctrl = CONTROLLERS[controller] if isinstance(controller, str) else controller
    t = TRAJECTORIES[traj]
    return CaseSpec(ctrl, t, replace(fault_by_name(fault), compensated=False), simulator,
                    t.duration_s)  # fmt: skip


def _run(spec: CaseSpec, hook: Callable[[Controller], object] | None = None) -> CaseResult:
    return run_case(spec, hook=hook)


def mitigation_table(simulator: str = "mujoco") -> list[dict]:
    """The campaign's worst cases (local controller) with each safeguard off and on.

    Returns rows ``{"case", "variant", "status", "sigma", "dev_max_mm", "q_viol",
    "q_excess_mrad", "fallbacks", "speed_end"}``.
    """
    rows = []

    def add(case: str, variant: str, r: CaseResult) -> None:
        rows.append(
            {
                "case": case,
                "variant": variant,
                "status": r.status,
                "sigma": r.sigma_reached_s,
                "dev_max_mm": 1000.0 * r.path_dev_max_m,
                "q_viol": r.q_violations_true,
                "q_excess_mrad": 1000.0 * r.q_excess_true_rad,
                "fallbacks": r.fallbacks,
                "speed_end": r.speed_end_rad_s,
            }
        )

    # joint limits: servo overshoot, noise, delay
    spec = _spec("near_limits", "circle", "local", simulator)
    add("near_limits/circle", "no margin", _run(spec, lambda c: position_margin(c, 0.0)))
    add("near_limits/circle", "margin 5 mrad (default)", _run(spec))
    spec = _spec("near_limits_noise", "circle", "local", simulator)
    add("near_limits_noise/circle", "margin 5 mrad (default)", _run(spec))
    add(
        "near_limits_noise/circle",
        "margin 6 mrad (3σ)",
        _run(spec, lambda c: position_margin(c, 6e-3)),
    )
    for sim in ("kinematic", simulator) if simulator != "kinematic" else ("kinematic",):
        spec = _spec("near_limits_delay_2", "circle", "local", sim)
        case = f"near_limits_delay_2/circle ({sim})"
        add(case, "no margin, unaware of the delay", _run(spec, lambda c: position_margin(c, 0)))
        add(case, "margin 5 mrad, unaware of the delay", _run(spec))
        add(case, "margin 5 mrad, delay compensated", _run(spec, lambda c: compensate_delay(c, 2)))
    # delay on the path
    spec = _spec("delay_2", "sinusoid", "local", simulator)
    add("delay_2/sinusoid", "unaware of the delay", _run(spec))
    add("delay_2/sinusoid", "delay compensated", _run(spec, lambda c: compensate_delay(c, 2)))
    # the singular boundary of the workspace: damping while stalled, or a larger μ
    for ctrl in ("local", "predictive_p6", "predictive_p10"):
        case = f"unreachable/circle/{ctrl}"
        base = CONTROLLERS[ctrl]
        variants = [
            ("no stall damping (μ = 1e-6)", (("stall_damping", 0.0),)),
            ("stall damping 1e-3 (default)", ()),
            ("no stall damping, μ = 1e-5", (("stall_damping", 0.0), ("regularization", 1e-5))),
        ]
        for label, extra in variants:
            tuned = replace(base, kwargs=base.kwargs + extra)
            add(case, label, _run(_spec("unreachable", "circle", tuned, simulator)))
    return rows


def render_mitigations(rows: list[dict]) -> str:
    """Markdown table of :func:`mitigation_table`."""
    lines = [
        "| case | variant | status | σ reached [s] | dev max [mm] | viol q true [max mrad] "
        "| fallbacks | speed end [rad/s] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        q = "0" if r["q_viol"] == 0 else f"{r['q_viol']} [{r['q_excess_mrad']:.2f}]"
        lines.append(
            f"| {r['case']} | {r['variant']} | {r['status']} | {r['sigma']:.2f} | "
            f"{r['dev_max_mm']:.1f} | {q} | {r['fallbacks']} | {r['speed_end']:.2f} |"
        )
    return "\n".join(lines) + "\n"
