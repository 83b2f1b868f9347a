"""``controller.mpc``: model predictive path following (paper Sec. II-D, III-E, Eq. 15, Table V).

Every control period the controller

1. forms the state ``x = [p mm, v mm/s]`` from the estimator's position and
   velocity (SI on the bus, converted to the model's units);
2. builds the reference positions ``r_1 .. r_N`` [mm] from the shared pure
   pursuit (look-ahead 9 mm, gain 0.001 s; see ``reference`` below);
3. solves Eq. 15 (see :mod:`cosim_plugins.controllers.mpc_qp`) for the plan
   of normalised commands ``u_k = omega_Hz / f_max_hz`` (element-wise, so
   ``|u| <= 1`` bounds each axis' spin-frequency component by ``f_max_hz``);
4. applies u_0: clipped into the bounds (``|u_0| <= u_max``,
   ``|u_0 - u_{-1}| <= du_max``; an OSQP iterate stopped at ``max_iter`` may
   miss them by eps), then, as a safety saturation that keeps the bounds,
   scaled down to ``|omega| / 2 pi <= f_norm_max_hz`` (step-out);
   ``omega = 2 pi f_max_hz u_0`` [rad/s]. Without a position estimate, or if
   OSQP fails, the command ramps to zero as fast as the Delta-u bound allows.

Table V defaults: N = 5, Q = [3 3 3] on the position error [mm^-2],
R = [1 1 1] on the command change, Ru = [1 1 1] on the command,
bounds +-1 on u and Delta u, look-ahead 9 mm and gain 0.001.

Model: ``model`` names a model file or kind (default the linear SINDy model,
resolved with :func:`cosim_plugins.identify.cache.resolve_model`). A linear model
gives (A, B, c) through ``linear_matrices()``; any other is linearised once at
set-up with ``jacobians()`` around hover: p = 0 (tank centre), v = 0,
u = ``hover_hz`` (default 0). The scenario step must be a multiple of the
model's step (the matrices are composed over it).

Reference (``reference``):

* ``pursuit`` (default): points on the straight line from the swimmer to the
  pure-pursuit target, ``r_k = p + min(k speed_mm_s dt, |target - p|) * dir``
  (the pure-pursuit carrot walked at cruise speed), plus the cross-track
  correction ``k dt cross_gain (closest - p)`` (the PI's proportional term).
  Without it (``cross_gain: 0``) the swimmer cuts every curve: the carrot
  9 mm ahead lies inside the curve's arc, and nothing pulls the swimmer back
  to the path (racetrack: 95 % of the time inside the curve, 1.1 mm against
  PI's 0.47 mm; 1, 3, 5: 0.79, 0.51, 0.40 mm);
* ``path``: points along the path ahead of the closest path point,
  ``r_k`` at arc length ``lead_mm + k * speed_mm_s * dt`` beyond it;
* ``target``: the pure-pursuit target itself for every k.

Latency (``latency_s``, default 0): a camera frame delivered ``latency_s``
after its capture gives, behind the passthrough estimator, the state of that
long ago; the controller steps it forward with its own model and the
commands it sent since (``x <- A x + B u + c``, as it predicts the horizon)
and builds the reference from that present state. Behind a filter that
already outputs the present (``estimator.kf`` with its ``latency_s``) set 0.
Without it, on the lab profile (40 ms, 40 mm/s) the loop rang and held the
swimmer ~3 mm below the path: racetrack 2.98 mm against PI's 0.80 mm
(30 s, seed 1), compensated 1.07 mm; the helix 3.11 -> 1.18 mm (PI 1.01).

Position terms (``position_terms``, default false): a model identified on
closed-loop logs learns a dependence on the absolute position that the
swimmer, in a field uniform over the workspace, does not have (the PI steers
by the position, so velocity and position correlate in its logs): the lab
model's y row reads ``y' = 1.0039 y + ...`` per 20 ms, 7.8 mm/s outwards at
the racetrack's y = 40 mm, so the MPC steered inwards against a drift that
is not there (mean radial offset -0.92 mm, on the straights too). Without
those columns (identity on p, none from p into v): racetrack 1.07 -> 0.53 mm
(lab, 30 s, seed 1, PI 0.80 mm).

The pure-pursuit tracker is stepped every period in all three (its closest
point orders the path following; ``path`` walks on from it).
"""

