"""Model discrepancy: how wrong a model is, where, and which physical effect explains it.

Pipeline of ``cosim diagnose`` (units mm, mm/s, Hz, s):

1. read the logs; the held-out data are the ``--validate`` logs, or else
   every third block of :data:`BLOCK_S` seconds of each log (the others
   train), so both halves see the same paths and conditions;
2. fit the baseline model (any registered model; the physical model is
   fitted quickly by its own method, then refined on the diagnose
   objective, :func:`cosim_plugins.identify.joint.fit_joint`);
3. measure open-loop errors on held-out windows: the initial state is
   solved on a lead-in of :data:`LEAD_S` (at least :data:`MIN_LEAD_ROWS` rows), then the model predicts alone for
   each horizon; the noise floor is the error a perfect model would show
   with the measurement noise estimated from the data (:mod:`.noise`);
4. localise the baseline's error on all windows (:mod:`.localise`);
5. refit the physical model jointly with each candidate effect on the
   training windows and rank the effects by the drop of held-out error at
   the reference horizon; :mod:`.verdict` names the effect (or not).

``--add`` effects are fitted into the reference model first: the report
shows the error before and after at every horizon, and the ranking then
looks for what remains.
"""

from __future__ import annotations

import inspect
import time
from dataclasses import dataclass, field, replace

import numpy as np
from threadpoolctl import threadpool_limits

from cosim.contract.errors import UserError
from cosim_plugins.identify.dataset import Dataset
from cosim_plugins.identify.effect import known_effects, load_effect_files, resolve
from cosim_plugins.identify.joint import JointModel, OpenLoop, fit_joint, supports_effects
from cosim_plugins.identify.localise import localise, window_features
from cosim_plugins.identify.noise import noise_floor, noise_sigma_mm
from cosim_plugins.identify.timeline import Timeline
from cosim_plugins.identify.verdict import BLOCK_S as VERDICT_BLOCK_S
from cosim_plugins.identify.verdict import fit_notes, paired_t, verdict
from cosim_plugins.raw_log import read_logs

HORIZONS_S = {"0.1": 0.1, "0.2": 0.2, "0.42": 0.42, "1.0": 1.0}
REFERENCE = "1.0"
# lead-in on which each evaluation window's initial state is solved, and never fewer log rows than that: from a
# shorter one the initial velocity is so noisy that a model which forgets it fast (a delay before a faster
# velocity response, whose delayed command is known from the log) predicts better than the true one
LEAD_S = 0.4
MIN_LEAD_ROWS = 10
FIT_WINDOW_S = 0.5  # length of the training windows
FIT_WINDOWS = 700  # training windows (a random sample)
EVAL_STRIDE = 2  # rows between evaluation window starts
BLOCK_S = 5.0  # split: block length
HOLDOUT_EVERY = 3  # split: every third block is held out
MIN_FIT_WINDOWS = 60
MIN_EVAL_WINDOWS = 30
SCORE_WINDOWS = 100  # training windows whose open-loop error picks a fit's start
POLISH_WINDOWS = 250  # training windows of the open-loop polish (another sample)
DISCOVER_WINDOWS = 400  # training windows of the discovery's regression (another sample)
EFFECT_MODEL = "physical"
DISCOVERED_FILE = "discovered_effect.py"
DISCOVER_ABOVE_FLOOR = 1.5  # a named effect leaving more than this x the floor: discovery runs too
TAU_RANGE_S = (0.005, 5.0)  # velocity time constants a non-degenerate fit can have
TAU_DEFAULT_S = 0.2  # for the noise floor when no fit gives one
# the baseline's starts spread over the velocity time constant (the quick fit's forces all scaled together: the
# same speed per Hz, another time constant). On 0.5 s windows with a free initial velocity the time constant of a
# slow swimmer is barely determined, and a fit from the quick start alone can end several times too fast.
TAU_STARTS_S = (0.03, 0.1, 0.3, 1.0)


@dataclass
class Settings:
    """Options of a diagnosis (the CLI's flags)."""

    model: str = "physical"
    effects_files: list = field(default_factory=list)
    add: list = field(default_factory=list)
    candidates: list | None = None  # None: every registered effect
    reference: str = REFERENCE
    horizons: dict = field(default_factory=lambda: dict(HORIZONS_S))
    fit_windows: int = FIT_WINDOWS
    max_nfev: int = 30
    seed: int = 0
    discover: bool = False  # also when no listed effect explains the error


