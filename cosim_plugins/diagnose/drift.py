"""Drift: do the logs disagree with each other, or does a log disagree with itself over time?

A lab's plant changes under it: the water warms and thins over a day, a
swimmer is re-inserted with its magnet slightly turned, a coil heats. After
the stepwise search, the chosen model's base parameters are refitted free
(:mod:`.per_unit`)

* per log, in the order recorded (the file order, or ``--t-start``), and
* per block of time within each log (a slow trend over minutes),

the rest shared. Free values per unit scatter (each unit has few windows), so
each fit is also smoothed to straight lines (:func:`~.per_unit.trend_fit`):
the per-log values on a line in the order recorded, the per-block values on a
line in time with a level per log. A quantity (the speed per Hz, the velocity
time constant, the sinking speed: :data:`~.per_unit.QUANTITIES`) is *flagged*
when

* the model that shows it lowers the held-out error at the reference horizon
  against the shared model, with paired t >= :data:`MIN_T`, by at least
  :data:`MIN_REDUCTION` or, near the noise floor, by :data:`EXCESS_SHARE` of
  the excess over it (:func:`_matters`): the drift matters for prediction;
  within logs, the trend model also beats the free per-log one with paired
  t >= :data:`BETTER_T`, and
* its values differ beyond their uncertainty: between logs, the chi-square
  test of their homogeneity (free per-log model) or the slope of their trend
  in the order recorded (trend model) gives p < :data:`P_FLAG`; within logs,
  the slope against time; the uncertainties are widened by how much blocks
  of one log scatter beyond them (a Birge ratio: conditions that change from
  block to block move a fit more than its covariance says),
* it is large enough to be a change of the plant: between logs, the values'
  spread beyond their uncertainty (or the trend's change from one log to the
  next) is >= :data:`MIN_SPREAD`; within, the trend changes it by
  >= :data:`MIN_CHANGE` over a log, and
* its own variation matters: holding it at its shared value in every unit
  (the other quantities as fitted, :func:`~.per_unit.held`) raises the
  held-out error with paired t >= :data:`MIN_T`. A quantity the logs barely
  determine (a time constant on logs at one speed) scatters from log to log
  through the other parameters' misfit, and is not flagged for that.

``--per-log PARAM,...`` fits the parameters named free per log (the rest
shared) as a candidate ranked like an effect, by its held-out drop.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np
from scipy.special import ndtr

from cosim_plugins.diagnose.per_unit import (
    CLUSTER_S,
    DRIFT_PARAMS,
    QUANTITIES,
    between_logs,
    block_units,
    fit_per_unit,
    held,
    log_units,
    quantities,
    sample_per_unit,
    trend_fit,
    within_logs,
)
from cosim_plugins.diagnose.result import DriftExplains, DriftResult, GivenDrift

MIN_REDUCTION = 0.05
MIN_T = 3.0
P_FLAG = 1e-3
# the smallest drift flagged: the logs' true values differ by >= 1 % (std), or a trend changes a quantity by
# >= 2 % over a log. A model's misfit of one path against another moves per-log fits by about 0.5 % (a steady
# plant, 6 logs, 0.5 % apart, held-out t = 7.5): real, but not a change of the plant.
MIN_SPREAD = 0.01
MIN_CHANGE = 0.02
TREND_T = 3.0  # a between-log difference is called a trend in the order recorded when its slope has |t| >= this
BETTER_T = 2.0  # the trend within the logs beats the per-log model with paired t >= this
EXCESS_SHARE = 0.5  # near the noise floor: the share of the excess over it a drifting model must remove


def per_log_name(params) -> str:
    """The candidate's name in the ranking: ``per-log k,Cd1``."""
    return "per-log " + ",".join(params)


def check_params(names, model) -> tuple:
    """The base parameters ``names`` of the physical model, or a ValueError naming the unknown ones."""
    base = [q.name for q in model.param_list if "." not in q.name]
    unknown = [n for n in names if n not in base]
    if unknown:
        raise ValueError(f"--per-log {','.join(unknown)}: not a base parameter of the model (one of "
                         f"{', '.join(base)})")
    return tuple(names)


