"""How visible each hidden effect of a blind-bench case is, measured with the bench's own simulator.

An effect is visible in a case's logs when a model that lacks it (and only
it) predicts the open-loop positions clearly worse than the truth does. The
bench's simulator gives both predictions exactly: from the true state at the
start of each window (position, velocity and the thrust-shaping effect's own
state, recorded by the closed loop), the case's plant with every hidden
effect but one is driven by the logged commands over the reference horizon
(1 s) and compared with the true path (a camera latency: the plant is started
where the camera shows the swimmer and compared with what the camera shows at
the horizon). ``dev_mm`` is the mean distance [mm] at the horizon over the
windows, after the plant's parameters and the size of the other hidden effect are
refitted to the true path (what of the missing effect they can absorb, they
do, as in the diagnosis's joint refit). ``floor_mm`` is the bench's noise floor: the open-loop error a
perfect model shows when its initial state comes from noisy positions,
first-order dynamics with the plant's velocity time constant tau_v and a
straight-line fit of the initial velocity on a lead-in of ``LEAD_S`` (the
camera's 3-D noise sigma carried as sigma_v tau_v (1 - exp(-H / tau_v)), plus
sigma itself). An effect is *visible* when dev_mm >= ``VISIBLE_OVER_FLOOR`` x
floor_mm: the error of the model without it, about sqrt(floor^2 + dev^2), is
then at least 1.8x the floor.

Nothing here imports ``cosim``: the measure is the simulator's, not the
diagnosis's.

    from blind_visible import visibility
    visibility(case)  # {"actuation_lag": {"dev_mm": 1.9, "floor_mm": 0.5, "ratio": 3.8}, ...}
"""

from __future__ import annotations

import math
from dataclasses import replace

import blind_sim
import numpy as np

HORIZON_S = 1.0  # the diagnosis's reference horizon [s]
LEAD_S = 0.2  # lead-in the initial velocity is fitted on [s]
VISIBLE_OVER_FLOOR = 1.5  # dev_mm / floor_mm from which an effect counts as visible
ATTEMPTS = 12  # visible_case: draws tried per pair
PAIRS = 3  # visible_case: pairs drawn anew when no draw of the case's own pair is visible
MAX_WINDOWS = 160  # windows per measure, evenly over the logs
WALL_MARGIN_MM = 1.0  # windows this close to the wall stop are left out
CHECK_S = 40.0  # each log is simulated for at most this long for the measure [s]


def bench_floor_mm(case: blind_sim.Case) -> float:
    """The bench's noise floor [mm] at :data:`HORIZON_S` for the case's camera and plant (module docstring)."""
    reg = case.regime
    dt, tau = reg["dt_s"], reg["tau_v_s"]
    sigma = reg["noise_mm"] * math.sqrt(sum(a * a for a in reg["noise_axis"]))  # 3-D rms [mm]
    n = max(2, round(LEAD_S / dt))
    sigma_v = sigma * math.sqrt(12.0 / (n * (n * n - 1))) / dt  # slope of a line fitted on n points [mm/s]
    return math.hypot(sigma, sigma_v * tau * (1.0 - math.exp(-HORIZON_S / tau)))


def _without(case: blind_sim.Case, effect: str) -> blind_sim.Case:
    """The case's plant with every hidden effect but ``effect``."""
    keep = [i for i, e in enumerate(case.effects) if e != effect]
    pick = lambda xs: [xs[i] for i in keep]  # noqa: E731
    return replace(case, effect="+".join(pick(case.effects)) or None, effects=pick(case.effects),
                   laws=pick(case.laws), truths=pick(case.truths), true_forms=[None] * len(keep),
                   true_form_names=[None] * len(keep))


