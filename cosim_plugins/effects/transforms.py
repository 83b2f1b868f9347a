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


def heading_relaxation(u: np.ndarray, dt_s: float, tau_s: float) -> np.ndarray:
    """Mean over each step of f b(t): the body axis b turning towards the command's direction u_hat under a
    magnetic torque, u (n, 3) [Hz] piecewise constant over steps of ``dt_s`` [s]; (n, 3).

    The torque is m B sin(theta) (theta the angle from b to u_hat), so an overdamped body turns as
    theta' = -sin(theta) / tau, tau = c_perp / (m B) [s]: in the plane of b and u_hat, s = tan(theta / 2)
    decays as exp(-t / tau). Over a step from s_0 to s_1 = s_0 e^{-dt/tau}, the means are
    mean cos(theta) = 1 - (tau/dt) ln((1 + s_0^2) / (1 + s_1^2)) and mean sin(theta) = (2 tau/dt)
    (atan s_0 - atan s_1). b starts on the first commanded row's u_hat; a row without a command (|u| < 0.5 Hz)
    keeps b; f = |u|.
    tau -> 0 returns u.
    """
    if tau_s < 1e-12 or len(u) == 0:
        return u.copy()
    f = np.linalg.norm(u, axis=1)
    target = u / np.where(f > 1e-12, f, 1.0)[:, None]
    a, r = math.exp(-dt_s / tau_s), tau_s / dt_s
    s0, normal = [0.0] * len(u), [(0.0, 0.0, 0.0)] * len(u)  # tan(theta / 2) at each step's start; the unit
    # vector in the plane of b and u_hat, normal to u_hat, towards b. Plain floats and lists: the rows depend on
    # each other, and numpy's per-element overhead would dominate
    sqrt = math.sqrt
    commanded = np.flatnonzero(f >= 0.5)
    if len(commanded) == 0:
        return u.copy()  # no command: the axis never matters (every row's thrust is |u| < 0.5 Hz times it)
    bx, by, bz = target[commanded[0]].tolist()
    for i, (x, y, z, fi) in enumerate(zip(*target.T.tolist(), f.tolist())):
        if fi < 0.5:
            continue
        c = bx * x + by * y + bz * z
        qx, qy, qz = bx - c * x, by - c * y, bz - c * z
        q = sqrt(qx * qx + qy * qy + qz * qz)
        if q < 1e-12:
            if c > 0:
                continue  # on the axis already
            qx, qy, qz = (-y, x, 0.0) if abs(z) < 0.9 else (0.0, -z, y)  # opposite: turn about any normal
            q = sqrt(qx * qx + qy * qy + qz * qz)
        ex, ey, ez = qx / q, qy / q, qz / q
        s = q / (1.0 + c) if c > -1.0 + 1e-12 else 1e6
        s0[i], normal[i] = s, (ex, ey, ez)
        s1 = s * a
        d = 1.0 / (1.0 + s1 * s1)
        cos1, sin1 = (1.0 - s1 * s1) * d, 2.0 * s1 * d
        bx, by, bz = cos1 * x + sin1 * ex, cos1 * y + sin1 * ey, cos1 * z + sin1 * ez
    s0 = np.array(s0)
    s1 = s0 * a
    mean_cos = 1.0 - r * np.log((1.0 + s0 * s0) / (1.0 + s1 * s1))
    mean_sin = 2.0 * r * (np.arctan(s0) - np.arctan(s1))
    return f[:, None] * (mean_cos[:, None] * target + mean_sin[:, None] * np.array(normal))


def _heading_lag(u, dt_s, prm):
    return heading_relaxation(u, dt_s, prm["tau"])


HEADING_LAG = Effect(
    name="heading_lag",
    kind="input",
    params=(EffectParam("tau", 0.0, 0.0, 1.0, "s", 0.05),),
    transform=_heading_lag,
    doc="The swimmer's body turns towards a new rotation axis under the magnetic torque against its rotational "
        "drag, so its thrust points along a lagging axis: the angle theta to the command's direction relaxes as "
        "theta' = -sin(theta) / tau, tau = c_perp / (m B) [s] (a small turn decays as exp(-t / tau), a large "
        "one slower at first); the magnitude (the spin rate) unchanged.",
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
    params=(EffectParam("delay", 0.0, 0.0, 25.0, "steps", 0.5),),  # 25: 0.5 s at 50 Hz, 0.25 s at 100 Hz
    transform=_sensor_latency,
    doc="Camera latency (exposure, transfer, image processing): the position logged at t_i is where the "
        "swimmer was at t_i - delay dt; delay [control periods] is fitted as a fraction or a number of "
        "steps, by linear interpolation along the predicted path.",
    starts=({"delay": 0.5}, {"delay": 1.5}, {"delay": 4.0}, {"delay": 10.0}),
    lookback=_latency_lookback,
)

TRANSFORM_EFFECTS = (ACTUATION_LAG, HEADING_LAG, SENSOR_LATENCY)
