"""The fits every stage of a diagnosis shares: a registered model fitted and refined, a model refitted with
more effects, held-out evaluations, rank entries and paired t (:class:`Fitter`). Units: mm, mm/s, Hz, s."""

from __future__ import annotations

import copy
import inspect
import multiprocessing
import pickle
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from cosim.contract.errors import UserError
from cosim_plugins.diagnose.rebuild import rebuilt
from cosim_plugins.diagnose.stepwise import Fit
from cosim_plugins.diagnose.verdict import blocks_t, gain_block_means, paired_t, paired_t_horizons
from cosim_plugins.identify.joint import JointModel, fit_joint, supports_effects

QUICK_NFEV = 6  # evaluations of a screening fit (stepwise rounds after the first, see stepwise.rank)
QUICK_STRIDE = 2  # ... on every second training window (its drop is a screen: the full fit decides)
# the baseline's starts spread over the velocity time constant (the quick fit's forces all scaled together: the
# same speed per Hz, another time constant). On 0.5 s windows with a free initial velocity the time constant of a
# slow swimmer is barely determined, and a fit from the quick start alone can end several times too fast.
TAU_STARTS_S = (0.03, 0.1, 0.3, 1.0)
TAU_RANGE_S = (0.005, 5.0)  # velocity time constants a non-degenerate fit can have [s]

if TYPE_CHECKING:
    from cosim_plugins.diagnose.pipeline import Settings


