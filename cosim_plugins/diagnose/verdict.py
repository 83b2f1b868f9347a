"""The verdict of a diagnosis: which effects explain the error, if any.

An effect is named only when its joint refit lowers the held-out error at
the reference horizon, against the model before it (the baseline, or the
effects chosen in earlier rounds of :mod:`.stepwise`; :func:`passes`),

* by at least :data:`MIN_REDUCTION` (relative),
* significantly: paired per-window improvements, averaged in blocks of
  :data:`BLOCK_S` (neighbouring windows share data), give t >= :data:`MIN_T`
  (:func:`gain_t`: the plain t, or the trimmed t when a few blocks gain far
  more than the rest; a candidate short of it only there is tested on every
  fold of the time blocks, :mod:`.crossfold`),
* and by at least :data:`MIN_EXPLAINED` of that model's excess over the
  noise floor (the part of the error that is explainable at all).

Look-alikes (:mod:`.lookalike`) are named as a group, never as one member,
with the experiment that tells them apart. Otherwise the verdict is "the
model is at the noise floor" when the baseline's error is within
:data:`AT_FLOOR` of the floor, else "no listed effect explains the remaining
error" with the localisation clues. Candidates whose parameters do not change
the predictions are not identifiable and never named. When a discovered form
(:mod:`.discover`, fitted to what the named effects leave) lowers that error
by at least :data:`DISCOVERED_MARGIN`, the verdict says so.
:func:`fit_notes` says in words where a fit is degenerate or two
parameters trade off.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from cosim_plugins.diagnose.drift import sentence as drift_sentence
from cosim_plugins.diagnose.result import DiagnosisResult, Verdict
from cosim_plugins.diagnose.wording import given_words, params_text

MIN_REDUCTION = 0.10
DISCOVERED_MARGIN = 0.3  # a discovered form is reported when it cuts the named effects' error by this share
NOTE_CONDITION = 1e8  # a scaled Jacobian's condition number beyond which the parameters are undetermined
MIN_T = 3.0
MIN_EXPLAINED = 0.25
AT_FLOOR = 0.25  # error <= (1 + AT_FLOOR) x floor
BLOCK_S = 1.0
TRIM = 0.1  # share of blocks trimmed at each end by the trimmed t (gain_t)


def paired_t(ref: dict, cand: dict, starts: np.ndarray, block_rows: int) -> float:
    """t statistic of |e_ref| - |e_cand| over windows valid in both, averaged per block of start rows."""
    return _t_of(gain_block_means(ref, cand, starts, block_rows))


def _gain(ref: dict, cand: dict, ok: np.ndarray) -> np.ndarray:
    """(n_ok,) per-window drop of the error size from ``ref`` to ``cand`` [mm] over the windows ``ok``."""
    return np.linalg.norm(ref["err"][ok], axis=1) - np.linalg.norm(cand["err"][ok], axis=1)


def paired_t_horizons(ref: dict, cand: dict, starts: np.ndarray, block_rows: int) -> float:
    """:func:`paired_t` of the improvement averaged over every horizon: ``ref``, ``cand`` are
    {horizon: {"valid", "err"}}; windows valid at every horizon count. A lag and a latency that end a
    second-long prediction at the same point still differ on the way there."""
    ok = np.logical_and.reduce([ref[h]["valid"] & cand[h]["valid"] for h in ref])
    if ok.sum() < 4:
        return 0.0
    d = np.mean([_gain(ref[h], cand[h], ok) for h in ref], axis=0)
    return _block_t(d, starts[ok], block_rows)


def gain_t(ref: dict, cand: dict, starts: np.ndarray, block_rows: int) -> float:
    """The t of a candidate's gain that the gates use: the larger of :func:`paired_t` and Yuen's trimmed t of
    the same block means (:data:`TRIM` of the blocks cut at each end). A model that blows up in a few blocks
    (a spin rate above a step-out it lacks) makes the candidate's gain there so large that the plain t's
    spread swamps the gain every other block shows (a drop of 42 % at t = 2.4, with 45 of 57 blocks gaining);
    the trimmed t is not swayed by those blocks. The relative drop, a mean over every window, still counts them
    all, so a candidate that loses badly in a few blocks does not pass on the trimmed t."""
    return blocks_t(gain_block_means(ref, cand, starts, block_rows))


def gain_block_means(ref: dict, cand: dict, starts: np.ndarray, block_rows: int) -> np.ndarray:
    """(blocks,) a candidate's per-window gain over ``ref`` (:func:`paired_t`'s) averaged per block of start
    rows; empty when fewer than 4 windows are valid in both."""
    ok = ref["valid"] & cand["valid"]
    if ok.sum() < 4:
        return np.zeros(0)
    return _block_means(_gain(ref, cand, ok), starts[ok], block_rows)


def blocks_t(means: np.ndarray) -> float:
    """:func:`gain_t` of block means (n,): the larger of the plain and the trimmed t."""
    return max(_t_of(means), trimmed_t(means))


def _block_t(d: np.ndarray, starts: np.ndarray, block_rows: int) -> float:
    """t of the mean of ``d`` (per window) over blocks of ``block_rows`` start rows (windows in a block share data)."""
    return _t_of(_block_means(d, starts, block_rows))


def _block_means(d: np.ndarray, starts: np.ndarray, block_rows: int) -> np.ndarray:
    """(blocks,) means of ``d`` (per window) over blocks of ``block_rows`` start rows."""
    block = starts // max(block_rows, 1)
    _, inv = np.unique(block, return_inverse=True)
    return np.bincount(inv, weights=d) / np.bincount(inv)


def _t_of(means: np.ndarray) -> float:
    """One-sample t of the mean of ``means`` (0 with fewer than 3 or no spread)."""
    if len(means) < 3:
        return 0.0
    sd = float(np.std(means, ddof=1))
    return float(np.mean(means) / (sd / np.sqrt(len(means)))) if sd > 0 else 0.0


def trimmed_t(means: np.ndarray, trim: float = TRIM) -> float:
    """Yuen's one-sample trimmed t of ``means`` (n,): the mean of the values left after cutting
    floor(``trim`` n) at each end, over its standard error from the winsorised variance; 0 when fewer than 3
    values are left or they do not spread."""
    n = len(means)
    g = int(trim * n)
    h = n - 2 * g
    if h < 3:
        return 0.0
    x = np.sort(means)
    w = np.clip(x, x[g], x[n - 1 - g])
    var_w = float(np.var(w, ddof=1))
    if var_w <= 0:
        return 0.0
    return float(np.mean(x[g:n - g]) / np.sqrt((n - 1) * var_w / (h * (h - 1))))


def explained_share(err_before: float, left: float, floor: float | None) -> float:
    """Share of the excess over the noise floor that a model removes (1 without a floor, 0 at the floor)."""
    excess = max(err_before - floor, 0.0) if floor is not None else 0.0
    return (err_before - left) / excess if excess > 0 else (1.0 if floor is None else 0.0)


def passes(entry: dict, err_before: float | None, floor: float | None, key: str) -> bool:
    """True when a candidate's refit earns a name against the model before it: an identifiable fit whose held-out
    error at ``key`` falls by >= :data:`MIN_REDUCTION`, with paired t >= :data:`MIN_T`, removing
    >= :data:`MIN_EXPLAINED` of that model's excess over the noise floor ``floor`` [mm]."""
    left = entry["rollout_mm"].get(key)
    if not entry.get("identifiable", True) or not err_before or left is None:
        return False
    return (entry["reduction"] >= MIN_REDUCTION and entry["t_stat"] >= MIN_T
            and explained_share(err_before, left, floor) >= MIN_EXPLAINED)


