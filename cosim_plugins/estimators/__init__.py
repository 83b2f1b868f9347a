"""Estimator plugins."""

from cosim import hookimpl
from cosim_plugins.estimators.kalman import KalmanEstimator
from cosim_plugins.estimators.passthrough import Passthrough


@hookimpl
def cosim_register_components(register):
    register("estimator.passthrough", Passthrough)
    register("estimator.kf", KalmanEstimator)
