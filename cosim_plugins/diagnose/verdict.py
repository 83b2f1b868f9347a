"""The verdict of a diagnosis: which effect explains the error, if any.

An effect is named only when its joint refit lowers the held-out error at
the reference horizon

* by at least :data:`MIN_REDUCTION` (relative),
* significantly: paired per-window improvements, averaged in blocks of
  :data:`BLOCK_S` (neighbouring windows share data), give t >= :data:`MIN_T`,
* and by at least :data:`MIN_EXPLAINED` of the baseline's excess over the
  noise floor (the part of the error that is explainable at all).

Otherwise the verdict is "the model is at the noise floor" when the
baseline's error is within :data:`AT_FLOOR` of the floor, else "no listed
effect explains the remaining error" with the localisation clues.
Candidates whose parameters do not change the predictions are not
identifiable and never named. When a discovered form (:mod:`.discover`)
leaves at most 1 - :data:`DISCOVERED_MARGIN` of the error the best listed
effect leaves, the verdict says so instead of naming that effect; when the
runner-up explains the error about as well (paired t < :data:`MIN_T`), it says
the logs cannot tell the two apart.
:func:`fit_notes` says in words where a fit is degenerate or two
parameters trade off.
"""

from __future__ import annotations

import numpy as np

from cosim_plugins.diagnose.wording import params_text

MIN_REDUCTION = 0.10
DISCOVERED_MARGIN = 0.3  # a discovered form is preferred when it cuts the best listed effect's error by this share
NOTE_CONDITION = 1e8  # a scaled Jacobian's condition number beyond which the parameters are undetermined
MIN_T = 3.0
MIN_EXPLAINED = 0.25
AT_FLOOR = 0.25  # error <= (1 + AT_FLOOR) x floor
BLOCK_S = 1.0


def paired_t(ref: dict, cand: dict, starts: np.ndarray, block_rows: int) -> float:
    """t statistic of |e_ref| - |e_cand| over windows valid in both, averaged per block of start rows."""
    ok = ref["valid"] & cand["valid"]
    if ok.sum() < 4:
        return 0.0
    d = np.linalg.norm(ref["err"][ok], axis=1) - np.linalg.norm(cand["err"][ok], axis=1)
    block = starts[ok] // max(block_rows, 1)
    _, inv = np.unique(block, return_inverse=True)
    means = np.bincount(inv, weights=d) / np.bincount(inv)
    if len(means) < 3:
        return 0.0
    sd = float(np.std(means, ddof=1))
    return float(np.mean(means) / (sd / np.sqrt(len(means)))) if sd > 0 else 0.0


def verdict(result: dict, key: str) -> dict:
    """{"effect": name or None, "status", "explanation"} from a diagnosis result (see :mod:`.diagnose`)."""
    ref = result["reference"] or result["baseline"]
    err, floor = ref["rollout_mm"][key], result["noise"]["floor_mm"][key]
    horizon = f"{key} s"
    excess = max(err - floor, 0.0) if err is not None and floor is not None else 0.0
    prefix = _added_text(result, key)
    best = next((e for e in result["ranking"] if e.get("identifiable", True)), None)
    found = result.get("discovered") or {}
    best_left = best["rollout_mm"][key] if best and best["rollout_mm"][key] is not None else err
    if (found.get("status") == "found" and err and found["reduction"] >= MIN_REDUCTION and found["t_stat"] >= MIN_T
            and found["rollout_mm"][key] <= (1.0 - DISCOVERED_MARGIN) * min(best_left, err)):
        best_text = (f"the best listed effect, {best['effect']}, lowers the held-out error at {horizon} by "
                     f"{best['reduction']:.0%}, " if best else "")
        text = (f"no listed effect explains the error as well as a form outside the library: {best_text}a sparse "
                f"combination of force terms fitted to what is left lowers it by {found['reduction']:.0%} (from "
                f"{err:.2f} to {found['rollout_mm'][key]:.2f} mm; t = {found['t_stat']:.1f}). "
                + _sentence("; ".join(found["words"])) + f". It is written to {found['file']}: rename it, edit its "
                f"form and refit with --effects-file {found['file']} --add discovered.")
        return {"effect": None, "status": "discovered", "explanation": prefix + text}
    if best is not None and err:
        gain = err - best["rollout_mm"][key]
        explained = gain / excess if excess > 0 else (1.0 if floor is None else 0.0)
        if best["reduction"] >= MIN_REDUCTION and best["t_stat"] >= MIN_T and explained >= MIN_EXPLAINED:
            left = best["rollout_mm"][key]
            text = (f"{best['effect']} explains the error: refitted with it, the held-out error at {horizon} falls "
                    f"from {err:.2f} to {left:.2f} mm ({best['reduction']:.0%}; t = {best['t_stat']:.1f}), "
                    + (f"{min(explained, 1.0):.0%} of the excess over the noise floor ({floor:.2f} mm). "
                       if floor is not None else "(no noise floor: the camera noise could not be estimated). ")
                    + f"Fitted: {params_text(best['params'])}.")
            if floor is not None and left > (1 + AT_FLOOR) * floor:
                text += (f" The remaining error is still {left / floor:.1f}x the noise floor: add it "
                         f"(--add {best['effect']}) and diagnose again to look for a second effect.")
            text += _runner_up_text(best)
            text += (f" Next: --add {best['effect']} --save-model MODEL.npz saves the model with it, which the "
                     "Kalman filter and the MPC take as their model (components.estimator.params.model=MODEL.npz).")
            return {"effect": best["effect"], "status": "explained", "explanation": prefix + text}
    if err is not None and floor is not None and err <= (1 + AT_FLOOR) * floor:
        text = (f"the model is at the noise floor: its held-out error at {horizon} is {err:.2f} mm against "
                f"{floor:.2f} mm that a perfect model would show with this camera noise; no effect is needed. "
                "Next: nothing to add for these logs; a smaller effect would show in longer logs, with less "
                "camera noise, or in conditions these logs do not cover (other speeds, heights, spin rates).")
        return {"effect": None, "status": "noise_floor", "explanation": prefix + text}
    clues = result.get("localisation", {}).get("clues", [])
    best_text = (f" The best candidate, {best['effect']}, lowers it by {best['reduction']:.0%} "
                 f"(t = {best['t_stat']:.1f}), which is not enough." if best else "")
    floor_text = f"a noise floor of {floor:.2f} mm" if floor is not None else "an unknown noise floor"
    text = (f"no listed effect explains the remaining error: {err:.2f} mm at {horizon} against {floor_text}."
            f"{best_text} Clues: " + ("; ".join(clues) if clues else "none stand out") + "."
            + _discovered_text(result, key))
    return {"effect": None, "status": "unexplained", "explanation": prefix + text}


