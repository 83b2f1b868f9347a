"""The multi-step extended Kalman filter over any dynamics model (plain numpy).

State ``x`` (n,) in the models' units: ``[p (mm, 3), v (mm/s, 3)]`` and, with
a drift state, ``d`` (mm/s, 3): a slowly varying velocity offset that the
model misses (first-order Gauss-Markov, ``d' = phi d``), added to the
position only::

    [p', v'] = model.predict([p, v], u, dt);   p' += dt d;   d' = phi d

The measurement is the position, ``H = [I 0]``. :meth:`predict` runs every
control period (frames or not), :meth:`update` when a frame arrives; frames
whose normalised innovation squared exceeds ``gate`` (a chi-square quantile,
3 dof) are rejected, and after ``max_rejects`` rejections in a row the
position is re-initialised on the frame (the filter was lost, not the camera).

Jacobians: a linear model's ``linear_matrices()`` (exact and constant, and
used for the mean too: the filter is then the textbook Kalman filter); any
other model by central differences of its vectorised ``predict`` over the six
states, refreshed every ``relinearize_steps`` predictions in one batched call
of 13 rows whose first row is that step's mean. Between refreshes the
covariance is propagated with the held Jacobian while the mean always goes
through the model.

Adaptive Q (``adapt_rate`` > 0): every frame moves a scale on Q so that the
log of the NIS averages its chi-square(3) expectation (an exponential
average in log terms, robust to the chi-square's tail; NIS capped at the gate
so that an outlier only nudges it; the scale bounded by ``scale_range``).

A model prediction that leaves the tank or is not finite (a model
extrapolating far from its data) is replaced by a constant-velocity step, the
predicted position is kept inside the tank and the velocity is clipped to
``v_max``: the filter never outputs NaN once started.
"""

from __future__ import annotations

import math

import numpy as np

from cosim_plugins.estimators.noise import transition_jacobian

FD_EPS = 1e-3  # finite-difference step [mm or mm/s]
E_LOG_CHI2_3 = math.log(2.0) + 0.03648997397857652  # E[log X], X ~ chi-square(3): log 2 + digamma(3/2)


def linear_step(model, dt_s: float):
    """(A (6, 6), B (6, 3), c (6,)) of a linear model over one period ``dt_s`` (None if not linear).

    A model stepping a fraction of the period is composed: x_k+1 = A x_k + B u + c, k times.
    """
    try:
        A, B, c = (np.asarray(m, dtype=float) for m in model.linear_matrices())
    except NotImplementedError:
        return None
    step = getattr(model, "dt_s", None) or dt_s
    k = int(round(dt_s / step))
    if k < 1 or abs(k * step - dt_s) > 1e-9:
        raise ValueError(f"the model steps {step * 1e3:g} ms; the period {dt_s * 1e3:g} ms is not a multiple")
    Ak, Bk, ck = np.eye(6), np.zeros((6, 3)), np.zeros(6)
    for _ in range(k):
        Ak, Bk, ck = A @ Ak, A @ Bk + B, A @ ck + c
    return Ak, Bk, ck