@dataclass
class Diagnosis:
    """``result`` is diagnosis.json; the arrays feed the report and the recording."""

    result: dict
    timeline: Timeline  # all logs
    starts: np.ndarray  # evaluation windows on all logs
    lead: int
    steps: dict
    errors: dict  # {"baseline": (w, 3), "after": (w, 3) or None, "after_label"} at the reference horizon, all logs
    #             ("after": with the --add effects, else with the effect the verdict names)
    features: dict
    curves: dict  # {label: {horizon: mean error on held-out}} for the before/after plot
    discovered_source: str | None = None  # discovered_effect.py, when a form was discovered
    added_model: JointModel | None = None  # with --add: the reference model with the added effects, refitted


@threadpool_limits.wrap(limits=1, user_api="blas")
def run(log_paths, validate_paths=(), settings: Settings | None = None, progress=None) -> Diagnosis:
    """Diagnose the baseline model on raw logs; see the module docstring.

    The BLAS runs on one thread meanwhile: its products here are thousands of small batched ones, which a
    second thread only slows down (five 40 s logs: 31 s with two threads on an idle 2-CPU machine, 25 s
    with one; with the other CPU busy, 46 s against 24 s); the figures agree to ~1e-8 (summation order).
    """
    s = settings or Settings()
    say = progress or (lambda msg: None)
    t_start = time.perf_counter()
    if s.reference not in s.horizons:
        raise UserError(f"reference horizon {s.reference} s is not one of {', '.join(s.horizons)}")
    added_files = load_effect_files(s.effects_files)
    known = known_effects()
    added = resolve(s.add, known)
    names = [n for n in (s.candidates if s.candidates is not None else list(known)) if n not in s.add]
    candidates = resolve(names, known)
    logs = read_logs(list(log_paths))
    train_logs, test_logs, split = split_logs(logs, read_logs(list(validate_paths)) if validate_paths else None)
    dtr, dte, dall = Dataset.from_logs(train_logs), Dataset.from_logs(test_logs), Dataset.from_logs(logs)
    ttr, tte, tall = (Timeline.from_dataset(d) for d in (dtr, dte, dall))
    dt = dall.dt_s
    lead = max(MIN_LEAD_ROWS, int(round(LEAD_S / dt)))
    steps = {h: max(1, int(round(v / dt))) for h, v in s.horizons.items()}
    fit_len = max(4, int(round(FIT_WINDOW_S / dt)))
    frac = float(np.mean(tall.measured))  # sparse camera frames: ask for a share of what the logs have
    fit_starts = _sample(ttr.window_starts(fit_len, 0.7 * frac), s.fit_windows, s.seed)
    test_starts = tte.window_starts(lead, 0.6 * frac, rows=lead + 1, measured_start=False)[::EVAL_STRIDE]
    all_starts = tall.window_starts(lead, 0.6 * frac, rows=lead + 1, measured_start=False)[::EVAL_STRIDE]
    _check_sizes(fit_starts, fit_len, test_starts, tte, lead, steps[s.reference], dt)
    sigma = noise_sigma_mm(tall)
    if not np.all(np.isfinite(sigma)):
        say("noise: too few runs of consecutive measurements to estimate the camera noise; no noise floor")
        sigma = None
    say(f"noise: sigma = {', '.join(f'{x:.3f}' for x in sigma) if sigma is not None else '?'} mm (x, y, z); "
        f"{len(fit_starts)} training windows, {len(test_starts)} held-out windows")

    def evaluate(jm, tl=tte, starts=test_starts):
        ev = jm.evaluate(tl, starts, lead, steps)
        return ev, _summary(ev)

    # a fit's starts are told apart by their open-loop error at the reference horizon on training windows:
    # the fit's own windows are shorter, and there a lag and a slower velocity response can cost about the same
    score_starts = _sample(ttr.window_starts(lead, 0.6 * frac, rows=lead + 1, measured_start=False)[::EVAL_STRIDE],
                           SCORE_WINDOWS, s.seed)

    def score(jm):
        r = jm.evaluate(ttr, score_starts, lead, {s.reference: steps[s.reference]})[s.reference]
        return float(np.mean(np.linalg.norm(r["err"][r["valid"]], axis=1))) if r["valid"].any() else np.inf

    # every fit then goes on on the open-loop errors up to the reference horizon: what the diagnosis measures
    train_open = ttr.window_starts(lead, 0.6 * frac, rows=lead + 1, measured_start=False)[::EVAL_STRIDE]
    polish = OpenLoop.upto(_sample(train_open, POLISH_WINDOWS, s.seed + 1), lead, steps[s.reference])
    open_train = OpenLoop.upto(_sample(train_open, DISCOVER_WINDOWS, s.seed + 2), lead, steps[s.reference])

    baseline = _fit_model(s.model, dtr, ttr, fit_starts, fit_len, s, say, score, polish)
    base_ev, base_sum = evaluate(baseline)
    say(f"baseline {s.model}: held-out error {_fmt(base_sum['rollout_mm'])}")
    reference = baseline if supports_effects(baseline.host) else _fit_model(EFFECT_MODEL, dtr, ttr, fit_starts,
                                                                            fit_len, s, say, score, polish)
    ref_ev, ref_sum = (base_ev, base_sum) if reference is baseline else evaluate(reference)
    fitted = [reference]
    added_out, after = None, None
    if added:
        say(f"adding {', '.join(e.name for e in added)} ...")
        after = _with_effects(reference, added, ttr, fit_starts, fit_len, s, say, score, polish)
        after_ev, after_sum = evaluate(after.model)
        added_out = {"effects": [e.name for e in added], "params": after.params, "std": after.std,
                     "before_mm": ref_sum["rollout_mm"], "rollout_mm": after_sum["rollout_mm"],
                     "conditioning": after.model.conditioning,
                     "reduction": {h: _reduction(ref_sum["rollout_mm"][h], after_sum["rollout_mm"][h])
                                   for h in steps}}
        reference, ref_ev, ref_sum = after.model, after_ev, after_sum
        fitted.append(reference)
    ranking, cand_models, cand_errors = [], {}, {}
    block_rows = max(1, int(round(VERDICT_BLOCK_S / dt)))
    for effect in candidates:
        say(f"candidate {effect.name} ...")
        cand = _with_effects(reference, [effect], ttr, fit_starts, fit_len, s, None, score, polish)
        ev, summ = evaluate(cand.model)
        ranking.append(_rank_entry(effect, cand, ev, summ, ref_ev, ref_sum, s.reference, test_starts, block_rows))
        fitted.append(cand.model)
        cand_models[effect.name], cand_errors[effect.name] = cand.model, ev[s.reference]
        say(f"  {effect.name}: " + (f"{ranking[-1]['reduction']:+.1%} at {s.reference} s" if ranking[-1]["identifiable"]
                                    else "not identifiable from these logs"))
    ranking.sort(key=lambda r: (r["identifiable"], r["reduction"]), reverse=True)
    _compare_runner_up(ranking, cand_errors, test_starts, block_rows)
    tau_floor, tau_from = _floor_time_constant(fitted)
    floor = _floor(tte, test_starts, lead, steps, sigma, tau_floor, base_ev, s.seed)
    # localise what is left: the baseline's error, or with --add the error of the model with the added effects
    ref_steps = {s.reference: steps[s.reference]}
    err_all = baseline.evaluate(tall, all_starts, lead, ref_steps)[s.reference]["err"]
    after_all = after.model.evaluate(tall, all_starts, lead, ref_steps)[s.reference]["err"] if after else None
    loc_sum = ref_sum if after else base_sum  # with --add, ref_sum is the added model's
    features = window_features(tall, all_starts, lead, steps[s.reference])
    excess = {float(s.horizons[h]): max(loc_sum["rollout_mm"][h] - (floor[h] or 0.0), 0.0) for h in steps
              if loc_sum["rollout_mm"][h] is not None}
    loc = localise(features, after_all if after else err_all, horizon_means=excess)
    loc["model"] = f"+ {' + '.join(s.add)}" if after else s.model
    result = {
        "logs": [str(p) for p in log_paths], "validate": [str(p) for p in validate_paths], "split": split,
        "dt_s": dt, "horizons_s": s.horizons, "reference_horizon_s": s.horizons[s.reference],
        "lead_in_s": lead * dt, "effects_files": [str(f) for f in s.effects_files], "file_effects": added_files,
        "baseline": {"model": s.model, **base_sum, "params": baseline.params(),
                     "std": {k: (v if np.isfinite(v) else None) for k, v in baseline.std.items()},
                     "conditioning": baseline.conditioning},
        "reference": None if reference is baseline else {"model": EFFECT_MODEL, "effects": s.add, **ref_sum},
        "noise": {"sigma_mm": dict(zip("xyz", map(float, sigma))) if sigma is not None else None,
                  "floor_mm": floor, "tau_s": tau_floor, "tau_from": tau_from},
        "noise_floor_mm": floor[s.reference],
        "localisation": loc, "added": added_out, "ranking": ranking,
    }
    result["fit_notes"] = fit_notes(result)
    result["verdict"] = verdict(result, s.reference)
    source = None
    if s.discover or result["verdict"]["status"] == "unexplained" or _left_above_floor(result, s.reference):
        result["discovered"], source = _discover(reference, ttr, fit_starts, fit_len, tte, test_starts, ref_ev,
                                                 ref_sum, s, dt, evaluate, say, score, polish, open_train)
        result["verdict"] = verdict(result, s.reference)
    result["timing_s"] = round(time.perf_counter() - t_start, 2)
    curves = {f"{s.model} (baseline)": base_sum["rollout_mm"], "noise floor": floor}
    if added_out:
        curves[f"+ {' + '.join(added_out['effects'])}"] = added_out["rollout_mm"]
    elif ranking and ranking[0]["identifiable"]:
        curves[f"+ {ranking[0]['effect']} (best)"] = ranking[0]["rollout_mm"]
    if (result.get("discovered") or {}).get("status") == "found" and not added_out:
        curves["+ discovered"] = result["discovered"]["rollout_mm"]
    named = result["verdict"]["effect"]
    if after is None and named in cand_models:  # the plots show the error with the named effect too
        after_all = cand_models[named].evaluate(tall, all_starts, lead, ref_steps)[s.reference]["err"]
    after_label = (f"+ {' + '.join(s.add)}" if after else f"+ {named} (named)") if after_all is not None else None
    return Diagnosis(result=result, timeline=tall, starts=all_starts, lead=lead, steps=steps,
                     errors={"baseline": err_all, "after": after_all, "after_label": after_label},
                     features=features, curves=curves,
                     discovered_source=source, added_model=after.model if after else None)


