"""``controller.mrac``: model reference adaptive control for 3D path following.

Plant, as the controller sees it (per axis, units mm, s, Hz):

    dv/dt = -a v + a b u + w,      u = omega / 2 pi  [Hz] (3,),

a first-order velocity lag (a ~ 1/0.15 s), an unknown input gain b > 0
(mm/s per Hz; nominally 2.5, less when the spin slips) and an unknown,
slowly varying disturbance w (3,) [mm/s^2] (sinking, drift, the gradient
force). Coil and heading lags are left to robustness.

Outer loop (shared pure pursuit, look-ahead 9 mm, gain 0.001 s): the desired
velocity ``v_d = v_pp - k_e e`` [mm/s], v_pp the cruise speed towards the
look-ahead target, e = p - p_c [mm] the cross-track error to the closest path
point p_c.

Reference model (first order, for the velocity), integrated exactly over a
period with v_d held:

    dv_m/dt = a_m (v_d - v_m),      v_m(0) = v(0);   eps = v - v_m  [mm/s]

Control: ``u = k_hat v_d + d_hat``, k_hat (scalar, Hz per mm/s) estimating
1/b and d_hat (3,) [Hz] estimating -w/(a b). With the ideal values and
a_m = a the closed loop equals the reference model (the matching
condition; a_m is a parameter, default 5 /s for the plant's lags).
Adaptation (Lyapunov V = |eps|^2/2 + a b/2 (k~^2/g_k + |d~|^2/g_d)),
Euler-discretised at the control period, with the v_d of the previous period
(the one that drove v_m and the plant to the present eps):

    dk_hat/dt = Proj_[k_min, k_max]( -g_k eps_dz . v_d - sigma (k_hat - k_0) )
    dd_hat/dt = Proj_{|d| <= d_max}( -g_d eps_dz         - sigma  d_hat        )

``eps_dz = eps max(0, 1 - dz / |eps|)`` is eps with a dead zone of radius dz
[mm/s] (velocity noise alone does not drive adaptation), sigma [1/s] is the
sigma-modification leakage towards the nominal values (bounded estimates
without persistent excitation), and Proj clips to the box (k_hat) or
scales back onto the ball (d_hat). The velocity is the estimator's (noisy
with a camera: the rates are small so the laws average it). ``omega = 2 pi u``
with |u| capped at ``f_max_hz`` (direction kept).
"""

from __future__ import annotations

import numpy as np

from cosim import ComponentError
from cosim.contract.params import Param, read_params
from cosim_plugins.controllers.common import PathController, SolveTimer
from cosim_plugins.controllers.pure_pursuit import PurePursuit

PARAMS = {
    "speed_mm_s": Param(20.0, "cruise speed [mm/s]", 0.0, 200.0),
    "lookahead_mm": Param(9.0, "pure-pursuit look-ahead distance [mm]", 0.1, 100.0),
    "lookahead_gain_s": Param(0.001, "look-ahead growth with speed [s]", 0.0, 10.0),
    "k_e": Param(1.0, "cross-track feedback of the outer loop [1/s]", 0.0, 100.0),
    "a_m": Param(5.0, "reference model rate a_m [1/s]", 0.0, 1000.0),
    "k0": Param(0.4, "nominal (initial) k_hat = 1/b [Hz per mm/s]", 0.0, 10.0),
    "k_min": Param(0.2, "lower bound of k_hat [Hz per mm/s]", 0.0, 10.0),
    "k_max": Param(1.2, "upper bound of k_hat [Hz per mm/s]", 0.0, 10.0),
    "gamma_k": Param(1e-3, "adaptation rate of k_hat [Hz/(mm/s) per (mm/s)^2 s]", 0.0, 10.0),
    "gamma_d": Param(0.2, "adaptation rate of d_hat [Hz per mm/s s]", 0.0, 100.0),
    "d_max_hz": Param(6.0, "radius of the ball d_hat is projected onto [Hz]", 0.0, 60.0),
    "sigma": Param(0.02, "sigma-modification leakage [1/s]", 0.0, 100.0),
    "dead_zone_mm_s": Param(2.0, "dead zone on the velocity-following error [mm/s]", 0.0, 1000.0),
    "f_max_hz": Param(20.0, "largest commanded spin frequency [Hz]", 0.0, 60.0),
}


