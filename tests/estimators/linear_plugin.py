"""Test plugin: user-defined linear model kinds (registered like any external plugin).

``test-linear``: a damped swimmer, v' = a v + b u + g, p' = p + dt v' (state [p mm, v mm/s],
u Hz), exact ``linear_matrices``. ``test-small``: a model with a 4-dim state (wrong size).
"""

from __future__ import annotations

import numpy as np

from cosim import hookimpl
from cosim_plugins.identify.model import Model

DT = 0.02


def damped_swimmer(a: float = 0.9, b: float = 0.25, sink: float = -0.05):
    """(A (6, 6), B (6, 3), c (6,)) of the test swimmer over DT."""
    A = np.zeros((6, 6))
    A[3:, 3:] = a * np.eye(3)
    A[:3, :3] = np.eye(3)
    A[:3, 3:] = DT * A[3:, 3:]
    B = np.zeros((6, 3))
    B[3:] = b * np.eye(3)
    B[:3] = DT * B[3:]
    c = np.zeros(6)
    c[5] = sink
    c[2] = DT * sink
    return A, B, c


class LinearSwimmer(Model):
    """Linear dynamics x' = A x + B u + c with fixed matrices."""

    name = "test-linear"
    version = 1

    def __init__(self):
        super().__init__()
        self.A, self.B, self.c = damped_swimmer()
        self.dt_s = DT

    def _step(self, x, u):
        return x @ self.A.T + u @ self.B.T + self.c

    def linear_matrices(self):
        return self.A, self.B, self.c

    def _state(self):
        return {}, {"A": self.A, "B": self.B, "c": self.c}

    def _restore(self, meta, arrays):
        self.A, self.B, self.c = arrays["A"], arrays["B"], arrays["c"]

    @property
    def n_params(self):
        return 0


class SmallModel(LinearSwimmer):
    """A 4-state model: the estimator must refuse it."""

    name = "test-small"
    state_dim = 4


@hookimpl
def cosim_register_models(register):
    register(LinearSwimmer.name, LinearSwimmer)
    register(SmallModel.name, SmallModel)
