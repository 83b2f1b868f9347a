"""The paper's physical model (Sec. II-A, Eq. 1-9), fitted by least squares.

Units: p mm, v mm/s, u = omega Hz, forces uN, mass mg, so the acceleration
is a [mm/s^2] = 1000 F / m. Forces (Eq. 1-7), with alpha the angle between
omega and v, v_perp the unit vector normal to v in the (omega, v) plane and
c_hat = -p / |p|::

    F_r  = k omega                                   k    [uN/Hz]
    F_d  = -(Cd0 sin(alpha) + Cd1) v                 Cd0, Cd1 [uN s/mm]
    F_l  = Cl0 sin(2 alpha) |v| v_perp               Cl0  [uN s/mm]
    F_vs = Fvs [0, 0, 1]                             Fvs  [uN]
    F_c  = Fmax sin(pi |p| / |P_b|) c_hat            Fmax [uN], P_b = [70, 70, 70] mm

plus any extra :class:`~cosim_plugins.identify.terms.ForceTerm`. With alpha, v_perp
and c_hat taken from the data the force is linear in the six parameters.

Integration (stable for any drag): over a step the drag is exact (exponential
integrator with rate lambda = 1000 Cd / m), the other forces held constant,
then the position moves with the new velocity: v' = e^{-lambda dt} v +
dt phi1(lambda dt) a_other, p' = p + dt v'. An extra term's drag (the part
of its force that grows with the velocity, along it) joins lambda, so a
stiff quadratic drag is as stable as the linear one. So v' = (p' - p) / dt, the paper's
backward-difference velocity, and a state built from data is consistent with
the model's own.

``hold="exact"`` (what ``cosim diagnose`` fits with) makes that recursion of
step-mean velocities exact for a command held over each step: a step-mean
velocity still carries half of the previous step's force, so the command's
force enters with weight phi2(z)/phi1(z) (phi2(z) = (1 - phi1(z))/z, about a
half) and the previous command's with the rest, and the angle of attack, the
lift and extra terms are taken at the step's mean velocity, not the last
step's. Without it the model leads a continuous-time swimmer by about half
a step wherever the command turns, which a diagnosis reads as a camera
latency that is not there. That mean velocity is the step's own result, so
each step is taken twice: first with the geometry at a prediction that
knows only the thrust and Cd1, then at the first pass's new velocity. With
the prediction alone the scheme is first-order where the angle terms (Cd0,
Cl0) are large against Cd1: a fast swimmer (m / (Cd0 + Cd1) = 33 ms,
30 mm/s) ends 0.24 mm off its finely integrated path after 1 s at 20 ms
steps, which a diagnosis took up as an effect; with the second pass,
0.046 mm, and the error falls as the step squared. The default, ``"paper"``,
is the scheme above.

Fit: (1) the six base parameters by linear instrumental-variable least
squares on the one-step velocity change, and a first-order response fit as a
fallback start (the better of the two by the stage 2 objective); (2) all parameters (extra terms
included) by ``scipy.optimize.least_squares`` on the multi-step position
error of many windows rolled out at once, with each window's initial state
eliminated by variable projection (measured V_i is noisy).
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np
from scipy.optimize import least_squares

from cosim.contract.errors import UserError
from cosim_plugins.identify.effect import effect_sources, library_data, restore_effects, water_params
from cosim_plugins.identify.model import Model
from cosim_plugins.identify.terms import EffectParam, ForceTerm
from cosim_plugins.models import kernels

BASE_PARAMS = (  # scales: typical magnitudes for a mm-sized swimmer (tau_v ~ 0.03-0.5 s, 1-5 mm/s per Hz)
    EffectParam("k", 0.1, unit="uN/Hz", scale=0.1),
    EffectParam("Cd0", 0.0, 0.0, math.inf, "uN s/mm", scale=0.02),
    EffectParam("Cd1", 0.05, 0.0, math.inf, "uN s/mm", scale=0.05),
    EffectParam("Cl0", 0.0, unit="uN s/mm", scale=0.02),
    EffectParam("Fvs", 0.0, unit="uN", scale=0.2),
    EffectParam("Fmax", 0.0, unit="uN", scale=0.1),
)
BASE_NAMES = tuple(p.name for p in BASE_PARAMS)


def geometry(p, v, u, pb_norm_mm: float):
    """Per-sample factors of Eq. 2-6.

    Args: p, v, u: (n, 3) position [mm], velocity [mm/s], omega [Hz].
    Returns:
        sin_a: (n,) sin(alpha) (0 when omega or v vanishes),
        lift: (n, 3) sin(2 alpha) |v| v_perp [mm/s],
        cent: (n, 3) sin(pi |p| / |P_b|) c_hat [-].
    """
    sin_a, lift = kernels.angle_terms(_floats(v).T, _floats(u).T)
    return sin_a, lift.T, _centring_t(_floats(p).T, pb_norm_mm).T


_sum3 = np.add.reduce  # _sum3(a * b, 0): the component sums of (3, n) arrays, a[0] b[0] + a[1] b[1] + a[2] b[2]


def _floats(a) -> np.ndarray:
    """``a`` as a float array (the compiled kernels take float64 arrays only)."""
    return a if isinstance(a, np.ndarray) and a.dtype == np.float64 else np.asarray(a, dtype=float)


def hydrodynamic_force(v: np.ndarray, u: np.ndarray, params: dict) -> np.ndarray:
    """(n, 3) [uN] drag and lift of Eq. 2-5 at velocity v (n, 3) [mm/s] through the water, command u (n, 3) [Hz]:
    -(Cd0 sin(alpha) + Cd1) v + Cl0 sin(2 alpha) |v| v_perp (``params``: Cd0, Cd1, Cl0; a missing one is 0)."""
    return kernels.hydrodynamic(_floats(v).T, _floats(u).T, float(params.get("Cd0", 0.0)),
                                float(params.get("Cd1", 0.0)), float(params.get("Cl0", 0.0))).T


def flow_force(v: np.ndarray, w: np.ndarray, u: np.ndarray, params: dict) -> np.ndarray:
    """(n, 3) [uN] H(v - w) - H(v): the change of :func:`hydrodynamic_force` at velocity v (n, 3) [mm/s] and
    command u (n, 3) [Hz] when the water moves at w ((3,) or (n, 3) [mm/s])."""
    w = np.asarray(w, dtype=float)
    return kernels.flow_change(_floats(v).T, w.reshape(-1, 3).T, _floats(u).T, float(params.get("Cd0", 0.0)),
                               float(params.get("Cd1", 0.0)), float(params.get("Cl0", 0.0))).T


def _centring_t(p, pb):
    """sin(pi |p| / |P_b|) c_hat (3, n) of :func:`geometry`, component-major."""
    return kernels.centring(_floats(p), float(pb))


def forces(p, v, u, params: dict, terms=(), pb_norm_mm: float = 70 * math.sqrt(3)):
    """Total force [uN], (n, 3), at p [mm], v [mm/s], u [Hz] for named ``params``."""
    f = params["k"] * u + hydrodynamic_force(v, u, params) + params["Fmax"] * _centring_t(p.T, pb_norm_mm).T
    f[:, 2] += params["Fvs"]
    for term, prm in zip(terms, _terms_params(terms, params)):
        f = f + term.force(p, v, u, prm)
    return f


def _terms_params(terms, params: dict) -> list:
    """Per term, its own parameters by short name, plus the base parameters (k, Cd0, ...) it may reuse and the
    water's velocity that a flow among ``terms`` sets (:func:`~cosim_plugins.identify.effect.water_params`)."""
    shared = {**{n: params[n] for n in BASE_NAMES}, **water_params(terms, params)}
    return [{**shared, **{q.name: params[f"{term.name}.{q.name}"] for q in term.params}} for term in terms]