def under_gate(reduction: float) -> str:
    """A drop under :data:`MIN_REDUCTION` as a percentage: whole, or to one decimal where a whole one would
    reach the gate (9.8 %, not "only 10 %")."""
    return f"{reduction:.1%}" if round(reduction, 2) >= MIN_REDUCTION else f"{reduction:.0%}"


def fails_by(reduction: float, t_stat: float) -> str:
    """Why a drop (share of the error, paired t) earns no name, in words: too small, or not significant (a
    drop that passes both fails on its share of the excess over the noise floor)."""
    if reduction < MIN_REDUCTION:
        return f"it lowers the error by only {under_gate(reduction)}, t = {t_stat:.1f}"
    if t_stat < MIN_T:
        return f"its drop of {reduction:.0%} is not significant: t = {t_stat:.1f}"
    return f"its drop of {reduction:.0%} (t = {t_stat:.1f}) is a small share of the excess over the noise floor"


def verdict(result: DiagnosisResult, key: str) -> Verdict:
    """The verdict of a diagnosis result (see :mod:`.pipeline`): the first effect named or None, every effect
    named in the order chosen, the look-alike groups the logs cannot tell apart, the status ("explained",
    "discovered" (a form outside the library explains what the named effects leave, or all of it), "drift" (no
    effect named, and the logs disagree with each other or drift within: :mod:`.drift`), "noise_floor" or
    "unexplained") and the explanation in words (:class:`~.result.Verdict`).
    """
    out = _verdict(result, key)
    words = drift_sentence(result.drift, key)
    if words and out.status in ("unexplained", "noise_floor"):
        return replace(out, status="drift", explanation=words + " " + _drift_left(result, key))
    if words:
        return replace(out, explanation=out.explanation + " " + words)
    return out


