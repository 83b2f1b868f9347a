"""The experiment that tells look-alike effects apart (model discrimination: a T-optimal design).

For a look-alike group, every member's fitted model (the model before the
group plus that member) runs the experiment in closed loop: a pure-pursuit
controller steers along a horizontal circle in the logs' workspace while a
candidate excitation (:mod:`.excitation`) sets the spin rate within the logs'
band (or, when a member is a force, stops and goes: :func:`any_force`). The
candidates are every excitation on every placement of the circle
(:func:`placements`): at the workspace's centre, and
pushed to each side of the box the logs visited (their positions'
:data:`BOX_PERCENTILES` per axis), so an effect that depends on where the
swimmer is (a wall's drag, a field's gradient) is probed where the logs say
the rig can go (the centre unless a side separates the members
:data:`PLACE_GAIN` x more). What each member predicts the camera would log (its sensor effects
applied, no noise) is one synthetic log per member; every other member is
then scored on it exactly as diagnose scores a model, by its held-out
open-loop error at the reference horizon with the initial state solved on the
lead-in, averaged over every horizon of the diagnosis (look-alikes end a
second-long prediction at nearly the same point and differ on the way). The
design keeps the excitation whose smallest such separation over the ordered
pairs of members is largest, and compares it with the noise floor. The
candidates are compared over :data:`DURATION_S`; the chosen one then lasts
long enough for its separation to show against the noise
(:func:`sized_duration`: a separation of :data:`SEPARATION_TARGET` x the
floor needs :data:`DURATION_S`, a smaller one more windows, up to
:data:`MAX_DURATION_S`). Units: mm, mm/s, Hz, s.

:class:`Experiment` writes ``experiment.yaml`` (a scenario: the path, PI
control, the excitation as the ``diagnose.spin_schedule`` shaper) and
``experiment_excitation.csv`` (``t_s,freq_hz``: the spin-rate schedule alone,
which any rig or simulator applies under its own path controller, on the
circle the scenario's ``path`` names: where the circle is matters as much as
the schedule when an effect depends on the position).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from cosim_plugins.diagnose.excitation import Excitation, candidates
from cosim_plugins.diagnose.result import ExperimentFiles, ExperimentPath, ExperimentResult, Tried
from cosim_plugins.identify.dataset import Dataset
from cosim_plugins.identify.timeline import Timeline
from cosim_plugins.raw_log import Log

DURATION_S = 40.0  # length over which the candidate excitations are compared [s]
MAX_DURATION_S = 300.0  # the longest experiment designed [s]
# separation / noise floor a DURATION_S experiment needs to tell members apart: on the blind bench (seed 8), look-alike
# pairs separated by 1.06x and 1.16x were told apart by a 40 s experiment's log, one separated by 0.29x was not
SEPARATION_TARGET = 1.0
LOOKAHEAD_MM = 9.0  # the design's pure pursuit (the PI controller's default look-ahead)
PATH_DS_MM = 0.5  # spacing of the circle's points
RADIUS_MM = (15.0, 35.0)  # the circle's radius: half the logs' horizontal spread, within this range
BOX_PERCENTILES = (1.0, 99.0)  # the workspace's box: these percentiles of the logged positions, per axis
# a circle off the centre is chosen only when it separates the members this much more than the best central
# candidate: members that do not depend on the position differ by rounding from place to place, and the centre
# keeps the swimmer furthest from the box's edges
PLACE_GAIN = 1.1
INPUT_WINDOW_S = 5.0  # rows of command history an input effect is evaluated on at each step
BAND_PERCENTILES = (5.0, 95.0)  # the spin-rate band: these percentiles of the logged spin rates
SCENARIO_FILE, EXCITATION_FILE = "experiment.yaml", "experiment_excitation.csv"


@dataclass
class Experiment:
    """A designed experiment: its excitation, path and the separation it predicts between the members."""

    members: list
    excitation: Excitation
    dt_s: float
    center_mm: list
    radius_mm: float
    place: str  # where the circle is (:func:`placements`): "centre" or the side of the workspace, e.g. "+z"
    separation_mm: float  # smallest mean separation (over windows and horizons) over the ordered pairs of members
    floor_mm: float | None
    tried: list = field(default_factory=list)  # [Tried] every candidate

    def schedule(self) -> tuple[np.ndarray, np.ndarray]:
        """(t_s (n,), freq_hz (n,)): the spin rate at every control period of the experiment."""
        t = np.arange(int(round(self.excitation.duration_s / self.dt_s))) * self.dt_s
        return t, self.excitation.freq_hz(t)

    def summary(self) -> ExperimentResult:
        """diagnosis.json's ``experiment``."""
        return ExperimentResult(
            members=self.members, kind=self.excitation.describe(), params=self.excitation.params(),
            duration_s=self.excitation.duration_s, separation_mm=self.separation_mm, floor_mm=self.floor_mm,
            separation_over_floor=self.separation_mm / self.floor_mm if self.floor_mm else None,
            path=ExperimentPath(plugin="circle", radius_mm=self.radius_mm, center_mm=self.center_mm),
            files=ExperimentFiles(scenario=SCENARIO_FILE, excitation=EXCITATION_FILE), tried=self.tried)

    def write(self, out_dir) -> list[Path]:
        """Write ``experiment.yaml`` and ``experiment_excitation.csv`` into ``out_dir``; returns their paths."""
        out = Path(out_dir)
        t, f = self.schedule()
        csv = out / EXCITATION_FILE
        csv.write_text("t_s,freq_hz\n" + "".join(f"{a:.4f},{b:.4f}\n" for a, b in zip(t, f)))
        yaml = out / SCENARIO_FILE
        yaml.write_text(self._scenario_text())
        return [yaml, csv]

    def _scenario_text(self) -> str:
        e = self.excitation
        sep = f"{self.separation_mm:.2f} mm" + (f" ({self.separation_mm / self.floor_mm:.1f}x the noise floor "
                                                 f"{self.floor_mm:.2f} mm)" if self.floor_mm else "")
        shaper = ", ".join(f"{k}: {v!r}" if isinstance(v, str) else f"{k}: {v:g}" for k, v in e.params().items())
        cx, cy, cz = self.center_mm
        where = ("at the centre of the logs' workspace" if self.place == "centre" else
                 f"at the {self.place} side of the logs' workspace")
        return f"""# The experiment cosim diagnose designed to tell {' / '.join(self.members)} apart.
#
# PI path following on a horizontal circle {where} while the spin rate follows
# {e.describe()} (the schedule alone is in {EXCITATION_FILE}: t_s,freq_hz, for a rig or
# simulator that applies it under its own path controller). The members' predictions of this
# log differ by {sep} at the reference horizon.
# Record it on the rig, add its log.csv to the logs and diagnose again. On a simulator, the plant and
# camera below are the FMU's defaults: set them as the other logs were recorded (--set components.plant.params...).
name: experiment
description: spin-rate excitation that tells {' / '.join(self.members)} apart
duration_s: {e.duration_s:g}
dt_s: {self.dt_s:g}
seed: 1
record: {{omega: shaper.omega}}
path:
  plugin: circle
  params: {{radius_mm: {self.radius_mm:.1f}, center_mm: [{cx:.1f}, {cy:.1f}, {cz:.1f}]}}
components:
  plant:
    plugin: plant.fmu
    params: {{p0_x: {(cx + self.radius_mm) / 1000:.4f}, p0_y: {cy / 1000:.4f}, p0_z: {cz / 1000:.4f}}}
    inputs:
      coil_voltage_amp: {{from: coil_driver.coil_voltage_amp, delay: 1}}
      coil_voltage_phase: {{from: coil_driver.coil_voltage_phase, delay: 1}}
      drive_freq: {{from: coil_driver.drive_freq, delay: 1}}
  camera:
    plugin: camera.emulator
    params: {{interval_s: {self.dt_s:g}}}
    inputs: {{position: plant.position}}
  estimator:
    plugin: estimator.passthrough
    inputs: {{position: camera.position}}
  controller:
    plugin: controller.pi
    inputs: {{position: estimator.position, velocity: estimator.velocity}}
  shaper:
    plugin: diagnose.spin_schedule
    params: {{{shaper}}}
    inputs: {{omega: controller.omega}}
  coil_driver:
    plugin: coil_driver.inverse
    inputs: {{omega: shaper.omega}}
"""