class MultiStepEKF:
    """EKF with multi-step prediction between frames; see the module docstring.

    Args:
        model: a :class:`cosim_plugins.identify.model.Model` (``predict`` on (6,) and (n, 6) states).
        dt_s: control period [s].
        q: (n,) per-step process noise variances (n = 6, or 9 with drift).
        r: (3,) measurement noise variances [mm^2].
        p_init: (n,) initial variances; the position entries are replaced by ``r``.
        phi: drift decay per step (required when n = 9).
        gate: NIS threshold (inf: accept every frame).
        max_rejects: rejections in a row before the position is re-initialised.
        relinearize_steps: predictions between Jacobian refreshes (1: every step).
        v_max: speed limit of the velocity state [mm/s]; tank: half-width of the tank [mm].
        adapt_rate: weight of each frame in the adaptive process-noise scale (0: Q fixed).
        scale_range: bounds of that scale.
    """

    def __init__(self, model, dt_s: float, q, r, p_init, phi: float | None = None, gate: float = np.inf,
                 max_rejects: int = 3, relinearize_steps: int = 1, v_max: float = np.inf, tank: float = np.inf,
                 adapt_rate: float = 0.0, scale_range: tuple[float, float] = (0.1, 100.0)):
        self.model, self.dt = model, float(dt_s)
        self.q = np.asarray(q, dtype=float)
        self.n = len(self.q)
        if self.n not in (6, 9):
            raise ValueError(f"process noise has {self.n} entries; expected 6 (p, v) or 9 (p, v, drift)")
        if self.n == 9 and phi is None:
            raise ValueError("a drift state needs its decay phi")
        self.phi = phi if self.n == 9 else None
        self.R = np.diag(np.asarray(r, dtype=float))
        self.p_init = np.asarray(p_init, dtype=float)
        self.gate, self.max_rejects = float(gate), int(max_rejects)
        self.adapt_rate = float(adapt_rate)
        self.log_scale = 0.0  # log of the process-noise scale (adaptive, see _adapt)
        self.log_scale_min, self.log_scale_max = math.log(scale_range[0]), math.log(scale_range[1])
        self.relinearize_steps = max(1, int(relinearize_steps))
        self.v_max, self.tank = float(v_max), float(tank)
        self._linear = linear_step(model, dt_s)
        self._fixed_F = None if self._linear is None else transition_jacobian(self._linear[0], self.dt, self.phi)
        self._F = self._fixed_F
        self._since = 0
        self._Qd = np.diag(self.q)
        self.x = np.full(self.n, np.nan)
        self.P = np.full((self.n, self.n), np.nan)
        self.rejects = 0
        self.started = False

    # ------------------------------------------------------------ state

    def start(self, z_mm: np.ndarray) -> None:
        """Initialise at a first frame: p = z, v = d = 0, P = diag(p_init) with R on the position."""
        self.x = np.zeros(self.n)
        self.x[:3] = z_mm
        self.P = np.diag(self.p_init)
        self.P[:3, :3] = self.R
        self.rejects, self._since, self._F = 0, 0, self._fixed_F
        self.started = True

    def snapshot(self):
        return self.x.copy(), self.P.copy(), self._F, self._since, self.rejects, self.log_scale, self._Qd

    def restore(self, snap) -> None:
        x, P, self._F, self._since, self.rejects, self.log_scale, self._Qd = snap
        self.x, self.P = x.copy(), P.copy()

    # ------------------------------------------------------------ predict

    def jacobian(self, u_hz: np.ndarray):
        """(F (n, n), f (6,)): transition Jacobian and model prediction at the current state, command u [Hz].

        One batched model call on 13 rows: the state and its +-FD_EPS perturbations.
        """
        zs = np.empty((13, 6))
        zs[:] = self.x[:6]
        idx = np.arange(6)
        zs[idx + 1, idx] += FD_EPS
        zs[idx + 7, idx] -= FD_EPS
        f = self.model.predict(zs, np.broadcast_to(u_hz, (13, 3)), self.dt)
        A = ((f[1:7] - f[7:]) / (2.0 * FD_EPS)).T
        if not np.all(np.isfinite(A)):
            A = _constant_velocity(self.dt)
        return transition_jacobian(A, self.dt, self.phi), f[0]

    def predict(self, u_hz: np.ndarray) -> None:
        """Advance one period with the command u (3,) [Hz] applied over it."""
        x = self.x
        if self._linear is not None:
            A, B, c = self._linear
            nxt = A @ x[:6] + B @ u_hz + c
        elif self._since >= self.relinearize_steps or self._F is None:
            self._F, nxt = self.jacobian(u_hz)
            self._since = 0
        else:
            nxt = self.model.predict(x[:6], u_hz, self.dt)
        self._since += 1
        px, py, pz, vx, vy, vz = nxt.tolist()
        if not (math.isfinite(px + py + pz + vx + vy + vz) and max(abs(px), abs(py), abs(pz)) <= self.tank):
            px, py, pz = (x[:3] + self.dt * x[3:6]).tolist()  # the model left its domain: constant velocity
            vx, vy, vz = x[3:6].tolist()
        if self.n == 9:
            dx, dy, dz = x[6:].tolist()
            px, py, pz = px + self.dt * dx, py + self.dt * dy, pz + self.dt * dz
        lim = self.tank  # the swimmer stays in the tank
        px, py, pz = min(max(px, -lim), lim), min(max(py, -lim), lim), min(max(pz, -lim), lim)
        speed2 = vx * vx + vy * vy + vz * vz
        if speed2 > self.v_max * self.v_max:
            k = self.v_max / math.sqrt(speed2)
            vx, vy, vz = k * vx, k * vy, k * vz
        if self.n == 9:
            phi = self.phi
            self.x = np.array([px, py, pz, vx, vy, vz, phi * dx, phi * dy, phi * dz])
        else:
            self.x = np.array([px, py, pz, vx, vy, vz])
        F = self._F
        self.P = F @ self.P @ F.T + self._Qd

    # ------------------------------------------------------------ update

    def innovation(self, z_mm: np.ndarray):
        """(nu (3,) [mm], S^-1 (3, 3) [1/mm^2], NIS) of a frame against the current prediction."""
        nu = z_mm - self.x[:3]
        S_inv = _inv3(self.P[:3, :3] + self.R)
        return nu, S_inv, float(nu @ S_inv @ nu)

    def update(self, z_mm: np.ndarray):
        """Fuse a frame z (3,) [mm]; returns (innovation (3,) [mm], NIS, accepted)."""
        nu, S_inv, nis = self.innovation(z_mm)
        if self.adapt_rate > 0.0:
            self._adapt(nis)
        if not nis <= self.gate:
            self.rejects += 1
            if self.rejects <= self.max_rejects:
                return nu, nis, False
            self._reset_position(z_mm)
            return nu, nis, True
        self.rejects = 0
        PHt = self.P[:, :3]
        K = PHt @ S_inv  # P H' S^-1
        self.x = self.x + K @ nu
        P = self.P - K @ PHt.T
        self.P = 0.5 * (P + P.T)
        return nu, nis, True

    def _adapt(self, nis: float) -> None:
        """Move the process-noise scale so that log NIS averages its chi-square(3) expectation.

        An exponential average with weight ``adapt_rate`` per frame, in log terms (robust to
        the chi-square's long tail); NIS is capped at the gate, so one outlier only nudges it.
        """
        step = math.log(max(min(nis, self.gate), 1e-6)) - E_LOG_CHI2_3
        self.log_scale = min(max(self.log_scale + self.adapt_rate * step, self.log_scale_min), self.log_scale_max)
        self._Qd = math.exp(self.log_scale) * np.diag(self.q)

    def _reset_position(self, z_mm: np.ndarray) -> None:
        """Lost: jump to the frame and forget what the covariance said (velocity and drift kept)."""
        self.x[:3] = z_mm
        self.P = np.diag(self.p_init)
        self.P[:3, :3] = self.R
        self.rejects = 0
        self._since = self.relinearize_steps


def _inv3(S: np.ndarray) -> np.ndarray:
    """Inverse of a symmetric positive definite 3 x 3 matrix (closed form, a few times faster than numpy)."""
    (a, b, c), (_, d, e), (_, _, f) = S.tolist()
    A, B, C = d * f - e * e, c * e - b * f, b * e - c * d
    det = a * A + b * B + c * C
    D, E, F = a * f - c * c, b * c - a * e, a * d - b * b
    return np.array([[A, B, C], [B, D, E], [C, E, F]]) / det


def _constant_velocity(dt_s: float) -> np.ndarray:
    A = np.eye(6)
    A[:3, 3:] = dt_s * np.eye(3)
    return A