from __future__ import annotations

from collections import deque
from pathlib import Path

import numpy as np

from cosim import ComponentError
from cosim.contract.params import Param, read_params, whole_ticks
from cosim_plugins.controllers.common import PathController, SolveTimer
from cosim_plugins.controllers.mpc_qp import CondensedMPC, CvxpyMPC, MPCSpec, clip_first
from cosim_plugins.controllers.pure_pursuit import PurePursuit

REFERENCES = ("path", "pursuit", "target")
BACKENDS = ("osqp", "cvxpy")

PARAMS = {
    "model": Param("sindy-linear", "model file (.npz) or kind, see `cosim models`"),
    "dataset": Param("ideal", "profile whose paper dataset trains a model named by kind "
                     "(the lab profile sets lab: a lab model for a lab scenario)"),
    "horizon": Param(5, "prediction horizon N [steps]", 1, 50),
    "q": Param([3.0, 3.0, 3.0], "position error weights Q (x, y, z) [1/mm^2]"),
    "r": Param([1.0, 1.0, 1.0], "command change weights R (x, y, z)"),
    "ru": Param([1.0, 1.0, 1.0], "command weights Ru (x, y, z)"),
    "f_max_hz": Param(20.0, "command normalisation: u = omega_Hz / f_max_hz [Hz]", 0.1, 100.0),
    "u_max": Param(1.0, "bound on |u| per axis (normalised)", 0.0, 10.0),
    "du_max": Param(1.0, "bound on |u_k - u_{k-1}| per axis (normalised)", 0.0, 10.0),
    "f_norm_max_hz": Param(20.0, "safety cap on |omega| / 2 pi after the QP [Hz]", 0.0, 100.0),
    "speed_mm_s": Param(20.0, "cruise speed spacing the reference points [mm/s]", 0.0, 200.0),
    "cross_gain": Param(3.0, "pursuit reference: cross-track correction walked over the horizon [1/s] "
                        "(PI's kp; 0: the bare pure-pursuit carrot, which cuts the curves)", 0.0, 100.0),
    "lead_mm": Param(0.0, "arc length from the closest path point to the first reference point [mm]",
                     -50.0, 100.0),
    "lookahead_mm": Param(9.0, "pure-pursuit look-ahead distance [mm]", 0.1, 100.0),
    "lookahead_gain_s": Param(0.001, "look-ahead growth with speed [s]", 0.0, 10.0),
    "reference": Param("pursuit", f"reference over the horizon: {', '.join(REFERENCES)}"),
    "backend": Param("osqp", "QP implementation: 'osqp' (condensed, fast) or 'cvxpy' (reference)"),
    "eps": Param(1e-4, "OSQP absolute and relative tolerance", 1e-10, 1.0),
    "max_iter": Param(200, "OSQP iteration limit per solve", 1, 100000),
    "latency_s": Param(0.0, "age of the state it is given: the camera's latency when the estimator does not "
                       "compensate it (passthrough); 0 behind a filter that outputs the present (estimator.kf "
                       "with its latency_s) [s], a multiple of dt", 0.0, 5.0),
    "position_terms": Param(False, "keep the model's dependence on the absolute position (false: the dynamics "
                            "are the same everywhere in the tank, p' = p + ..., v' independent of p)"),
    "hover_hz": Param(0.0, "spin frequency (along x) of the hover point a nonlinear model is linearised at", 0.0, 60.0),
}


def _weights(p: dict, key: str) -> tuple[float, float, float]:
    w = p[key]
    if np.ndim(w) == 0:
        w = [w] * 3
    try:
        w = tuple(float(v) for v in w)
    except (TypeError, ValueError):
        raise ComponentError(f"parameter {key}={p[key]!r}: expected three numbers") from None
    if len(w) != 3 or min(w) < 0 or not all(np.isfinite(w)):
        raise ComponentError(f"parameter {key}={p[key]!r}: expected three non-negative numbers")
    return w