def design_experiment(step, tl: Timeline, fitter, floor_mm: float | None, say=None,
                      duration_s: float = DURATION_S) -> Experiment:
    """The experiment that best separates the members of the look-alike ``step`` (a stepwise Step).

    ``tl``: all logs (the band and the workspace come from them); ``fitter`` gives the lead-in, the
    horizons and the reference key (the diagnosis's own scoring).
    """
    say = say or (lambda msg: None)
    members = list(step.effects)
    models = [step.member_fits[m].model for m in members]
    band = spin_band(tl)
    places, radius = placements(tl)
    shapes = candidates(band, duration_s, stops=any_force(members, models))
    tried = [(name, c, e) for name, c in places for e in shapes]  # every excitation on every placement
    dt = tl.dt_s
    n = int(round(duration_s / dt))
    freq = np.stack([e.freq_hz(np.arange(n) * dt) for _, _, e in tried])  # (K, n)
    paths = np.stack([circle_points(c, radius) for _, c, _ in tried])  # (K, N, 3)
    start = np.stack([np.asarray(c) + [radius, 0.0, 0.0] for _, c, _ in tried])  # (K, 3)
    logs = [simulate(jm, freq, dt, paths, start) for jm in models]  # per member: (u (K, n, 3), seen (K, n, 3))
    timelines = [_timeline(u, seen, dt) for u, seen in logs]
    sep = np.full(len(tried), np.inf)
    for a, truth in enumerate(timelines):
        starts = truth.window_starts(fitter.lead, 0.6, rows=fitter.lead + 1, measured_start=False)[::2]
        for b, jm in enumerate(models):
            if a == b:
                continue
            ev = jm.evaluate(truth, starts, fitter.lead, fitter.steps)
            ok = np.logical_and.reduce([r["valid"] for r in ev.values()])
            norm = np.mean([np.linalg.norm(np.nan_to_num(r["err"]), axis=1) for r in ev.values()], axis=0)
            norm = np.where(ok, norm, np.nan)
            per = np.array([np.nanmean(norm[truth.log[starts] == k]) for k in range(len(tried))])
            sep = np.minimum(sep, np.nan_to_num(per, nan=0.0))
    best = int(np.argmax(sep))
    central = np.array([i for i, (name, _, _) in enumerate(tried) if name == "centre"])
    at_centre = int(central[np.argmax(sep[central])])
    if sep[best] < PLACE_GAIN * sep[at_centre]:
        best = at_centre
    record = [Tried(excitation=e.describe(), separation_mm=float(s), place=name) for (name, _, e), s in zip(tried, sep)]
    place, center, shape = tried[best]
    chosen = replace(shape, duration_s=sized_duration(float(sep[best]), floor_mm, duration_s))
    say(f"experiment: {chosen.describe()} on the circle at the workspace's {place}: the members' predictions "
        f"differ by {sep[best]:.2f} mm"
        + (f" ({sep[best] / floor_mm:.1f}x the noise floor)" if floor_mm else "")
        + f"; {chosen.duration_s:.0f} s long")
    return Experiment(members=members, excitation=chosen, dt_s=dt, center_mm=[float(x) for x in center],
                      radius_mm=float(radius), place=place, separation_mm=float(sep[best]), floor_mm=floor_mm,
                      tried=record)