def _drift_left(result: DiagnosisResult, key: str) -> str:
    """What the drifting model leaves, against the noise floor."""
    floor = result.noise.floor_mm[key]
    left = result.drift.explains.rollout_mm[key]
    if floor is None:
        return f"With the drift in, {left:.2f} mm remain at {key} s."
    return (f"With the drift in, {left:.2f} mm remain at {key} s against a noise floor of {floor:.2f} mm"
            + (": what is left is noise." if left <= (1 + AT_FLOOR) * floor else
               ". " + _clues_text(result)))


def _verdict(result: DiagnosisResult, key: str) -> Verdict:
    err, floor = result.effects_model.rollout_mm[key], result.noise.floor_mm[key]
    sw = result.stepwise
    steps = sw.steps
    given = sw.given_discovered.steps if sw.given_discovered else []
    named = [st.effects[0] for st in steps + given if not st.group]

    def out(status: str, explanation: str) -> Verdict:
        return Verdict(effect=named[0] if named else None, effects=named,
                       lookalikes=[list(st.effects) for st in steps + given if st.group], status=status,
                       explanation=explanation)

    prefix = _added_text(result, key)
    left = sw.joint.rollout_mm[key] if steps else err
    found = result.discovered
    text = _steps_text(result, key) if steps else ""
    if discovered_explains(result, key) and found.refines:
        text += (f" What they leave is {found.refines}'s own law, not another effect: terms of its form lower it by "
                 f"a further {found.reduction:.0%} (from {left:.2f} to {found.rollout_mm[key]:.2f} mm at {key} s; "
                 f"t = {found.t_stat:.1f}), so the library's law for {found.refines} does not quite follow these "
                 "logs. " + _sentence("; ".join(found.words)) + f". The form is written to {found.file}: a law "
                 f"for {found.refines} of that shape in an effect file (examples/my_effect.py shows how) is "
                 "refitted with --effects-file FILE --add NAME." + _given_text(result, key))
        return out("explained", prefix + text.strip())
    if discovered_explains(result, key):
        best = next((e for e in result.ranking if e.identifiable), None)
        what = ("what they leave" if steps else "the error") + (
            "" if steps or best is None else f" (the best listed effect, {best.effect}, lowers it by only "
            f"{under_gate(best.reduction)})")
        on_top = [d for d in sw.dropped if d.given == "on_top"]
        if on_top and not steps:  # the form was found on what they left: its drop is against that
            names = " and ".join(d.effect for d in on_top)
            text = (f"{names}, chosen first, {'was' if len(on_top) == 1 else 'were'} dropped once the discovered "
                    "form and the effects named on top of it were in ("
                    + "; ".join(f"{d.effect}: {fails_by(d.reduction, d.t_stat)}" for d in on_top) + "). ")
            what, left = f"what {names} left", found.rollout_mm[key] / (1.0 - found.reduction)
        # a flow term's name: w<axes>_<feature>
        terms = "force terms and a flow of the water" if any(n.startswith("w") for n in found.terms or ()) \
            else "force terms"
        text += (f"{' And a' if steps else 'A'} form outside the library explains {what}: a sparse combination "
                 f"of {terms} lowers it by a further {found.reduction:.0%} (from {left:.2f} to "
                 f"{found.rollout_mm[key]:.2f} mm at {key} s; t = {found.t_stat:.1f}). "
                 + _sentence("; ".join(found.words)) + f". It is written to {found.file}: rename it, edit its "
                 f"form and refit with --effects-file {found.file} --add discovered." + _given_text(result, key))
        return out("discovered", prefix + text.strip())
    if steps:
        if floor is not None and left > (1 + AT_FLOOR) * floor:
            more = ("; --discover fits a sparse combination of force terms to what is left" if not found else
                    f"; discovery: {found.explanation}" if found.status != "found" else "")
            text += (f" The remaining error is still {left / floor:.1f}x the noise floor: no other listed effect "
                     f"passes the tests given these{more}.")
        elif floor is not None:
            text += " What remains is at the noise floor."
        if named:
            text += (" Next: --add " + " --add ".join(named) + " --save-model MODEL.npz saves the model with "
                     + ("it" if len(named) == 1 else "them") + ", which the Kalman filter and the MPC take as their "
                     "model (components.estimator.params.model=MODEL.npz).")
        return out("explained", prefix + text.strip())
    horizon = f"{key} s"
    if err is not None and floor is not None and err <= (1 + AT_FLOOR) * floor:
        text = (f"the model is at the noise floor: its held-out error at {horizon} is {err:.2f} mm against "
                f"{floor:.2f} mm that a perfect model would show with this camera noise; no effect is needed. "
                "Next: nothing to add for these logs; a smaller effect would show in longer logs, with less "
                "camera noise, or in conditions these logs do not cover (other speeds, heights, spin rates).")
        return out("noise_floor", prefix + text)
    best = next((e for e in result.ranking if e.identifiable), None)
    best_text = (f" The best candidate, {best.effect}, lowers it by {best.reduction:.0%} "
                 f"(t = {best.t_stat:.1f}), which is not enough." if best else "")
    floor_text = f"a noise floor of {floor:.2f} mm" if floor is not None else "an unknown noise floor"
    text = (f"no listed effect explains the remaining error: {err:.2f} mm at {horizon} against {floor_text}."
            f"{best_text} " + _clues_text(result) + _discovered_text(result, key))
    return out("unexplained", prefix + text)


