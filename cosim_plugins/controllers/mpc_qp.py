"""The MPC's quadratic program (paper Eq. 15), built once, solved every step.

Model (discrete, one control period): ``x+ = A x + B f_max u + c`` with
state x = [p mm, v mm/s] (6,), normalised command ``u = omega_Hz / f_max``
(3,). Over the horizon N the commands ``u_0 .. u_{N-1}`` are decided; u_0 is
applied over the next period, ``u_{-1}`` is the command applied last.

    min  sum_{k=1..N} (p_k - r_k)' Q (p_k - r_k)            p_k = x_k[:3] [mm]
       + sum_{k=0..N-1} (u_k - u_{k-1})' R (u_k - u_{k-1})
       + sum_{k=0..N-1} u_k' Ru u_k
    s.t. x_0 = x (measured), x_{k+1} = A x_k + B f_max u_k + c,
         |u_k| <= u_max, |u_k - u_{k-1}| <= du_max (element-wise)

Q, R, Ru are diagonal (weights per axis). Two implementations:

* :class:`CvxpyMPC`: the formulation above written in cvxpy with Parameters
  (x, r, u_{-1}), DPP-compliant, solved by OSQP warm-started. The reference.
* :class:`CondensedMPC`: the states eliminated (``p = Phi x + Gamma U + g``),
  leaving a 3N-variable QP whose matrices are fixed; each step only the
  linear cost term and the Delta-u bounds change, passed to ``osqp`` with
  ``update(q=, l=, u=)``. The fast path (~10x less overhead than cvxpy).

Both return the plan ``U`` (N, 3) in normalised units; the caller clips u_0
into the bounds (an iterate stopped at ``max_iter`` may violate them by eps).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

#: OSQP statuses whose solution we accept (an inaccurate one is still clipped into the bounds).
ACCEPTED = ("solved", "solved inaccurate", "maximum iterations reached")


@dataclass(frozen=True)
class MPCSpec:
    """Everything that fixes the QP's structure.

    A (6, 6), B (6, 3) [per Hz], c (6,): the model in mm, mm/s, Hz. ``f_max_hz``
    scales the command; weights q, r, ru are (3,) diagonals; N = ``horizon``.
    """

    A: np.ndarray
    B: np.ndarray
    c: np.ndarray
    horizon: int = 5
    q: tuple = (3.0, 3.0, 3.0)
    r: tuple = (1.0, 1.0, 1.0)
    ru: tuple = (1.0, 1.0, 1.0)
    f_max_hz: float = 20.0
    u_max: float = 1.0
    du_max: float = 1.0
    eps: float = 1e-4
    max_iter: int = 200

    @property
    def Bn(self) -> np.ndarray:
        """B per normalised command unit, (6, 3)."""
        return np.asarray(self.B, dtype=float) * self.f_max_hz


def condensed(spec: MPCSpec):
    """Prediction matrices of the positions over the horizon.

    Returns ``(Phi (3N, 6), Gamma (3N, 3N), G (3N, 6))`` with the stacked
    positions ``[p_1; ...; p_N] = Phi x_0 + Gamma U + G c`` and
    ``U = [u_0; ...; u_{N-1}]``.
    """
    A, Bn, N = np.asarray(spec.A, float), spec.Bn, spec.horizon
    powers = [np.eye(6)]
    for _ in range(N):
        powers.append(A @ powers[-1])
    Phi = np.zeros((3 * N, 6))
    Gamma = np.zeros((3 * N, 3 * N))
    G = np.zeros((3 * N, 6))
    drift = np.zeros((6, 6))
    for k in range(1, N + 1):
        rows = slice(3 * (k - 1), 3 * k)
        Phi[rows] = powers[k][:3]
        for j in range(k):
            Gamma[rows, 3 * j: 3 * j + 3] = (powers[k - 1 - j] @ Bn)[:3]
        drift = A @ drift + np.eye(6)
        G[rows] = drift[:3]
    return Phi, Gamma, G


def difference_matrix(N: int) -> np.ndarray:
    """D (3N, 3N) with ``(D U)_k = u_k - u_{k-1}`` (``u_{-1}`` enters separately)."""
    return np.eye(3 * N) - np.eye(3 * N, k=-3)


class CondensedMPC:
    """Eq. 15 as a condensed QP solved with ``osqp`` directly (see the module docstring)."""

    def __init__(self, spec: MPCSpec):
        import osqp
        from osqp.interface import OSQPException

        self._error = OSQPException
        self.spec = spec
        N = spec.horizon
        Phi, Gamma, G = condensed(spec)
        Qb = np.diag(np.tile(np.asarray(spec.q, float), N))
        Rb = np.diag(np.tile(np.asarray(spec.r, float), N))
        Rub = np.diag(np.tile(np.asarray(spec.ru, float), N))
        D = difference_matrix(N)
        E = np.zeros((3 * N, 3))
        E[:3] = np.eye(3)
        H = Gamma.T @ Qb @ Gamma + D.T @ Rb @ D + Rub  # (3N, 3N), positive definite (Rub > 0 or Q)
        # OSQP minimises 1/2 U'PU + q'U: P = 2H, q = 2 (Gamma'Q (Phi x + G c - r) - D'R E u_prev)
        self._Fx = 2 * Gamma.T @ Qb @ Phi
        self._Fr = -2 * Gamma.T @ Qb
        self._f0 = 2 * Gamma.T @ Qb @ G @ np.asarray(spec.c, float)
        self._Fu = -2 * D.T @ Rb @ E
        Ac = sp.csc_matrix(np.vstack([np.eye(3 * N), D]))
        self._lo = np.concatenate([np.full(3 * N, -spec.u_max), np.full(3 * N, -spec.du_max)])
        self._hi = -self._lo
        self.solver = osqp.OSQP()
        self.solver.setup(sp.triu(sp.csc_matrix(2 * H), format="csc"), np.zeros(3 * N), Ac,
                          self._lo.copy(), self._hi.copy(), eps_abs=spec.eps, eps_rel=spec.eps,
                          max_iter=spec.max_iter, warm_starting=True, polishing=False, verbose=False)
        self.status = ""
        self.iterations = 0

    def solve(self, x0: np.ndarray, ref: np.ndarray, u_prev: np.ndarray) -> np.ndarray | None:
        """Plan U (N, 3) for state x0 (6,) [mm, mm/s], reference ref (N, 3) [mm], last command u_prev (3,).

        Returns None when OSQP reports no usable solution.
        """
        N = self.spec.horizon
        q = self._Fx @ x0 + self._Fr @ np.ravel(ref) + self._f0 + self._Fu @ u_prev
        lo, hi = self._lo.copy(), self._hi.copy()
        lo[3 * N: 3 * N + 3] += u_prev
        hi[3 * N: 3 * N + 3] += u_prev
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            self.status = "non-finite data"
            return None
        try:
            self.solver.update(q=q, l=lo, u=hi)
            res = self.solver.solve(raise_error=False)
        except (ValueError, self._error) as exc:
            self.status = f"error: {exc}"
            return None
        self.status, self.iterations = res.info.status, res.info.iter
        if self.status not in ACCEPTED or res.x is None or not np.all(np.isfinite(res.x)):
            self.solver.warm_start(x=np.zeros(3 * N), y=np.zeros(6 * N))  # do not start from a bad iterate
            return None
        return res.x.reshape(N, 3)


class CvxpyMPC:
    """Eq. 15 written in cvxpy with Parameters (DPP), solved warm-started by OSQP. The reference."""

    def __init__(self, spec: MPCSpec, solver_opts: dict | None = None):
        """``solver_opts``: keyword arguments of ``problem.solve`` (default: OSQP, warm start, spec's eps)."""
        import cvxpy as cp

        self.spec = spec
        N, A, Bn, c = spec.horizon, np.asarray(spec.A, float), spec.Bn, np.asarray(spec.c, float)
        self.x0 = cp.Parameter(6, name="x0")
        self.ref = cp.Parameter((N, 3), name="ref")
        self.u_prev = cp.Parameter(3, name="u_prev")
        self.U = cp.Variable((N, 3), name="U")
        X = cp.Variable((N + 1, 6), name="X")
        sq, sr, sru = (np.sqrt(np.asarray(w, float)) for w in (spec.q, spec.r, spec.ru))
        cons = [X[0] == self.x0]
        cost = 0
        for k in range(N):
            cons.append(X[k + 1] == A @ X[k] + Bn @ self.U[k] + c)
            du = self.U[k] - (self.u_prev if k == 0 else self.U[k - 1])
            cons += [du <= spec.du_max, du >= -spec.du_max]
            cost += cp.sum_squares(cp.multiply(sq, X[k + 1, :3] - self.ref[k]))
            cost += cp.sum_squares(cp.multiply(sr, du)) + cp.sum_squares(cp.multiply(sru, self.U[k]))
        cons += [self.U <= spec.u_max, self.U >= -spec.u_max]
        self.problem = cp.Problem(cp.Minimize(cost), cons)
        self.opts = solver_opts or dict(solver=cp.OSQP, warm_start=True, eps_abs=spec.eps, eps_rel=spec.eps,
                                        max_iter=spec.max_iter, polishing=False)
        self.status = ""

    def is_dpp(self) -> bool:
        return self.problem.is_dpp()

    def solve(self, x0: np.ndarray, ref: np.ndarray, u_prev: np.ndarray) -> np.ndarray | None:
        """Same contract as :meth:`CondensedMPC.solve`."""
        import cvxpy as cp

        try:
            self.x0.value = np.asarray(x0, float)
            self.ref.value = np.asarray(ref, float).reshape(self.spec.horizon, 3)
            self.u_prev.value = np.asarray(u_prev, float)
            self.problem.solve(**self.opts)
        except (ValueError, cp.error.SolverError) as exc:  # non-finite data, solver failure
            self.status = f"error: {exc}"
            return None
        self.status = self.problem.status
        U = self.U.value
        if U is None or self.status not in ("optimal", "optimal_inaccurate") or not np.all(np.isfinite(U)):
            return None
        return np.array(U)


def clip_first(u0: np.ndarray, u_prev: np.ndarray, u_max: float, du_max: float) -> np.ndarray:
    """u_0 (3,) clipped into ``|u| <= u_max`` and ``|u - u_prev| <= du_max`` (u_prev inside the box)."""
    lo = np.maximum(-u_max, u_prev - du_max)
    hi = np.minimum(u_max, u_prev + du_max)
    return np.clip(u0, lo, hi)
