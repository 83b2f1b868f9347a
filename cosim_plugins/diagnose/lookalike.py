"""Look-alike effects: candidates the logs cannot tell apart, declared as a group instead of one name.

The round's best candidate (by its drop of held-out error at the reference
horizon) is compared with every rival that lowers the model's error too (by
at least :data:`~cosim_plugins.diagnose.verdict.MIN_REDUCTION`, with paired
t >= :data:`~cosim_plugins.diagnose.verdict.MIN_T`):

* the best is told apart from a rival when it is significantly better at the
  reference horizon, or averaged over every horizon (a lag and a latency that
  end a second-long prediction at the same point still differ on the way);
* a rival significantly better than the best averaged over every horizon
  (and not significantly worse at the reference) is the better explanation:
  it takes the best's place;
* otherwise, or when the two predict every log less than
  :data:`SAME_PREDICTION` of the noise floor apart on average (no excitation
  in the logs separates them beyond the camera's noise), they are
  look-alikes. The distance is taken log by log: a designed experiment is
  the one log where the members differ, and pooled with the logs where they
  do not, its separation would be diluted by the archive's size. A log
  longer than :data:`SEPARATION_LOG_S` counts its distance times the square
  root of its length over that: a paired test's t grows with the windows it
  averages, the rule :func:`.experiment.sized_duration` sizes a designed
  experiment by, so a long experiment separates members its short logs
  could not.

Typical groups: an actuation lag, a camera latency and a heading lag on logs
whose spin rate changes slowly; a quadratic drag and a slower velocity
response on logs at one speed. :mod:`.experiment` designs the log that tells
a group's members apart.
"""

from __future__ import annotations

import numpy as np

from cosim_plugins.diagnose.verdict import MIN_REDUCTION, MIN_T

# effects that can mimic each other: a stepwise round gives each member the full fit once one of them would be
# named (a quick screen's fit may miss a member the group test needs)
FAMILIES = (frozenset({"actuation_lag", "sensor_latency", "heading_lag"}),)
SAME_PREDICTION = 0.5  # predictions this share of the noise floor apart (or closer) cannot be told apart
MIN_LOG_WINDOWS = 20  # a log's distance between two predictions counts with at least this many held-out windows
SEPARATION_LOG_S = 40.0  # a log this long [s] (or shorter) counts its distance as it is; a longer one gains sqrt(s/40)


def group_of(fitter, best: dict, entries: list, fits: dict, floor: float | None, key: str):
    """(members, evidence): the leading effect's name first, then each rival it cannot be told from.

    The leader is ``best`` unless a rival beats it over every horizon (see the module doc). ``entries``: the
    round's rank entries; ``fits``: {effect: Fit} of the round; ``fitter`` gives the verdict's paired t at one
    horizon (``paired_t``) and over all (``paired_t_horizons``); ``floor`` [mm] the noise floor at ``key``.
    ``evidence``: {rival: {"t_stat", "t_horizons", "differ_mm"}} (t > 0: the leader is better).
    """
    rivals = [e["effect"] for e in entries if e["effect"] != best["effect"] and e["identifiable"]
              and e["reduction"] >= MIN_REDUCTION and e["t_stat"] >= MIN_T]
    lead = best["effect"]
    for name in rivals:  # a rival better over every horizon, and not worse at the reference, leads instead
        t_ref = fitter.paired_t(fits[name].ev[key], fits[lead].ev[key])
        if t_ref < MIN_T and fitter.paired_t_horizons(fits[lead], fits[name]) >= MIN_T:
            lead = name
    members, evidence = [lead], {}
    for name in [best["effect"], *rivals]:
        if name == lead:
            continue
        ev = evidence_of(fitter, fits[lead], fits[name], key)
        if ((ev["t_stat"] < MIN_T and abs(ev["t_horizons"]) < MIN_T)
                or (floor is not None and ev["differ_weighted_mm"] < SAME_PREDICTION * floor)):
            members.append(name)
            evidence[name] = ev
    return members, evidence


def evidence_of(fitter, lead, rival, key: str) -> dict:
    """How far the data tell ``lead`` from ``rival`` (two Fits): paired t at ``key`` and over every horizon
    (positive: the lead is better), how far their predictions are apart [mm] over all held-out windows
    (``differ_mm``) and on the log that separates them most (``differ_log_mm``; ``differ_weighted_mm`` is that
    distance times sqrt(the log's length / :data:`SEPARATION_LOG_S`), at least 1x, which ranks the logs)."""
    tl = fitter.tte
    logs = tl.log[fitter.test_starts]
    per_log = []  # (weighted, raw) distance of each log with enough windows
    for k in np.unique(logs):
        if np.sum(logs == k) >= MIN_LOG_WINDOWS:
            raw = predictions_apart(lead.ev, rival.ev, logs == k)
            per_log.append((raw * np.sqrt(max(1.0, np.sum(tl.log == k) * tl.dt_s / SEPARATION_LOG_S)), raw))
    pooled = predictions_apart(lead.ev, rival.ev)
    weighted, raw = max(per_log, default=(pooled, pooled))
    return {"t_stat": fitter.paired_t(rival.ev[key], lead.ev[key]), "t_horizons": fitter.paired_t_horizons(rival, lead),
            "differ_mm": pooled, "differ_log_mm": raw, "differ_weighted_mm": weighted}


def predictions_apart(a: dict, b: dict, among: np.ndarray | None = None) -> float:
    """Mean distance [mm] between two models' predictions, over the horizons and the windows valid for both
    (and in ``among``, (w,) bool, when given).

    ``a``, ``b``: {horizon: {"valid": (w,) bool, "err": (w, 3) predicted - measured}}; the measurement cancels.
    """
    out = []
    for h in a:
        ok = a[h]["valid"] & b[h]["valid"] & (True if among is None else among)
        if ok.any():
            out.append(float(np.mean(np.linalg.norm(a[h]["err"][ok] - b[h]["err"][ok], axis=1))))
    return float(np.mean(out)) if out else 0.0