def phi1(z):
    """(1 - exp(-z)) / z, accurate near 0."""
    small = np.abs(z) < 1e-6
    zs = np.where(small, 1.0, z)
    return np.where(small, 1.0 - 0.5 * z, -np.expm1(-zs) / zs)


class PhysicalModel(Model):
    """Paper Eq. 1-9 with k, Cd0, Cd1, Cl0, Fvs, Fmax (+ extra terms); see module doc."""

    name = "physical"
    version = 1

    def __init__(self, mass_mg=12.4, pb_mm=(70.0, 70.0, 70.0), horizon=20, max_windows=3000,
                 max_nfev=25, vp_passes=2, substeps=1, seed=0, terms=(), hold="paper"):
        if hold not in ("paper", "exact"):
            raise ValueError(f"physical model: hold must be 'paper' or 'exact', not {hold!r}")
        super().__init__(mass_mg=mass_mg, pb_mm=list(pb_mm), horizon=horizon, max_windows=max_windows,
                         max_nfev=max_nfev, vp_passes=vp_passes, substeps=substeps, seed=seed, hold=hold)
        self._exact = hold == "exact"
        self.terms: list[ForceTerm] = list(terms)
        for term in self.terms:
            if getattr(term, "kind", "force") != "force":
                raise ValueError(f"effect {term.name!r} is a {term.kind} transform, not a force term")
        self._pb = float(np.linalg.norm(pb_mm))
        self._scale = 1000.0 / mass_mg
        self._theta = np.array([p.init for p in self.all_params()])
        self._columns: dict | None = None  # see set_columns
        self._groups: _Groups | None = None  # see set_groups
        self.fit_info: dict = {}

    @classmethod
    def from_params(cls, params: dict, dt_s: float = 0.02, **options) -> "PhysicalModel":
        """A model with given parameters (e.g. a synthetic plant); missing ones keep initial values."""
        model = cls(**options)
        model.set_params(params)
        model.dt_s = dt_s
        return model

    # ------------------------------------------------------------ parameters

    def all_params(self) -> list[EffectParam]:
        """Base and extra-term parameters, extra ones named ``term.param``."""
        out = list(BASE_PARAMS)
        for term in self.terms:
            out += [replace(q, name=f"{term.name}.{q.name}") for q in term.params]
        return out

    def _param_names(self) -> tuple[str, ...]:
        """Names of :meth:`all_params`, remembered while the terms stay the same (the rollouts' hot path)."""
        key = tuple(map(id, self.terms))
        if getattr(self, "_names_key", None) != key:
            self._names_key, self._names = key, tuple(q.name for q in self.all_params())
        return self._names

    def _velocity_terms(self) -> tuple[bool, ...]:
        """Per term: does its force change with the velocity? (probed once, a typical step from the initial values)"""
        key = tuple(map(id, self.terms))
        if getattr(self, "_moving_key", None) != key:
            rng = np.random.default_rng(0)
            p, u = rng.uniform(-40.0, 40.0, (8, 3)), rng.uniform(-10.0, 10.0, (8, 3))
            v = rng.uniform(-30.0, 30.0, (8, 3))
            named = {q.name: float(np.clip(q.init + q.typical(), q.lo, q.hi)) for q in self.all_params()}
            flags = []
            for term, prm in zip(self.terms, _terms_params(self.terms, named)):
                with np.errstate(all="ignore"):
                    moved = term.force(p, v, u, prm) - term.force(p, np.zeros_like(v), u, prm)
                flags.append(not np.allclose(moved, 0.0, atol=0.0))
            self._moving_key, self._moving = key, tuple(flags)
        return self._moving

    def set_params(self, params: dict) -> None:
        names = [p.name for p in self.all_params()]
        unknown = set(params) - set(names)
        if unknown:
            raise ValueError(f"unknown physical parameters {sorted(unknown)}; known: {names}")
        self._theta = np.array([params.get(n, t) for n, t in zip(names, self._theta)], dtype=float)

    def params(self) -> dict:
        return {p.name: float(t) for p, t in zip(self.all_params(), self._theta)}

    def set_columns(self, columns: dict | None) -> None:
        """Base parameters that differ per batch column in :meth:`predict_t`: ``{name: (n,) values}`` for a
        batch of n columns (e.g. a drag fitted per log), None to share them again. Extra terms keep reading
        the shared values of the base parameters they reuse."""
        if not columns:
            self._columns = None
            return
        unknown = set(columns) - set(BASE_NAMES)
        if unknown:
            raise ValueError(f"only base parameters can differ per column, not {sorted(unknown)}")
        if self._groups is not None:
            raise ValueError("set_columns: parameters per group of columns are set (set_groups); clear them first")
        self._columns = {BASE_NAMES.index(n): np.asarray(v, dtype=float) for n, v in columns.items()}

    def set_groups(self, thetas: np.ndarray | None, width: int = 0) -> None:
        """Every parameter differing per group of batch columns in :meth:`predict_t`, None to share them again.

        ``thetas`` (G, P): the values of :meth:`all_params` (extra terms' included) for G groups of ``width``
        consecutive columns each, a batch of G * width columns (e.g. the perturbed parameter vectors of a
        Jacobian's columns, rolled out at once). Each group steps with the same arithmetic as a model with its
        own parameters (the same results, column by column); an extra term is called once per set of groups
        that agree on the parameters it reads, on that set's columns, always with scalar parameters
        (:class:`_TermGroups`).
        """
        if thetas is None:
            self._groups = None
            return
        if self._columns is not None:
            raise ValueError("set_groups: base parameters per column are set (set_columns); clear them first")
        thetas = np.asarray(thetas, dtype=float)
        if thetas.ndim != 2 or thetas.shape[1] != self.n_params or width < 1:
            raise ValueError(f"set_groups: thetas must be (groups, {self.n_params}) and width >= 1, "
                             f"not {thetas.shape} and {width}")
        self._groups = _Groups(thetas, int(width), self._param_names(), self.terms)

    @property
    def n_params(self) -> int:
        return len(self._theta)

    # ------------------------------------------------------------ dynamics

    def predict(self, x, u, dt_s: float) -> np.ndarray:
        """Next state for any dt_s [s] (continuous-time model); see :meth:`Model.predict`."""
        x = np.asarray(x, dtype=float)
        u = np.asarray(u, dtype=float)
        n, h = self.options["substeps"], dt_s / self.options["substeps"]
        if x.ndim == 1 and not self.terms and not self._exact:
            xs, us = x.tolist(), u.tolist()
            for _ in range(n):
                xs = _step_scalar(xs, us, h, self._theta, self._scale, self._pb)
            return np.array(xs)
        single = x.ndim == 1
        xt, ut = np.atleast_2d(x).T, np.atleast_2d(u).T
        for _ in range(n):
            xt = self._step_t(xt, ut, h, self._theta)
        return xt.T[0] if single else xt.T

    def predict_t(self, xt: np.ndarray, ut: np.ndarray, dt_s: float, ut_prev: np.ndarray | None = None) -> np.ndarray:
        """:meth:`predict` on component-major batches, xt (6, n), ut (3, n) -> (6, n) (fast batch rollouts).

        ``ut_prev`` (3, n): the previous step's commands, which ``hold="exact"`` uses (default: ``ut``).
        """
        n, h = self.options["substeps"], dt_s / self.options["substeps"]
        th, groups = self._theta, self._groups
        if groups is not None:
            if xt.shape[1] != groups.columns:
                raise ValueError(f"predict_t: a batch of {xt.shape[1]} columns, but set_groups made "
                                 f"{groups.columns}")
            th = groups.th
        elif self._columns is not None:
            th = list(th)
            for i, values in self._columns.items():
                th[i] = values
        for i in range(n):
            xt = self._step_t(xt, ut, h, th, ut_prev if i == 0 else None, groups)
        return xt

    def _step_t(self, x, u, h, th, u_prev=None, groups=None):
        """One step of h [s] on component-major arrays: x (6, n), u and u_prev (3, n) -> (6, n); ``groups``: the
        :class:`_Groups` of :meth:`set_groups` (``th`` is then theirs). ``hold="exact"`` takes it twice, the
        second time with the geometry at the first's new (step-mean) velocity (see the module doc); what does
        not depend on the velocity (the held command, the centring force, the terms' calls) is made once."""
        p, v = x[:3], x[3:]
        s = self._scale
        f = u  # the command whose force acts
        if self._exact:  # see the module doc
            if groups is not None:
                f1, w, decay = groups.hold(s, h)
            elif np.ndim(th[2]):  # a drag per column (set_columns)
                z1 = s * h * np.maximum(th[2], 0.0)
                f1 = phi1(z1)
                w = np.where(z1 > 1e-6, (1.0 - f1) / (np.maximum(z1, 1e-300) * f1), 0.5 + z1 / 12.0)
                decay = np.exp(-z1)
            else:
                f1, w, decay = _hold_factors(s, h, th[2])
            if u_prev is not None:
                f = w * u + (1.0 - w) * u_prev
        drive = th[0] * f
        drive[2] += th[4]
        cent = _centring_t(p, self._pb)
        packed = groups.packed if groups is not None else _packed(th, x.shape[1])
        calls = self._term_calls(th, groups) if self.terms else ()
        # a velocity term's force at rest, (3, n) or None: the same for both passes
        at_rest = [call(term, p, np.zeros_like(v), f) if moving else None
                   for term, moving, call in zip(self.terms, self._velocity_terms(), calls)]
        if not self._exact:  # the paper's scheme: the geometry at the last step's velocity
            return self._pass_t(x, u, f, drive, cent, v, h, packed, calls, at_rest)
        # first pass: the geometry at a prediction of the step's mean velocity that knows only the thrust and Cd1
        out = self._pass_t(x, u, f, drive, cent, decay * v + (s * h * f1) * drive, h, packed, calls, at_rest)
        return self._pass_t(x, u, f, drive, cent, out[3:], h, packed, calls, at_rest)

    def _term_calls(self, th, groups) -> list:
        """Per extra term, its force on (p, v, u) (3, n) with this step's parameters (a group's, under set_groups)."""
        if groups is not None:
            return [g.force for g in groups.terms]
        # under set_columns the terms read the shared values of the base parameters
        named = dict(zip(self._param_names(), self._theta if self._columns is not None else th))
        return [_one_call(prm) for prm in _terms_params(self.terms, named)]

    def _pass_t(self, x, u, f, drive, cent, v_geo, h, packed, calls, at_rest):
        """:meth:`_step_t`'s one pass: the drive and the centring force (3, n) held, the angle terms and the extra
        terms taken at ``v_geo`` (3, n) [mm/s] (``at_rest``: each velocity term's force at zero velocity, else
        None; ``packed``: the base parameters (6, 1 or n), :func:`_packed`); the step's new state (6, n)
        (:func:`~cosim_plugins.models.kernels.exp_pass`)."""
        term_forces = slowing = None  # the terms' forces (3, n) [uN], their drag power (n,) [uN mm/s]
        if self.terms:
            for term, rest, call in zip(self.terms, at_rest, calls):
                ft = call(term, x[:3], v_geo, f)
                term_forces = ft if term_forces is None else term_forces + ft
                if rest is not None:  # the part of its force that grows with the velocity, along it
                    drop = _sum3((ft - rest) * v_geo, 0)
                    slowing = -drop if slowing is None else slowing - drop
            term_forces = _floats(term_forces)
            slowing = None if slowing is None else _floats(slowing)
        return kernels.exp_pass(x, u, drive, cent, _floats(v_geo), packed, self._scale * h, h, term_forces, slowing)

    # ------------------------------------------------------------ fitting

    def fit(self, dataset) -> "PhysicalModel":
        t0 = time.perf_counter()
        self.dt_s = dataset.dt_s
        self._refine(dataset, [self._initial_iv(dataset), self._initial_response(dataset)])
        self.train_time_s = time.perf_counter() - t0
        return self

    def _regressors(self, p, v, vm, u):
        """(n, 3, 6) columns of the base force: geometry from (p, v), drag at vm."""
        sin_a, lift, cent = geometry(p, v, u, self._pb)
        ez = np.zeros_like(p)
        ez[:, 2] = 1.0
        return np.stack([u, -sin_a[:, None] * vm, -vm, lift, ez, cent], axis=2)

    def _initial_iv(self, dataset):
        """Stage 1: the base force is linear in the six parameters; solve it by
        instrumental variables on the one-step velocity change.

        Regressors use the step's mean velocity (V_i + V_{i+1}) / 2, whose
        measurement noise is shared with the target; the instruments are the same
        columns built from V_{i-2}, whose noise is independent. Falls back to
        ordinary least squares when there are too few such triples.
        """
        dt = dataset.dt_s
        idx = dataset.pair_index()
        idx_iv = idx[idx >= 2]
        idx_iv = idx_iv[dataset.state_ok[idx_iv - 2] & dataset.step_ok[idx_iv - 2] & dataset.step_ok[idx_iv - 1]]
        use_iv = len(idx_iv) >= 20 * len(BASE_PARAMS)
        i = idx_iv if use_iv else idx
        if len(i) < len(BASE_PARAMS):
            raise UserError(f"physical fit: only {len(i)} valid one-step pairs in the logs; need more data")
        p, v, u, vn = dataset.x[i, :3], dataset.x[i, 3:], dataset.u[i], dataset.x[i + 1, 3:]
        y = (vn - v) / (dt * self._scale)  # uN
        if self.terms:
            named = dict(zip((q.name for q in self.all_params()), self._theta))
            for term, prm in zip(self.terms, _terms_params(self.terms, named)):
                y = y - term.force(p, v, u, prm)
        A = self._regressors(p, v, 0.5 * (v + vn), u).reshape(-1, 6)
        norms = np.linalg.norm(A, axis=0)
        norms[norms == 0] = 1.0
        if use_iv:
            vl = dataset.x[i - 2, 3:]
            Z = self._regressors(p, vl, vl, u).reshape(-1, 6) / norms
            sol = np.linalg.lstsq(Z.T @ (A / norms), Z.T @ y.reshape(-1), rcond=None)[0] / norms
        else:
            sol = np.linalg.lstsq(A / norms, y.reshape(-1), rcond=None)[0] / norms
        theta = self._theta.copy()
        theta[:6] = sol
        self._report(f"physical: stage 1 ({'IV' if use_iv else 'LS'}) on {len(i)} pairs")
        return self._clip(theta)

    def _initial_response(self, dataset, taus=np.geomspace(0.02, 1.0, 13)):
        """Stage 1b, a robust fallback: a first-order velocity response to the commands.

        For each candidate time constant tau, V_i (noise only on this side) is
        regressed on the exponentially filtered command and a vertical offset:
        V = g u_bar + f z_hat. The best tau gives Cd1 = m / (1000 tau),
        k = g Cd1, Fvs = f Cd1; the other parameters start at zero.
        """
        from scipy.signal import lfilter

        ok = dataset.state_ok
        ok[0] = False
        u = np.nan_to_num(dataset.u)
        V = dataset.x[ok, 3:]
        best = None
        for tau in taus:
            a = math.exp(-dataset.dt_s / tau)
            u_bar = lfilter([0.0, 1.0 - a], [1.0, -a], u, axis=0)[ok]
            ez = np.zeros_like(u_bar)
            ez[:, 2] = 1.0
            A = np.stack([u_bar.reshape(-1), ez.reshape(-1)], axis=1)
            sol, res, *_ = np.linalg.lstsq(A, V.reshape(-1), rcond=None)
            sse = float(res[0]) if len(res) else float(np.sum((A @ sol - V.reshape(-1)) ** 2))
            if best is None or sse < best[0]:
                best = (sse, tau, sol)
        _, tau, (g, f) = best
        cd1 = self.options["mass_mg"] / (1000.0 * tau)
        theta = self._theta.copy()
        theta[:6] = [g * cd1, 0.0, cd1, 0.0, f * cd1, 0.0]
        self._report(f"physical: stage 1b (first-order response) tau = {tau:.3f} s")
        return self._clip(theta)

    def _clip(self, theta):
        ps = self.all_params()
        lo = np.array([p.lo for p in ps])
        hi = np.array([p.hi for p in ps])
        span = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
        return np.clip(theta, lo + 1e-9 * span, hi - 1e-9 * span)

    def _refine(self, dataset, starts):
        """Stage 2: multi-step position error over windows, all parameters jointly.

        Each window's initial position and velocity are nuisance unknowns,
        eliminated by variable projection (a small linear solve per window on
        the rollout's sensitivity to them, re-linearised ``vp_passes`` times):
        starting from the measured, noisy V_i biases the parameters towards
        over-damping. ``vp_passes=0`` gives the paper's objective (rollouts
        from the measured states), which scores better on noisy one-step and
        short-rollout comparisons but does not recover the true parameters.
        """
        k = int(self.options["horizon"])
        idx = dataset.window_index(k)
        if len(idx) < 2 * self.n_params:
            self._report("physical: too few multi-step windows without gaps; keeping the stage 1 fit")
            self.fit_info = {"windows": int(len(idx))}
            self._theta = starts[0]
            return
        m = int(self.options["max_windows"])
        if len(idx) > m:
            idx = np.sort(np.random.default_rng(self.options["seed"]).choice(idx, m, replace=False))
        X0, U, P = dataset.windows(k, idx)
        w, h, dv = len(idx), dataset.dt_s, 1.0
        eye = dv * np.eye(6)[3:]  # velocity perturbations (3, 6)
        Us = np.ascontiguousarray(np.concatenate([U] * 4).transpose(1, 2, 0))  # (k, 3, 4w)
        target = P.reshape(w, 3 * k)
        s_p = np.tile(np.eye(3), (k, 1))  # sensitivity to the initial position: identity at every step
        ridge = np.diag([1e-6] * 3 + [1e-6 * h * h] * 3)
        passes = int(self.options["vp_passes"])
        state = {"n": 0}

        def residual(theta):
            state["n"] += 1
            if state["n"] % 20 == 0:
                self._report(f"physical: stage 2, {state['n']} evaluations")
            if passes == 0:  # the paper's objective: rollouts from the measured states
                x = X0.T.copy()
                out = np.empty((k, 3, w))
                for j in range(k):
                    x = self._step_t(x, Us[j, :, :w], h, theta)
                    out[j] = x[:3]
                r = (out.reshape(3 * k, w).T - target).reshape(-1)
                return np.where(np.isfinite(r), r, DIVERGED_MM)
            x0 = X0
            for _ in range(passes):
                x = np.concatenate([x0] + [x0 + e for e in eye]).T.copy()  # (6, 4w)
                out = np.empty((k, 3, 4 * w))
                for j in range(k):
                    x = self._step_t(x, Us[j], h, theta)
                    out[j] = x[:3]
                out = out.reshape(k * 3, 4, w).transpose(1, 2, 0)  # (4, w, 3k), step-major
                r = out[0] - target
                S = np.empty((w, 3 * k, 6))
                S[:, :, :3] = s_p
                S[:, :, 3:] = ((out[1:] - out[0]) / dv).transpose(1, 2, 0)
                with np.errstate(over="ignore", invalid="ignore"):
                    G = np.einsum("wki,wkj->wij", S, S) + ridge
                good = np.isfinite(r).all(axis=1) & np.isfinite(S).all(axis=(1, 2)) & np.isfinite(G).all(axis=(1, 2))
                if not good.all():  # a rollout that blew up (a start or a trial step far off): no solve there
                    r[~good], S[~good], G[~good] = DIVERGED_MM, 0.0, np.eye(6)
                rhs = -np.einsum("wki,wk->wi", S, r)[..., None]
                try:
                    d = np.linalg.solve(G, rhs)[..., 0]
                except np.linalg.LinAlgError:  # sensitivities so large that G is singular in floating point
                    d = (np.linalg.pinv(G) @ rhs)[..., 0]
                x0 = x0 + d
            return (r + np.einsum("wki,wi->wk", S, d)).reshape(-1)

        ps = self.all_params()
        lo = np.array([p.lo for p in ps])
        hi = np.array([p.hi for p in ps])
        costs = [float(np.sum(residual(t) ** 2)) for t in starts]
        start = starts[int(np.argmin(costs))]
        r0 = residual(start)
        res = least_squares(residual, start, bounds=(lo, hi), x_scale="jac", method="trf",
                            max_nfev=int(self.options["max_nfev"]), ftol=1e-6, xtol=1e-6)
        self._theta = res.x
        rms0 = float(np.sqrt(np.mean(r0**2)))
        rms1 = float(np.sqrt(np.mean(res.fun**2)))
        self.fit_info = {"windows": int(w), "horizon": k, "evaluations": state["n"], "start": int(np.argmin(costs)),
                         "rms_mm_before": rms0, "rms_mm_after": rms1, "status": int(res.status)}
        self._report(f"physical: stage 2 on {w} windows x {k} steps: "
                     f"rms {rms0:.3f} -> {rms1:.3f} mm ({state['n']} evaluations)")

    # ------------------------------------------------------------ files

    def _state(self):
        meta = {"params": self.params(), "terms": [t.name for t in self.terms], "fit_info": self.fit_info,
                "effect_sources": effect_sources(self.terms), "effect_terms": library_data(self.terms)}
        return meta, {"theta": self._theta}

    def _restore(self, meta, arrays):
        if meta["terms"]:
            self.terms = restore_effects(meta["terms"], meta.get("effect_sources", {}),
                                         meta.get("effect_terms", {}))
        self._theta = np.asarray(arrays["theta"], dtype=float)
        self.fit_info = meta.get("fit_info", {})