class Fitter:
    """The fits and evaluations every stage shares: training windows, the open-loop polish, held-out windows.

    ``with_effects`` refits a model with more effects, ``refit`` re-polishes one from its own solution,
    ``without`` refits a chosen set less one, ``entry`` is a candidate's rank entry against the model before
    it, ``paired_t`` the verdict's paired t of two held-out evaluations at the reference horizon.
    """

    def __init__(self, s: "Settings", added, ttr, fit_starts, fit_len, score, polish, tte, test_starts, lead, steps,
                 block_rows):
        self.s, self.added, self.ttr, self.fit_starts, self.fit_len = s, list(added), ttr, fit_starts, fit_len
        self.score, self.polish = score, polish
        self.tte, self.test_starts, self.lead, self.steps, self.block_rows = tte, test_starts, lead, steps, block_rows
        self.folds = None  # the split's other folds (:class:`.crossfold.CrossFolds`), when it has any

    def evaluate(self, jm) -> Fit:
        """The model's held-out open-loop errors at every horizon."""
        ev = jm.evaluate(self.tte, self.test_starts, self.lead, self.steps)
        return Fit(jm, ev, _summary(ev))

    def with_effects(self, before: Fit, effects, say=None, quick: bool = False, fresh: bool = True
                     ) -> tuple[Fit, bool]:
        """(``before``'s model plus ``effects``, all parameters refitted jointly; whether the new parameters
        change the predictions at all). ``quick``: a screening fit (:data:`QUICK_NFEV` evaluations from the
        listed starts, no equation-error starts, no open-loop polish, every :data:`QUICK_STRIDE`-th training
        window); ``fresh=False``: no equation-error starts (the effects' own values are already a good start)."""
        if quick:
            fitted = _with_effects(before.model, effects, self.ttr, self.fit_starts[::QUICK_STRIDE], self.fit_len,
                                   replace(self.s, max_nfev=QUICK_NFEV), say, self.score, None, fresh=False)
        else:
            fitted = _with_effects(before.model, effects, self.ttr, self.fit_starts, self.fit_len, self.s, say,
                                   self.score, self.polish, fresh=fresh)
        fit = self.evaluate(fitted.model)
        fit.fitted = fitted
        return fit, fitted.identifiable

    def with_each(self, before: Fit, effects, quick: bool = False) -> list:
        """[:meth:`with_effects` (``before``, [effect]) for each effect (None: ``before`` refitted with nothing
        added)], in order, over ``s.jobs`` forked processes (they inherit this fitter's data; each returns its
        fit). One process when ``jobs`` is 1, the platform cannot fork, or a fit's effects (``before``'s and the
        new one) cannot be sent between processes (then each fit runs here)."""
        jobs = self.s.jobs if picklable([*before.model.effects, *effects]) else 1
        # the fits with the most starts first, so the processes end together (a step-out's sixteen starts,
        # begun last, ran on alone); the results in the given order
        order = sorted(range(len(effects)), key=lambda i: -self._starts(effects[i]))

        def fit(k: int) -> Fit:
            effect = effects[order[k]]
            return self.with_effects(before, [] if effect is None else [effect], quick=quick)

        done = fork_map(fit, len(effects), jobs, "quick fits" if quick else "candidate fits")
        return [done[order.index(i)] for i in range(len(effects))]

    def _starts(self, effect) -> int:
        """How many starts a fit with ``effect`` added refines (None: none added), what its time grows with."""
        return 0 if effect is None else len(effect.qualified_starts(self.ttr.u, self.ttr.dt_s))

    def refit(self, jm) -> Fit:
        """``jm`` refitted from its own solution (every parameter free, the same budget as a candidate's fit)."""
        fit_joint(jm, self.ttr, self.fit_starts, self.fit_len, max_nfev=self.s.max_nfev, score=self.score,
                  polish=self.polish)
        return self.evaluate(jm)

    def beside(self, effects) -> "Fitter":
        """This fitter, its models holding ``effects`` too wherever :meth:`without` takes chosen ones out (a
        discovered form a search runs on top of stays in)."""
        other = copy.copy(self)
        other.added = [*self.added, *effects]
        return other

    def without(self, final: Fit, keep) -> Fit:
        """The final model's host with only the effects ``keep``, started at the final solution and refitted."""
        jm = rebuilt(final.model, [*self.added, *keep])
        jm.per_unit = final.model.per_unit
        return self.refit(jm)

    def paired_t(self, ref_ev: dict, new_ev: dict) -> float:
        """Paired t of ``new``'s improvement over ``ref`` (held-out evaluations at one horizon)."""
        return paired_t(ref_ev, new_ev, self.test_starts, self.block_rows)

    def paired_t_horizons(self, ref: Fit, new: Fit) -> float:
        """Paired t of ``new``'s improvement over ``ref``, averaged over every horizon."""
        return paired_t_horizons(ref.ev, new.ev, self.test_starts, self.block_rows)

    def entry(self, effect, fit: Fit, identifiable: bool, before: Fit) -> dict:
        """A candidate's rank entry: its errors, reductions and t of its gain over ``before`` (:func:`gain_t`; on
        every fold of the split when this fold's alone is borderline, :mod:`.crossfold`: ``t_folds`` says how
        many folds); its parameters."""
        key = self.s.reference
        red = {h: reduction_of(before.summary["rollout_mm"][h], fit.summary["rollout_mm"][h])
               for h in fit.summary["rollout_mm"]}
        jm = fit.model
        own = effect.param_names()
        units = {q.name: q.unit for q in jm.param_list}
        std = {n: (float(jm.std[n]) if np.isfinite(jm.std.get(n, np.nan)) else None) for n in own}
        params = {n: {"value": jm.params()[n], "std": std[n], "unit": units[n]} for n in own}
        fitted = getattr(fit, "fitted", None)
        means = gain_block_means(before.ev[key], fit.ev[key], self.test_starts, self.block_rows)
        out = {"effect": effect.name, "kind": effect.kind, "rollout_mm": fit.summary["rollout_mm"],
               "reduction": red[key], "reduction_by_horizon": red, "t_stat": blocks_t(means),
               "identifiable": identifiable,
               "params": params, "fit": fitted.fit if fitted else {}, "conditioning": jm.conditioning,
               "doc": effect.doc}
        if (self.folds is not None and self.folds.wanted(out) and jm.per_unit is None
                and before.model.per_unit is None):
            out["t_stat"], out["t_folds"] = self.folds.t_stat(means, before, fit, key)
        return out