def analyse(final, fitter, train_starts: np.ndarray, params=None, order=None, chosen=(), floor=None,
            say=None) -> DriftResult:
    """The drift section of diagnosis.json (see the module doc) for the chosen model ``final`` (a Fit).

    ``train_starts``: the training open-loop window starts (all of them; sampled per unit here);
    ``params``: the base parameters fitted per unit (default :data:`~.per_unit.DRIFT_PARAMS`);
    ``order`` (L,): each log's start time [s] (default: the file order); ``chosen``: the effects the stepwise
    search put in ``final``, each checked again once the drift is allowed for (``given_drift``: those that
    no longer pass the verdict's tests are dropped); ``floor``: the noise floor at the reference horizon [mm].
    """
    from cosim_plugins.diagnose.fitting import fork_map, picklable, reduction_of  # fitting -> verdict -> here

    say = say or (lambda msg: None)
    jm, ttr, tte = final.model, fitter.ttr, fitter.tte
    names = check_params(params or DRIFT_PARAMS, jm)
    key, lead, k_ref = fitter.s.reference, fitter.lead, fitter.steps[fitter.s.reference]
    shared = jm.params()
    mass = float(jm.host.options.get("mass_mg", 12.4))
    n_logs = int(ttr.log.max()) + 1
    how = "file order" if order is None else "t_start"
    order = np.arange(n_logs, dtype=float) if order is None else np.asarray(order, dtype=float)
    if len(order) != n_logs:
        raise ValueError(f"--t-start gives {len(order)} start times for {n_logs} logs")
    cluster = max(1, int(round(CLUSTER_S / ttr.dt_s)))
    out = DriftResult(params=list(names), order=how, flagged=[], per_log={}, t={}, words=[])

    def held_out(fit):
        ev = fit.model.evaluate(tte, fitter.test_starts, lead, fitter.steps)
        summ = {h: _mean_norm(r) for h, r in ev.items()}
        return ev, summ, reduction_of(final.summary["rollout_mm"][key], summ[key]), \
            fitter.paired_t(final.ev[key], ev[key])

    def held_t(fit, quantity, ev_fit):
        """Paired t of the per-unit model against itself with ``quantity`` held shared (inf: cannot hold it)."""
        model = held(fit, quantity, shared)
        if model is None:
            return float("inf")
        ev = model.evaluate(tte, fitter.test_starts, lead, {key: fitter.steps[key]})
        return fitter.paired_t(ev[key], ev_fit[key])

    logs, blocks = log_units(ttr), block_units(ttr)
    log_min = float(np.mean([np.nanmax(ttr.t_s[ttr.log == k]) for k in range(n_logs)])) / 60.0  # mean length
    before = final.summary["rollout_mm"][key]

    def gate(fit_out) -> bool:
        return _matters(fit_out["reduction"], fit_out["t_stat"], before, fit_out["rollout_mm"][key], floor)

    fits = []  # (units, their training windows): per log, per block of time; fitted at once over --jobs
    if n_logs >= 2:
        starts_log = sample_per_unit(train_starts, logs, fitter.s.seed + 5)
        say(f"drift: {', '.join(names)} free per log ({n_logs} logs, {len(starts_log)} windows) ...")
        fits.append((logs, starts_log))
    if blocks.n > n_logs:
        starts_block = sample_per_unit(train_starts, blocks, fitter.s.seed + 6)
        say(f"drift: {', '.join(names)} free per block of time ({blocks.n} blocks, {len(starts_block)} windows) ...")
        fits.append((blocks, starts_block))
    jobs = fitter.s.jobs if picklable(jm.effects) else 1
    done = fork_map(lambda i: fit_per_unit(jm, ttr, fits[i][1], fits[i][0], names, lead, k_ref, cluster),
                    len(fits), jobs, "drift fits")
    between = done.pop(0) if n_logs >= 2 else None
    within = done.pop(0) if blocks.n > n_logs else None
    trends = {}  # within logs, per quantity; their scatter also widens the between-log test
    flagged: dict[str, _Shown] = {}
    if between is not None:
        ev_log, summ, red, t = held_out(between)
        out.between = b = {"rollout_mm": summ, "reduction": red, "t_stat": t}
        say(f"drift: per log, held-out error at {key} s {summ[key]:.3f} mm ({red:+.1%}, t = {t:.1f})")
        trend_log = trend_fit(between, np.zeros(n_logs), order, shared) if n_logs >= 3 else None
        if trend_log is not None:
            ev_tl, summ, red, t = held_out(trend_log)
            b["trend"] = {"rollout_mm": summ, "reduction": red, "t_stat": t}
            say(f"drift: a trend from log to log, held-out error at {key} s {summ[key]:.3f} mm ({red:+.1%}, "
                f"t = {t:.1f})")
    if within is not None:
        trends = {n: within_logs(x, sd, blocks.log, blocks.t_s) for n, (x, sd) in quantities(within, shared,
                                                                                             mass).items()}
        _, summ_free, red_free, t_free = held_out(within)
        trend_block = trend_fit(within, blocks.log, blocks.t_s, shared)
        ev_block, summ, red, t = held_out(trend_block)
        vs_log = fitter.paired_t(ev_log[key], ev_block[key]) if between is not None else t
        out.within = w = {"blocks": blocks.n, "rollout_mm": summ, "reduction": red, "t_stat": t,
                             "t_vs_per_log": vs_log, "quantities": trends,
                             "free": {"rollout_mm": summ_free, "reduction": red_free, "t_stat": t_free}}
        say(f"drift: a trend within the logs ({blocks.n} blocks), held-out error at {key} s {summ[key]:.3f} mm "
            f"({red:+.1%}, t = {t:.1f}; against per log t = {vs_log:.1f})")
        if gate(w) and vs_log >= BETTER_T:
            for n, v in trends.items():
                v["t_held"] = held_t(trend_block, n, ev_block)
                v["change_per_log"] = v["change_per_min"] * log_min
                if v["p"] < P_FLAG and v["t_held"] >= MIN_T and abs(v["change_per_log"]) >= MIN_CHANGE:
                    flagged[f"within:{n}"] = _Shown(trend_block, w, _within_words(n, v), "a trend within the logs",
                                              lambda m: trend_fit(fit_per_unit(m, ttr, starts_block, blocks, names,
                                                                               lead, k_ref, cluster), blocks.log,
                                                                  blocks.t_s, m.params()))
    if between is not None:
        b["quantities"] = {n: {**between_logs(x, sd, order, trends.get(n, {}).get("scatter", 1.0)),
                               "values": _list(x), "std": _list(sd)}
                           for n, (x, sd) in quantities(between, shared, mass).items()}
        out.per_log = {n: _list(between.values[:, j]) for j, n in enumerate(names)}
        out.t = {n: v["slope_t"] for n, v in b["quantities"].items()}
        free_ok, trend_ok = gate(b), "trend" in b and gate(b["trend"])
        for n, v in b["quantities"].items():
            if free_ok:  # the logs differ, in any order
                v["t_held"] = held_t(between, n, ev_log)
                if v["p"] < P_FLAG and v["t_held"] >= MIN_T and v["excess_sd"] >= MIN_SPREAD:
                    flagged[n] = _Shown(between, b, _between_words(n, v), "per log",
                                  lambda m: fit_per_unit(m, ttr, starts_log, logs, names, lead, k_ref, cluster))
                    continue
            if trend_ok:  # the logs change in the order recorded
                v["t_held_trend"] = held_t(trend_log, n, ev_tl)
                p_slope = float(2 * ndtr(-abs(v["slope_t"])))
                if p_slope < P_FLAG and v["t_held_trend"] >= MIN_T and abs(v["change_per_step"]) >= MIN_SPREAD:
                    flagged[n] = _Shown(trend_log, b["trend"], _between_words(n, v), "a trend from log to log",
                                  lambda m: trend_fit(fit_per_unit(m, ttr, starts_log, logs, names, lead, k_ref,
                                                                   cluster), np.zeros(n_logs), order, m.params()))
    order_flags = [f for f in flagged if not f.startswith("within:")] + [f for f in flagged if f.startswith("within:")]
    out.flagged = order_flags
    out.words = [flagged[f].words for f in order_flags]
    if order_flags:
        shown = flagged[order_flags[0]]  # between before within: a drift between logs explains more
        out.explains = DriftExplains(fit=shown.label, **{k: shown.figures[k] for k in ("rollout_mm", "reduction",
                                                                                       "t_stat")})
        if chosen:
            out.given_drift = _effects_given_drift(final, shown.fit, shown.remake, fitter, chosen, floor, say)
    return out


