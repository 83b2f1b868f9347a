"""A model plus effects, fitted jointly on window rollouts, and its open-loop errors.

:class:`JointModel` wraps a fitted host model (any :class:`~cosim_plugins.identify.model.Model`;
effects need a parametric host with ``terms``, ``all_params``, ``set_params``
and ``params``, like the physical model) with extra effects: force effects
become the host's terms, input effects transform the command timeline and
sensor effects the predicted measurements. Units: mm, mm/s, Hz, s.

Rollouts are batched over windows (see :mod:`cosim_plugins.identify.timeline`).
Each window's initial position and velocity are nuisance unknowns solved by
a small linear least-squares step on the rollout's sensitivity to them
(variable projection), because a measured velocity carries the camera noise
(~7 mm/s at 0.1 mm and 20 ms):

* fitting (:func:`fit_joint`): the initial state fits the whole window and
  all parameters minimise the remaining position residuals
  (``scipy.optimize.least_squares``), with standard errors from the
  Jacobian at the solution;
* evaluation (:meth:`JointModel.evaluate`): the initial state fits only a
  lead-in of ``lead`` steps, and the open-loop error is read ``K`` steps
  after the lead-in's last measurement, as an estimator would predict;
* the open-loop polish (``fit_joint(..., polish=OpenLoop(...))``): the fit
  goes on minimising those open-loop errors at every step up to the
  reference horizon. On the short windows the initial state absorbs much of
  a slow drift (a flow, a too-slow velocity response that keeps an initial
  velocity) and a delay trades off against the velocity response almost
  for free; over the horizon the model must predict alone, they do not.

Every least-squares problem here takes its Jacobian with the initial state's
sensitivity held at the current parameters (:class:`HeldJacobian`, Kaufman's
approximation of variable projection): a parameter's column then costs one
rollout of the windows instead of four (the nominal one and one per
velocity component). On a host that takes parameters per group of batch
columns (the physical model's ``set_groups``) the columns' perturbed
parameter vectors are rolled out together, as extra batch columns of one
rollout: the same numbers as one rollout per column, far fewer (and wider)
array operations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares

from cosim.contract.errors import UserError
from cosim_plugins.identify.effect import split_kinds

DV = 1.0  # velocity perturbation for the sensitivities [mm/s]
SHORT_NFEV = 3  # evaluations of the short refinement of every start, on the screening windows
SCREEN_EVERY = 8  # the screening windows: every 8th training window
EE_WINDOWS = 200  # training windows the equation-error starts use
EE_NFEV = 15  # evaluations of each equation-error fit
DIVERGED_MM = 1000.0  # the error of a window whose rollout diverged (larger than any tank) [mm]
#: The largest residual [mm] a fit's least squares sees: a trial point's NaN, inf or anything larger becomes it
#: (a rollout that ran off to 1e200 mm is finite, but its squares overflow and the solver's SVD then fails)
RESIDUAL_CAP_MM = 1e6
TRADEOFF_CORR = 0.95  # |correlation| of two estimates beyond which the data cannot tell them apart
# the initial-state solve's ridge [mm^2 per mm^2, mm^2 per (mm/s)^2]: it keeps the correction of the guess finite
# where the windows do not see a direction. The velocity's is worth about one measurement row per 10 mm/s: a
# velocity response faster than a control period forgets the initial velocity within a row, and a rollout that
# starts rows before its window (a latency's lookback) leaves it to the position alone; unbounded, the solve then
# chose velocities of ~100 mm/s off the guess, a nonlinear transient that changed the error by ~10 % each time a
# latency's lookback crossed a whole period (the fit stalled at whole periods)
RIDGE = np.diag([1e-6] * 3 + [1e-4] * 3)
POLISH_NFEV = 8  # evaluations of the open-loop polish
BASIN_SCALES = 2.0  # a start this far from the polished solution (effect parameters, in typical scales) is polished too
MAX_BATCH_COLUMNS = 4096  # batch columns a rollout steps at once (wider ones miss the caches: slower)
# Gauss-Newton passes of an open-loop window's initial-state solve, in the evaluation and in every fit of open-loop
# errors alike: a fit that minimised one-pass errors while the diagnosis measured two-pass ones settled where the
# two disagree (a baseline 25 % above the truth's held-out error on logs with nothing hidden, which any effect's
# refit then "explained")
OPEN_LOOP_PASSES = 2


def capped(r: np.ndarray) -> np.ndarray:
    """Residuals [mm] with NaN, inf and magnitudes above :data:`RESIDUAL_CAP_MM` set to +-RESIDUAL_CAP_MM."""
    return np.clip(np.nan_to_num(r, nan=RESIDUAL_CAP_MM), -RESIDUAL_CAP_MM, RESIDUAL_CAP_MM)


@dataclass(frozen=True)
class OpenLoop:
    """Open-loop windows: each starts at ``starts`` (w,), its initial state solved on a lead-in of ``lead``
    steps (:data:`OPEN_LOOP_PASSES` passes, as :meth:`JointModel.evaluate`), its error read ``k`` steps after
    the lead-in for every k in ``steps`` (H,)."""

    starts: np.ndarray
    lead: int
    steps: tuple

    @classmethod
    def upto(cls, starts: np.ndarray, lead: int, horizon: int) -> "OpenLoop":
        """Errors at every step 1 .. ``horizon`` after the lead-in."""
        return cls(starts, lead, tuple(range(1, horizon + 1)))

    def errors(self, jm: "JointModel", tl, held: "Solve | None" = None) -> tuple[np.ndarray, "Solve"]:
        """((w * H * 3,) predicted - measured [mm] (window-major), 0 where a window does not reach step k;
        the initial-state solve), the solve held from ``held`` when given (see :meth:`JointModel.projected`)."""
        valid, err, solve = jm.open_loop_errors(tl, self.starts, self.lead, self.steps, OPEN_LOOP_PASSES, held)
        return np.where(valid[..., None], err, 0.0).reshape(-1), solve


@dataclass(frozen=True)
class Solve:
    """The initial-state solve of a batch of windows: the state its last pass started from, x0 (w, 6), the
    sensitivity S (w, L + 1, 3, 6) and its normal matrix G (w, 6, 6), and the rollouts' lookback; the rows
    the solve fitted, use (w, L + 1) bool, and S on them, Su (w, 3 (L + 1), 6) (reused by held solves)."""

    x0: np.ndarray
    S: np.ndarray
    G: np.ndarray
    lookback: int
    use: np.ndarray | None = None
    Su: np.ndarray | None = None


@dataclass(frozen=True)
class UnitOffsets:
    """Base parameters that differ per unit of timeline rows (a log, a block of time): a window starting in
    unit u uses ``shared + offsets[u]``. ``names`` (F,), ``of_row`` (n,) the unit of each row of the timelines
    the model is evaluated on, ``offsets`` (U, F) in each parameter's own unit."""

    names: tuple
    of_row: np.ndarray
    offsets: np.ndarray

    def values(self, prm: dict, starts: np.ndarray) -> dict:
        """{name: (w,) the value each window at ``starts`` uses}."""
        u = self.of_row[starts]
        return {n: prm[n] + self.offsets[u, j] for j, n in enumerate(self.names)}


