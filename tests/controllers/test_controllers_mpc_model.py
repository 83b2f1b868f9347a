"""Where the MPC's matrices come from (a linear model's (A, B, c) composed over the step, or a
nonlinear model's linearisation at hover), and its parameter checks."""

from __future__ import annotations

import numpy as np
import pytest
from test_controllers_mpc_qp import swimmer_like

from cosim import ComponentError
from cosim.scenario.paths import make_path
from cosim_plugins.controllers.mpc import MPCController, model_matrices
from cosim_plugins.identify.model import Model


class Linear(Model):
    name = "test-linear"

    def __init__(self):
        super().__init__()
        self.dt_s = 0.02
        self.A, self.B, self.c = swimmer_like(sink_mm_s=3.5)

    def _step(self, x, u):
        return x @ self.A.T + u @ self.B.T + self.c

    def linear_matrices(self):
        return self.A, self.B, self.c


class Quadratic(Linear):
    """The linear swimmer plus quadratic drag on v (zero slope at hover, v = 0)."""

    name = "test-quadratic"

    def linear_matrices(self):
        raise NotImplementedError

    def _step(self, x, u):
        out = super()._step(x, u)
        out[:, 3:] -= 0.01 * x[:, 3:] * np.abs(x[:, 3:])
        return out


def test_linear_model_is_composed_over_the_scenario_step():
    model = Linear()
    A, B, c = model_matrices(model, 0.04)
    rng = np.random.default_rng(0)
    x, u = rng.normal(size=6), rng.normal(size=3)
    np.testing.assert_allclose(A @ x + B @ u + c, model.predict(x, u, 0.04), atol=1e-12)


def test_nonlinear_model_is_linearised_at_hover():
    model, lin = Quadratic(), Linear()
    A, B, c = model_matrices(model, 0.02, hover_hz=0.0)
    np.testing.assert_allclose(A, lin.A, atol=1e-6)
    np.testing.assert_allclose(B, lin.B, atol=1e-6)
    np.testing.assert_allclose(c, lin.c, atol=1e-6)


@pytest.mark.parametrize("bad, word", [({"q": [1, 2]}, "q="), ({"ru": [1, -1, 1]}, "ru="),
                                       ({"reference": "carrot"}, "carrot"), ({"backend": "gurobi"}, "gurobi"),
                                       ({"horizon": 2.5}, "horizon"), ({"horizon": 0}, "horizon"),
                                       ({"q": [0, 0, 0]}, "q must not"), ({"speed": 3}, "unknown")])
def test_bad_parameters_are_named_before_any_model_is_loaded(bad, word):
    with pytest.raises(ComponentError, match=word):
        MPCController.validate_params(bad)  # what `cosim validate` and the runner call first
    with pytest.raises(ComponentError, match=word):
        MPCController().setup({**bad, "dt": 0.02, "path": make_path("racetrack")}, np.random.default_rng(0))