def bar(items, what: str, total: int | None = None):
    """``items`` with a progress bar on stderr when it is a terminal (none in logs, pipes and tests)."""
    from tqdm import tqdm

    return tqdm(items, desc=what, total=total, file=sys.stderr, leave=False, disable=None, dynamic_ncols=True)


_FORKED = None  # the function fork_map's forked workers call, inherited from the parent


def fork_map(fn, n: int, jobs: int, what: str) -> list:
    """[fn(i) for i in range(n)], in order, over min(``jobs``, n) forked processes, with a progress bar.

    The workers inherit ``fn`` (a closure over this process's data: it need not pickle; what it returns must).
    Here, one by one, when ``jobs`` is 1 or the platform cannot fork.
    """
    global _FORKED
    jobs = min(jobs, n)
    if jobs > 1 and "fork" in multiprocessing.get_all_start_methods():
        _FORKED = fn
        try:
            with ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("fork")) as pool:
                return list(bar(pool.map(_call_forked, range(n)), what, n))
        finally:
            _FORKED = None
    return [fn(i) for i in bar(range(n), what)]


def _call_forked(i: int):
    return _FORKED(i)


def picklable(obj) -> bool:
    """Whether ``obj`` can be sent to another process (an effect file's function may not be importable there)."""
    try:
        pickle.dumps(obj)
    except Exception:  # an effect file's function that another process cannot import, etc.
        return False
    return True


@dataclass
class _Fitted:
    model: JointModel
    params: dict
    std: dict
    fit: dict
    identifiable: bool = True


def fit_model(name, dtr, ttr, starts, length, s: "Settings", say, score=None, polish=None) -> JointModel:
    """Fit a registered model on the training data; a parametric one is then refined on the windows.

    A parametric model's refit also starts from the integrated equation-error fit begun at the
    model's initial parameters, so a poor quick fit cannot trap it.
    """
    from cosim.contract.plugins import lookup

    cls = lookup("model", name)
    accepted = inspect.signature(cls.__init__).parameters
    # a start, refined below; a continuous-time model steps the logged commands as held over each step
    quick = {"seed": s.seed, "max_windows": 400, "max_nfev": 3, "horizon": 15, "hold": "exact"}
    model = cls(**{k: v for k, v in quick.items() if k in accepted})
    nfev = s.max_nfev
    try:
        model.fit(dtr)
    except UserError as exc:  # e.g. sparse camera frames: no one-step pairs for the model's own start
        if not supports_effects(model):
            raise
        say(f"{name}: its own fit failed ({exc}); starting from its initial parameters")
        model.dt_s, nfev = dtr.dt_s, 3 * s.max_nfev
    jm = JointModel(model)
    if supports_effects(model):
        fit_joint(jm, ttr, starts, length, max_nfev=nfev, fresh_starts=[_host_init(jm.host)],
                  free_starts=_time_constant_starts(jm), progress=say, score=score, polish=polish)
    return jm


def _time_constant_starts(jm: JointModel) -> list:
    """Starts at each of :data:`TAU_STARTS_S` (:func:`at_time_constant`) from the short-window fit's time
    constant; none for hosts without one."""
    tau = velocity_time_constant(jm)
    if tau is None or not np.isfinite(tau) or tau <= 0:
        return []
    return [at_time_constant(jm, tau, target) for target in TAU_STARTS_S]


def at_time_constant(jm: JointModel, tau_s: float, target_s: float) -> dict:
    """{host parameter: value}: every force parameter of the physical host scaled by tau_s / target_s, so the
    steady speed per Hz is unchanged and the velocity time constant m / Cd1 moves from ``tau_s`` to
    ``target_s`` [s] (a saved model's effect parameters untouched)."""
    return {n: v * tau_s / target_s for n, v in jm.params().items() if "." not in n}