def supports_effects(model) -> bool:
    """True if ``model`` can take force terms and expose its parameters (the physical model can)."""
    return all(hasattr(model, a) for a in ("terms", "all_params", "set_params", "params"))


class JointModel:
    """A host model with effects; parameters are the host's plus the transforms' (see module doc)."""

    def __init__(self, host, effects=(), base_params: dict | None = None):
        self.effects = list(effects)
        forces, self.inputs, self.sensors = split_kinds(self.effects)
        self.dt_s = host.dt_s
        if self.effects:
            if not supports_effects(host):
                raise ValueError(f"model {host.name!r} cannot include effects")
            opts = dict(host.options)
            own = host.params()
            host = type(host)(**opts, terms=[*host.terms, *forces])
            host.set_params(own)
            host.dt_s = self.dt_s
        self.host = host
        # a host that steps step-mean velocities exactly needs each step's previous command
        self._held = getattr(host, "options", {}).get("hold") == "exact"
        self.param_list = list(host.all_params()) if supports_effects(host) else []
        for e in (*self.inputs, *self.sensors):
            self.param_list += [replace(q, name=f"{e.name}.{q.name}") for q in e.params]
        self.names = [q.name for q in self.param_list]
        self.std: dict = {}  # standard errors after fit_joint
        self.conditioning: dict = {}  # after fit_joint, see conditioning()
        self.window_params: dict = {}  # after fit_joint: the short-window fit's parameters, before any polish
        self.per_unit: UnitOffsets | None = None  # base parameters that differ per log or block of time
        self._commands = None  # (timeline, input parameters, commands) of :meth:`commands`
        self._variants: _Variants | None = None  # a Jacobian's parameter vectors rolled out together
        self._fitted_rows = None  # (timeline, starts, length, fit_rows, target, use, tz, positions) of the last
        start = {q.name: q.init for q in self.param_list}
        start.update(host.params() if supports_effects(host) else {})
        start.update(base_params or {})
        self._set(np.array([start[n] for n in self.names], dtype=float))

    def savable(self):
        """The host model with the force effects in it and the fitted parameters: what a model file holds.

        Input and sensor effects transform the logged timelines, which a model file cannot carry: a
        UserError names them.
        """
        other = [f"{e.name} ({e.kind})" for e in (*self.inputs, *self.sensors)]
        if other:
            raise UserError(f"cannot save {', '.join(other)} into a model file: only force effects become part "
                            "of the model the Kalman filter and the MPC use")
        self._set(self.theta)
        return self.host

    # ------------------------------------------------------------ parameters

    def _set(self, theta: np.ndarray) -> None:
        self.theta = np.asarray(theta, dtype=float)
        prm = dict(zip(self.names, self.theta))
        if supports_effects(self.host):
            host_names = [q.name for q in self.host.all_params()]
            self.host.set_params({n: prm[n] for n in host_names})
        self.prm = prm

    def params(self) -> dict:
        return {n: float(t) for n, t in zip(self.names, self.theta)}

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array([q.lo for q in self.param_list]), np.array([q.hi for q in self.param_list])

    def scales(self) -> np.ndarray:
        """(P,) typical magnitude of each parameter (:meth:`EffectParam.typical`): the optimiser's units."""
        return np.array([q.typical() for q in self.param_list])

    def clip(self, theta: np.ndarray) -> np.ndarray:
        """theta moved strictly inside the bounds (least_squares needs an interior start)."""
        lo, hi = self.bounds()
        span = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
        return np.clip(theta, lo + 1e-9 * span, hi - 1e-9 * span)

    # ------------------------------------------------------------ rollouts

    def _step(self, xt, ut):
        if hasattr(self.host, "predict_t"):
            return self.host.predict_t(xt, ut, self.dt_s)
        return self.host.predict(xt.T, ut.T, self.dt_s).T

    def commands(self, tl) -> np.ndarray:
        """(n, 3) the timeline's commands after this model's input effects, remembered for the last timeline
        and input parameters (a Jacobian's columns for the other parameters reuse them: on an archive the
        transforms run over every row)."""
        key = self._input_key(self.prm)
        if self._commands is None or self._commands[0] is not tl or self._commands[1] != key:
            self._commands = (tl, key, tl.effective_commands(self.inputs, self.prm))
        return self._commands[2]

    def _input_key(self, prm: dict) -> tuple:
        return tuple(prm[f"{e.name}.{q.name}"] for e in self.inputs for q in e.params)

    def _commands_of(self, tl, prms: list) -> list:
        """[(n, 3) :meth:`commands` with each of the parameters ``prms``], one array per distinct input
        parameters (the current ones' remembered)."""
        made: dict = {}
        now = self._input_key(self.prm)
        for prm in prms:
            key = self._input_key(prm)
            if key not in made:
                made[key] = self.commands(tl) if key == now else tl.effective_commands(self.inputs, prm)
        return [made[self._input_key(prm)] for prm in prms]

    def __getstate__(self):  # sent between processes without the remembered commands (and their timeline)
        return {**self.__dict__, "_commands": None, "_variants": None, "_fitted_rows": None}

    def lookback(self, prm: dict | None = None) -> int:
        """Rows before each window the rollouts start at: what the sensor effects read (see the effect doc);
        with the parameters ``prm`` (default the current ones)."""
        prm = self.prm if prm is None else prm
        m = 0
        for e in self.sensors:
            if e.lookback is not None:
                m = max(m, int(e.lookback({q.name: prm[f"{e.name}.{q.name}"] for q in e.params})))
        return m

    def batchable(self) -> bool:
        """True when rollouts of several parameter vectors can share one batch (see :meth:`rollouts`): a host
        with parameters per group of columns, and no parameters per unit of rows."""
        return self.per_unit is None and hasattr(self.host, "set_groups") and hasattr(self.host, "predict_t")

    def trajectories(self, tl, starts: np.ndarray, length: int, x0: np.ndarray, u_eff=None) -> np.ndarray:
        """Predicted measurements (c, w, L + 1, 3) at rows ``starts`` (w,) .. + L.

        The rollouts start :meth:`lookback` (m) rows earlier, from initial states x0 (c, w, 6) at rows
        ``starts - m`` (at most back to the segment's first row, whose command the earlier rows repeat);
        ``c`` stacks variants of the same windows (the velocity perturbations);
        commands past a window's usable run are replaced by zeros (callers mask those rows).
        Inside :meth:`HeldJacobian.jac` a single rollout (c = 1) of one of its columns' parameter vectors is
        taken from a rollout of them all (:class:`_Variants`).
        """
        if self._variants is not None and x0.shape[0] == 1:
            traj = self._variants.take(self, tl, starts, length, x0, u_eff)
            if traj is not None:
                return traj
        return self.rollouts(tl, starts, length, x0, u_eff)[0]

    def rollouts(self, tl, starts: np.ndarray, length: int, x0: np.ndarray, u_eff=None, thetas=None) -> list:
        """[:meth:`trajectories` (c, w, L + 1, 3) with the parameters of each row of ``thetas`` (G, P)] from
        one batch of G c w columns (the host's ``set_groups``); ``thetas`` None: the current parameters alone.
        Every row must have the same :meth:`lookback`; the commands after the input effects are each row's own
        unless ``u_eff`` (n, 3) is given."""
        c, w = x0.shape[:2]
        if thetas is None:
            groups, prms = 1, [self.prm]
        else:
            if not self.batchable():
                raise ValueError(f"model {self.host.name!r}: rollouts of several parameter vectors need a host "
                                 "with set_groups and no parameters per unit")
            groups, prms = len(thetas), [dict(zip(self.names, th)) for th in thetas]
        m = self.lookback() if thetas is None else self.lookback(prms[0])
        if any(self.lookback(prm) != m for prm in prms[1:]):
            raise ValueError("rollouts: the parameter vectors need different lookbacks; roll them out apart")
        rows = np.minimum(starts[:, None] + np.arange(-m, length)[None, :], tl.n - 1)
        if m:
            rows = np.maximum(rows, tl.segment_start[starts][:, None])
        u_effs = [u_eff] * groups if u_eff is not None else self._commands_of(tl, prms)

        def batch(r):  # (w, m + L) rows -> (m + L, 3, G c w) commands, group-major, C-contiguous
            own = {id(u): u for u in u_effs}
            own = {k: np.nan_to_num(u[r]).transpose(1, 2, 0)[:, :, None, :] for k, u in own.items()}
            out = np.empty((m + length, 3, groups, c, w))
            if len(own) == 1:
                out[:] = own[id(u_effs[0])][:, :, None]
            else:
                for g, u in enumerate(u_effs):
                    out[:, :, g] = own[id(u)]
            return out.reshape(m + length, 3, groups * c * w)

        Ut = batch(rows)
        Up = batch(tl.previous[rows]) if self._held else None
        xt = np.ascontiguousarray(x0.reshape(c * w, 6).T)
        if groups > 1:
            xt = np.ascontiguousarray(np.tile(xt, (1, groups)))
        n = groups * c * w
        out = np.empty((m + length + 1, 3, n))
        out[0] = xt[:3]
        # a wide batch of one parameter vector is stepped in pieces that stay in the caches
        pieces = [slice(0, n)] if thetas is not None or n <= MAX_BATCH_COLUMNS else \
            [slice(a, min(a + MAX_BATCH_COLUMNS, n)) for a in range(0, n, MAX_BATCH_COLUMNS)]
        columns = None
        if self.per_unit is not None:
            columns = {name: np.tile(v, c) for name, v in self.per_unit.values(self.prm, starts).items()}
        if thetas is not None:
            self.host.set_groups(np.asarray(thetas)[:, : self.host.n_params], c * w)
        try:
            for cols in pieces:
                whole = len(pieces) == 1
                x = xt if whole else np.ascontiguousarray(xt[:, cols])
                U = Ut if whole else np.ascontiguousarray(Ut[:, :, cols])
                P = Up if whole or Up is None else np.ascontiguousarray(Up[:, :, cols])
                if columns is not None:
                    self.host.set_columns({name: v[cols] for name, v in columns.items()})
                for j in range(m + length):
                    x = self.host.predict_t(x, U[j], self.dt_s, P[j]) if self._held else self._step(x, U[j])
                    out[j + 1, :, cols] = x[:3]
        finally:
            if self.per_unit is not None:
                self.host.set_columns(None)
            if thetas is not None:
                self.host.set_groups(None)
        trajs = out.transpose(2, 0, 1).reshape(groups, c, w, m + length + 1, 3)
        result = []
        for traj, prm in zip(trajs, prms):
            for effect in self.sensors:
                own = {q.name: prm[f"{effect.name}.{q.name}"] for q in effect.params}
                traj = np.stack([effect.transform(t, tl.dt_s, own) for t in traj])
            result.append(traj[:, :, m:])
        return result

    def projected(self, tl, starts, length, fit_rows: np.ndarray, passes: int = 1, u_eff=None,
                  held: Solve | None = None):
        """Rollouts with each window's initial state solved on ``fit_rows``.

        Args:
            fit_rows: (w, L + 1) bool, rows whose measurements determine the initial state.
            held: a :class:`Solve` of the same windows to hold: one rollout from its x0, corrected with its
                sensitivity (a Jacobian's column, see :class:`HeldJacobian`); ignored when the lookback changed.
        Returns:
            (pred (w, L + 1, 3) predicted measurements after the correction, the :class:`Solve`).
        """
        target, use, tz = self._targets(tl, starts, length, fit_rows)
        m = self.lookback()
        if held is not None and held.lookback == m:
            q0 = self.trajectories(tl, starts, length, held.x0[None], u_eff)[0]
            Su = held.Su if held.use is not None and np.array_equal(held.use, use) else None
            return _corrected(q0, held.S, use, tz, held.G, Su)[0], held
        x0 = lookback_guess(tl, starts, m)  # the guess where the rollouts start
        xs = np.stack([x0] + [x0 + DV * np.eye(6)[3 + a] for a in range(3)])
        q = self.trajectories(tl, starts, length, xs, u_eff)
        S = np.zeros(q.shape[1:3] + (3, 6))
        S[..., :3] = np.eye(3)
        S[..., 3:] = ((q[1:] - q[0]) / DV).transpose(1, 2, 3, 0)
        S = np.where(np.isfinite(S), S, 0.0)
        pred, d, G, Su = _corrected(q[0], S, use, tz)
        solve = Solve(x0, S, G, m, use, Su)
        for _ in range(passes - 1):  # further passes from the corrected state, the sensitivity held
            solve = replace(solve, x0=solve.x0 + d)
            q0 = self.trajectories(tl, starts, length, solve.x0[None], u_eff)[0]
            pred, d, _, _ = _corrected(q0, S, use, tz, G, Su)
        return pred, solve

    # ------------------------------------------------------------ evaluation

    def evaluate(self, tl, starts: np.ndarray, lead: int, steps: dict, passes: int = OPEN_LOOP_PASSES):
        """Open-loop errors ``steps[key]`` steps after a lead-in of ``lead`` steps.

        Args:
            starts: (w,) window start rows (the lead-in's first row).
            steps: {horizon key: steps after the lead-in}.
            passes: Gauss-Newton passes of the initial state's solve (one is exact for a model linear in it;
                the later ones hold the first one's sensitivity).
        Returns:
            {key: {"valid": (w,) bool, "err": (w, 3) predicted - measured [mm]}}; a window whose
            rollout diverged (NaN, or off by more than :data:`DIVERGED_MM`) has an error of DIVERGED_MM
        """
        return self.open_loop(tl, starts, lead, steps, passes)[0]

    def open_loop(self, tl, starts, lead, steps, passes: int = OPEN_LOOP_PASSES, held: Solve | None = None):
        """(:meth:`evaluate`'s errors, the initial-state :class:`Solve`), the solve held from ``held`` if given."""
        valid, err, solve = self.open_loop_errors(tl, starts, lead, tuple(steps.values()), passes, held)
        return {key: {"valid": valid[:, h].copy(), "err": err[:, h].copy()} for h, key in enumerate(steps)}, solve

    def open_loop_errors(self, tl, starts, lead, ks, passes: int = OPEN_LOOP_PASSES, held: Solve | None = None):
        """(valid (w, H) bool, err (w, H, 3) predicted - measured [mm], the :class:`Solve`): :meth:`open_loop`'s
        errors ``ks`` (H,) steps after the lead-in, as arrays (NaN where not valid)."""
        ks = np.asarray(ks, dtype=np.int64)
        length = lead + int(ks.max())
        fit_rows = np.zeros((len(starts), length + 1), dtype=bool)
        fit_rows[:, : lead + 1] = True
        with np.errstate(all="ignore"):  # a model that diverges shows as a huge error, not a warning
            pred, solve = self.projected(tl, starts, length, fit_rows, passes=passes, held=held)
        rows = lead + ks
        target = self._targets(tl, starts, length, fit_rows)[0][:, rows]  # (w, H, 3)
        valid = (tl.run[starts][:, None] >= rows[None, :]) & np.all(np.isfinite(target), axis=2)
        err = np.where(valid[..., None], pred[:, rows] - np.nan_to_num(target), np.nan)
        with np.errstate(all="ignore"):
            diverged = valid & ~(np.linalg.norm(err, axis=2) <= DIVERGED_MM)  # NaN too
        err[diverged] = DIVERGED_MM / math.sqrt(3.0)
        return valid, err, solve

    def _targets(self, tl, starts, length, fit_rows):
        """(:func:`targets` (w, L + 1, 3), the rows that fit the initial state: ``fit_rows`` and measured (w, L + 1),
        the targets there and 0 elsewhere), remembered for the last windows (a Jacobian's columns reuse them)."""
        last = self._fitted_rows
        if not (last is not None and last[0] is tl and last[7] is tl.p and last[2] == length
                and (last[1] is starts or np.array_equal(last[1], starts)) and np.array_equal(last[3], fit_rows)):
            target = targets(tl, starts, length)
            use = fit_rows & np.all(np.isfinite(target), axis=2)
            last = (tl, starts, length, fit_rows, target, use, np.where(use[..., None], target, 0.0), tl.p)
            self._fitted_rows = last
        return last[4:7]