def any_force(members: list, models: list) -> bool:
    """Whether a member of the group is a force effect: only then does the design try stop-and-go schedules.

    At rest only a force moves the swimmer (a flow pushes it, a drag does not), so stops tell forces apart. An
    input or a sensor effect (a lag, a latency) has nothing to act on at rest but the start from it, a regime
    no log showed, where the baseline's own start-up is untested: on the plant FMU a stop-and-go experiment
    for a latency / lag pair shifted the latency's fit by 15 % and left the pair tied.
    """
    return any(e.kind == "force" for name, jm in zip(members, models) for e in jm.effects if e.name == name)


def sized_duration(separation_mm: float, floor_mm: float | None, base_s: float = DURATION_S) -> float:
    """How long [s] an experiment whose members' predictions differ by ``separation_mm`` (mean over its windows)
    must last for that to show against a noise floor ``floor_mm`` [mm]: a paired test's t grows with the square
    root of the windows, so ``base_s`` x (:data:`SEPARATION_TARGET` x floor / separation)^2, at least ``base_s``
    and at most :data:`MAX_DURATION_S` (``base_s`` when there is no floor)."""
    if not floor_mm or floor_mm <= 0 or not np.isfinite(separation_mm):
        return float(base_s)
    if separation_mm <= 0:
        return float(max(base_s, MAX_DURATION_S))
    need = base_s * (SEPARATION_TARGET * floor_mm / separation_mm) ** 2
    return float(min(max(need, base_s), max(base_s, MAX_DURATION_S)))