def _host_init(host) -> dict:
    """The host model's own parameters at their initial values (a start that owes nothing to a fit)."""
    return {q.name: q.init for q in host.all_params() if "." not in q.name}


def _with_effects(ref: JointModel, effects, ttr, starts, length, s: "Settings", say, score=None, polish=None,
                  fresh: bool = True) -> _Fitted:
    """The reference model plus ``effects``, all parameters refitted jointly.

    Starts: the reference's parameters with each effect's starts (its listed ones and those drawn
    from the logged commands), and (``fresh``) the equation-error fit from the host's initial parameters
    with each of them (see :func:`cosim_plugins.identify.joint.fit_joint`).
    """
    jm = rebuilt(ref, [*ref.effects, *effects])  # from the plain host, so the effects are not added twice
    extra = [st for e in effects for st in e.qualified_starts(ttr.u, ttr.dt_s)]
    host0 = _host_init(jm.host)
    # the effects' own starts held while the host adapts
    fresh_starts = [host0] + [{**host0, **st} for st in extra] if fresh else []
    # from a degenerate reference even the equation-error fits settle in its corner (no drag, no thrust): the
    # host's initial parameters with each effect's start, refined on the windows as they are, can leave it
    free_starts = [{**host0, **st} for st in extra] if fresh and degenerate(ref) else []
    res = fit_joint(jm, ttr, starts, length, max_nfev=s.max_nfev, extra_starts=extra, fresh_starts=fresh_starts,
                    free_starts=free_starts, progress=say, score=score, polish=polish)
    own = [q for e in effects for q in e.param_names()]
    units = {q.name: q.unit for q in jm.param_list}
    std = {n: (float(res.std[n]) if np.isfinite(res.std[n]) else None) for n in own}
    params = {n: {"value": res.params[n], "std": std[n], "unit": units[n]} for n in own}
    unseen = set(jm.conditioning.get("unseen", ()))
    return _Fitted(model=jm, params=params, std=std,
                   fit={"rms_mm": res.rms_mm, "evaluations": res.evaluations, "status": res.status,
                        "start": res.start},
                   identifiable=not all(n in unseen or std[n] is None for n in own))


def degenerate(jm: JointModel) -> bool:
    """True when the physical host's fit has no usable drag: Cd1 at its bound, or a velocity time constant
    outside :data:`TAU_RANGE_S` (always False for hosts without a drag parameter)."""
    tau = velocity_time_constant(jm)
    return tau is not None and ("Cd1" in (jm.conditioning or {}).get("at_bound", ())
                                or not TAU_RANGE_S[0] <= tau <= TAU_RANGE_S[1])


def velocity_time_constant(jm: JointModel) -> float | None:
    """The physical host's velocity time constant m / Cd1 [s] (the drag along the swimmer's axis, where it
    mostly swims: sin(alpha) ~ 0) in its short-window fit (the open-loop polish can trade the velocity
    response against a drift); None for hosts without a drag parameter, inf without drag."""
    prm = jm.window_params or jm.prm
    if "Cd1" not in prm or "mass_mg" not in jm.host.options:
        return None
    return jm.host.options["mass_mg"] / (1000.0 * prm["Cd1"]) if prm["Cd1"] > 0 else float("inf")


def _summary(ev: dict) -> dict:
    out = {"rollout_mm": {}, "windows": {}}
    for h, r in ev.items():
        v = r["valid"]
        out["rollout_mm"][h] = float(np.mean(np.linalg.norm(r["err"][v], axis=1))) if v.any() else None
        out["windows"][h] = int(v.sum())
    return out


def reduction_of(before, after) -> float:
    """1 - after / before: the share of an error [mm] a change removes (0 without a usable before)."""
    return float(1.0 - after / before) if before and after is not None and before > 0 else 0.0