def lookback_guess(tl, starts: np.ndarray, m: int) -> np.ndarray:
    """(w, 6) the guess of the state [mm, mm/s] at the row each rollout starts from, ``m`` rows before the windows
    at ``starts`` (w,) (at most back to the segment's first row).

    A lookback belongs to a sensor effect that reports earlier positions (a latency, see
    :mod:`cosim_plugins.identify.effect`): what the camera shows at a window's first row is where the swimmer was
    about ``m`` rows before it, so that row's state estimate is the guess. The state logged ``m`` rows earlier is
    where it was about ``2 m`` rows before: a start that far off the path needs a correction beyond the linearised
    initial-state solve, and a model with a larger latency would be judged on a worse start than one without.
    Where the segment's start clips the rollout, the state shown ``m`` rows after its first row is the guess.
    """
    if m == 0:
        return tl.x_lin[starts]
    r0 = np.maximum(starts - m, tl.segment_start[starts])
    return tl.x_lin[np.minimum(r0 + m, tl.n - 1)]


def _corrected(q0, S, use, tz, G=None, Su=None):
    """(q0 corrected by the Gauss-Newton step of the initial state (w, L + 1, 3), the step d (w, 6), G, Su): the
    step fits the rows ``use`` (w, L + 1) of the targets ``tz`` (0 elsewhere) with the sensitivity S and its
    normal matrix G (w, 6, 6), S on the rows used Su (w, 3 (L + 1), 6) (each made here when not given)."""
    w, rows = use.shape
    q0 = np.where(np.isfinite(q0), q0, 0.0)
    r = np.where(use[..., None], q0 - tz, 0.0)
    if Su is None:
        Su = (S * use[..., None, None]).reshape(w, rows * 3, 6)  # batched matmul: BLAS, not einsum loops
    SuT = Su.transpose(0, 2, 1)
    if G is None:
        G = SuT @ Su + RIDGE
    rhs = -(SuT @ r.reshape(w, rows * 3, 1))
    try:
        d = np.linalg.solve(G, rhs)[..., 0]
    except np.linalg.LinAlgError:  # a window whose rollout blew up (its normal matrix singular) gets no step
        d = np.zeros((w, 6))
        for i in range(w):
            try:
                d[i] = np.linalg.solve(G[i], rhs[i])[:, 0]
            except np.linalg.LinAlgError:
                pass
    return q0 + (S.reshape(w, rows * 3, 6) @ d[..., None]).reshape(q0.shape), d, G, Su


