"""Input and sensor transform effects.

Input transforms map the logged command timeline of one gap-free segment,
u (n, 3) [Hz], to the command the swimmer follows (causal, row i may use rows
<= i); sensor transforms map predicted trajectories (w, L + 1, 3) [mm] to
what the camera reports. ``dt_s`` is the control period [s].
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

from cosim_plugins.identify.effect import Effect, EffectParam


def first_order_lag(u: np.ndarray, dt_s: float, tau_s: float) -> np.ndarray:
    """Mean over each step of a first-order lag of the piecewise-constant input u (n, k).

    The lag state starts at u[0] (at rest); with y_i its value at t_i,
    y_{i+1} = u_i + (y_i - u_i) e^{-dt/tau}, and the step's mean is
    u_i + (y_i - u_i) (tau/dt)(1 - e^{-dt/tau}). tau -> 0 returns u.
    """
    if tau_s < 1e-12 or len(u) == 0:
        return u.copy()
    a = np.exp(-dt_s / tau_s)
    phi = (tau_s / dt_s) * (1.0 - a)
    z = u - u[0]
    y = lfilter([0.0, 1.0 - a], [1.0, -a], z, axis=0)  # y_0 = 0, y_{i+1} = a y_i + (1 - a) z_i
    return u + (y - z) * phi


def _actuation_lag(u, dt_s, prm):
    return first_order_lag(u, dt_s, prm["tau"])


ACTUATION_LAG = Effect(
    name="actuation_lag",
    kind="input",
    params=(EffectParam("tau", 0.0, 0.0, 1.0, "s", 0.05),),
    transform=_actuation_lag,
    doc="Lag between the command and the field: coil inductance (L/R, or the envelope of a series RLC "
        "drive) and amplifier bandwidth make the rotating field follow a new command with a first-order "
        "lag; the swimmer follows omega filtered with time constant tau [s] (fitted).",
    starts=({"tau": 0.03}, {"tau": 0.1}, {"tau": 0.3}),
)


def _heading_lag(u, dt_s, prm):
    f = np.linalg.norm(u, axis=1, keepdims=True)
    axis = u / np.where(f > 1e-12, f, 1.0)
    lagged = first_order_lag(axis, dt_s, prm["tau"])
    n = np.linalg.norm(lagged, axis=1, keepdims=True)
    return f * lagged / np.where(n > 1e-12, n, 1.0)


HEADING_LAG = Effect(
    name="heading_lag",
    kind="input",
    params=(EffectParam("tau", 0.0, 0.0, 1.0, "s", 0.05),),
    transform=_heading_lag,
    doc="The swimmer's body turns towards a new rotation axis through its rotational drag (time constant "
        "c_perp / (m B)), so its thrust points along a lagged axis: the command's direction filtered by a "
        "first-order lag of time constant tau [s], its magnitude (the spin rate) unchanged.",
    starts=({"tau": 0.03}, {"tau": 0.1}, {"tau": 0.3}),
)


def _sensor_latency(traj, dt_s, prm):
    n = traj.shape[1]
    s = np.arange(n) - prm["delay"]  # fractional step index each measurement shows
    j0 = np.clip(np.floor(s).astype(int), 0, n - 2)
    f = (s - j0)[None, :, None]
    return traj[:, j0] + f * (traj[:, j0 + 1] - traj[:, j0])  # linear; before row 0 extrapolated


def _latency_lookback(prm) -> int:
    """Rows before a window the latency reads: the delay rounded up."""
    return math.ceil(prm["delay"] - 1e-9)


SENSOR_LATENCY = Effect(
    name="sensor_latency",
    kind="sensor",
    params=(EffectParam("delay", 0.0, 0.0, 10.0, "steps", 0.5),),
    transform=_sensor_latency,
    doc="Camera latency (exposure, transfer, image processing): the position logged at t_i is where the "
        "swimmer was at t_i - delay dt; delay [control periods] is fitted as a fraction or a number of "
        "steps, by linear interpolation along the predicted path.",
    starts=({"delay": 0.5}, {"delay": 1.5}, {"delay": 4.0}),
    lookback=_latency_lookback,
)

TRANSFORM_EFFECTS = (ACTUATION_LAG, HEADING_LAG, SENSOR_LATENCY)