def _left_above_floor(result: dict, key: str) -> bool:
    """True when even the named effect leaves the error well above the noise floor (something else is missing)."""
    named = result["verdict"]["effect"]
    floor = result["noise"]["floor_mm"][key]
    if named is None or not floor:
        return False
    left = next(e for e in result["ranking"] if e["effect"] == named)["rollout_mm"][key]
    return left > DISCOVER_ABOVE_FLOOR * floor


def _discover(reference, ttr, fit_starts, fit_len, tte, test_starts, ref_ev, ref_sum, s, dt, evaluate, say, score,
              polish, train):
    """(result["discovered"], effect file source or None): the sparse regression of :mod:`.discover`."""
    from cosim_plugins.identify.discover import discover

    if not supports_effects(reference.host):
        return {"status": "unsupported", "explanation": "discovery needs a parametric reference model"}, None

    def refit(effect):
        fitted = _with_effects(reference, [effect], ttr, fit_starts, fit_len, s, None, score, polish)
        ev, summ = evaluate(fitted.model)
        return fitted, summ, ev

    test = OpenLoop.upto(test_starts, train.lead, max(train.steps))
    found = discover(reference, ttr, tte, train, test, refit, say)
    if found["status"] != "found":
        return found, None
    summ, ev = found.pop("summary"), found.pop("ev")
    found.pop("fitted")
    source = found.pop("source")
    key = s.reference
    found.update({"rollout_mm": summ["rollout_mm"], "file": DISCOVERED_FILE,
                  "reduction": _reduction(ref_sum["rollout_mm"][key], summ["rollout_mm"][key]),
                  "reduction_by_horizon": {h: _reduction(ref_sum["rollout_mm"][h], summ["rollout_mm"][h])
                                           for h in summ["rollout_mm"]},
                  "t_stat": paired_t(ref_ev[key], ev[key], test_starts, max(1, int(round(VERDICT_BLOCK_S / dt))))})
    say(f"discover: refitted with the discovered terms: {found['reduction']:+.1%} at {key} s")
    if not found["reduction"] > 0.0:  # the linearised choice did not survive the full refit (or it diverged)
        return {"status": "none", "explanation": "the sparse form chosen on the linearised problem does not lower "
                "the held-out error once refitted: what is left looks like noise, or a form the candidates cannot "
                "express", "terms": found["terms"]}, None
    return found, source