class HeldJacobian:
    """Residuals ``fn(held) -> (r (N,), Solve)`` of windows whose initial states are solved, as a function of
    the parameters, with a forward-difference Jacobian that holds the initial-state solve at the current
    parameters (Kaufman's approximation of variable projection): one rollout per column instead of four.

    ``step``: each column's step in units of its parameter's scale (default: :data:`STEP` of the parameter's
    size or scale, whichever is larger)."""

    STEP = 1.5e-8  # relative forward-difference step (the square root of the machine epsilon)

    def __init__(self, jm: "JointModel", fn, counter: dict | None = None, step: float | None = None):
        self.jm, self.fn, self.counter, self.step = jm, fn, counter, step
        self.theta, self.r, self.solve = None, None, None

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        if self.counter is not None:
            self.counter["n"] += 1
        self.jm._set(theta)
        self.r, self.solve = self.fn(None)
        self.theta = np.array(theta, dtype=float)
        return self.r

    def jac(self, theta: np.ndarray, cols=None, batched: bool = True) -> np.ndarray:
        """(N, len(cols)) derivatives of the residuals by the parameters ``cols`` (default: all).

        ``batched``: the columns' rollouts share batches where the model allows (:meth:`JointModel.batchable`;
        the same numbers as one rollout per column), else one rollout per column."""
        theta = np.asarray(theta, dtype=float)
        if self.theta is None or not np.array_equal(theta, self.theta):
            self(theta)
        r0, solve = self.r, self.solve
        cols = np.arange(len(theta)) if cols is None else np.asarray(cols)
        _, hi = self.jm.bounds()
        scale = self.jm.scales()
        J = np.empty((len(r0), len(cols)))
        steps, thetas = [], []
        for j in cols:
            th = theta.copy()
            h = self.step * scale[j] if self.step is not None else self.STEP * max(abs(th[j]), scale[j])
            h = -h if th[j] + h > hi[j] else h
            th[j] += h
            steps.append(h)
            thetas.append(th)
        if batched and len(cols) > 1 and self.jm.batchable():
            self.jm._variants = _Variants(np.array(thetas))
        try:
            for n, (th, h) in enumerate(zip(thetas, steps)):
                self.jm._set(th)
                J[:, n] = (self.fn(solve)[0] - r0) / h
        finally:
            self.jm._variants = None
            self.jm._set(theta)
        return J