def check_params(params) -> dict:
    """Parameters with defaults, checked (ComponentError names the bad one); no model is touched."""
    p = read_params(params, PARAMS)
    if p["reference"] not in REFERENCES:
        raise ComponentError(f"reference {p['reference']!r} unknown; known: {', '.join(REFERENCES)}")
    if p["backend"] not in BACKENDS:
        raise ComponentError(f"backend {p['backend']!r} unknown; known: {', '.join(BACKENDS)}")
    for key in ("horizon", "max_iter"):
        if p[key] != int(p[key]):
            raise ComponentError(f"parameter {key}={p[key]!r}: expected a whole number")
    q, _, ru = (_weights(p, key) for key in ("q", "r", "ru"))
    if sum(q) == 0 or sum(q) + sum(ru) == 0:
        raise ComponentError("q must not be all zero (nothing to track), nor q and ru both")
    return p


def without_position_terms(A: np.ndarray) -> np.ndarray:
    """``A`` with the state's dependence on the absolute position removed: identity on p, zero p -> v."""
    A = np.array(A, dtype=float)
    A[:3, :3] = np.eye(3)
    A[3:, :3] = 0.0
    return A


def model_matrices(model, dt_s: float, hover_hz: float = 0.0, position_terms: bool = True):
    """(A (6, 6), B (6, 3), c (6,)) of ``model`` over one step of ``dt_s`` [s] (mm, mm/s, Hz).

    Linear models use ``linear_matrices()`` composed ``dt_s / model.dt_s`` times;
    others are linearised at hover (p = 0, v = 0, u = [hover_hz, 0, 0]) over dt_s.
    ``position_terms=False``: the model's one step without its position columns
    (:func:`without_position_terms`), composed.
    """
    try:
        A, B, c = (np.asarray(m, dtype=float) for m in model.linear_matrices())
    except NotImplementedError:
        u_h = np.array([hover_hz, 0.0, 0.0])
        A, B, c = (np.asarray(m, dtype=float) for m in model.jacobians(np.zeros(6), u_h, dt_s))
        return (A if position_terms else without_position_terms(A)), B, c
    if not position_terms:
        A = without_position_terms(A)
    ratio = dt_s / model.dt_s
    n = int(round(ratio))
    if n < 1 or abs(ratio - n) > 1e-6:
        raise ValueError(f"the model steps {model.dt_s * 1e3:g} ms; the scenario's {dt_s * 1e3:g} ms is not a multiple")
    An, Bn, cn = np.eye(6), np.zeros((6, 3)), np.zeros(6)
    for _ in range(n):
        An, Bn, cn = A @ An, A @ Bn + B, A @ cn + c
    return An, Bn, cn


