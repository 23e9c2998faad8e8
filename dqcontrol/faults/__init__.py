"""Fault injection and the fault campaign: the controllers under measurement
noise and delay, model mismatch, torque saturation, impossible tasks, awkward starts and
failing or contradictory QPs.

- :mod:`~dqcontrol.faults.simulation` — :func:`fault_driver`, a case's arm with its faults
  as driver wrappers (:class:`~dqcontrol.sim.FaultyDriver`,
  :class:`~dqcontrol.sim.PayloadDriver`, :class:`~dqcontrol.sim.TorqueLimitDriver`);
- :mod:`~dqcontrol.faults.qp_faults` — QPs with contradictory bounds (:func:`contradictory`);
- :mod:`~dqcontrol.faults.scenarios` — the controllers, trajectories and faults by name;
- :mod:`~dqcontrol.faults.cases` — the cases and their rows (:class:`CaseSpec`,
  :func:`campaign_cases`, :class:`CaseResult`, :class:`CampaignResult`);
- :mod:`~dqcontrol.faults.campaign` — :func:`run_campaign` and :func:`run_case`: the runs
  and their judgement;
- :mod:`~dqcontrol.faults.report` — the report (:func:`render_markdown`, :func:`render_csv`).
"""

from dqcontrol.faults.campaign import (
    CampaignResult,
    CaseResult,
    CaseSpec,
    campaign_cases,
    render_csv,
    render_markdown,
    run_campaign,
    run_case,
)
from dqcontrol.faults.qp_faults import ContradictoryBoundsQP, contradictory
from dqcontrol.faults.scenarios import CONTROLLERS, FAULTS, TRAJECTORIES, Fault, fault_by_name
from dqcontrol.faults.simulation import fault_driver

__all__ = [
    "CONTROLLERS",
    "FAULTS",
    "TRAJECTORIES",
    "CampaignResult",
    "CaseResult",
    "CaseSpec",
    "ContradictoryBoundsQP",
    "Fault",
    "campaign_cases",
    "contradictory",
    "fault_by_name",
    "fault_driver",
    "render_csv",
    "render_markdown",
    "run_campaign",
    "run_case",
]