class _Shown(NamedTuple):
    """A flag's evidence: the fit that shows it, its held-out figures (diagnosis.json's), the verdict's words,
    the fit's name, and ``remake(model) -> PerUnitFit``: the same fit on another model."""

    fit: object
    figures: dict
    words: str
    label: str
    remake: Callable


def _matters(reduction: float, t_stat: float, before_mm: float, after_mm: float, floor_mm: float | None) -> bool:
    """A drifting model's held-out drop counts when its paired t >= MIN_T and it removes >= MIN_REDUCTION of the
    error or, near the noise floor (where 5 % may be more than is left), >= EXCESS_SHARE of the excess over it."""
    if t_stat < MIN_T:
        return False
    if reduction >= MIN_REDUCTION:
        return True
    excess = before_mm - floor_mm if floor_mm else 0.0
    return excess > 0 and before_mm - after_mm >= EXCESS_SHARE * excess


def _effects_given_drift(final, fit, remake, fitter, chosen, floor, say) -> list:
    """Each chosen effect checked again with the drift in: ``fit`` (a PerUnitFit of ``final``) is the drift that
    showed, ``remake(model)`` fits it the same way (per log, or a trend) on another model; the model with the
    effect and its drift is compared with the model refitted without the effect and its drift fitted again, by
    the verdict's tests of the drop (:func:`~.verdict.passes`). Refitting the drift too matters: offsets fitted
    beside an effect have already given it part of their work.
    [GivenDrift per chosen effect]."""
    from cosim_plugins.diagnose.fitting import reduction_of
    from cosim_plugins.diagnose.verdict import passes

    key = fitter.s.reference
    drifted = fitter.evaluate(fit.model)
    out = []
    for name in chosen:
        keep = [e for e in final.model.effects if e.name != name and e not in fitter.added]
        say(f"drift: is {name} still needed once the drift is in? refitting without it ...")
        without = fitter.evaluate(remake(fitter.without(final, keep).model).model)
        before = without.summary["rollout_mm"][key]
        entry = {"effect": name, "rollout_mm": drifted.summary["rollout_mm"],
                 "reduction": reduction_of(before, drifted.summary["rollout_mm"][key]),
                 "t_stat": fitter.paired_t(without.ev[key], drifted.ev[key])}
        entry["kept"] = passes(entry, before, floor, key)
        out.append(GivenDrift(**{k: entry[k] for k in ("effect", "reduction", "t_stat", "kept")}))
    return out