def discovered_explains(result: DiagnosisResult, key: str) -> bool:
    """True when the discovered form (``result.discovered``) lowers what the chosen effects leave (or the
    reference's error) by >= :data:`MIN_REDUCTION` with t >= :data:`MIN_T`, and it, with the effects named on top of
    it (``stepwise.given_discovered``), to at most 1 - :data:`DISCOVERED_MARGIN` of it: the verdict then reports
    it."""
    sw, found = result.stepwise, result.discovered
    left = sw.joint.rollout_mm[key] if sw.steps else result.effects_model.rollout_mm[key]
    if found is None or found.status != "found" or not left:
        return False
    given = sw.given_discovered
    after = given.joint.rollout_mm[key] if given and given.steps else found.rollout_mm[key]
    return bool(found.reduction >= MIN_REDUCTION and found.t_stat >= MIN_T
                and after <= (1.0 - DISCOVERED_MARGIN) * left)


def _given_text(result: DiagnosisResult, key: str) -> str:
    """What the stepwise search named on top of the discovered form, one sentence per step."""
    sw = result.stepwise.given_discovered
    floor = result.noise.floor_mm[key]
    parts = []
    for st in sw.steps if sw else ():
        share = explained_share(st.rollout_before_mm, st.rollout_mm, floor)
        drop = (f"the held-out error at {key} s falls from {st.rollout_before_mm:.2f} to {st.rollout_mm:.2f} mm "
                f"({st.reduction:.0%}; t = {st.t_stat:.1f}"
                + (f"; {min(share, 1.0):.0%} of the excess over the noise floor)" if floor is not None else ")"))
        if st.group:
            parts.append(f" Given the discovered form, {' or '.join(st.effects)} explain part of what is left "
                         f"about equally well ({drop} with {st.effects[0]}); none of them is named.")
        else:
            parts.append(f" Given the discovered form, {st.effects[0]} explains part of what is left: refitted "
                         f"with it, {drop}. Fitted: {params_text(st.params)}.")
    return "".join(parts)


