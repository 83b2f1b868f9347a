"""Starting values for joint fits: least squares on the integrated equation of motion.

A rollout fit (:func:`cosim_plugins.identify.joint.fit_joint`) is non-convex: started
from a poor model it can settle in a degenerate corner (no drag, no thrust,
a large centring force) or leave an effect's parameters where they started.
This module gives it starts that do not depend on a previous fit.

Along each training window the model's acceleration is evaluated on the
*measured* trajectory (positions interpolated over gaps, velocities from a
five-point derivative, the logged commands through the input effects),
integrated twice and compared with the measured positions; each window's
initial position and velocity are eliminated by a 2 x 2 linear solve per
window and axis. For a force linear in its parameters (thrust, drag, weight,
a flow, a gradient) the problem is linear least squares: the drag term
integrates to the displacement itself, so noise enters only once averaged
over the window (no errors-in-variables blow-up of a one-step fit). Other
parameters (a step-out frequency, a lag) enter through
``scipy.optimize.least_squares`` on the same cheap residual (no rollout).

Units: mm, mm/s, Hz, s. Works for any host with a continuous-time
``predict_t`` (the physical model); :func:`supported` tells.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from cosim_plugins.identify.joint import capped, targets

H_S = 1e-4  # step of the one-step difference that gives the acceleration [s]


def supported(jm) -> bool:
    """True when the host model can be evaluated at an arbitrary small step (continuous time)."""
    return hasattr(jm.host, "predict_t")


def smooth_velocity(p: np.ndarray, ok: np.ndarray, dt_s: float, fallback: np.ndarray) -> np.ndarray:
    """(n, 3) five-point derivative of positions p (n, 3) [mm] where rows i-2..i+2 are usable, else ``fallback``.

    ``ok`` (n,) marks regular steps i -> i+1 (the timeline's ``run > 0``).
    """
    n = len(p)
    v = fallback.copy()
    if n < 5:
        return v
    i = np.arange(2, n - 2)
    good = ok[i - 2] & ok[i - 1] & ok[i] & ok[i + 1] & np.all(np.isfinite(p[i - 2]), axis=1) \
        & np.all(np.isfinite(p[i + 2]), axis=1)
    i = i[good]
    v[i] = (2.0 * (p[i + 2] - p[i - 2]) + (p[i + 1] - p[i - 1])) / (10.0 * dt_s)
    return v


class EquationError:
    """The integrated equation-error residual of a :class:`~cosim_plugins.identify.joint.JointModel` on windows.

    Args:
        jm: the joint model (host + effects); its parameters are set by :meth:`residual`.
        tl: the training :class:`~cosim_plugins.identify.timeline.Timeline`.
        starts: (w,) window start rows; length: steps per window.
    """

    def __init__(self, jm, tl, starts: np.ndarray, length: int):
        self.jm, self.tl, self.length = jm, tl, length
        rows = starts[:, None] + np.arange(length + 1)[None, :]
        rows = np.minimum(rows, tl.n - 1)
        p_interp = tl.x_lin[:, :3]
        v = smooth_velocity(p_interp, tl.run > 0, tl.dt_s, tl.x_lin[:, 3:])
        self.x = np.concatenate([p_interp, v], axis=1)[rows[:, :-1]]  # (w, L, 6) states along the data
        self.rows = rows[:, :-1]
        self.target = targets(tl, starts, length)  # (w, L + 1, 3)
        self.use = np.all(np.isfinite(self.target), axis=2)  # (w, L + 1)
        self.y = np.nan_to_num(self.target)
        t = np.arange(length + 1) * tl.dt_s
        self.basis = np.stack([np.ones_like(t), t])  # (2, L + 1): initial position, initial velocity
        w = len(starts)
        self.xt = np.ascontiguousarray(self.x.reshape(w * length, 6).T)  # (6, w L)

    def accelerations(self, u_eff: np.ndarray) -> np.ndarray:
        """(w, L, 3) model accelerations [mm/s^2] on the measured states with commands ``u_eff`` (n, 3)."""
        jm = self.jm
        ut = np.ascontiguousarray(np.nan_to_num(u_eff[self.rows]).reshape(-1, 3).T)
        nxt = jm.host.predict_t(self.xt, ut, H_S)
        a = (nxt[3:] - self.xt[3:]) / H_S
        return a.T.reshape(self.x.shape[0], self.length, 3)

    def residual(self, theta: np.ndarray) -> np.ndarray:
        """Measured minus predicted positions (initial states eliminated), flattened; zero on unused rows."""
        jm = self.jm
        jm._set(theta)
        a = self.accelerations(jm.commands(self.tl))
        dt = self.tl.dt_s
        forced = np.zeros(self.y.shape)
        forced[:, 1:] = dt * dt * np.cumsum(np.cumsum(a, axis=1), axis=1)  # p_k - p_0 - k dt v_0
        basis = np.broadcast_to(self.basis[:, None, :, None], (2, 1, self.length + 1, 3))
        if jm.sensors:  # what the camera reports of the trajectory: transform each part (linear for a delay)
            forced = self._sense(forced)
            basis = np.stack([self._sense(np.broadcast_to(b, (1, self.length + 1, 3)).copy()) for b in basis[:, 0]])
        m = self.use[..., None].astype(float)  # (w, L + 1, 1)
        r0 = (self.y - forced) * m
        hb = np.broadcast_to(basis, (2, *forced.shape)) * m  # (2, w, L + 1, 3)
        g = np.einsum("iwka,jwka->waij", hb, hb) + 1e-9 * np.eye(2)  # per window and axis
        b = np.einsum("iwka,wka->wai", hb, r0)
        c = np.linalg.solve(g, b[..., None])[..., 0]  # (w, 3, 2)
        return (r0 - np.einsum("iwka,wai->wka", hb, c)).reshape(-1)

    def _sense(self, traj: np.ndarray) -> np.ndarray:
        for effect in self.jm.sensors:
            prm = {q.name: self.jm.prm[f"{effect.name}.{q.name}"] for q in effect.params}
            traj = effect.transform(traj, self.tl.dt_s, prm)
        return traj

    def fit(self, theta0: np.ndarray, free: np.ndarray | None = None, max_nfev: int = 15) -> tuple[np.ndarray, float]:
        """(theta, cost) minimising the residual from ``theta0``; only ``free`` (bool mask) parameters move."""
        jm = self.jm
        lo, hi = jm.bounds()
        theta0 = jm.clip(np.asarray(theta0, dtype=float))
        free = np.ones(len(theta0), dtype=bool) if free is None else np.asarray(free, dtype=bool)
        if not free.any():
            return theta0, float(np.sum(self.residual(theta0) ** 2))

        def res(z):
            th = theta0.copy()
            th[free] = z
            with np.errstate(all="ignore"):  # a trial point may diverge: its cost is then huge, not an error
                return capped(self.residual(th))

        out = least_squares(res, theta0[free], bounds=(lo[free], hi[free]), x_scale=jm.scales()[free],
                            method="trf", max_nfev=max_nfev, ftol=1e-8, xtol=1e-8)
        theta = theta0.copy()
        theta[free] = out.x
        return theta, float(2 * out.cost)