#: The residual [mm] of every step of a window whose rollout blew up (overflow, NaN): far worse than any fit, finite
#: so the optimiser rejects the step that caused it instead of failing on a singular solve.
DIVERGED_MM = 1e3


def _hold_factors(s: float, h: float, cd1) -> tuple[float, float, float]:
    """``hold="exact"``'s factors of a step of h [s] with drag Cd1 (scalars): (phi1(z), the command's weight
    phi2(z) / phi1(z), exp(-z)) with z = s h Cd1, s = 1000 / m."""
    z1 = s * h * max(float(cd1), 0.0)
    f1 = -math.expm1(-z1) / z1 if z1 >= 1e-6 else 1.0 - 0.5 * z1  # phi1 on a scalar
    w = (1.0 - f1) / (z1 * f1) if z1 > 1e-6 else 0.5 + z1 / 12.0
    return f1, w, math.exp(-z1)


def _one_call(prm: dict):
    """A term's force on component-major p, v, u (3, n) with the parameters ``prm``: (3, n) [uN]."""
    return lambda term, p, v, u: term.force(p.T, v.T, u.T, prm).T


class _Reads(dict):
    """A term's parameters that remember the names the term reads (``everything``: it listed or copied them)."""

    def __init__(self, prm: dict):
        super().__init__(prm)
        self.names: set = set()
        self.everything = False

    def __getitem__(self, name):
        self.names.add(name)
        return super().__getitem__(name)

    def get(self, name, default=None):
        self.names.add(name)
        return super().get(name, default)

    def __contains__(self, name):
        self.names.add(name)
        return super().__contains__(name)