def _steps_text(result: DiagnosisResult, key: str) -> str:
    """One sentence per chosen step (an effect, or a look-alike group with its experiment), then the joint drop."""
    sw, floor = result.stepwise, result.noise.floor_mm[key]
    parts = []
    for i, st in enumerate(sw.steps):
        on = st.given if st.given is not None else [s.effects[0] for s in sw.steps[:i]]
        given = f" given {given_words(on, ' and ')}" if on else ""
        share = explained_share(st.rollout_before_mm, st.rollout_mm, floor)
        drop = (f"the held-out error at {key} s falls from {st.rollout_before_mm:.2f} to {st.rollout_mm:.2f} mm"
                f"{given} ({st.reduction:.0%}; t = {st.t_stat:.1f}"
                + (f"; {min(share, 1.0):.0%} of the excess over the noise floor, {floor:.2f} mm)" if floor is not None
                   else "; no noise floor: the camera noise could not be estimated)"))
        if st.alone is not None and not st.group:
            parts.append(f"{st.effects[0]} explains part of the error only together with {given_words(on, ' and ')}: "
                         f"alone it lowers it by {st.alone.reduction:.0%} (t = {st.alone.t_stat:.1f}), not enough, "
                         f"but refitted with it, {drop}. Fitted: {params_text(st.params)}.")
            continue
        if not st.group:
            parts.append(f"{st.effects[0]} explains {'the' if len(sw.steps) == 1 else 'part of the'} error: "
                         f"refitted with it, {drop}. Fitted: {params_text(st.params)}.")
            continue
        rivals = ", ".join(f"{m} (t = {ev.t_stat:.1f} at {key} s, {ev.t_horizons:.1f} over all horizons; "
                           f"predictions {_apart_text(ev)}; refitted together it adds {ev.adds:+.0%})"
                           for m, ev in st.group_evidence.items())
        parts.append(f"{' or '.join(st.effects)} explain the error about equally well: refitted with "
                     f"{st.effects[0]}, {drop}, and these logs cannot tell it from {rivals}. None of them is "
                     "named: " + _experiment_text(result, st.effects))
    if len(sw.steps) > 1:
        j = sw.joint
        parts.append(f"Together ({' + '.join(j.effects)}) they lower the held-out error at {key} s from "
                     f"{result.effects_model.rollout_mm[key]:.2f} to {j.rollout_mm[key]:.2f} mm "
                     f"({j.reduction[key]:.0%}).")
    for d in sw.dropped:
        if d.given == "discovered" and d.part_of:
            parts.append(f"{d.effect} was dropped: it is the uniform part of a {d.part_of} flow found without it, "
                         f"which still lowers the error by {d.form_reduction:.0%} (t = {d.form_t_stat:.1f}) once "
                         f"{d.effect} is in; a flow that varies with position has its uniform part in it (its value "
                         "at the tank's origin), so the two are one flow.")
            continue
        if d.given == "discovered":
            again = d.effect in sw.named_on_top()
            parts.append(f"{d.effect} was {'set aside' if again else 'dropped'}: it stands in for a form outside the "
                         f"library. Discovered without it, that form leaves {d.effect} only {d.reduction:.0%} "
                         f"(t = {d.t_stat:.1f}), while it still lowers the error by {d.form_reduction:.0%} "
                         f"(t = {d.form_t_stat:.1f}) once {d.effect} is in."
                         + (" On top of the form found on what is left it passes again (below)." if again else ""))
            continue
        parts.append(f"{d.effect} was dropped once "
                     + {"drift": "the drift between the logs was allowed for",
                        "on_top": "the discovered form and the effects named on top of it were in"}.get(
                         d.given, "the others were in")
                     + f" ({fails_by(d.reduction, d.t_stat)}).")
    return " ".join(parts)


def _apart_text(ev) -> str:
    """How far apart a group's members predict, in words: on the log where they differ most, with the distance
    its length makes it count for (:data:`.lookalike.SEPARATION_LOG_S`) when that is larger."""
    if ev.differ_log_mm is None:
        return f"{ev.differ_mm:.2f} mm apart"
    text = f"{ev.differ_log_mm:.2f} mm apart on the log where they differ most"
    if ev.differ_weighted_mm is not None and ev.differ_weighted_mm > ev.differ_log_mm + 0.005:
        text += f", counted as {ev.differ_weighted_mm:.2f} mm for its length"
    return text


def _experiment_text(result: DiagnosisResult, members: list) -> str:
    exp = result.experiment
    if not exp or set(exp.members) != set(members):
        return "record logs where their predictions differ (faster spin-rate changes) and diagnose again."
    where = ""
    # the circle matters (an effect of the position differs only where it acts); a diagnosis.json written before
    # the circle was kept has none
    if exp.path is not None and exp.path.center_mm:
        x, y, z = exp.path.center_mm
        where = f" on a circle of {exp.path.radius_mm:.0f} mm about ({x:.0f}, {y:.0f}, {z:.0f}) mm"
    return (f"record the experiment designed to tell them apart ({exp.files.scenario}, or apply "
            f"{exp.files.excitation} as the spin-rate schedule on the rig{where}: {exp.duration_s:.0f} s of "
            f"{exp.kind}), on which their predictions differ by {exp.separation_mm:.2f} mm "
            f"({exp.separation_over_floor:.1f}x the noise floor); add its log to these and diagnose again.")