def check_params(params) -> dict:
    """Parameters with defaults, checked (ComponentError names the bad one)."""
    p = read_params(params, PARAMS)
    if not p["k_min"] <= p["k0"] <= p["k_max"]:
        raise ComponentError(f"need k_min <= k0 <= k_max, got {p['k_min']}, {p['k0']}, {p['k_max']}")
    return p


class MRACController(PathController):
    """Direct MRAC of the velocity under a pure-pursuit outer loop: adaptive inverse gain + bias, projected."""

    @classmethod
    def validate_params(cls, params):
        check_params(params)

    def setup(self, params, rng):
        p = self.p = check_params(params)
        self.dt = params["dt"]
        self.pursuit = PurePursuit(params["path"], p["lookahead_mm"] * 1e-3, p["lookahead_gain_s"])
        self.blend = 1.0 - np.exp(-p["a_m"] * self.dt)
        self.k_hat = p["k0"]
        self.d_hat = np.zeros(3)
        self.v_m: np.ndarray | None = None
        self.v_d_prev = np.zeros(3)  # the regressor that drove v_m (and the plant) over the last period

    def step(self, t, inputs):
        with SolveTimer() as timer:
            omega = self._control(t, np.asarray(inputs["position"]), np.asarray(inputs["velocity"]))
        return {"omega": omega, "solve_time": timer.elapsed}

    @property
    def gains(self) -> tuple[float, np.ndarray]:
        """Current estimates (k_hat [Hz per mm/s], d_hat (3,) [Hz])."""
        return self.k_hat, self.d_hat.copy()

    def _control(self, t: float, pos: np.ndarray, vel: np.ndarray) -> np.ndarray:
        if not np.all(np.isfinite(pos)):
            return np.zeros(3)
        vel = vel if np.all(np.isfinite(vel)) else np.zeros(3)
        p = self.p
        target, closest, at_end = self.pursuit.reference(pos, vel, t)
        e = (pos - closest) * 1e3  # [mm]
        to_target = (target - pos) * 1e3
        dist = np.linalg.norm(to_target)
        speed = p["speed_mm_s"] * (min(dist / (self.pursuit.lookahead_m * 1e3), 1.0) if at_end else 1.0)
        v_d = speed * to_target / max(dist, 1e-9) - p["k_e"] * e  # [mm/s]
        v = vel * 1e3
        if self.v_m is None:
            self.v_m = v.copy()
        self._adapt(v - self.v_m, self.v_d_prev)
        self.v_m = self.v_m + self.blend * (v_d - self.v_m)
        self.v_d_prev = v_d
        u = self.k_hat * v_d + self.d_hat  # [Hz]
        f = np.linalg.norm(u)
        if f > p["f_max_hz"]:
            u = u * (p["f_max_hz"] / f)
        return 2 * np.pi * u

    def _adapt(self, eps: np.ndarray, v_d: np.ndarray) -> None:
        """One Euler step of the projected, sigma-modified, dead-zoned adaptive laws."""
        p, dt = self.p, self.dt
        n = np.linalg.norm(eps)
        eps_dz = eps * max(0.0, 1.0 - p["dead_zone_mm_s"] / n) if n > 0 else eps
        k_dot = -p["gamma_k"] * float(eps_dz @ v_d) - p["sigma"] * (self.k_hat - p["k0"])
        self.k_hat = float(np.clip(self.k_hat + dt * k_dot, p["k_min"], p["k_max"]))
        d = self.d_hat + dt * (-p["gamma_d"] * eps_dz - p["sigma"] * self.d_hat)
        size = np.linalg.norm(d)
        self.d_hat = d if size <= p["d_max_hz"] else d * (p["d_max_hz"] / size)
