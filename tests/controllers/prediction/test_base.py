"""The prediction-model interface (dqcontrol/controllers/prediction/base.py): the
prediction's phase weights and the abstract model's contract."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.prediction.base import Prediction, PredictionModel


def _prediction(sigma_weights):
    q = np.zeros((2, 3))
    sigma = np.zeros(2)
    weights = np.array([[1.0, 0.0], [1.0, 2.0]])
    return Prediction(q, sigma, q, sigma, weights, None, None, sigma_weights)


def test_phase_weights_default_to_the_joint_weights():
    pred = _prediction(None)
    assert pred.phase_weights is pred.weights
    own = np.array([[3.0, 0.0], [3.0, 4.0]])
    assert _prediction(own).phase_weights is own


def test_a_model_must_implement_reset_predict_and_commit():
    class Partial(PredictionModel):
        def reset(self, q0, qd0):
            pass

        def predict(self, q, sigma):
            raise NotImplementedError

    with pytest.raises(TypeError, match="commit"):
        Partial()
    assert PredictionModel.warm is False  # no warm start unless a controller asks for one
