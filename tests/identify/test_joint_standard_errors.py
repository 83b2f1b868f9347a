"""The joint fit's parameter uncertainties: ordinary least squares' on a linear problem, none when undefined."""

import numpy as np

from cosim_plugins.identify.joint import _standard_errors


def test_standard_errors_of_a_linear_fit_are_the_textbook_ones():
    rng = np.random.default_rng(7)
    X = rng.normal(size=(400, 3)) * [1.0, 10.0, 0.1]  # badly scaled columns
    r = rng.normal(0.0, 0.5, 400)
    textbook = np.sqrt(np.diag(np.linalg.inv(X.T @ X)) * (r @ r) / (400 - 3))
    assert np.allclose(_standard_errors(X, r, 400, 400), textbook)
    assert np.allclose(_standard_errors(X, r, 400, 100), 2.0 * textbook)  # each row counted four times


def test_a_column_the_residuals_do_not_see_or_a_non_finite_jacobian_gives_no_uncertainty():
    rng = np.random.default_rng(8)
    X, r = rng.normal(size=(50, 2)), rng.normal(size=50)
    X[:, 1] = 0.0
    std = _standard_errors(X, r, 50, 50)
    assert np.isfinite(std[0]) and np.isnan(std[1])
    X[3, 0] = np.inf
    assert np.all(np.isnan(_standard_errors(X, r, 50, 50)))
