"""The MLP: better than constant velocity on held-out data; seeded and deterministic."""

from __future__ import annotations

import numpy as np

from cosim_plugins.models.mlp import MLPModel


def _one_step_position_error(predict, ds):
    X, U, Xn = ds.pairs()
    return np.mean(np.linalg.norm(predict(X, U)[:, :3] - Xn[:, :3], axis=1))


def test_mlp_beats_constant_velocity_on_held_out_data(rich_data):
    train, test = rich_data
    model = MLPModel(epochs=60, seed=0).fit(train)
    assert model.n_params == 276  # paper Table I
    assert model.history["n_test"] > 0 and model.history["epochs"] == 60

    def constant_velocity(X, U):
        return np.concatenate([X[:, :3] + test.dt_s * X[:, 3:], X[:, 3:]], axis=1)

    mlp = _one_step_position_error(lambda X, U: model.predict(X, U, test.dt_s), test)
    cv = _one_step_position_error(constant_velocity, test)
    assert mlp < 0.8 * cv, (mlp, cv)


def test_mlp_training_is_deterministic(rich_data):
    train, _ = rich_data
    a = MLPModel(epochs=3, seed=7).fit(train)
    b = MLPModel(epochs=3, seed=7).fit(train)
    c = MLPModel(epochs=3, seed=8).fit(train)
    for wa, wb in zip(a.weights, b.weights):
        np.testing.assert_array_equal(wa, wb)
    assert not np.array_equal(a.weights[0], c.weights[0])