# ---------------------------------------------------------------- data


def split_logs(logs, validate=None):
    """(train logs, held-out logs, description): the validate logs, or every third time block held out."""
    if validate:
        return logs, validate, {"kind": "validate", "train_logs": len(logs), "validate_logs": len(validate)}
    train, test = [], []
    for lg in logs:
        block = np.floor((lg.t_s - lg.t_s[0]) / BLOCK_S).astype(int)
        held = block % HOLDOUT_EVERY == HOLDOUT_EVERY - 1
        train.append(_masked(lg, held))
        test.append(_masked(lg, ~held))
    return train, test, {"kind": "time_blocks", "block_s": BLOCK_S, "held_out": f"every {HOLDOUT_EVERY}rd block"}


def _masked(lg, hide):
    p = lg.p_mm.copy()
    p[hide] = np.nan
    return replace(lg, p_mm=p)


def _sample(starts, n, seed):
    if len(starts) <= n:
        return starts
    return np.sort(np.random.default_rng(seed).choice(starts, n, replace=False))


def _check_sizes(fit_starts, fit_len, test_starts, tte, lead, k_ref, dt):
    if len(fit_starts) < MIN_FIT_WINDOWS:
        raise UserError(f"logs too short to fit: {len(fit_starts)} gap-free training windows of "
                        f"{fit_len * dt:g} s (need {MIN_FIT_WINDOWS}); give longer logs (>= 30 s in total)")
    n_ref = int(np.sum((tte.run[test_starts] >= lead + k_ref)
                       & tte.measured[np.minimum(test_starts + lead + k_ref, tte.n - 1)]))
    if n_ref < MIN_EVAL_WINDOWS:
        raise UserError(f"logs too short to diagnose: {n_ref} held-out windows reach the reference horizon "
                        f"{k_ref * dt:g} s (need {MIN_EVAL_WINDOWS}); give longer logs or --validate logs")


