"""What-if experiments behind the campaign's findings (docs/faults.md).

Each function here emulates, on one controller *instance*, a change that is proposed for
the controllers or the solver wrapper — without editing them — so that the proposal comes
with a measurement:

- :func:`compensate_delay`: predict the current joint positions from a ``d``-period-old
  measurement and the ``d`` commands sent since (``q̂ = q_meas + T Σ qd_cmd``);
- :func:`position_margin`: keep a margin inside every joint limit (QP controllers);
- :func:`validate_bounds`: refuse a QP whose bounds are crossed or NaN instead of passing it
  to a solver that silently keeps the previous problem's solution;
- :func:`keep_warm_start`: do not throw the solver's warm start away after a failed solve.

:func:`mitigation_table` runs the campaign's worst cases with and without them.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from dqcontrol.controllers.base import Controller
from dqcontrol.controllers.qp_solver import QPSolution
from dqcontrol.controllers.tracking import TrackingController
from dqcontrol.errors import ParameterError
from dqcontrol.faults.campaign import CaseResult, CaseSpec, run_case
from dqcontrol.faults.scenarios import CONTROLLERS, TRAJECTORIES, ControllerSpec, fault_by_name

__all__ = [
    "compensate_delay",
    "keep_warm_start",
    "mitigation_table",
    "position_margin",
    "validate_bounds",
]


def compensate_delay(controller: Controller, delay_periods: int) -> Controller:
    """Feed ``controller`` the predicted current positions ``q_meas + T Σ`` (last ``d``
    commands) instead of the ``d``-period-old measurement. Returns the same instance."""
    d = int(delay_periods)
    if d < 0:
        raise ParameterError(f"delay_periods must be ≥ 0, got {delay_periods!r}")
    if d == 0:
        return controller
    sent: deque[np.ndarray] = deque([np.zeros(controller.n)] * d, maxlen=d)
    step, reset = controller.step, controller.reset

    def predicted_step(q, qd=None):
        result = step(np.asarray(q, dtype=float) + controller.period_s * sum(sent), qd)
        sent.append(result.qd_command.copy())
        return result

    def fresh_reset(q0, qd0=None, sigma0=0.0):
        sent.extend([np.zeros(controller.n)] * d)
        return reset(q0, qd0, sigma0)

    controller.step = predicted_step
    controller.reset = fresh_reset
    return controller


def position_margin(controller: TrackingController, margin_rad: float) -> TrackingController:
    """Narrow the joint limits the QP controller enforces by ``margin_rad`` on each side."""
    if not isinstance(controller, TrackingController):
        raise ParameterError("position_margin needs a QP (TrackingController) controller")
    lim = controller.robot.limits
    controller.q_min = lim.q_min + margin_rad
    controller.q_max = lim.q_max - margin_rad
    return controller


class _ValidatingQP:
    """Solver proxy that fails a QP with ``lower > upper`` or NaN bounds (the proposed check
    in ``OsqpQP.solve``) and passes everything else on."""

    def __init__(self, inner) -> None:
        self.inner = inner

    def __getattr__(self, name):
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)

    def solve(self, p_values, c, lower, upper, warm_x=None):
        if np.isnan(lower).any() or np.isnan(upper).any() or np.any(lower > upper):
            return QPSolution(None, None, False, "invalid_bounds", 0, 0.0)
        return self.inner.solve(p_values, c, lower, upper, warm_x)


def validate_bounds(controller: TrackingController) -> TrackingController:
    """Put a bounds check between ``controller`` and its solver (innermost, so that a
    :class:`~dqcontrol.faults.qp_faults.ContradictoryBoundsQP` still corrupts first)."""
    qp = controller.qp
    if hasattr(qp, "mode") and hasattr(qp, "inner"):  # the fault proxy: validate behind it
        qp.inner = _ValidatingQP(qp.inner)
    else:
        controller.qp = _ValidatingQP(qp)
    return controller


def keep_warm_start(controller: TrackingController) -> TrackingController:
    """Keep the solver's state after a failed solve: the controller's fallback path resets
    the solver (a cold start next step); here only :meth:`Controller.reset` does."""
    qp = controller.qp
    inner = getattr(qp, "inner", qp)
    real_reset = inner.reset
    in_reset = {"flag": False}
    reset = controller.reset

    def reset_run(*args, **kwargs):
        in_reset["flag"] = True
        try:
            return reset(*args, **kwargs)
        finally:
            in_reset["flag"] = False

    def maybe_reset():
        if in_reset["flag"]:
            real_reset()

    inner.reset = maybe_reset
    controller.reset = reset_run
    return controller


def _spec(fault: str, traj: str, controller: str | ControllerSpec, simulator: str) -> CaseSpec:
    ctrl = CONTROLLERS[controller] if isinstance(controller, str) else controller
    t = TRAJECTORIES[traj]
    return CaseSpec(ctrl, t, fault_by_name(fault), simulator, t.duration_s)


def _run(spec: CaseSpec, hook: Callable[[Controller], object] | None = None) -> CaseResult:
    return run_case(spec, hook=hook)


def mitigation_table(simulator: str = "mujoco") -> list[dict]:
    """The campaign's worst cases (local controller) with and without each proposed change.

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
    add("near_limits/circle", "as is", _run(spec))
    add("near_limits/circle", "margin 1 mrad", _run(spec, lambda c: position_margin(c, 1e-3)))
    spec = _spec("near_limits_noise", "circle", "local", simulator)
    add("near_limits_noise/circle", "as is", _run(spec))
    add(
        "near_limits_noise/circle",
        "margin 6 mrad (3σ)",
        _run(spec, lambda c: position_margin(c, 6e-3)),
    )
    for sim in ("kinematic", simulator) if simulator != "kinematic" else ("kinematic",):
        spec = _spec("near_limits_delay_2", "circle", "local", sim)
        case = f"near_limits_delay_2/circle ({sim})"
        add(case, "as is", _run(spec))
        add(case, "delay compensation", _run(spec, lambda c: compensate_delay(c, 2)))
        add(
            case,
            "compensation + margin 1 mrad",
            _run(spec, lambda c: position_margin(compensate_delay(c, 2), 1e-3)),
        )
    # delay on the path
    spec = _spec("delay_2", "sinusoid", "local", simulator)
    add("delay_2/sinusoid", "as is", _run(spec))
    add("delay_2/sinusoid", "delay compensation", _run(spec, lambda c: compensate_delay(c, 2)))
    # contradictory bounds reaching the solver
    for ctrl in ("local", "predictive_p6"):
        spec = _spec("qp_crossed", "sinusoid", ctrl, simulator)
        add(f"qp_crossed/sinusoid/{ctrl}", "as is", _run(spec))
        add(f"qp_crossed/sinusoid/{ctrl}", "bounds validated", _run(spec, validate_bounds))
    # flaky solver: cold restart after every failure
    spec = _spec("solver_flaky", "sinusoid", "local", simulator)
    add("solver_flaky/sinusoid", "as is", _run(spec))
    add("solver_flaky/sinusoid", "warm start kept", _run(spec, keep_warm_start))
    # the singular boundary of the workspace: more damping
    for ctrl in ("local", "predictive_p6"):
        case = f"unreachable/circle/{ctrl}"
        add(case, "as is (μ = 1e-6)", _run(_spec("unreachable", "circle", ctrl, simulator)))
        for mu in (1e-5, 1e-4):
            base = CONTROLLERS[ctrl]
            tuned = replace(base, kwargs=base.kwargs + (("regularization", mu),))
            add(case, f"μ = {mu:g}", _run(_spec("unreachable", "circle", tuned, simulator)))
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
