"""``cosim twin calibrate``: the plant FMU calibrated to a lab's logs, with the effects diagnose found.

Route (fast fit first, then the FMU; both reported):

1. **Host fit.** The paper's physical model with the named effects is fitted as
   ``cosim diagnose --add EFFECT`` fits it (:func:`cosim_plugins.diagnose.pipeline.run`,
   no candidates, no drift test), or read from a saved model (``--model M.npz``).
   Its held-out error is diagnose's figure for the best host model with these effects.
2. **Mapping.** Its k, Cd1, Fvs set the FMU's propulsion, drag and net weight, with an
   isotropic drag (:func:`.knobs.plant_from_host`); the effects' parameters and the
   paper's angle-of-attack drag, lift and centring force, which the FMU's law lacks
   (:mod:`.host_forces`), go to the FMU's external force input. A latency the host
   fitted (``sensor_latency``) starts the camera's.
3. **First stage.** Candidates (:func:`_candidates`): the mapped host fit under each
   combination of the FMU's coil lag and heading dynamics (both off, instant actuation
   and the axis on the spin axis, is the host model's structure and preferred), and the
   FMU's own defaults with its own dynamics. Each is polished briefly (3 steps, every
   other training chunk), scored on the other training chunks, and the preferred one
   kept unless another lowers that error by more than 2 % (:func:`_choose`).
4. **FMU polish.** From the kept candidate every knob (:mod:`.knobs`: propulsion, drags,
   anisotropy, net weight, heading response, gradient force, camera latency, effect
   parameters) is refined by least squares on the FMU's own open-loop replay of the
   training chunks (:mod:`.replay`: every chunk and trial value in lockstep, errors every
   5 rows up to 1.0 s), the chunks spread over ``jobs`` processes. The FMU has what the
   host model lacks (heading dynamics, the coils' lag, an anisotropic drag, the coils'
   gradient force) and lacks what it has: the polish makes the two agree on the logs,
   not on paper.
5. **Held-out scores** on diagnose's held-out windows and horizons
   (:mod:`.windows`): the uncalibrated FMU (its defaults, no effects), the mapped FMU
   (step 2) and the calibrated twin (step 4).

Uncertainties: the polish's covariance, robust to the correlation of the windows
within one chunk (a cluster jackknife over chunks, :func:`_cluster_std`); a knob whose
standard error exceeds half its value (or its scale, for a knob that may be 0) is
reported as not determined.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from cosim.contract.errors import UserError
from cosim_plugins.diagnose.fitting import fork_map
from cosim_plugins.twin import knobs as K
from cosim_plugins.twin.host_forces import NAME as PAPER
from cosim_plugins.twin.host_forces import paper_forces_effect
from cosim_plugins.twin.replay import FmuBank, make_chunks, window_errors

SWITCHES = ("actuation_lag_on", "heading_dynamics_on")  # FMU dynamics the logs may show or not (chosen)
SWITCHED = {"rot_drag_perp": "heading_dynamics_on"}  # knobs that act only with their FMU switch on
SWITCH_GAIN = 0.05  # another first-stage candidate must lower the preferred one's error by this share
SWITCH_NFEV = 3  # polish steps of each first-stage candidate (start and switches) before they are compared
TRAIN_CHUNKS = 30  # training chunks of the FMU polish (a random sample of 1 s spans)
POLISH_EVERY = 5  # the polish scores each window every this many rows up to the reference horizon
MAX_NFEV = 10  # polish iterations (each: one Jacobian by finite differences, all knobs at once)
FD_STEP = 0.01  # finite-difference step in x (1 % of a log knob; a hundredth of a linear knob's scale)
UNDETERMINED = 0.5  # std above this share of |value| (or of the scale): not determined by the logs
HOST_TRANSFORMS = {"sensor_latency": "the camera's latency_s (calibrated on the FMU)",
                   "heading_lag": "the FMU's heading dynamics (rot_drag_perp, calibrated)",
                   "actuation_lag": "the FMU's coil circuit (R, L, C: fixed, not calibrated)"}


@dataclass
class Settings:
    """Options of ``cosim twin calibrate``."""

    effects: list = field(default_factory=list)  # library effect names (force effects, or the transforms above)
    model: str | None = None  # a saved physical model: its effects and parameters (no host fit)
    jobs: int = 1
    seed: int = 0
    max_nfev: int = MAX_NFEV
    host_fit: bool = True  # False: start from the FMU's defaults (tests; no host model)
    train_chunks: int = TRAIN_CHUNKS
    free: list | None = None  # the knobs fitted (None: all); the others stay at their start values
    paper_forces: bool = True  # apply the host's lift and centring force (twin_paper_forces) through the input


@dataclass
class Calibration:
    """What a calibration found: ``result`` is twin.json; ``values`` and ``std`` the knobs; ``effects`` the force
    effects applied (their parameters in ``values``; they reuse the twin's own drag, thrust and weight); ``host``
    the host fit's k, Cd0, ... (None without one); ``sigma_mm``
    the camera noise (x, y, z) [mm]."""

    result: dict
    values: dict
    std: dict
    effects: list
    host: dict
    sigma_mm: np.ndarray | None
    switches: dict


class Replay:
    """Held FMU runs over chunks of windows: errors for any set of knob values (parallel over chunks)."""

    def __init__(self, tl, starts, lead, ks, jobs, chunks=None):
        self.tl, self.lead, self.ks, self.jobs = tl, lead, np.asarray(ks), jobs
        self.chunks = chunks if chunks is not None else make_chunks(tl, starts, lead, int(np.max(ks)))
        self.n = int(sum(len(c.starts) for c in self.chunks))

    def halves(self) -> tuple["Replay", "Replay"]:
        """The replays of every other chunk, from the first and from the second (the first stage fits on one
        and compares on the other)."""
        return tuple(Replay(self.tl, None, self.lead, self.ks, self.jobs, chunks=self.chunks[i::2]) for i in (0, 1))

    def trajectories(self, settings: list, what: str) -> list:
        """[[traj (rows + 1, 6) per chunk] per setting]; a setting is (fmu params, AppliedEffects or None).

        The chunks are split into ``jobs`` groups of about equal rows, each replayed in lockstep under
        every setting by one process (:class:`.replay.FmuBank`)."""
        tl, chunks = self.tl, self.chunks
        groups = _groups([c.r1 - c.r0 for c in chunks], self.jobs)
        bank = _bank()  # loaded before the fork: the workers inherit it

        def one(g):
            return bank.run([chunks[i] for i in groups[g]], settings, tl.dt_s)

        per_group = fork_map(one, len(groups), self.jobs, what)
        out = [[None] * len(chunks) for _ in settings]
        for g, res in zip(groups, per_group):
            for s, trajs in enumerate(res):
                for i, tr in zip(g, trajs):
                    out[s][i] = tr
        return out

    def errors(self, trajs: list, latency_s: float, tau_s: float):
        """(valid (w, H), err (w, H, 3) [mm], chunk id (w,)) of one setting's trajectories (initial states solved
        on the lead-ins with the velocity time constant ``tau_s``, see :func:`.replay.window_errors`)."""
        vs, es, ids = [], [], []
        for c, (chunk, tr) in enumerate(zip(self.chunks, trajs)):
            v, e = window_errors(self.tl, chunk, tr, self.lead, self.ks, latency_s, tau_s)
            vs.append(v)
            es.append(e)
            ids.append(np.full(len(v), c))
        return np.concatenate(vs), np.concatenate(es), np.concatenate(ids)


_BANK = {}


def _bank() -> FmuBank:
    """This process's FMU bank (a forked worker inherits its parent's)."""
    if "fmu" not in _BANK:
        _BANK["fmu"] = FmuBank()
    return _BANK["fmu"]


def _groups(rows: list, n: int) -> list:
    """Indices of ``rows`` (rows of each chunk) in at most ``n`` groups of about equal total rows."""
    n = max(1, min(n, len(rows)))
    groups, load = [[] for _ in range(n)], [0] * n
    for i in sorted(range(len(rows)), key=lambda i: -rows[i]):
        g = int(np.argmin(load))
        groups[g].append(i)
        load[g] += rows[i]
    return [sorted(g) for g in groups if g]


def calibrate(log_paths, validate_paths=(), settings: Settings | None = None, progress=None) -> Calibration:
    """Calibrate the twin on raw logs; see the module docstring."""
    from cosim_plugins.raw_log import read_log
    from cosim_plugins.twin.windows import diagnose_windows

    s = settings or Settings()
    say = progress or (lambda msg: None)
    t0 = time.perf_counter()
    if s.jobs < 1:
        raise UserError(f"--jobs {s.jobs}: give at least 1")
    if s.model and s.effects:
        raise UserError("give --effects or --model, not both (a model file names its own effects)")
    if not log_paths:
        raise UserError("no log files given")
    named = _resolve(s.effects)
    logs = [read_log(p) for p in log_paths]
    validate = [read_log(p) for p in validate_paths] if validate_paths else None
    win = diagnose_windows(logs, validate, seed=s.seed)
    say(f"windows: {len(win.test_starts)} held-out (diagnose's), {win.lead} lead-in rows, horizons "
        f"{', '.join(win.steps)} s")

    host = _host(log_paths, validate_paths, s, named, say)
    forces = [e for e in host["effects"] if e.kind == "force"]
    paper = paper_forces_effect()
    applied_effects = [*forces, paper] if s.paper_forces else list(forces)
    start = {**(K.plant_from_host(host["params"]) if host["params"] else K.plant_defaults()),
             "latency_s": host["latency_s"]}
    start.update({q: host["params"].get(q, p.init) for e in forces for q, p in zip(e.param_names(), e.params)})
    start.update({f"{paper.name}.{q}": host["params"].get(q, 0.0) for q in ("Cd0", "Cl0", "Fmax")})
    knobs = [*K.PLANT_KNOBS, K.LATENCY, *K.effect_knobs(applied_effects)]
    unknown = sorted(set(s.free or ()) - {k.name for k in knobs})
    if unknown:
        raise UserError(f"free: unknown parameter(s) {', '.join(unknown)}; valid: {', '.join(k.name for k in knobs)}")
    start = {k.name: float(np.clip(start[k.name], k.lo, k.hi)) for k in knobs}

    ks_test = list(win.steps.values())
    test = Replay(win.test, win.test_starts, win.lead, ks_test, s.jobs)
    k_ref = win.steps[win.reference]
    ks_train = list(range(POLISH_EVERY, k_ref + 1, POLISH_EVERY))
    train = _train_replay(win, ks_train, s)
    say(f"FMU replay: {test.n} held-out windows in {len(test.chunks)} runs, {train.n} training windows in "
        f"{len(train.chunks)} runs")

    uncal = _held_out(test, [(K.fmu_values(K.plant_defaults()), None)], [0.0], "uncalibrated FMU")[0]
    host_structure = {k: False for k in SWITCHES}  # instant actuation, the axis on the spin axis
    mapped_h = _held_out(test, [_setting(start, applied_effects, host_structure)],
                         [start["latency_s"]], "mapped FMU")[0]
    say(f"uncalibrated FMU: {_fmt(uncal)}; host fit mapped onto the FMU: {_fmt(mapped_h)}")

    fmu_start = {**start, **{k: v for k, v in K.plant_defaults().items() if k in start}}
    candidates = _candidates(start if host["params"] else None, fmu_start)
    fit_half, check_half = train.halves()
    first, switch_rms, trial = _choose(fit_half, check_half, knobs, candidates, applied_effects, s, say)
    switches = candidates[first][1]
    values, std, info = _polish(train, knobs, trial, applied_effects, s, say, switches)
    calibrated = _held_out(test, [_setting(values, applied_effects, switches)],
                           [values["latency_s"]], "calibrated twin")[0]
    say(f"calibrated twin: {_fmt(calibrated)}")

    sigma = host["sigma_mm"]
    fitted = set(info["free"])
    undetermined = {k.name: "standard error above half its value" for k in knobs if k.name in fitted and (
                    not np.isfinite(std[k.name]) or std[k.name] > UNDETERMINED * max(abs(values[k.name]),
                                                                                       0.0 if k.log else k.scale))}
    if "actuation_lag" in host["transforms"]:
        undetermined["actuation_lag"] = HOST_TRANSFORMS["actuation_lag"]
    units = {k.name: k.unit for k in knobs}
    result = {
        "logs": [str(p) for p in log_paths], "validate": [str(p) for p in validate_paths], "split": win.split,
        "dt_s": win.dt_s, "horizons_s": {h: float(h) for h in win.steps}, "lead_in_rows": win.lead,
        "windows": {"held_out": int(test.n), "training": int(train.n)},
        "route": "host physical model fitted as diagnose does, mapped onto the FMU, then polished on the FMU's "
                 "open-loop replay of training windows" if s.host_fit else "FMU polish from the FMU's defaults",
        "effects": [e.name for e in forces], "host_transforms": {n: HOST_TRANSFORMS[n] for n in host["transforms"]},
        "held_out_error_mm": calibrated, "uncalibrated_error_mm": uncal, "mapped_error_mm": mapped_h,
        "host_error_mm": host["rollout_mm"], "host_model": host["origin"],
        "params": {k.name: {"value": values[k.name], "std": _finite(std[k.name]), "unit": units[k.name],
                            "start": candidates[first][0][k.name], "where": k.where, "doc": k.doc} for k in knobs},
        "host_params": {n: {"value": v, "std": _finite(host["std"].get(n))} for n, v in host["params"].items()},
        "camera_noise_mm": dict(zip("xyz", map(float, sigma))) if sigma is not None else None,
        "heading_time_constant_s": K.heading_time_constant_s(values["rot_drag_perp"]),
        "switches": switches, "first_stage": {"kept": first, "rms_mm": switch_rms},
        "not_determined": undetermined, "held_fixed": K.NOT_DETERMINED, "polish": info,
    }
    result["timing_s"] = round(time.perf_counter() - t0, 2)
    return Calibration(result=result, values=values, std=std, effects=applied_effects, host=host["reuse"],
                       sigma_mm=sigma, switches=switches)


def _resolve(names) -> list:
    """The named library effects; an unknown name raises a UserError listing the known ones."""
    from cosim_plugins.identify.effect import known_effects, resolve

    if not names:
        return []
    effects = resolve(list(names), known_effects())
    for e in effects:
        if e.kind != "force" and e.name not in HOST_TRANSFORMS:
            raise UserError(f"effect {e.name!r} is a {e.kind} transform the twin has no counterpart for; the twin "
                            f"applies force effects and stands in for {', '.join(HOST_TRANSFORMS)}")
    return effects


def _host(log_paths, validate_paths, s: Settings, named, say) -> dict:
    """The host fit: params (k, Cd0, ...; effect parameters qualified), std, effects, held-out error by horizon,
    camera noise, a latency start [s], the transforms it fitted, and the host parameters the effects reuse."""
    from cosim_plugins.diagnose.noise import noise_sigma_mm
    from cosim_plugins.identify.dataset import Dataset
    from cosim_plugins.identify.timeline import Timeline
    from cosim_plugins.raw_log import read_log
    from cosim_plugins.twin.units import HOST_UNITS

    empty = {"params": {}, "std": {}, "effects": list(named), "rollout_mm": None, "origin": None,
             "latency_s": 0.0, "transforms": [e.name for e in named if e.kind != "force"]}
    tall = Timeline.from_dataset(Dataset.from_logs([read_log(p) for p in log_paths]))
    sigma = noise_sigma_mm(tall)
    sigma = sigma if np.all(np.isfinite(sigma)) else None
    if s.model:
        host = _from_model(s.model, tall.dt_s)
    elif s.host_fit:
        from cosim_plugins.diagnose.pipeline import Settings as DiagnoseSettings
        from cosim_plugins.diagnose.pipeline import run

        say(f"host fit: the physical model{' + ' + ' + '.join(e.name for e in named) if named else ''}, as "
            "cosim diagnose fits it ...")
        d = run(list(log_paths), list(validate_paths), DiagnoseSettings(add=[e.name for e in named], candidates=[],
                                                                        drift=False, jobs=s.jobs, seed=s.seed),
                progress=lambda m: say(f"  diagnose: {m}"))
        r = d.result
        jm = d.added_model
        part = r.added if named else r.baseline
        params = jm.params() if jm is not None else r.baseline.params
        std = jm.std if jm is not None else r.baseline.std
        host = {"params": params, "std": {k: v for k, v in std.items()}, "effects": list(named),
                "rollout_mm": part.rollout_mm, "origin": "physical" + "".join(f" + {e.name}" for e in named),
                "transforms": [e.name for e in named if e.kind != "force"]}
    else:
        host = dict(empty)
    host.setdefault("latency_s", 0.0)
    delay = host["params"].get("sensor_latency.delay")
    if delay is not None:
        host["latency_s"] = float(delay) * tall.dt_s
    host["sigma_mm"] = sigma
    host["reuse"] = ({k: float(host["params"][k]) for k in HOST_UNITS} if host["params"] else None)
    return host


def _from_model(path, dt_s: float) -> dict:
    """A saved physical model as the host fit (no held-out error: it was fitted elsewhere)."""
    from cosim_plugins.identify.model import load_model, read_model_file

    header, _ = read_model_file(path)
    if header["kind"] != "physical":
        raise UserError(f"--model {path}: a {header['kind']!r} model; the twin starts from a physical model")
    model = load_model(path)
    effects = [t for t in model.terms if t.kind == "force" or t.name in HOST_TRANSFORMS]
    return {"params": model.params(), "std": {}, "effects": effects, "rollout_mm": None,
            "origin": f"model file {path}", "transforms": [e.name for e in effects if e.kind != "force"]}


def _train_replay(win, ks, s: Settings) -> Replay:
    """The polish's replay: a random sample of 1 s chunks of every training window (diagnose's stride)."""
    from cosim_plugins.diagnose import pipeline

    frac = float(np.mean(win.train.measured))
    starts = win.train.window_starts(win.lead, 0.6 * frac, rows=win.lead + 1, measured_start=False)
    starts = starts[::pipeline.EVAL_STRIDE]
    chunks = make_chunks(win.train, starts, win.lead, max(ks))
    if len(chunks) > s.train_chunks:
        pick = np.sort(np.random.default_rng(s.seed + 3).choice(len(chunks), s.train_chunks, replace=False))
        chunks = [chunks[i] for i in pick]
    return Replay(win.train, None, win.lead, ks, s.jobs, chunks=chunks)


def _setting(values: dict, effects, switches: dict | None = None) -> tuple:
    """(FMU parameters, AppliedEffects) of knob values (and the FMU's effect ``switches``)."""
    from cosim_plugins.twin.applied import AppliedEffects

    fmu = {**K.fmu_values({k: v for k, v in values.items() if k in {p.name for p in K.PLANT_KNOBS}}),
           **(switches or {})}
    eff = {q: float(values[q]) for e in effects for q in e.param_names()}
    # the effects reuse the twin's own drag, thrust and weight (a flow's w is then the flow's speed), never the
    # host fit's: the FMU's law may need other values than the host model's to give the same motion
    return fmu, AppliedEffects(effects, eff, effects_host(fmu, values))


def effects_host(fmu: dict, values: dict) -> dict:
    """The host parameters (k, Cd0, Cd1, ...; uN, mm, s) the twin's effects reuse: its FMU's (``fmu``, by FMI
    name), with the angle-of-attack drag Cd0 of ``twin_paper_forces`` when the knob ``values`` hold one."""
    from cosim_plugins.twin.units import host_params_from_fmu

    host = host_params_from_fmu(fmu)
    cd0 = values.get(f"{PAPER}.Cd0")
    if cd0 is not None:
        host["Cd0"] = float(cd0)
    return host


def _held_out(replay: Replay, settings: list, latencies: list, what: str) -> list:
    """[{horizon key: mean held-out error [mm]} per setting] on diagnose's held-out windows."""
    from cosim_plugins.diagnose.pipeline import HORIZONS_S

    out = []
    for trajs, lat, (fmu, _) in zip(replay.trajectories(settings, what), latencies, settings):
        valid, err, _ = replay.errors(trajs, lat, _tau(fmu))
        out.append({h: (float(np.mean(np.linalg.norm(err[valid[:, i], i], axis=1))) if valid[:, i].any() else None)
                    for i, h in enumerate(HORIZONS_S)})
    return out


def _candidates(host_start: dict | None, fmu_start: dict) -> dict:
    """{name: (start values, FMU switches)} the first stage compares, the preferred one first: the host fit
    mapped onto the FMU under every combination of :data:`SWITCHES` (both off, the host model's structure,
    preferred) and the FMU's own defaults with its own dynamics (both on); without a host fit, the FMU's
    defaults under every combination (its own dynamics preferred). Effect knobs start at the host fit's
    values in both."""
    import itertools

    combos = [dict(zip(SWITCHES, bits)) for bits in itertools.product((False, True), repeat=len(SWITCHES))]
    label = {(False, False): "host structure", (True, True): "FMU dynamics", (True, False): "coil lag only",
             (False, True): "heading dynamics only"}
    if host_start is None:
        return {f"FMU defaults, {label[tuple(c.values())]}": (fmu_start, c) for c in combos[::-1]}
    out = {f"host fit, {label[tuple(c.values())]}": (host_start, c) for c in combos}
    out["FMU defaults, FMU dynamics"] = (fmu_start, combos[-1])
    return out


def _choose(fit: Replay, check: Replay, knobs, candidates: dict, effects, s: Settings,
            say) -> tuple[str, dict, dict]:
    """(the candidate kept, the rms error [mm] of each on ``check``, its briefly polished values): each candidate
    (start values and FMU switches, :func:`_candidates`) is polished :data:`SWITCH_NFEV` steps on ``fit`` (half
    the training chunks) and scored on ``check`` (the other half, which it was not fitted to); the first
    (preferred) one is kept unless another lowers its error by more than :data:`SWITCH_GAIN`. Brief polishes,
    not the starts, are compared: a switch turned on needs its own values (the coils' lag delays the thrust: a
    drag fitted without it is off), and a start far from the logs' values (the host model's drag absorbs what
    its law lacks) needs steps to show where it leads; they are compared on chunks they were not fitted to, as
    a switch's extra freedom lowers the error it was fitted on whether the logs' plant has it or not."""
    trials, settings = {}, []
    for name, (start, switches) in candidates.items():
        trials[name], _, _ = _polish(fit, knobs, start, effects, s, lambda m: None, switches,
                                     max_nfev=SWITCH_NFEV, with_std=False)
        settings.append(_setting(trials[name], effects, switches))
    table = {}
    for name, trajs in zip(candidates, check.trajectories(settings, "first stage")):
        v = trials[name]
        valid, err, _ = check.errors(trajs, v["latency_s"], _tau(K.fmu_values({"drag_axial": v["drag_axial"]})))
        table[name] = float(np.sqrt(np.mean(err[valid] ** 2))) if valid.any() else float("inf")
    first = next(iter(candidates))
    best = min(table, key=table.get)
    if not table[best] < (1.0 - SWITCH_GAIN) * table[first]:
        best = first
    say(f"first stage ({SWITCH_NFEV} polish steps each on {fit.n} training windows, scored on the other "
        f"{check.n}): " + "; ".join(f"{k}: {v:.3f} mm" for k, v in table.items()) + f" -> {best}")
    return best, table, trials[best]


def _polish(train: Replay, knobs, start: dict, effects, s: Settings, say, switches: dict,
            max_nfev: int | None = None, with_std: bool = True):
    """(values, std, info): every knob refined on the FMU's replay of the training chunks (see the module doc)."""
    held = {k.name: start[k.name] for k in knobs if (s.free is not None and k.name not in s.free)
            or (k.name in SWITCHED and not switches[SWITCHED[k.name]])}
    all_knobs, knobs = knobs, [k for k in knobs if k.name not in held]
    names = [k.name for k in knobs]
    x0 = np.array([k.to_x(start[k.name]) for k in knobs])
    lo, hi = (np.array(b) for b in zip(*(k.x_bounds() for k in knobs)))
    x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
    i_lat = names.index("latency_s") if "latency_s" in names else None
    cache: dict = {}
    count = {"runs": 0}

    def values_of(x):
        return {**held, **{k.name: k.from_x(float(v)) for k, v in zip(knobs, x)}}

    def batch(xs: list) -> list:
        """Residual vectors (and per-window cluster ids) of several x, FMU runs shared where only latency differs."""
        keys = [tuple(np.round(x if i_lat is None else np.delete(x, i_lat), 12)) for x in xs]
        todo = [j for j, key in enumerate(keys) if key not in cache]
        uniq = {keys[j]: j for j in todo}
        if uniq:
            settings = [_setting(values_of(xs[j]), effects, switches) for j in uniq.values()]
            count["runs"] += len(settings)
            for key, trajs in zip(uniq, train.trajectories(settings, "FMU polish")):
                cache[key] = trajs
        out = []
        for x, key in zip(xs, keys):
            v = values_of(x)
            tau = _tau(K.fmu_values({"drag_axial": v["drag_axial"]}))
            valid, err, ids = train.errors(cache[key], v["latency_s"], tau)
            r = np.where(valid[..., None], np.nan_to_num(err), 0.0)
            out.append((r.reshape(-1), np.repeat(ids, r.shape[1] * 3)))
        if len(cache) > 64:
            cache.clear()
        return out

    state = {"jac": None}

    def fun(x):
        return batch([x])[0][0]

    def jac(x):
        xs = [x]
        for i in range(len(x)):
            step = np.zeros_like(x)
            h = FD_STEP if x[i] + FD_STEP <= hi[i] else -FD_STEP
            step[i] = h
            xs.append(x + step)
        res = batch(xs)
        r0 = res[0][0]
        J = np.stack([(res[i + 1][0] - r0) / (xs[i + 1][i] - x[i]) for i in range(len(x))], axis=1)
        state["jac"] = (x.copy(), J)
        return J

    r_start = fun(x0)
    # x is already scaled (log of a positive knob, value / scale otherwise): no further scaling
    sol = least_squares(fun, x0, jac=jac, bounds=(lo, hi), method="trf", x_scale=1.0,
                        max_nfev=max_nfev or s.max_nfev,
                        ftol=1e-4, xtol=1e-4)
    x = sol.x
    r, ids = batch([x])[0]
    if not with_std:
        std_x = np.full(len(x), np.nan)
    else:
        last = state["jac"]  # the solver's Jacobian at its last accepted point, which is the solution
        J = last[1] if last is not None and np.array_equal(last[0], x) else jac(x)
        std_x = _cluster_std(J, r, ids)
    values = values_of(x)
    std = {n: float("nan") for n in held}  # held, not fitted
    for k, v, sx in zip(knobs, x, std_x):
        std[k.name] = abs(k.from_x(v)) * sx if k.log else sx * k.scale
    std = {k.name: std[k.name] for k in all_knobs}
    rms0 = float(np.sqrt(np.mean(r_start ** 2))) if len(r_start) else float("nan")
    rms1 = float(np.sqrt(np.mean(r ** 2))) if len(r) else float("nan")
    say(f"FMU polish: {train.n} windows, rms {rms0:.3f} -> {rms1:.3f} mm ({sol.nfev} steps, {count['runs']} FMU "
        "replays of the training chunks)")
    info = {"windows": int(train.n), "chunks": len(train.chunks), "rows_scored": list(map(int, train.ks)),
            "rms_mm_start": rms0, "rms_mm": rms1, "steps": int(sol.nfev), "status": int(sol.status),
            "replays": count["runs"], "free": names, "held": sorted(held)}
    return values, std, info


def _cluster_std(J: np.ndarray, r: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """Standard errors of x from the Jacobian J (m, p) and residuals r (m,), robust to any correlation of the
    residuals within each cluster ``ids`` (m,) (a chunk: its windows overlap and share their rows' errors):
    the cluster jackknife (CR3), ((C - 1) / C) sum_c (d_c - mean d)(d_c - mean d)' with d_c the change of x
    when cluster c is left out, (J'J - J_c'J_c)^-1 J_c' r_c. With the polish's 30 chunks and about ten knobs
    the plain cluster sandwich (J'J)^-1 (sum_c J_c' r_c r_c' J_c) (J'J)^-1 is too small (95 % intervals cover
    about 85 % in a simulation of this shape; the jackknife's about 94 %)."""
    A = J.T @ J
    clusters = np.unique(ids)
    n = len(clusters)
    if n < 2:
        return np.full(J.shape[1], np.inf)
    d = np.empty((n, J.shape[1]))
    for i, c in enumerate(clusters):
        Jc = J[ids == c]
        d[i] = np.linalg.lstsq(A - Jc.T @ Jc, Jc.T @ r[ids == c], rcond=1e-12)[0]
    d -= d.mean(axis=0)
    out = np.sqrt((n - 1) / n * np.sum(d * d, axis=0))
    out[np.diag(A) <= 1e-12 * max(float(np.max(np.diag(A))), 1e-300)] = np.inf  # a knob the logs do not move
    return out


def _tau(fmu: dict) -> float:
    """The FMU's velocity time constant along its axis, mass / drag_axial [s], for FMU parameters ``fmu``."""
    from cosim_plugins.twin.units import fmu_defaults

    p = {**fmu_defaults(), **fmu}
    return p["mass"] / p["drag_axial"]


def _finite(v):
    return float(v) if v is not None and np.isfinite(v) else None


def _fmt(d: dict) -> str:
    return ", ".join(f"{v:.3f} mm at {h} s" for h, v in d.items() if v is not None)


def pretty(values: dict, std: dict, unit: dict) -> list[str]:
    """Lines 'name = value +- std unit' (3 significant digits)."""
    return [f"{n} = {values[n]:.4g} +- {std[n]:.2g} {unit[n]}" if math.isfinite(std[n]) else
            f"{n} = {values[n]:.4g} (not determined) {unit[n]}" for n in values]