def _reads_everything(name: str):
    base = getattr(dict, name)

    def method(self, *args, **kwargs):
        self.everything = True
        return base(self, *args, **kwargs)

    return method


for _name in ("__iter__", "__len__", "__eq__", "__ne__", "__or__", "__ror__", "__repr__", "__reduce_ex__",
              "__reversed__", "keys", "items", "values", "copy", "pop", "popitem", "setdefault"):
    setattr(_Reads, _name, _reads_everything(_name))

_MISSING = object()


class _TermGroups:
    """One extra term's parameters per group of batch columns (``prms``, G dicts; ``width`` columns a group).

    :meth:`force` calls the term once per set of groups that agree on every parameter it reads (each call's
    parameters are a group's own scalars, on that set's columns laid out as a batch of its own), so a term
    that does not read a column's perturbed parameter runs once for all those columns. The names it reads
    are learnt from its calls (the first step calls it once per distinct parameter set) and every call is
    checked: one that reads another name is redone with the groups split by it too.
    """

    def __init__(self, prms: list, width: int):
        self.prms, self.width = prms, width
        self.reads: set | bool | None = None  # the names the term reads; None: not known yet; True: all
        self._parts: dict = {}

    def _partition(self) -> list:
        """[(columns: None for all, a slice or an index array; the parameters of the set's first group)]."""
        key = self.reads if self.reads is None or self.reads is True else frozenset(self.reads)
        if key not in self._parts:
            sets: dict = {}
            for g, prm in enumerate(self.prms):
                sig = tuple(prm.items()) if key is None or key is True else \
                    tuple(prm.get(n, _MISSING) for n in sorted(key))
                sets.setdefault(sig, []).append(g)
            parts = []
            for members in sets.values():
                w = self.width
                if len(members) == len(self.prms):
                    cols = None
                elif members[-1] - members[0] == len(members) - 1:
                    cols = slice(members[0] * w, (members[-1] + 1) * w)
                else:
                    cols = np.concatenate([np.arange(g * w, (g + 1) * w) for g in members])
                parts.append((cols, self.prms[members[0]]))
            self._parts[key] = parts
        return self._parts[key]

    def force(self, term, p, v, u) -> np.ndarray:
        """(3, n) the term's force [uN] on component-major p, v, u (3, n) of every group's columns."""
        while True:
            known = self.reads
            out, seen, everything, redo = None, set(), False, False
            for cols, prm in self._partition():
                arg = prm if known is True else _Reads(prm)
                if cols is None:
                    f = term.force(p.T, v.T, u.T, arg).T
                else:
                    f = term.force(*(np.ascontiguousarray(a[:, cols]).T for a in (p, v, u)), arg).T
                if known is not True:
                    everything |= arg.everything
                    seen |= arg.names
                    if known is not None and (arg.everything or not arg.names <= known):
                        redo = True  # merged on names that do not decide this call: split by the new ones too
                        break
                if cols is None:
                    out = f
                else:
                    if out is None:
                        out = np.empty_like(p)
                    out[:, cols] = f
            if known is not True:
                self.reads = True if everything else seen | (known or set())
            if not redo:
                return out