def spin_band(tl: Timeline) -> tuple[float, float]:
    """(low, high) [Hz]: the :data:`BAND_PERCENTILES` of the logged spin rates (the rig's proven range)."""
    f = np.linalg.norm(tl.u, axis=1)
    f = f[np.isfinite(f) & (f > 0.5)]
    if len(f) == 0:
        return 4.0, 16.0
    lo, hi = np.percentile(f, BAND_PERCENTILES)
    return float(lo), float(max(hi, lo + 1.0))


def workspace(tl: Timeline) -> tuple[np.ndarray, float]:
    """(centre (3,) [mm], radius [mm]) of a horizontal circle within the measured positions' spread."""
    p = tl.p[np.all(np.isfinite(tl.p), axis=1)]
    center = np.median(p, axis=0)
    spread = np.percentile(np.linalg.norm(p[:, :2] - center[:2], axis=1), 90) if len(p) else 2 * RADIUS_MM[1]
    return center, float(np.clip(0.5 * spread, *RADIUS_MM))


def placements(tl: Timeline) -> tuple[list, float]:
    """([(name, centre (3,) [mm])], radius [mm]): where the experiment's circle may go.

    The circle of :func:`workspace` at its centre ("centre"), then moved along each axis to either side of
    the box the logs visited (their positions' :data:`BOX_PERCENTILES`): horizontally until the circle
    touches the box ("-x", "+x", "-y", "+y"), vertically to the box's floor or ceiling ("-z", "+z"). A side
    the circle cannot move toward (the box narrower than the circle, or the centre already there) is left out.
    Every circle stays inside the box: the centre is moved in from a side it would cross, and the radius is at
    most half the box's narrower horizontal side (:data:`RADIUS_MM`'s least at the smallest).
    """
    center, radius = workspace(tl)
    p = tl.p[np.all(np.isfinite(tl.p), axis=1)]
    if len(p) == 0:
        return [("centre", center)], radius
    lo, hi = np.percentile(p, BOX_PERCENTILES, axis=0)
    radius = float(max(min(radius, 0.5 * min(hi[:2] - lo[:2])), RADIUS_MM[0]))
    center = _inside(center, lo, hi, radius)  # the median of logs that dwell near a wall lies near it
    out = [("centre", center)]
    for axis in range(3):
        reach = 0.0 if axis == 2 else radius  # how far the circle reaches from its centre along the axis
        for sign, edge in ((-1, lo[axis] + reach), (+1, hi[axis] - reach)):
            if sign * (edge - center[axis]) <= PATH_DS_MM:
                continue
            c = np.array(center, dtype=float)
            c[axis] = edge
            out.append((("-" if sign < 0 else "+") + "xyz"[axis], c))
    return out, radius


def _inside(center, lo, hi, radius_mm: float) -> np.ndarray:
    """``center`` (3,) [mm] moved horizontally so that a circle of ``radius_mm`` about it stays inside the box
    ``lo``..``hi`` (3,) [mm] (about the box's middle along an axis narrower than the circle); its height, a
    median of the positions, is inside already."""
    c = np.array(center, dtype=float)
    for axis in (0, 1):
        a, b = lo[axis] + radius_mm, hi[axis] - radius_mm
        c[axis] = np.clip(c[axis], a, b) if a <= b else 0.5 * (lo[axis] + hi[axis])
    return c