# ---------------------------------------------------------------- models


@dataclass
class _Fitted:
    model: JointModel
    params: dict
    std: dict
    fit: dict
    identifiable: bool = True


def _fit_model(name, dtr, ttr, starts, length, s: Settings, say, score=None, polish=None) -> JointModel:
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
    """Starts at each of :data:`TAU_STARTS_S`: every force parameter of the physical host scaled by one factor
    (the steady speed per Hz unchanged, the velocity time constant m / Cd1 moved there); none for other hosts."""
    tau = velocity_time_constant(jm)
    if tau is None or not np.isfinite(tau) or tau <= 0:
        return []
    own = {n: v for n, v in jm.params().items() if "." not in n}  # not a saved model's effect parameters
    return [{n: v * tau / target for n, v in own.items()} for target in TAU_STARTS_S]


def _host_init(host) -> dict:
    """The host model's own parameters at their initial values (a start that owes nothing to a fit)."""
    return {q.name: q.init for q in host.all_params() if "." not in q.name}


def _with_effects(ref: JointModel, effects, ttr, starts, length, s: Settings, say, score=None, polish=None) -> _Fitted:
    """The reference model plus ``effects``, all parameters refitted jointly.

    Starts: the reference's parameters with each effect's starts (its listed ones and those drawn
    from the logged commands), and the equation-error fit from the host's initial parameters with
    each of them (see :func:`cosim_plugins.identify.joint.fit_joint`).
    """
    base_host = ref.host
    if ref.effects:  # rebuild from the plain host so the effects are not added twice
        base_host = type(ref.host)(**ref.host.options)
        base_host.dt_s = ref.dt_s
    jm = JointModel(base_host, [*ref.effects, *effects], base_params=ref.params())
    extra = [st for e in effects for st in e.qualified_starts(ttr.u, ttr.dt_s)]
    host0 = _host_init(base_host)
    fresh = [host0] + [{**host0, **st} for st in extra]  # the effects' own starts held while the host adapts
    res = fit_joint(jm, ttr, starts, length, max_nfev=s.max_nfev, extra_starts=extra, fresh_starts=fresh,
                    progress=say, score=score, polish=polish)
    own = [q for e in effects for q in e.param_names()]
    units = {q.name: q.unit for q in jm.param_list}
    std = {n: (float(res.std[n]) if np.isfinite(res.std[n]) else None) for n in own}
    params = {n: {"value": res.params[n], "std": std[n], "unit": units[n]} for n in own}
    unseen = set(jm.conditioning.get("unseen", ()))
    return _Fitted(model=jm, params=params, std=std,
                   fit={"rms_mm": res.rms_mm, "evaluations": res.evaluations, "status": res.status,
                        "start": res.start},
                   identifiable=not all(n in unseen or std[n] is None for n in own))