class _Groups:
    """The per-group parameters of :meth:`PhysicalModel.set_groups`: ``th`` the six base parameters (a scalar
    where every group has the same value, else (G * width,) per column), ``terms`` a :class:`_TermGroups` per
    extra term, ``columns`` G * width."""

    def __init__(self, thetas: np.ndarray, width: int, names: tuple, terms):
        self.thetas, self.width, self.columns = thetas, width, len(thetas) * width
        self.th = [self._per_column(thetas[:, i]) for i in range(len(BASE_NAMES))]
        named = [dict(zip(names, row)) for row in thetas]
        per_group = [_terms_params(terms, nm) for nm in named]
        self.terms = [_TermGroups([prms[i] for prms in per_group], width) for i in range(len(terms))]
        self._hold: dict = {}
        self.packed = _packed(self.th, self.columns)  # the six base parameters for the compiled pass

    def _per_column(self, values: np.ndarray):
        return values[0] if np.all(values == values[0]) else np.repeat(values, self.width)

    def hold(self, s: float, h: float):
        """:func:`_hold_factors` of each group's Cd1, per column (scalars when the groups share Cd1)."""
        if h not in self._hold:
            factors = np.array([_hold_factors(s, h, cd1) for cd1 in self.thetas[:, 2]])
            self._hold[h] = tuple(self._per_column(factors[:, k]) for k in range(3))
        return self._hold[h]