def candidate_entry(drift: DriftResult, key: str) -> dict | None:
    """The ``--per-log`` fit as a ranking entry (effect ``per-log PARAMS``, kind "drift"), None without one."""
    b = drift.between
    if not b:
        return None
    return {"effect": per_log_name(drift.params), "kind": "drift", "rollout_mm": b["rollout_mm"],
            "reduction": b["reduction"], "reduction_by_horizon": {}, "t_stat": b["t_stat"], "identifiable": True,
            "params": {}, "fit": {}, "conditioning": {},
            "doc": f"{', '.join(drift.params)} fitted free per log, the rest shared"}


def sentence(drift: DriftResult | None, key: str) -> str:
    """The verdict's words on drift ('' when nothing is flagged)."""
    if not drift or not drift.flagged:
        return ""
    between_flagged = any(not f.startswith("within:") for f in drift.flagged)
    parts = [("The logs disagree with each other: " if between_flagged else "The plant drifts within the logs: ")
             + "; ".join(drift.words) + "."]
    fit = drift.explains
    parts.append(f"With {', '.join(drift.params)} fitted as {fit.fit}, the held-out error at {key} s falls by "
                 f"{fit.reduction:.0%} (to {fit.rollout_mm[key]:.2f} mm; t = {fit.t_stat:.1f}).")
    gone = [g.effect for g in drift.given_drift or () if not g.kept]
    if gone:
        parts.append(f"{' and '.join(gone)}, which the search chose before, {'is' if len(gone) == 1 else 'are'} "
                     "not needed once the drift is allowed for.")
    parts.append("Next: look for what changed " + ("between the experiments (water temperature, the swimmer's "
                 f"insertion, coil heating); --per-log {','.join(drift.params)} fits them per log."
                 if between_flagged else "during each experiment (coil heating, water warming, a swimmer "
                 "wearing); shorter logs, or logs recorded once the rig has settled, avoid it."))
    return " ".join(parts)


def _between_words(name: str, v: dict) -> str:
    words, unit = QUANTITIES[name][0], QUANTITIES[name][1]
    vals = [x for x in v["values"] if x is not None]
    if abs(v["slope_t"]) >= TREND_T:
        way = "falls" if v["change_per_step"] < 0 else "rises"
        return (f"{words} {way} {abs(v['change_per_step']):.0%} from log to log, in the order recorded "
                f"(from {vals[0]:.3g} to {vals[-1]:.3g} {unit}; homogeneity p = {v['p']:.0e})")
    return (f"{words} differs between logs beyond its uncertainty, not in the order recorded "
            f"({min(vals):.3g} to {max(vals):.3g} {unit}; homogeneity p = {v['p']:.0e})")


def _within_words(name: str, v: dict) -> str:
    words = QUANTITIES[name][0]
    way = "falls" if v["change_per_min"] < 0 else "rises"
    return f"{words} {way} {abs(v['change_per_min']):.1%} per minute within the logs (|t| = {abs(v['slope_t']):.1f})"


def _mean_norm(r: dict) -> float | None:
    v = r["valid"]
    return float(np.mean(np.linalg.norm(r["err"][v], axis=1))) if v.any() else None


def _list(x) -> list:
    return [float(v) if np.isfinite(v) else None for v in np.asarray(x, dtype=float)]