def _windows(rows: list, lead: int, h: int, p_true) -> tuple[np.ndarray, np.ndarray]:
    """(log index, start row) of up to :data:`MAX_WINDOWS` windows of ``h`` rows, ``lead`` rows from each
    log's start, half a window apart, evenly thinned; a window that comes within :data:`WALL_MARGIN_MM` of
    the wall stop anywhere from ``lead`` rows before it to its end is left out (the stop is not replayed)."""
    near = (np.abs(p_true) >= blind_sim.CLAMP_MM - WALL_MARGIN_MM).any(axis=2)  # (n, L)
    logs, starts = [], []
    for j, n in enumerate(rows):
        s = np.arange(lead, n - h - 1, max(1, h // 2))
        hit = np.concatenate([[0], np.cumsum(near[:n, j])])
        s = s[hit[s + h + 1] - hit[s - lead] == 0]
        logs += [j] * len(s)
        starts += s.tolist()
    logs, starts = np.array(logs, dtype=int), np.array(starts, dtype=int)
    if len(starts) > MAX_WINDOWS:
        keep = np.linspace(0, len(starts) - 1, MAX_WINDOWS).round().astype(int)
        logs, starts = logs[keep], starts[keep]
    return logs, starts


def _replay(case: blind_sim.Case, res: dict, logs, starts, marks, shift: int, effect_state: bool) -> np.ndarray:
    """(w, F, 3) positions [mm] after ``marks`` (F,) periods (ascending) of ``case``'s plant, started at the true
    state of rows ``starts - shift`` of ``logs`` (with the thrust-shaping state when ``effect_state``) and
    driven by the commands of rows ``starts`` on."""
    plant = blind_sim._Plant(case)
    r0 = starts - shift
    p, v = res["p_true_mm"][r0, logs].copy(), res["v_true_mm_s"][r0, logs].copy()
    if effect_state:
        held = [res["effect_state"][r][j] for r, j in zip(r0, logs)]
        plant.state = None if held[0] is None else np.stack(held)
    out = np.empty((len(starts), len(marks), 3))
    with np.errstate(all="ignore"):
        for i in range(max(marks)):
            P, V = plant.period(p, v, res["omega_hz"][starts + i, logs], (starts + i) * case.regime["dt_s"])
            p, v = P[-1], V[-1]
            for f, m in enumerate(marks):
                if m == i + 1:
                    out[:, f] = p
    return out


BASE = ("k", "Cd0", "Cd1", "Cl0", "Fvs", "Fmax")  # the plant's parameters the baseline model fits too
FIT_AT = (0.25, 0.5, 1.0)  # shares of the horizon whose positions the baseline's refit matches


# the size of each effect the model keeps, refitted with the plant's parameters (one factor each): the keys of its
# truth scaled together; a camera latency is held (it shifts the windows, not the plant)
MAGNITUDE = {"background_flow": ("w_x_mm_s", "w_y_mm_s"), "wall_drag": ("c_uNs_mm",), "step_out": ("f_so_hz",),
             "gradient_force": ("b_uN_mm",), "anisotropic_drag": ("c_uNs_mm",), "quadratic_drag": ("c_uNs2_mm2",),
             "actuation_lag": ("tau_s",), "heading_lag": ("tau_s",), "rotating_flow": ("omega_rad_s",),
             "thrust_nonuniform": ("g_per_mm",), "shear_flow": ("gamma_x_per_s", "gamma_y_per_s"),
             "periodic": ("f0_uN",)}


def _sized(effects: list) -> list:
    """The effects of ``effects`` whose size :func:`_with_base` refits."""
    return [e for e in effects if e in MAGNITUDE]


def _with_base(case: blind_sim.Case, x: np.ndarray) -> blind_sim.Case:
    """The case with its plant's parameters changed by ``x`` (6 + one per :func:`_sized` effect): k and Cd1 times
    exp(x0), exp(x2); Cd0, Cl0, Fvs and Fmax plus x times the true Cd1 (so every entry is of order one); each
    sized effect's :data:`MAGNITUDE` keys times exp(x[6 + i])."""
    pl = case.regime["plant"]
    cd1 = pl["Cd1"]
    new = {**pl, "k": pl["k"] * math.exp(x[0]), "Cd0": max(pl["Cd0"] + x[1] * cd1, 0.0),
           "Cd1": cd1 * math.exp(x[2]), "Cl0": pl["Cl0"] + x[3] * cd1, "Fvs": pl["Fvs"] + x[4] * cd1,
           "Fmax": pl["Fmax"] + x[5] * cd1}
    scale = dict(zip(_sized(case.effects), np.exp(x[6:])))
    truths = [t if e not in scale else {**t, **{k: (np.asarray(t[k]) * scale[e]).tolist() for k in MAGNITUDE[e]}}
              for e, t in zip(case.effects, case.truths)]
    return replace(case, regime={**case.regime, "plant": new}, truths=truths)


def _refit_base(rest: blind_sim.Case, run, target: np.ndarray) -> blind_sim.Case:
    """``rest`` with the plant's parameters (:data:`BASE`) and the size of each effect it keeps refitted so that
    ``run(case)`` (w, F, 3) [mm] comes closest to ``target`` (w, F, 3) in least squares: what of a missing effect
    the model's other parameters absorb (the diagnosis refits them all together)."""
    from scipy.optimize import least_squares

    def resid(x):
        r = run(_with_base(rest, x)) - target
        return np.nan_to_num(np.clip(r, -100.0, 100.0), nan=100.0).ravel()

    sol = least_squares(resid, np.zeros(len(BASE) + len(_sized(rest.effects))), x_scale=0.3, diff_step=1e-3,
                        max_nfev=60)
    return _with_base(rest, sol.x)


def visibility(case: blind_sim.Case, check_s: float = CHECK_S) -> dict:
    """{effect: {"dev_mm", "floor_mm", "ratio", "visible"}} for every hidden effect of ``case`` (module doc).

    The case's logs are simulated for at most ``check_s`` each (the same regime and truths; the windows'
    states and commands come from that run). The model without an effect has the plant's parameters
    (:data:`BASE`) refitted first, as the diagnosis's baseline would be.
    """
    reg = case.regime
    short = [min(d, check_s) for d in reg["log_durations_s"]]
    res = blind_sim.run_case(replace(case, regime={**reg, "log_durations_s": short}), states=True)
    dt = reg["dt_s"]
    h = max(1, round(HORIZON_S / dt))
    marks = sorted({max(1, round(a * h)) for a in FIT_AT})
    delay = dict(zip(case.effects, case.truths)).get("sensor_latency", {}).get("delay_periods", 0.0)
    lo, f = int(math.floor(delay)), delay - math.floor(delay)
    logs, starts = _windows(res["rows"], lo + 2, h, res["p_true_mm"])
    floor = bench_floor_mm(case)
    shaping = set(case.effects) & set(blind_sim.THRUST_SHAPING)
    true = res["p_true_mm"]
    out = {}
    for effect in case.effects:
        rest = _without(case, effect)
        if effect == "sensor_latency":  # started where the camera shows it, compared with what it shows
            def run(c, keep=bool(shaping)):
                return sum(w * _replay(c, res, logs, starts, marks, s, keep) for w, s in ((1 - f, lo), (f, lo + 1)))
            target = sum(w * true[starts[:, None] + np.array(marks)[None] - s, logs[:, None]]
                         for w, s in ((1 - f, lo), (f, lo + 1)))
        else:
            def run(c, keep=bool(shaping - {effect})):
                return _replay(c, res, logs, starts, marks, 0, keep)
            target = true[starts[:, None] + np.array(marks)[None], logs[:, None]]
        fitted = _refit_base(rest, run, target)
        if not len(starts):
            out[effect] = {"dev_mm": None, "floor_mm": round(floor, 4), "ratio": None, "visible": False}
            continue
        d = np.linalg.norm(run(fitted)[:, -1] - target[:, -1], axis=1)
        dev = float(np.mean(np.where(np.isfinite(d), np.minimum(d, 100.0), 100.0)))
        out[effect] = {"dev_mm": round(dev, 4), "floor_mm": round(floor, 4), "ratio": round(dev / floor, 3),
                       "visible": dev >= VISIBLE_OVER_FLOOR * floor}
    return out


def visible_case(case: blind_sim.Case, attempts: int = ATTEMPTS) -> tuple[blind_sim.Case, dict]:
    """(case, draw) with every hidden effect visible (:func:`visibility`): ``case`` itself when it is, else the
    first of up to ``attempts - 1`` redraws of the same effects (regime and magnitudes anew, from case seeds of
    the stream [case seed, 9]) that is. When no draw of the pair is, the pair itself is drawn anew, of the same
    kind (two library effects, or a library and an outside one: :func:`blind_sim.compatible_pairs`), up to
    :data:`PAIRS` times with ``attempts`` draws each (some effects rarely show at all: an anisotropic drag
    hides in a swimmer that seldom moves across its axis); when none is, the attempt whose least visible
    effect is the most. ``draw`` is {"seed" (the case's own seed), "attempts", "visibility" ({effect: ...} of
    the case returned), "all_visible", "pairs" (the pairs tried, the drawn one first)}: rejection sampling,
    so each effect's magnitude still spans its whole drawn range, limited only by what these logs can show."""
    stream = np.random.default_rng([case.seed, 9])
    kind = "library" if all(e in blind_sim.LIBRARY for e in case.effects) else "outside"
    others = [p for p in blind_sim.compatible_pairs(kind) if set(p) != set(case.effects)]
    best, n, pairs = None, 0, [list(case.effects)]
    for round_no in range(PAIRS + 1):
        effects = pairs[-1]
        seeds = stream.integers(0, 2**31 - 1, max(attempts - 1, 0) + (round_no > 0))
        firsts = [case] if round_no == 0 else []
        trials = firsts + [int(x) for x in seeds]
        for trial in trials:
            if not isinstance(trial, blind_sim.Case):
                trial = blind_sim.draw_multi_case(trial, effects, index=case.index)
            n += 1
            vis = visibility(trial)
            worst = min((v["ratio"] or 0.0) for v in vis.values())
            if best is None or worst > best[0]:
                best = (worst, trial, vis, n)
            if all(v["visible"] for v in vis.values()):
                break
        if all(v["visible"] for v in best[2].values()) or not others:
            break
        pairs.append(list(others.pop(int(stream.integers(len(others))))))
    _, trial, vis, chosen = best
    return trial, {"seed": case.seed, "attempts": n, "chosen_attempt": chosen, "visibility": vis,
                   "all_visible": all(v["visible"] for v in vis.values()), "pairs": pairs}


def visible_lookalike_case(case: blind_sim.Case, attempts: int = ATTEMPTS) -> tuple[blind_sim.Case, dict]:
    """(case, draw) for a look-alike case: ``case`` itself when its hidden effect is visible (:func:`visibility`),
    else the first of up to ``attempts - 1`` redraws of the same effect (regime and magnitude anew, case seeds
    from the stream [case seed, 10]) that is; when none is, the draw that shows it most. ``draw`` has the keys of
    :func:`visible_case`'s (``pairs`` is the one effect's list). Rejection sampling, as there: the magnitude still
    spans its whole drawn range, limited only by what these logs can show."""
    stream = np.random.default_rng([case.seed, 10])
    trials = [case] + [int(x) for x in stream.integers(0, 2**31 - 1, max(attempts - 1, 0))]
    best, n = None, 0
    for trial in trials:
        if not isinstance(trial, blind_sim.Case):
            trial = blind_sim.draw_lookalike_case(trial, case.effect, index=case.index)
        n += 1
        vis = visibility(trial)
        ratio = vis[case.effect]["ratio"] or 0.0
        if best is None or ratio > best[0]:
            best = (ratio, trial, vis, n)
        if vis[case.effect]["visible"]:
            break
    _, trial, vis, chosen = best
    return trial, {"seed": case.seed, "attempts": n, "chosen_attempt": chosen, "visibility": vis,
                   "all_visible": vis[case.effect]["visible"], "pairs": [[case.effect]]}