def circle_points(center, radius_mm: float) -> np.ndarray:
    """(N, 3) [mm] points of a horizontal circle, counter-clockwise, :data:`PATH_DS_MM` apart."""
    n = max(int(2 * np.pi * radius_mm / PATH_DS_MM), 16)
    th = 2 * np.pi * np.arange(n) / n
    return np.asarray(center) + radius_mm * np.stack([np.cos(th), np.sin(th), 0 * th], axis=1)


def simulate(jm, freq: np.ndarray, dt_s: float, path: np.ndarray, start_mm) -> tuple[np.ndarray, np.ndarray]:
    """A fitted model in closed loop under K spin-rate schedules at once.

    Args:
        jm: a JointModel (host, force, input and sensor effects).
        freq: (K, n) spin rate [Hz] per control period.
        path: (N, 3) [mm] closed path the pure pursuit follows, or (K, N, 3) one per schedule; start_mm (3,) or
            (K, 3) the start at rest.
    Returns:
        (u (K, n, 3) logged commands [Hz], seen (K, n, 3) what the camera logs [mm], no noise).
    """
    k, n = freq.shape
    x = np.zeros((6, k))
    x[:3] = np.broadcast_to(np.asarray(start_mm, dtype=float), (k, 3)).T
    path = np.broadcast_to(path, (k, *path.shape[-2:]))
    rows = np.arange(k)
    u = np.zeros((n, k, 3))
    pos = np.empty((n + 1, k, 3))
    pos[0] = x[:3].T
    ahead = int(round(LOOKAHEAD_MM / PATH_DS_MM))
    window = max(1, int(round(INPUT_WINDOW_S / dt_s)))
    prm = jm.prm
    prev = None
    for i in range(n):
        here = x[:3].T
        d = ((path - here[:, None]) ** 2).sum(-1)  # (K, N)
        target = path[rows, (d.argmin(1) + ahead) % path.shape[1]]
        to = target - here
        u[i] = freq[:, i, None] * to / np.maximum(np.linalg.norm(to, axis=1, keepdims=True), 1e-9)
        ue = _effective(jm, u[max(0, i - window + 1): i + 1], dt_s, prm)
        ut = np.ascontiguousarray(ue.T)
        if jm._held:
            x = jm.host.predict_t(x, ut, dt_s, ut if prev is None else prev)
        else:
            x = jm._step(x, ut)
        prev = ut
        pos[i + 1] = x[:3].T
    traj = pos.transpose(1, 0, 2)  # (K, n + 1, 3)
    for effect in jm.sensors:
        own = {q.name: prm[f"{effect.name}.{q.name}"] for q in effect.params}
        traj = effect.transform(traj, dt_s, own)
    return u.transpose(1, 0, 2), traj[:, :n]


def _effective(jm, history: np.ndarray, dt_s: float, prm: dict) -> np.ndarray:
    """(K, 3) the command the swimmer follows now: the input effects on the recent ``history`` (m, K, 3)."""
    if not jm.inputs:
        return history[-1]
    out = np.empty(history.shape[1:])
    for j in range(history.shape[1]):
        seq = history[:, j]
        for effect in jm.inputs:
            seq = effect.transform(seq, dt_s, {q.name: prm[f"{effect.name}.{q.name}"] for q in effect.params})
        out[j] = seq[-1]
    return out


def _timeline(u: np.ndarray, seen: np.ndarray, dt_s: float) -> Timeline:
    """One Timeline of K noiseless synthetic logs (u, seen: (K, n, 3))."""
    k, n = u.shape[:2]
    t = np.arange(n) * dt_s
    none = np.zeros(n, dtype=bool)
    logs = [Log(path=f"experiment_{j}", t_s=t, omega_hz=u[j], p_mm=seen[j], gap=none, repeat=none, outlier=none)
            for j in range(k)]
    return Timeline.from_dataset(Dataset.from_logs(logs))