class MPCController(PathController):
    """Eq. 15 on a linear(ised) model, warm-started OSQP every step; pure-pursuit reference."""

    @classmethod
    def validate_params(cls, params):
        """Cheap checks of the scenario's params (the model is not resolved here)."""
        check_params(params)

    @classmethod
    def prepare(cls, params):
        """Train the model now if it is named by kind and not cached yet."""
        from cosim_plugins.identify.cache import resolve_model

        p = check_params(params)
        resolve_model(str(p["model"]), profile=str(p["dataset"]))

    @classmethod
    def artifacts(cls, params) -> list:
        spec = Path(str(check_params(params)["model"]))
        return [spec] if spec.suffix == ".npz" or spec.is_file() else []

    def setup(self, params, rng):
        p = self.p = check_params(params)
        q, r, ru = (_weights(p, key) for key in ("q", "r", "ru"))
        self.dt = params["dt"]
        self.path = params["path"]
        self.pursuit = PurePursuit(self.path, p["lookahead_mm"] * 1e-3, p["lookahead_gain_s"])
        A, B, c = self._load_model(p)
        self.spec = MPCSpec(A=A, B=B, c=c, horizon=int(p["horizon"]), q=q, r=r, ru=ru, f_max_hz=p["f_max_hz"],
                            u_max=p["u_max"], du_max=p["du_max"], eps=p["eps"], max_iter=int(p["max_iter"]))
        self.qp = CondensedMPC(self.spec) if p["backend"] == "osqp" else CvxpyMPC(self.spec)
        #: the commands u (normalised) sent over the camera's latency, oldest first
        self.sent: deque[np.ndarray] = deque(maxlen=whole_ticks(p["latency_s"], self.dt, "latency_s"))
        self.u_prev = np.zeros(3)
        self.failures = 0
        self.last_plan: np.ndarray | None = None

    def _load_model(self, p):
        from cosim.contract.errors import UserError
        from cosim_plugins.identify.cache import resolve_model

        try:
            model = resolve_model(str(p["model"]), profile=str(p["dataset"]))
            A, B, c = model_matrices(model, self.dt, p["hover_hz"], bool(p["position_terms"]))
        except (UserError, ValueError, RuntimeError) as exc:
            raise ComponentError(f"model {p['model']!r}: {exc}") from None
        if not (np.all(np.isfinite(A)) and np.all(np.isfinite(B)) and np.all(np.isfinite(c))):
            raise ComponentError(f"model {p['model']!r}: non-finite matrices")
        if np.abs(B).max() == 0:
            raise ComponentError(f"model {p['model']!r}: the command has no effect at the linearisation point "
                                 "(set hover_hz or use a linear model)")
        return A, B, c

    def step(self, t, inputs):
        with SolveTimer() as timer:
            omega = self._control(t, np.asarray(inputs["position"]), np.asarray(inputs["velocity"]))
        return {"omega": omega, "solve_time": timer.elapsed}

    # ------------------------------------------------------------ control

    def _control(self, t: float, pos: np.ndarray, vel: np.ndarray) -> np.ndarray:
        s = self.spec
        if not np.all(np.isfinite(pos)):  # no estimate (yet): ramp to zero within the Delta-u bound
            self.u_prev = clip_first(np.zeros(3), self.u_prev, s.u_max, s.du_max)
            self.sent.append(self.u_prev)
            return 2 * np.pi * s.f_max_hz * self.u_prev
        vel = vel if np.all(np.isfinite(vel)) else np.zeros(3)
        x = self.present_state(np.concatenate([pos, vel]) * 1e3)  # [mm, mm/s]
        pos, vel = x[:3] * 1e-3, x[3:] * 1e-3
        ref = self.horizon_reference(t, pos, vel) * 1e3  # (N, 3) [mm]
        plan = self.qp.solve(x, ref, self.u_prev)
        if plan is None:
            self.failures += 1
        self.last_plan = plan
        u0 = clip_first(np.zeros(3) if plan is None else plan[0], self.u_prev, s.u_max, s.du_max)
        f_norm = np.linalg.norm(u0) * s.f_max_hz
        if f_norm > self.p["f_norm_max_hz"]:
            u0 = u0 * (self.p["f_norm_max_hz"] / f_norm)  # towards zero: the bounds still hold
        self.u_prev = u0
        self.sent.append(u0)
        return 2 * np.pi * s.f_max_hz * u0

    def present_state(self, x: np.ndarray) -> np.ndarray:
        """The state ``latency`` periods after ``x`` [mm, mm/s]: the model stepped with the commands
        sent since (the frame's capture), as the horizon itself is predicted; ``x`` without latency."""
        s = self.spec
        for u in self.sent:
            x = s.A @ x + s.B @ (u * s.f_max_hz) + s.c
        return x

    def horizon_reference(self, t: float, pos: np.ndarray, vel: np.ndarray) -> np.ndarray:
        """Reference positions r_1..r_N, shape (N, 3) [m] (see the module docstring)."""
        N, kind = self.spec.horizon, self.p["reference"]
        target, closest, _ = self.pursuit.reference(pos, vel, t)
        step_m = self.p["speed_mm_s"] * 1e-3 * self.dt
        if kind == "target":
            return np.tile(target, (N, 1))
        if kind == "pursuit":
            to_target = target - pos
            dist = np.linalg.norm(to_target)
            k = np.arange(1, N + 1)
            s = np.minimum(step_m * k, dist)
            cross = (self.p["cross_gain"] * self.dt * k)[:, None] * (closest - pos)
            return pos + s[:, None] * (to_target / max(dist, 1e-12)) + cross
        return self.pursuit.along(self.p["lead_mm"] * 1e-3 + step_m * np.arange(1, N + 1), t)