def _packed(th, n: int) -> np.ndarray:
    """The six base parameters ``th[:6]`` for the compiled pass: a (6, 1) view of the model's own parameter
    vector, else (6, n) per column (a list of scalars and (n,) arrays: set_columns, set_groups)."""
    if isinstance(th, np.ndarray):
        return th[:6].reshape(6, 1)
    out = np.empty((6, n))
    for k in range(6):
        out[k] = th[k]
    return out


def _step_scalar(x, u, h, th, s, pb):
    """:meth:`PhysicalModel._step_t` for one sample in plain floats (lists of 6 and 3)."""
    px, py, pz, vx, vy, vz = x
    wx, wy, wz = u
    vn = math.sqrt(vx * vx + vy * vy + vz * vz)
    wn = math.sqrt(wx * wx + wy * wy + wz * wz)
    ax, ay, az = th[0] * wx, th[0] * wy, th[0] * wz + th[4]
    sin_a = 0.0
    if vn * wn > 1e-12:
        cos = min(1.0, max(-1.0, (wx * vx + wy * vy + wz * vz) / (vn * wn)))
        sin_a = math.sqrt(1.0 - cos * cos)
        f1, f2 = th[3] * 2.0 * cos * vn / wn, th[3] * 2.0 * cos * cos
        ax, ay, az = ax + f1 * wx - f2 * vx, ay + f1 * wy - f2 * vy, az + f1 * wz - f2 * vz
    pn = math.sqrt(px * px + py * py + pz * pz)
    if pn > 1e-12:
        c = -th[5] * math.sin(math.pi * pn / pb) / pn
        ax, ay, az = ax + c * px, ay + c * py, az + c * pz
    z = s * h * (th[1] * sin_a + th[2])
    e = math.exp(-z)
    g = s * h * ((1.0 - 0.5 * z) if abs(z) < 1e-6 else -math.expm1(-z) / z)
    vx, vy, vz = e * vx + g * ax, e * vy + g * ay, e * vz + g * az
    return [px + h * vx, py + h * vy, pz + h * vz, vx, vy, vz]


def synthetic_plant(richer: bool = True) -> PhysicalModel:
    """The plant of :mod:`cosim_plugins.identify.synthetic` logs (tests, benchmarks, demos).

    The paper's model with :data:`~cosim_plugins.identify.synthetic.TRUE_PARAMS`; if
    ``richer``, plus quadratic drag (c = 0.0015 uN s^2/mm^2) and 4 substeps
    per period, so no fitted model is exactly right.
    """
    from cosim_plugins.identify.synthetic import TRUE_PARAMS
    from cosim_plugins.identify.terms import quadratic_drag

    if richer:
        return PhysicalModel.from_params({**TRUE_PARAMS, "quadratic_drag.c": 0.0015}, substeps=4,
                                         terms=[quadratic_drag()])
    return PhysicalModel.from_params(TRUE_PARAMS)