def _runner_up_text(best: dict) -> str:
    """A sentence when the second-ranked effect explains the error about as well (paired t < :data:`MIN_T`)."""
    rival = best.get("runner_up")
    if not rival or rival["reduction"] < MIN_REDUCTION or rival["t_stat"] >= MIN_T:
        return ""
    return (f" {rival['effect']} lowers it almost as much ({rival['reduction']:.0%}) and the two do not differ "
            f"significantly (t = {rival['t_stat']:.1f} < {MIN_T:.0f}): these logs cannot tell {best['effect']} "
            f"from {rival['effect']}; refit with each (--add) and compare their parameters with what you know of "
            "the rig, or record logs where they differ.")


def _sentence(text: str) -> str:
    return text[:1].upper() + text[1:]


def _discovered_text(result: dict, key: str) -> str:
    found = result.get("discovered")
    if not found:
        return " Next: --discover fits a sparse combination of candidate force terms to what is left."
    if found["status"] != "found":
        return (f" Discovery: {found['explanation']}. Next: the clues say where the error grows; an effect of "
                "that form written in a file (examples/my_effect.py shows how) is refitted with --effects-file "
                "FILE --add NAME.")
    words = "; ".join(found["words"])
    return (f" Discovered form: {words}. Refitted with it, the held-out error at {key} s falls by "
            f"{found['reduction']:.0%} (t = {found['t_stat']:.1f}); it is written to {found['file']}: rename it, "
            f"edit its form and refit with --effects-file {found['file']} --add discovered.")


def _added_text(result: dict, key: str) -> str:
    added = result.get("added")
    if not added:
        return ""
    before, after = added["before_mm"][key], added["rollout_mm"][key]
    return (f"With {' + '.join(added['effects'])} added, the held-out error at {key} s "
            f"went from {before:.2f} to {after:.2f} mm. For what remains: ")


def fit_notes(result: dict) -> list[str]:
    """Sentences on the quality of the fits: degenerate baseline, trade-offs, unidentifiable candidates."""
    notes = []
    cond = result["baseline"].get("conditioning") or {}
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
    best = next((e for e in result["ranking"] if e.get("identifiable", True)), None)
    if best is not None:
        own = set(best["params"])
        ccond = best.get("conditioning") or {}
        for a, b, c in ccond.get("tradeoffs", ()):
            if (a in own) != (b in own):
                mine, other = (a, b) if a in own else (b, a)
                notes.append(f"{mine} trades off with {other} (correlation {c:+.2f}): in these logs the effect and "
                             f"a change of {other} look alike, so the reduction is real but the split between "
                             "them is uncertain")
                break
        pinned = [n for n in ccond.get("at_bound", ()) if n in own]
        if pinned:
            notes.append(f"{', '.join(pinned)} of {best['effect']} sits at a bound of its range: the fit wants more "
                         "than the form allows")
    hidden = [e["effect"] for e in result["ranking"] if not e.get("identifiable", True)]
    if hidden:
        notes.append(f"not identifiable from these logs: {', '.join(hidden)} (their parameters do not change the "
                     "predictions: the logs never reach the conditions where they act)")
    return notes
