"""Step contexts shared by the tests of the terms and limits (not a test module): a context
at random states of a real robot, and a consistent prediction at seeded random plans."""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import DecisionLayout
from dqcontrol.controllers.prediction.consistent import ConsistentPrediction, interval_breakpoints
from dqcontrol.controllers.prediction.thesis import ThesisPrediction
from dqcontrol.model import LBR4P_Q0


def random_context(robot, p: int, seed: int, with_scaling: bool = True) -> StepContext:
    """A context at random states near ``LBR4P_Q0`` with the robot's real kinematics and
    random targets (some of them on the other side of ``±x``)."""
    rng = np.random.default_rng(seed)
    n = robot.nq
    tau = np.linspace(0.0, 1.0, p) ** 2 if p > 1 else np.zeros(1)
    durations = np.append(np.diff(tau), np.diff(tau)[-1:]) if p > 1 else np.array([0.01])
    layout = DecisionLayout(n, tau, durations, with_scaling=with_scaling)
    q = LBR4P_Q0 + rng.uniform(-0.3, 0.3, n)
    q_lin = q + rng.uniform(-0.2, 0.2, (p, n))
    q_lin[0] = q
    xs, jacs = robot.poses_and_jacobians(q_lin)
    xd = xs + rng.normal(scale=0.05, size=xs.shape)
    xd[::2] *= -1.0  # the nearer of ±x must be taken
    flip = np.einsum("pk,pk->p", xs, xd) < 0
    xs = np.where(flip[:, None], -xs, xs)
    jacs = np.where(flip[:, None, None], -jacs, jacs)
    dxd = rng.normal(size=xs.shape)
    sigma_lin = np.sort(rng.uniform(0.0, 1.0, p))
    pred = (
        ThesisPrediction(layout, 0.01)
        .predict(q, 0.0)
        ._replace(q_lin=q_lin, q_base=q_lin, sigma_lin=sigma_lin, sigma_base=sigma_lin)
    )
    a_max = rng.uniform(2.0, 20.0, (p, n))
    return StepContext(
        robot, None, layout, 0.01, q, rng.uniform(-1, 1, n), 0.0, pred, xs, jacs, xd, dxd,
        a_max,
    )  # fmt: skip


def split(layout: DecisionLayout, z: np.ndarray):
    """The joint velocities ``(p, n)`` of a decision ``z`` and its scalings ``(p,)`` (None
    without scaling variables)."""
    blocks = z.reshape(layout.num_blocks, layout.block_size)
    n = layout.num_joints
    return blocks[:, :n], (blocks[:, n] if layout.with_scaling else None)


def consistent_prediction(seed: int, p: int = 5, n: int = 4):
    """A path-following prediction of ``p`` intervals over ``n`` joints after a seeded
    random plan: the model, its prediction and the generator that drew it."""
    model = ConsistentPrediction(interval_breakpoints(p, 0.5, 0.01), n, 0.01)
    rng = np.random.default_rng(seed)
    model.commit(rng.normal(size=(p, n)), rng.uniform(0.0, 1.0, p))
    return model, model.predict(rng.uniform(-1.0, 1.0, n), 0.2), rng


class PredictionContext:
    """The two fields of a step context the path-following limits' rows read."""

    def __init__(self, prediction, a_max):
        self.prediction, self.a_max = prediction, a_max