# ---------------------------------------------------------------- noise floor


def velocity_time_constant(jm: JointModel) -> float | None:
    """The physical host's velocity time constant m / Cd1 [s] (the drag along the swimmer's axis, where it
    mostly swims: sin(alpha) ~ 0) in its short-window fit (the open-loop polish can trade the velocity
    response against a drift); None for hosts without a drag parameter, inf without drag."""
    prm = jm.window_params or jm.prm
    if "Cd1" not in prm or "mass_mg" not in jm.host.options:
        return None
    return jm.host.options["mass_mg"] / (1000.0 * prm["Cd1"]) if prm["Cd1"] > 0 else float("inf")


def _floor_time_constant(models) -> tuple[float, str]:
    """(tau [s], where it came from): the median velocity time constant of the fits that are not degenerate."""
    taus = []
    for jm in models:
        tau = velocity_time_constant(jm)
        if tau is not None and TAU_RANGE_S[0] <= tau <= TAU_RANGE_S[1] and "Cd1" not in jm.conditioning.get(
                "at_bound", ()):
            taus.append(tau)
    if not taus:
        return TAU_DEFAULT_S, f"no fit gives a usable drag: {TAU_DEFAULT_S} s assumed"
    return float(np.median(taus)), f"median of {len(taus)} fits"


def _floor(tte, starts, lead, steps, sigma, tau_s, base_ev, seed) -> dict:
    """{horizon: mean noise floor [mm] over the held-out windows valid at that horizon} (None without sigma)."""
    if sigma is None:
        return {h: None for h in steps}
    per = noise_floor(tte, starts, lead, steps, sigma, tau_s, seed=seed)
    return {h: float(np.mean(per[h][base_ev[h]["valid"]])) if base_ev[h]["valid"].any() else None for h in steps}


# ---------------------------------------------------------------- summaries


def _summary(ev: dict) -> dict:
    out = {"rollout_mm": {}, "windows": {}}
    for h, r in ev.items():
        v = r["valid"]
        out["rollout_mm"][h] = float(np.mean(np.linalg.norm(r["err"][v], axis=1))) if v.any() else None
        out["windows"][h] = int(v.sum())
    return out


def _reduction(before, after) -> float:
    return float(1.0 - after / before) if before and after is not None and before > 0 else 0.0


def _rank_entry(effect, cand: _Fitted, ev, summ, ref_ev, ref_sum, key, starts, block_rows) -> dict:
    red = {h: _reduction(ref_sum["rollout_mm"][h], summ["rollout_mm"][h]) for h in summ["rollout_mm"]}
    t = paired_t(ref_ev[key], ev[key], starts, block_rows)
    return {"effect": effect.name, "kind": effect.kind, "rollout_mm": summ["rollout_mm"],
            "reduction": red[key], "reduction_by_horizon": red, "t_stat": t, "identifiable": cand.identifiable,
            "params": cand.params, "fit": cand.fit, "conditioning": cand.model.conditioning, "doc": effect.doc}


def _compare_runner_up(ranking: list, errors: dict, starts: np.ndarray, block_rows: int) -> None:
    """Give the best identifiable entry a ``runner_up``: the second one, its reduction, and the paired t of the
    best's held-out errors against it (small t: the logs cannot tell the two effects apart)."""
    top = [e for e in ranking if e["identifiable"]][:2]
    if len(top) == 2:
        best, second = top
        best["runner_up"] = {"effect": second["effect"], "reduction": second["reduction"],
                             "t_stat": paired_t(errors[second["effect"]], errors[best["effect"]], starts, block_rows)}


def _fmt(d: dict) -> str:
    return ", ".join(f"{v:.3f} mm at {h} s" for h, v in d.items() if v is not None)