def _clues_text(result: DiagnosisResult) -> str:
    clues = result.localisation.clues if result.localisation else []
    return "Clues: " + ("; ".join(clues) if clues else "none stand out") + "."


def _sentence(text: str) -> str:
    return text[:1].upper() + text[1:]


def _discovered_text(result: DiagnosisResult, key: str) -> str:
    found = result.discovered
    if not found:
        return " Next: --discover fits a sparse combination of candidate force terms to what is left."
    if found.status != "found":
        return (f" Discovery: {found.explanation}. Next: the clues say where the error grows; an effect of "
                "that form written in a file (examples/my_effect.py shows how) is refitted with --effects-file "
                "FILE --add NAME.")
    words = "; ".join(found.words)
    return (f" Discovered form: {words}. Refitted with it, the held-out error at {key} s falls by "
            f"{found.reduction:.0%} (t = {found.t_stat:.1f}); it is written to {found.file}: rename it, "
            f"edit its form and refit with --effects-file {found.file} --add discovered.")


def _added_text(result: DiagnosisResult, key: str) -> str:
    added = result.added
    if not added:
        return ""
    before, after = added.before_mm[key], added.rollout_mm[key]
    return (f"With {' + '.join(added.effects)} added, the held-out error at {key} s "
            f"went from {before:.2f} to {after:.2f} mm. For what remains: ")


def fit_notes(result: DiagnosisResult) -> list[str]:
    """Sentences on the quality of the fits: a noise floor lowered to a refit, degenerate baseline, trade-offs,
    unidentifiable candidates."""
    notes = []
    noise = result.noise
    if noise.reached_by is not None:
        key = result.reference_key
        notes.append(f"the noise floor estimated from the camera noise ({noise.estimated_mm[key]:.3f} mm at "
                     f"{result.reference_horizon_s:g} s) is above the error {noise.reached_by}'s refit reaches "
                     f"({noise.floor_mm[key]:.3f} mm): no model goes below the floor, so it is taken as that refit's "
                     "errors")
    cond = result.baseline.conditioning or {}
    if "Cd1" in cond.get("at_bound", ()):
        notes.append("the baseline fit is degenerate: its linear drag Cd1 sits at its bound 0, so it predicts that "
                     "the swimmer keeps any velocity it has; the model's form cannot represent these logs, and "
                     "what is missing changes how the speed responds to the command (a step-out, a lag, a drag "
                     "law) more than a small extra force would")
    if cond.get("condition", 0.0) > NOTE_CONDITION:
        notes.append(f"the baseline's parameters are nearly undetermined by these logs (condition number "
                     f"{cond['condition']:.1e}): richer excitation (spin rates, turns) would pin them down")
    for a, b, c in cond.get("tradeoffs", ())[:2]:
        notes.append(f"in the baseline, {a} and {b} trade off (correlation {c:+.2f}): the logs cannot tell them "
                     "apart, so their values are not meaningful one by one")
    best = next((e for e in result.ranking if e.identifiable), None)
    if best is not None:
        own = set(best.params)
        ccond = best.conditioning or {}
        for a, b, c in ccond.get("tradeoffs", ()):
            if (a in own) != (b in own):
                mine, other = (a, b) if a in own else (b, a)
                notes.append(f"{mine} trades off with {other} (correlation {c:+.2f}): in these logs the effect and "
                             f"a change of {other} look alike, so the reduction is real but the split between "
                             "them is uncertain")
                break
        pinned = [n for n in ccond.get("at_bound", ()) if n in own]
        if pinned:
            notes.append(f"{', '.join(pinned)} of {best.effect} sits at a bound of its range: the fit wants more "
                         "than the form allows")
    hidden = [e.effect for e in result.ranking if not e.identifiable]
    if hidden:
        notes.append(f"not identifiable from these logs: {', '.join(hidden)} (their parameters do not change the "
                     "predictions: the logs never reach the conditions where they act)")
    return notes