class _Variants:
    """The parameter vectors (G, P) of a Jacobian's columns, rolled out together: the first single rollout a
    column asks for (:meth:`JointModel.trajectories`) is made for it and the columns after it with the same
    lookback, up to :data:`MAX_BATCH_COLUMNS` batch columns, and each later column takes its own. A request
    for other windows or initial states than the first one's is not served (the caller rolls it out alone)."""

    def __init__(self, thetas: np.ndarray):
        self.thetas = thetas
        self.request = None  # (timeline, starts, length, x0, u_eff) the rollouts are of
        self.ready: dict = {}  # column -> its rollout (1, w, L + 1, 3), until taken
        self.made: set = set()  # columns rolled out

    def take(self, jm: JointModel, tl, starts, length, x0, u_eff):
        """The rollout of ``jm``'s current parameter vector, or None when it is not one of the columns' or the
        request is not the first one's."""
        hit = np.flatnonzero(np.all(self.thetas == jm.theta, axis=1))
        if not len(hit):
            return None
        i = int(hit[0])
        if self.request is None:
            self.request = (tl, starts, length, x0, u_eff)
        else:
            tl0, starts0, length0, x00, u0 = self.request
            if not (tl0 is tl and length0 == length and u0 is u_eff
                    and (starts0 is starts or np.array_equal(starts0, starts)) and np.array_equal(x00, x0)):
                return None
        if i not in self.ready:
            if i in self.made:  # asked for twice
                return None
            m = jm.lookback()
            width = max(1, MAX_BATCH_COLUMNS // max(len(starts), 1))
            chunk = [j for j in range(i, len(self.thetas))
                     if j not in self.made and jm.lookback(dict(zip(jm.names, self.thetas[j]))) == m][:width]
            self.ready.update(zip(chunk, jm.rollouts(tl, starts, length, x0, u_eff, self.thetas[chunk])))
            self.made.update(chunk)
        return self.ready.pop(i)


def targets(tl, starts: np.ndarray, length: int) -> np.ndarray:
    """(w, L + 1, 3) measured positions of windows at ``starts``; NaN past the end of the data."""
    rows = starts[:, None] + np.arange(length + 1)[None, :]
    out = tl.p[np.minimum(rows, tl.n - 1)]
    out[rows >= tl.n] = np.nan
    return out


def floor_draws(S, G, use, lead, steps, sigma, draws, seed) -> dict:
    """Per-window expected error norm of a perfect model under white noise ``sigma`` (3,) [mm]."""
    rng = np.random.default_rng(seed)
    sigma = np.asarray(sigma, dtype=float)
    w, rows = use.shape
    acc = {key: np.zeros(w) for key in steps}
    for _ in range(draws):
        n = rng.normal(size=(w, rows, 3)) * sigma
        nu = np.where(use[..., None], n, 0.0)
        d = np.linalg.solve(G, np.einsum("wkai,wka->wi", S * use[..., None, None], nu)[..., None])[..., 0]
        for key, k in steps.items():
            row = lead + k
            e = -n[:, row] + np.einsum("wai,wi->wa", S[:, row], d)
            acc[key] += np.linalg.norm(e, axis=1) / draws
    return acc


@dataclass
class FitResult:
    """Outcome of :func:`fit_joint`: parameters, standard errors, costs."""

    params: dict
    std: dict
    rms_mm: float
    rms_start_mm: float
    evaluations: int
    status: int
    start: int = 0
    extra: dict = field(default_factory=dict)


def fit_joint(jm: JointModel, tl, starts: np.ndarray, length: int, max_nfev: int = 30,
              extra_starts=(), fresh_starts=(), free_starts=(), progress=None, score=None,
              polish: OpenLoop | None = None) -> FitResult:
    """Fit all parameters of ``jm`` on windows of ``length`` steps at rows ``starts``.

    Starts: the current parameters; each ``extra_starts`` dict ``{name: value}``
    applied to them; and, for continuous-time hosts, the integrated
    equation-error fit (:mod:`cosim_plugins.identify.equation_error`) from each
    ``fresh_starts`` dict applied to the current parameters (a start that does
    not inherit a degenerate previous fit; the effect parameters it names,
    ``effect.param``, are held at their values, the host's adapt); each
    ``free_starts`` dict applied to the current parameters, nothing held
    (e.g. the host's forces scaled to another velocity time constant). Every
    distinct start is refined for :data:`SHORT_NFEV` evaluations (an extra
    start holding its own values, the rest adapting to them) on every
    :data:`SCREEN_EVERY`-th window (a start's own cost says little: in a flat
    degenerate basin the right one can start dearer); the best of them by
    ``score(jm)`` (lower is better; default: the screening cost) is refined
    for up to ``max_nfev`` on all windows. The optimiser works in units of
    each parameter's typical scale. Standard errors come
    from the Jacobian at the solution, sigma^2 (J^T J)^-1, inflated by how
    often each measurement enters overlapping windows;
    ``extra["conditioning"]`` says how well the data pin the parameters down
    (:func:`conditioning`).
    """
    counter = {"n": 0}
    fixed_u = None if jm.inputs else tl.effective_commands([], {})

    def objective(rows: np.ndarray):
        """The residual function on the windows at ``rows`` (w,), and its mask of measured rows (w, L + 1)."""
        fit_rows = np.ones((len(rows), length + 1), dtype=bool)
        target = targets(tl, rows, length)
        use = np.all(np.isfinite(target), axis=2)
        target = np.nan_to_num(target)

        def residual(held):
            with np.errstate(all="ignore"):  # a trial point may diverge: its cost is then huge, not an error
                pred, solve = jm.projected(tl, rows, length, fit_rows, u_eff=fixed_u, held=held)
                r = np.where(use[..., None], pred - target, 0.0)
            return capped(r.reshape(-1)), solve

        return HeldJacobian(jm, residual, counter), use

    residual, use = objective(starts)

    def applied(values: dict) -> np.ndarray:
        th = jm.theta.copy()
        for name, value in values.items():
            th[jm.names.index(name)] = value
        return jm.clip(th)

    theta_now = jm.clip(jm.theta)
    # (start, the names it holds during its brief refinement): an effect's listed start keeps its own values
    # while the rest adapts to them (a lag of 0.3 s needs a faster velocity response than the fit without it)
    candidates = [(theta_now, ())] + [(applied(extra), tuple(extra)) for extra in extra_starts]
    candidates += [(applied(start), ()) for start in free_starts]
    if fresh_starts and supports_equation_error(jm):
        from cosim_plugins.identify.equation_error import EquationError

        sub = starts if len(starts) <= EE_WINDOWS else starts[:: int(np.ceil(len(starts) / EE_WINDOWS))]
        ee = EquationError(jm, tl, sub, length)
        for start in fresh_starts:
            held = tuple(n for n in start if "." in n)  # an effect's start values stay; the host adapts to them
            free = np.array([n not in held for n in jm.names])
            candidates.append((jm.clip(ee.fit(applied(start), free, max_nfev=EE_NFEV)[0]), ()))
        jm._set(theta_now)
    lo, hi = jm.bounds()
    scale = jm.scales()
    candidates = _distinct(candidates, scale)
    if len(candidates) > 1:  # every start refined briefly on a few windows, the best one goes on
        screen, _ = objective(starts[::SCREEN_EVERY])
        short = [_refine_held(screen, th, [jm.names.index(n) for n in held], lo, hi, scale)
                 for th, held in candidates]
        costs = [cost for _, cost in short]
        if score is not None:  # e.g. the open-loop error at a longer horizon than the windows'
            costs = [_scored(jm, th, score) if np.isfinite(cost) else np.inf for th, cost in short]
        best = int(np.argmin(costs))
        start_theta = short[best][0]
    else:
        best, start_theta = 0, candidates[0][0]
    r0 = residual(candidates[best][0])
    res = least_squares(residual, start_theta, jac=residual.jac, bounds=(lo, hi), x_scale=scale, method="trf",
                        max_nfev=max_nfev, ftol=1e-6, xtol=1e-7)
    n_window = int(use.sum()) * 3  # residuals of the window fit
    rows_used = np.zeros(tl.n, dtype=bool)
    rows_used[(starts[:, None] + np.arange(length + 1)[None, :])[use]] = True
    x, jac, fun, n_used, n_distinct = res.x, res.jac, res.fun, n_window, 3 * int(rows_used.sum())
    jm.window_params = dict(zip(jm.names, map(float, x)))
    polished = None
    if polish is not None:
        # the polish starts from the best-scored of the window fit's solution, the start it began from and the
        # model as it came (an added effect at its initial value): on short windows that hardly see an effect,
        # the window fit can wander along a flat valley to where the longer horizon is worse than where it began
        known = {1: costs[best]} if len(candidates) > 1 and score is not None else {}  # start_theta's, scored above
        polish_from = [x, start_theta] + ([theta_now] if start_theta is not theta_now else [])
        polished = _polish(jm, tl, polish, polish_from, lo, hi, scale, counter, score, progress, known)
        if len(candidates) > 1 and score is not None:  # another basin: the start farthest in the effects' values
            polished = _other_basin(jm, tl, polish, short, costs, polished, x, lo, hi, scale, counter, score,
                                    progress)
    if polished is not None:  # the open-loop windows are a sample: their measurements hardly overlap
        x, jac, fun = polished
        n_used = n_distinct = int(np.count_nonzero(fun))
    jm._set(x)
    std = _standard_errors(jac, fun, n_used, n_distinct)
    jm.std = {n: float(v) for n, v in zip(jm.names, std)}
    jm.conditioning = conditioning(jm, x, jac)
    if progress:
        progress(f"fit {len(starts)} windows x {length} steps: "
                 f"rms {math.sqrt(np.mean(r0 ** 2) * r0.size / n_window):.3f}"
                 f" -> {math.sqrt(2 * res.cost / n_window):.3f} mm ({counter['n']} evaluations, "
                 f"start {best + 1} of {len(candidates)})")
    return FitResult(params=jm.params(), std=dict(zip(jm.names, std)),
                     rms_mm=math.sqrt(2 * res.cost / n_window),
                     rms_start_mm=math.sqrt(float(np.sum(r0 ** 2)) / n_window),
                     evaluations=counter["n"], status=int(res.status), start=best,
                     extra={"conditioning": jm.conditioning})


def _polish(jm, tl, ol: OpenLoop, thetas, lo, hi, scale, counter, score, progress, known=None):
    """The fit refined on the open-loop errors of ``ol`` from the best-scored of ``thetas`` (the window fit's
    solution first; ``known``: {index: score} already computed): (theta, Jacobian, residuals), or None when
    the window fit's solution stands (nothing lowers ``score`` below it). Without a score the polish starts
    from the window fit's solution."""

    def errors(held):
        with np.errstate(all="ignore"):
            e, solve = ol.errors(jm, tl, held)
        return np.nan_to_num(e, nan=DIVERGED_MM, posinf=DIVERGED_MM, neginf=-DIVERGED_MM), solve

    residual = HeldJacobian(jm, errors, counter)
    known = known or {}
    scored = [known[i] if i in known else _scored(jm, th, score)
              for i, th in enumerate(thetas if score is not None else thetas[:1])]
    first = int(np.argmin(scored))
    before, theta = scored[first], jm.clip(thetas[first])
    r = least_squares(residual, theta, jac=residual.jac, bounds=(lo, hi), x_scale=scale, method="trf",
                      max_nfev=POLISH_NFEV, ftol=1e-6, xtol=1e-7)
    after = _scored(jm, r.x, score)
    keep = after < before if score is not None else True
    if progress:
        progress(f"open-loop polish on {len(ol.starts)} windows x {max(ol.steps)} steps"
                 + (f" from start {first + 1} of {len(scored)}" if first else "") + ": "
                 + (f"score {before:.3f} -> {after:.3f} mm ({'kept' if keep else 'not kept'})" if score is not None
                    else f"rms {math.sqrt(2 * r.cost / max(np.count_nonzero(r.fun), 1)):.3f} mm"))
    if keep:
        return r.x, r.jac, r.fun
    if first == 0:
        return None
    jac = residual.jac(theta)  # a start scores better than the window fit's solution: it stands
    return theta, jac, residual.r


def _other_basin(jm, tl, ol: OpenLoop, short: list, costs: list, polished: tuple | None, x: np.ndarray, lo, hi,
                 scale, counter, score, progress) -> tuple | None:
    """``polished`` ((theta, Jacobian, residuals) of :func:`_polish`, or None: the window fit's solution ``x``
    stands), or the polish of another start when that scores lower.

    The score of an effect's time constant or delay can have two basins, and the brief refinement of the starts
    on short windows ranks them badly (a 0.45 s lag held at a 0.3 s start scores worse, before the host has
    adapted, than a 0.09 s one; polished, it is far better). So the refined start whose effect parameters are
    farthest (in units of their typical scale) from the polished solution's is polished too, when it lies more
    than :data:`BASIN_SCALES` away; the lower score wins."""
    eff = np.array(["." in n for n in jm.names])
    if not eff.any():
        return polished
    x = x if polished is None else polished[0]
    far = [(float(np.linalg.norm((th[eff] - x[eff]) / scale[eff])), i) for i, (th, _) in enumerate(short)
           if np.isfinite(costs[i])]
    dist, i = max(far, default=(0.0, -1))
    if dist <= BASIN_SCALES:
        return polished
    before = _scored(jm, x, score)
    alt = _polish(jm, tl, ol, [short[i][0]], lo, hi, scale, counter, None, None)
    after = _scored(jm, alt[0], score)
    if progress:
        progress(f"open-loop polish from another basin (start {i + 1}, {dist:.1f} scales away): "
                 f"score {after:.3f} against {before:.3f} mm ({'kept' if after < before else 'not kept'})")
    return alt if after < before else polished


def _scored(jm, theta, score) -> float:
    if score is None:
        return 0.0
    jm._set(theta)
    value = float(score(jm))
    return value if np.isfinite(value) else np.inf


def _distinct(candidates: list, scale: np.ndarray) -> list:
    """``candidates`` (theta, held names) without repeats: a start within a hundredth of every parameter's
    scale of an earlier one with the same held names."""
    out = []
    for th, held in candidates:
        if not any(h == held and np.all(np.abs(th - kept) <= 0.01 * scale) for kept, h in out):
            out.append((th, held))
    return out


def _refine_held(fun: HeldJacobian, theta: np.ndarray, held: list, lo, hi, scale) -> tuple[np.ndarray, float]:
    """:data:`SHORT_NFEV` evaluations of least squares from ``theta`` with the parameters at indices ``held``
    kept at their values; (the refined theta, its cost, inf when not finite)."""
    free = np.setdiff1d(np.arange(len(theta)), held)

    def full(x):
        th = theta.copy()
        th[free] = x
        return th

    r = least_squares(lambda x: fun(full(x)), theta[free], jac=lambda x: fun.jac(full(x), free),
                      bounds=(lo[free], hi[free]), x_scale=scale[free], method="trf",
                      max_nfev=SHORT_NFEV, ftol=1e-6, xtol=1e-7)
    out = theta.copy()
    out[free] = r.x
    return out, float(r.cost) if np.isfinite(r.cost) else np.inf


def supports_equation_error(jm) -> bool:
    """True when the equation-error starts apply: a continuous-time host with parameters."""
    return supports_effects(jm.host) and hasattr(jm.host, "predict_t")


def conditioning(jm: JointModel, theta: np.ndarray, J: np.ndarray) -> dict:
    """How well the data pin the fitted parameters down.

    Returns ``{"at_bound": [names], "condition": float, "tradeoffs": [[a, b, corr]], "unseen": [names]}``:
    parameters within 1e-6 of a scale from a finite bound; the condition number of the Jacobian in
    scaled units; pairs whose estimates are correlated beyond :data:`TRADEOFF_CORR` (the data
    cannot tell them apart: one can stand in for the other); parameters the residuals do not depend on.
    """
    J = np.asarray(J) * jm.scales()[None, :]
    lo, hi = jm.bounds()
    tol = 1e-6 * jm.scales()
    at_bound = [n for n, t, a, b in zip(jm.names, theta, lo, hi) if abs(t - a) <= tol[jm.names.index(n)]
                or abs(b - t) <= tol[jm.names.index(n)]]
    col = np.linalg.norm(J, axis=0)
    seen = col > 1e-9 * max(float(col.max()), 1e-300)
    unseen = [n for n, ok in zip(jm.names, seen) if not ok]
    Js = J[:, seen] / col[seen]
    sv = np.linalg.svd(Js, compute_uv=False) if Js.size else np.ones(1)
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf
    cov = np.linalg.pinv(Js.T @ Js)
    d = np.sqrt(np.maximum(np.diag(cov), 1e-300))
    corr = cov / np.outer(d, d)
    names = [n for n, ok in zip(jm.names, seen) if ok]
    pairs = [[names[i], names[j], float(corr[i, j])] for i in range(len(names)) for j in range(i + 1, len(names))
             if abs(corr[i, j]) >= TRADEOFF_CORR]
    pairs.sort(key=lambda x: -abs(x[2]))
    return {"at_bound": at_bound, "condition": cond, "tradeoffs": pairs, "unseen": unseen}


def _standard_errors(J, r, n_used: int, n_distinct: int) -> np.ndarray:
    """sqrt(diag(s^2 (J^T J)^+)) with s^2 = |r|^2 / (n - P), times the overlap inflation n_used / n_distinct.

    NaN for a parameter the residuals do not depend on (e.g. a step-out frequency above every command), and
    for every parameter when the Jacobian or the residuals hold a non-finite value (a rollout that diverged at
    the solution): no uncertainty is better than a made-up one.
    """
    J = np.asarray(J)
    p = J.shape[1]
    if not (np.all(np.isfinite(J)) and np.all(np.isfinite(r))):
        return np.full(p, np.nan)
    s2 = float(r @ r) / max(n_used - p, 1)
    JTJ = J.T @ J
    scale = np.sqrt(np.maximum(np.diag(JTJ), 1e-300))
    cov = np.linalg.pinv(JTJ / np.outer(scale, scale)) / np.outer(scale, scale)
    inflation = max(n_used / max(n_distinct, 1), 1.0)
    std = np.sqrt(np.maximum(np.diag(cov), 0.0) * s2 * inflation)
    std[np.diag(JTJ) <= 1e-12 * max(float(np.max(np.diag(JTJ))), 1e-300)] = np.nan  # the data do not see it
    return std
