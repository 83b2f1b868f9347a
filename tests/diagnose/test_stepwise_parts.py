"""The parts of the stepwise search: the naming gates at their edges, look-alike evidence, excitations, the
experiment's closed loop, and the command shaper that applies a designed excitation."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.contract.plugins import lookup
from cosim_plugins.diagnose.excitation import Excitation, SpinSchedule, candidates
from cosim_plugins.diagnose.experiment import circle_points, simulate
from cosim_plugins.diagnose.lookalike import predictions_apart
from cosim_plugins.diagnose.verdict import MIN_EXPLAINED, MIN_REDUCTION, MIN_T, passes
from cosim_plugins.identify.joint import JointModel

KEY = "1.0"


def _entry(reduction, t, left_mm, identifiable=True):
    return {"reduction": reduction, "t_stat": t, "rollout_mm": {KEY: left_mm}, "identifiable": identifiable}


@pytest.mark.parametrize("reduction, t, left, floor, named", [
    (MIN_REDUCTION, MIN_T, 0.5, 0.1, True),  # every gate met exactly
    (MIN_REDUCTION - 1e-6, 5.0, 0.5, 0.1, False),  # the drop just short
    (0.5, MIN_T - 1e-6, 0.5, 0.1, False),  # not significant
    (0.2, 5.0, 0.8, 0.1, False),  # 1.0 -> 0.8 mm removes 0.2 / 0.9 = 22 % of the excess: short of 25 %
    (0.2, 5.0, 0.77, 0.1, True),  # 0.23 / 0.9 = 26 % of the excess
    (0.2, 5.0, 0.8, None, True),  # no floor: the share is not asked
])
def test_naming_gates_at_their_edges(reduction, t, left, floor, named):
    assert MIN_EXPLAINED == 0.25
    assert passes(_entry(reduction, t, left), 1.0, floor, KEY) is named


def test_an_unidentifiable_candidate_is_never_named():
    assert not passes(_entry(0.9, 50.0, 0.1, identifiable=False), 1.0, 0.05, KEY)


def test_predictions_apart_cancels_the_measurement():
    rng = np.random.default_rng(0)
    meas = rng.normal(size=(50, 3))
    a = {KEY: {"valid": np.ones(50, bool), "err": meas + [0.3, 0.0, 0.0]}}
    b = {KEY: {"valid": np.ones(50, bool), "err": meas - [0.0, 0.4, 0.0]}}
    assert predictions_apart(a, b) == pytest.approx(0.5)


def test_look_alikes_are_told_apart_by_the_log_where_their_predictions_differ():
    """Four logs where two members predict alike and one (an experiment) where they differ by 0.4 mm: pooled, the
    distance is 0.08 mm, under half a 0.2 mm floor; log by log it is the experiment's 0.4 mm. Made 160 s long (four
    times the 40 s a distance counts as it is over), the experiment's 0.4 mm weigh twice as much."""
    from types import SimpleNamespace

    from cosim_plugins.diagnose.lookalike import evidence_of

    logs = np.repeat(np.arange(5), 40)
    apart = np.where(logs == 4, 0.4, 0.0)[:, None] * [1.0, 0.0, 0.0]
    ev = {KEY: {"valid": np.ones(200, bool), "err": np.zeros((200, 3))}}
    lead, rival = SimpleNamespace(ev=ev), SimpleNamespace(ev={KEY: {"valid": ev[KEY]["valid"], "err": apart}})
    tl = SimpleNamespace(log=logs, dt_s=0.25)  # 40 rows: each log 10 s long
    fitter = SimpleNamespace(tte=tl, test_starts=np.arange(200), paired_t=lambda a, b: 0.0,
                             paired_t_horizons=lambda a, b: 0.0)
    out = evidence_of(fitter, lead, rival, KEY)
    assert out["differ_mm"] == pytest.approx(0.08) and out["differ_log_mm"] == pytest.approx(0.4)
    assert out["differ_weighted_mm"] == pytest.approx(0.4)  # shorter than 40 s: as it is
    tl.log = np.concatenate([logs, np.full(600, 4)])  # the experiment's log 160 s long, its windows the same
    assert evidence_of(fitter, lead, rival, KEY)["differ_weighted_mm"] == pytest.approx(0.8)


def test_excitations_stay_in_the_band():
    t = np.arange(2000) * 0.02
    for e in candidates((4.0, 16.0), 40.0):
        f = e.freq_hz(t)
        moving = f[f > 0] if e.kind == "stop" else f  # stop and go rests at 0 Hz, and moves within the band
        assert moving.min() >= 4.0 - 1e-9 and moving.max() <= 16.0 + 1e-9, e.describe()
        assert e.kind != "stop" or 0.3 < np.mean(f == 0.0) < 0.7, e.describe()  # half the time at rest
    steps = Excitation("steps", 4.0, 16.0, 40.0, period_s=1.0).freq_hz(t)
    assert steps[0] == 16.0 and steps[25] == 4.0 and steps[50] == 16.0  # half a period each
    with pytest.raises(ValueError, match="kind"):
        Excitation("sawtooth", 4.0, 16.0, 40.0)


def test_spin_schedule_keeps_the_direction_and_sets_the_rate():
    shaper = SpinSchedule()
    shaper.setup({"kind": "steps", "f_lo_hz": 5.0, "f_hi_hz": 10.0, "period_s": 2.0, "dt": 0.02}, None)
    out = shaper.step(1.5, {"omega": np.array([0.0, 3.0, 4.0])})["omega"]  # second half period: 5 Hz
    assert np.allclose(out, 2 * np.pi * 5.0 * np.array([0.0, 0.6, 0.8]))
    assert np.allclose(shaper.step(0.0, {"omega": np.zeros(3)})["omega"], 0.0)
    assert lookup("component", "diagnose.spin_schedule") is SpinSchedule


def test_the_design_loop_keeps_a_model_on_its_circle():
    """The experiment's closed loop: the physical model under a stepped spin rate follows the circle."""
    model = lookup("model", "physical")()
    model.dt_s = 0.02
    jm = JointModel(model)
    path = circle_points(np.zeros(3), 25.0)
    freq = np.stack([Excitation("steps", 4.0, 12.0, 20.0, period_s=2.0).freq_hz(np.arange(1000) * 0.02)])
    u, seen = simulate(jm, freq, 0.02, path, [25.0, 0.0, 0.0])
    assert u.shape == (1, 1000, 3) and seen.shape == (1, 1000, 3)
    assert np.allclose(np.linalg.norm(u[0], axis=1), freq[0])  # the spin rate is the schedule's
    radius = np.linalg.norm(seen[0, 200:, :2], axis=1)
    assert np.all(np.abs(radius - 25.0) < 6.0) and np.all(np.abs(seen[0, 200:, 2]) < 6.0)
    angle = np.unwrap(np.arctan2(seen[0, :, 1], seen[0, :, 0]))
    assert angle[-1] - angle[0] > np.pi  # it travels along the circle


def test_an_experiment_lasts_long_enough_for_its_separation_to_show():
    """A separation at the target needs the base length; half of it four times as many windows; the length is
    capped, and without a floor stays the base."""
    from cosim_plugins.diagnose.experiment import DURATION_S, MAX_DURATION_S, SEPARATION_TARGET, sized_duration

    floor = 0.2
    assert sized_duration(SEPARATION_TARGET * floor * 3.0, floor) == DURATION_S
    assert sized_duration(SEPARATION_TARGET * floor, floor) == pytest.approx(DURATION_S)
    assert sized_duration(SEPARATION_TARGET * floor / 2.0, floor) == pytest.approx(4.0 * DURATION_S)
    assert sized_duration(SEPARATION_TARGET * floor / 100.0, floor) == MAX_DURATION_S
    assert sized_duration(0.0, floor) == MAX_DURATION_S
    assert sized_duration(0.01, None) == DURATION_S


class _Quick:
    """A fitter whose quick fits lose what the open-loop polish gave the model before (``POLISH`` mm): each
    candidate effect takes ``gain`` [mm] off the error, quick or full."""

    POLISH = 0.3

    def __init__(self, gain: dict):
        self.gain = gain

    def _fit(self, err):
        from cosim_plugins.diagnose.stepwise import Fit

        return Fit(model=None, ev={}, summary={"rollout_mm": {"1.0": err}})

    def with_effects(self, before, effects, quick=False):
        lost = self.POLISH if quick else 0.0
        return self._fit(before.error("1.0") + lost - sum(self.gain[e.name] for e in effects)), True

    def with_each(self, before, effects, quick=False):  # None: before refitted with nothing added
        return [self.with_effects(before, [e] if e is not None else [], quick) for e in effects]

    def entry(self, effect, fit, identifiable, before):
        err = fit.error("1.0")
        return {"effect": effect.name, "reduction": 1.0 - err / before.error("1.0"), "t_stat": 5.0,
                "identifiable": identifiable, "rollout_mm": {"1.0": err}}


def test_a_quick_screen_is_measured_against_the_model_before_refitted_the_same_quick_way():
    """The candidate that lowers the error by 0.2 mm reaches the full fit although its quick fit, without the
    polish, ends above the polished model before; the others keep their quick entries."""
    from types import SimpleNamespace

    from cosim_plugins.diagnose.stepwise import SCREEN_KEEP, rank

    gain = {"lag": 0.2, "flow": 0.0, "drag": 0.0, "wall": 0.0, "latency": 0.0}
    assert len(gain) > SCREEN_KEEP
    fitter = _Quick(gain)
    before = fitter._fit(1.0)
    entries, _ = rank(fitter, before, [SimpleNamespace(name=n) for n in gain], "1.0", screen=True)
    lag = next(e for e in entries if e["effect"] == "lag")
    assert entries[0] is lag and not lag.get("screened") and lag["reduction"] == pytest.approx(0.2)
    assert all(e.get("screened") for e in entries if e["effect"] != "lag")


def test_when_no_quick_fit_reaches_the_screen_the_best_still_get_the_full_fit():
    """Quick fits that see none of what the full fits find (an actuation lag given a quadratic drag: 0.0 % by its
    quick fit, 81 % by its true form): the SCREEN_KEEP best are refitted in full all the same."""
    from types import SimpleNamespace

    from cosim_plugins.diagnose.stepwise import SCREEN_KEEP, rank

    class Blind(_Quick):
        def with_effects(self, before, effects, quick=False):
            if quick:
                return self._fit(before.error("1.0") + self.POLISH), True
            return super().with_effects(before, effects)

    gain = {"lag": 0.3, "flow": 0.0, "drag": 0.0, "wall": 0.0, "latency": 0.0}
    entries, _ = rank(Blind(gain), Blind(gain)._fit(1.0), [SimpleNamespace(name=n) for n in gain], "1.0",
                      screen=True)
    assert entries[0]["effect"] == "lag" and entries[0]["reduction"] == pytest.approx(0.3)
    assert sum(not e.get("screened") for e in entries) == SCREEN_KEEP


def test_a_candidate_whose_quick_fit_changes_nothing_still_gets_the_full_fit():
    """A step-out's quick fit leaves f_so above the band (not identifiable) while its full fit, given a gradient
    force, lowers the error by 77 %: it is refitted in full beside the three best quick fits, and leads."""
    from types import SimpleNamespace

    from cosim_plugins.diagnose.stepwise import SCREEN_KEEP, rank

    class Stuck(_Quick):
        def with_effects(self, before, effects, quick=False):
            fit, _ = super().with_effects(before, effects, quick)
            return fit, not (quick and any(e.name == "step_out" for e in effects))

    gain = {"step_out": 0.77, "flow": 0.1, "drag": 0.08, "wall": 0.06, "lag": 0.05}
    entries, _ = rank(Stuck(gain), Stuck(gain)._fit(1.0), [SimpleNamespace(name=n) for n in gain], "1.0",
                      screen=True)
    assert entries[0]["effect"] == "step_out" and entries[0]["identifiable"]
    assert entries[0]["reduction"] == pytest.approx(0.77)
    assert {e["effect"] for e in entries if not e.get("screened")} == {"step_out", "flow", "drag", "wall"}
    assert SCREEN_KEEP == 3


def test_a_candidate_whose_quick_fit_ends_far_above_its_reference_still_gets_the_full_fit():
    """A step-out's quick fit beside a uniform flow standing in for a shear ended 25 % above the quick reference
    while its full fit gained 23 %: a quick fit that loses SCREEN_FAILED or more failed (the effect at its null
    value is the reference), so it is refitted in full beside the three best; one that loses less is not."""
    from types import SimpleNamespace

    from cosim_plugins.diagnose.stepwise import SCREEN_FAILED, rank

    class Failed(_Quick):
        def with_effects(self, before, effects, quick=False):
            fit, ok = super().with_effects(before, effects, quick)
            if quick and any(e.name in ("step_out", "gradient") for e in effects):
                loss = {"step_out": 0.25, "gradient": 0.5 * SCREEN_FAILED}[effects[0].name]
                return self._fit((before.error("1.0") + self.POLISH) * (1.0 + loss)), ok
            return fit, ok

    gain = {"step_out": 0.23, "flow": 0.1, "drag": 0.08, "wall": 0.06, "lag": 0.05, "gradient": 0.04}
    entries, _ = rank(Failed(gain), Failed(gain)._fit(1.0), [SimpleNamespace(name=n) for n in gain], "1.0",
                      screen=True)
    assert entries[0]["effect"] == "step_out" and entries[0]["reduction"] == pytest.approx(0.23)
    assert {e["effect"] for e in entries if not e.get("screened")} == {"step_out", "flow", "drag", "wall"}


def test_the_look_alikes_of_a_candidate_about_to_be_named_get_their_full_fit():
    """A latency fully fitted leads a round in which the lag had only its quick fit: the lag gets the full fit
    before the group test, and leads once it does better; a flow's quick entry stays as it was."""
    from types import SimpleNamespace

    from cosim_plugins.diagnose.stepwise import _full_family

    fitter = _Quick({"sensor_latency": 0.2, "actuation_lag": 0.25, "background_flow": 0.0})
    before = fitter._fit(1.0)
    quick = {"reduction": -0.06, "t_stat": -1.0, "identifiable": True, "screened": True, "rollout_mm": {"1.0": 1.06}}
    entries = [{"effect": "sensor_latency", "reduction": 0.2, "t_stat": 5.0, "identifiable": True,
                "rollout_mm": {"1.0": 0.8}},
               {"effect": "background_flow", **quick}, {"effect": "actuation_lag", **quick}]
    by_name = {n: SimpleNamespace(name=n) for n in fitter.gain}
    fits = {}
    entries, best = _full_family(fitter, before, entries, fits, entries[0], by_name, "1.0", lambda m: None)
    assert best["effect"] == "actuation_lag" and best["reduction"] == pytest.approx(0.25) and "actuation_lag" in fits
    assert [e["effect"] for e in entries] == ["actuation_lag", "sensor_latency", "background_flow"]
    assert entries[-1].get("screened")


class _Rounds(_Quick):
    """A :class:`_Quick` fitter that records the effects each fit adds; effects in ``hidden`` act nowhere the
    logs go (not identifiable); a refit keeps a model's error."""

    POLISH = 0.0

    def __init__(self, gain: dict, hidden: set):
        super().__init__(gain)
        self.hidden, self.fitted = hidden, []

    def _fit(self, err):
        from types import SimpleNamespace

        from cosim_plugins.diagnose.stepwise import Fit

        return Fit(model=SimpleNamespace(err=err), ev={}, summary={"rollout_mm": {"1.0": err}})

    def with_effects(self, before, effects, quick=False):
        self.fitted += [e.name for e in effects]
        fit, _ = super().with_effects(before, effects, quick)
        return fit, not any(e.name in self.hidden for e in effects)

    def refit(self, model):
        return self._fit(model.err)


def test_a_candidate_not_identifiable_in_the_first_round_is_refitted_given_the_first_choice():
    """A step-out fitted beside a missing flow runs to f_so = 100 Hz, where it changes nothing (not
    identifiable); given the flow it is found. Round 2 refits it, and both are named."""
    from types import SimpleNamespace

    from cosim_plugins.diagnose.stepwise import rank, select

    class Beside(_Rounds):
        def with_effects(self, before, effects, quick=False):
            fit, seen = super().with_effects(before, effects, quick)
            return fit, seen or before.error("1.0") < 1.0  # identifiable once the flow is in

        def without(self, final, keep):
            return self._fit(1.0 - sum(self.gain[e.name] for e in keep))

    names = ("flow", "step_out", "drag", "wall", "lag")
    fitter = Beside({"flow": 0.5, "step_out": 0.3, "drag": 0.0, "wall": 0.0, "lag": 0.0}, hidden={"step_out"})
    effects = [SimpleNamespace(name=n) for n in names]
    start = fitter._fit(1.0)
    first = rank(fitter, start, effects, "1.0")
    assert not next(e for e in first[0] if e["effect"] == "step_out")["identifiable"]
    sel = select(fitter, start, effects, first, 3, {"1.0": 0.1}, "1.0")
    assert [s.effects for s in sel.steps] == [["flow"], ["step_out"]]
    again = next(e for e in sel.rounds[1] if e["effect"] == "step_out")
    assert again["identifiable"] and again["reduction"] == pytest.approx(0.6)


class _Sets:
    """A fitter whose model is the set of effects in it, with a held-out error [mm] per set (``errors``, missing
    sets keep the error of the set without their last effect); t = 5 for any drop."""

    def __init__(self, errors: dict):
        self.errors = {frozenset(k): v for k, v in errors.items()}
        self.fitted = []

    def _fit(self, effects):
        from types import SimpleNamespace

        from cosim_plugins.diagnose.stepwise import Fit

        effects = frozenset(effects)
        err = self.errors.get(effects)
        if err is None:
            err = min(self.errors.get(effects - {e}, 1.0) for e in effects) if effects else 1.0
        return Fit(model=SimpleNamespace(effects=effects), ev={}, summary={"rollout_mm": {"1.0": err}})

    def with_effects(self, before, effects, quick=False):
        self.fitted.append((tuple(sorted(e.name for e in effects)), quick))
        return self._fit(before.model.effects | {e.name for e in effects}), True

    def with_each(self, before, effects, quick=False):
        return [self.with_effects(before, [e] if e is not None else [], quick) for e in effects]

    def refit(self, model):
        return self._fit(model.effects)

    added = ()

    def beside(self, effects):
        import copy

        other = copy.copy(self)
        other.added = (*self.added, *effects)
        return other

    def without(self, final, keep):
        return self._fit({e.name for e in (*self.added, *keep)})

    def entry(self, effect, fit, identifiable, before):
        err = fit.error("1.0")
        drop = 1.0 - err / before.error("1.0")
        return {"effect": effect.name, "reduction": drop, "t_stat": 5.0 if drop > 0 else 0.0,
                "identifiable": identifiable, "rollout_mm": {"1.0": err}, "params": {}}


@pytest.mark.parametrize("pair_error, named", [(0.3, ["flow", "drag"]), (0.93, [])])
def test_two_effects_that_show_only_together_are_found_by_the_look_ahead(pair_error, named):
    """A flow alone lowers the error by 5 % and a drag alone by nothing, together by 70 %: the flow is taken
    tentatively, the drag passes given it, the two earn their places together, and the flow's drop is reported
    given the drag (with its drop alone). When the pair explains little more, the tentative flow goes again."""
    from types import SimpleNamespace

    from cosim_plugins.diagnose.stepwise import rank, select

    names = ("flow", "drag", "wall", "lag", "aniso")
    fitter = _Sets({(): 1.0, ("flow",): 0.95, ("drag",): 1.0, ("flow", "drag"): pair_error})
    effects = [SimpleNamespace(name=n) for n in names]
    start = fitter._fit(())
    first = rank(fitter, start, effects, "1.0")
    sel = select(fitter, start, effects, first, 3, {"1.0": 0.25}, "1.0")
    assert [s.effects[0] for s in sel.steps] == named
    if not named:
        assert sel.stop == "none_passes" and sel.final.error("1.0") == 1.0
        return
    flow, drag = sel.steps
    assert flow.alone["reduction"] == pytest.approx(0.05) and flow.given == ["drag"]
    assert flow.entry["reduction"] == pytest.approx(0.7) and flow.before.error("1.0") == 1.0
    assert drag.entry["reduction"] == pytest.approx(1.0 - 0.3 / 0.95) and drag.alone is None
    assert sel.final.error("1.0") == pytest.approx(0.3) and sel.stop == "noise_floor"
    round2 = fitter.fitted[len(names):len(names) + len(names) - 1]  # after the tentative step: full fits, no screen
    assert sorted(round2) == sorted(((n,), False) for n in names if n != "flow")


def test_a_confirmed_look_ahead_does_not_weigh_a_look_alike_already_chosen_beside_it():
    """A latency taken tentatively and confirmed given an actuation lag: its look-alikes are weighed in its place,
    but the lag, already in the model as the other step, is not refitted there (it would stand in it twice)."""
    from types import SimpleNamespace

    from cosim_plugins.diagnose.stepwise import Step, _given_family

    fitter = _Sets({(): 1.0, ("actuation_lag",): 0.8, ("actuation_lag", "sensor_latency"): 0.3})
    by_name = {n: SimpleNamespace(name=n) for n in ("actuation_lag", "sensor_latency", "heading_lag")}
    before = fitter._fit({"actuation_lag"})
    both = fitter._fit({"actuation_lag", "sensor_latency"})
    entry = fitter.entry(by_name["sensor_latency"], both, True, before)
    step = Step(effects=["sensor_latency"], entry=entry, fit=both, before=before, given=["actuation_lag"])
    out = _given_family(fitter, step, by_name, 0.1, "1.0", lambda msg: None)
    assert fitter.fitted == [(("heading_lag",), False)]
    assert out.effects == ["sensor_latency"] and out.entry["reduction"] == pytest.approx(1.0 - 0.3 / 0.8)


def test_a_look_ahead_whose_pair_is_not_confirmed_keeps_the_partner_alone():
    """A flow taken tentatively, a drag that passes given it, but the flow no longer earns its place once the drag
    is in (the model refitted without the flow, from the pair's solution, does about as well): the flow goes. The
    drag so refitted lowers the baseline's error by 38 % (its own first-round fit, 3 %, had ended in a poorer
    basin): it is named alone, its drop measured against the baseline."""
    from types import SimpleNamespace

    from cosim_plugins.diagnose.stepwise import Fit, rank, select

    names = ("flow", "drag", "wall", "lag", "aniso")
    fitter = _Sets({(): 1.0, ("flow",): 0.95, ("drag",): 0.97, ("flow", "drag"): 0.6})
    fitter.without = lambda final, keep: Fit(model=SimpleNamespace(effects=frozenset(e.name for e in keep)), ev={},
                                             summary={"rollout_mm": {"1.0": 0.62}})
    effects = [SimpleNamespace(name=n) for n in names]
    start = fitter._fit(())
    first = rank(fitter, start, effects, "1.0")
    sel = select(fitter, start, effects, first, 3, {"1.0": 0.25}, "1.0")
    assert [s.effects for s in sel.steps] == [["drag"]] and sel.stop == "none_passes"
    drag, = sel.steps
    assert drag.before.error("1.0") == 1.0 and drag.entry["reduction"] == pytest.approx(0.38)
    assert sel.final.error("1.0") == pytest.approx(0.62)


def test_the_effect_left_after_a_backward_drop_is_measured_again_without_the_dropped_one():
    """A quadratic drag chosen first (1.0 -> 0.4 mm) and a step-out given it (-> 0.2 mm); the drag alone, refitted
    from the pair's solution, reaches 0.21 mm, so the step-out goes. The drag's drop is then the model left
    against the baseline (79 %, from 1.0 to 0.21 mm), no longer its first round's 60 %."""
    from types import SimpleNamespace

    from cosim_plugins.diagnose.stepwise import rank, select

    class FromThePair(_Sets):
        def without(self, final, keep):
            fit = self._fit({e.name for e in keep})
            if fit.model.effects == {"quadratic_drag"}:  # the drag's better basin, from the pair's solution
                fit.summary["rollout_mm"]["1.0"] = 0.21
            return fit

    names = ("quadratic_drag", "step_out", "wall_drag")
    fitter = FromThePair({(): 1.0, ("quadratic_drag",): 0.4, ("step_out",): 0.99, ("quadratic_drag", "step_out"): 0.2})
    effects = [SimpleNamespace(name=n) for n in names]
    start = fitter._fit(())
    said = []
    sel = select(fitter, start, effects, rank(fitter, start, effects, "1.0"), 3, {"1.0": 0.05}, "1.0", said.append)
    assert [d["effect"] for d in sel.dropped] == ["step_out"] and sel.chosen == ["quadratic_drag"]
    assert any(m.startswith("backward: step_out dropped once the others are in") for m in said)
    drag, = sel.steps
    assert drag.given == [] and drag.before.error("1.0") == 1.0 and drag.fit.error("1.0") == pytest.approx(0.21)
    assert drag.entry["reduction"] == pytest.approx(0.79) and sel.final.error("1.0") == pytest.approx(0.21)


@pytest.mark.parametrize("lookaheads", [2, 1])
def test_when_nothing_passes_given_the_first_look_ahead_the_next_hopeful_candidate_is_tried(lookaheads,
                                                                                           monkeypatch):
    """An anisotropic drag leads the first round (4.6 %) but nothing passes given it; a step-out (3.9 %) and a
    quadratic drag (0.3 %) lower the error by 86 % together. The step-out, taken tentatively next, lets the drag
    pass and both are named; with one look-ahead allowed nothing is named."""
    from types import SimpleNamespace

    from cosim_plugins.diagnose import stepwise

    monkeypatch.setattr(stepwise, "LOOKAHEADS", lookaheads)
    names = ("aniso", "step_out", "drag", "wall", "lag")
    fitter = _Sets({(): 1.0, ("aniso",): 0.954, ("step_out",): 0.961, ("drag",): 0.997,
                    ("step_out", "drag"): 0.14})
    effects = [SimpleNamespace(name=n) for n in names]
    start = fitter._fit(())
    first = stepwise.rank(fitter, start, effects, "1.0")
    sel = stepwise.select(fitter, start, effects, first, 3, {"1.0": 0.1}, "1.0")
    if lookaheads == 2:
        assert [s.effects[0] for s in sel.steps] == ["step_out", "drag"]
        assert sel.rounds_given == [[], ["aniso"], ["step_out"], ["step_out", "drag"]]
        step_out = sel.steps[0]
        assert step_out.alone["reduction"] == pytest.approx(0.039) and step_out.given == ["drag"]
        assert sel.final.error("1.0") == pytest.approx(0.14)
    else:
        assert sel.steps == [] and sel.rounds_given == [[], ["aniso"]]
        assert sel.stop == "none_passes" and sel.final.error("1.0") == 1.0


class _Told(_Sets):
    """A :class:`_Sets` fitter whose fits carry held-out errors (every window errs by the set's error along x), so
    the look-alike test can weigh them: t = +-5 for a gap of more than 2 % between two fits, else 0."""

    def __init__(self, errors: dict, windows: int = 40):
        from types import SimpleNamespace

        super().__init__(errors)
        self.test_starts = np.arange(windows)
        self.tte = SimpleNamespace(log=np.zeros(windows, int), dt_s=0.02)

    def _fit(self, effects):
        fit = super()._fit(effects)
        err = np.zeros((len(self.test_starts), 3))
        err[:, 0] = fit.error("1.0")
        fit.ev["1.0"] = {"valid": np.ones(len(err), bool), "err": err}
        return fit

    def paired_t(self, ref_ev, new_ev):
        ref, new = ref_ev["err"][0, 0], new_ev["err"][0, 0]
        return 0.0 if abs(ref - new) <= 0.02 * ref else 5.0 * np.sign(ref - new)

    def paired_t_horizons(self, ref, new):
        return self.paired_t(ref.ev["1.0"], new.ev["1.0"])


def test_a_look_alike_group_is_weighed_again_given_the_effects_chosen_after_it():
    """A latency and an actuation lag tie in the first round (0.75 mm each, beside a missing flow) and are declared
    a group, led by the latency; the flow is chosen given it. Given the flow, the lag leaves 0.14 mm and the latency
    0.25: the lag is named alone, the final model has it, and the flow's drop is measured again given it."""
    from types import SimpleNamespace

    from cosim_plugins.diagnose.stepwise import rank, select

    names = ("sensor_latency", "actuation_lag", "heading_lag", "background_flow")
    fitter = _Told({(): 1.0, ("sensor_latency",): 0.75, ("actuation_lag",): 0.752, ("heading_lag",): 0.9,
                    ("background_flow",): 0.77, ("sensor_latency", "background_flow"): 0.25,
                    ("actuation_lag", "background_flow"): 0.14, ("heading_lag", "background_flow"): 0.3})
    effects = [SimpleNamespace(name=n) for n in names]
    start = fitter._fit(())
    first = rank(fitter, start, effects, "1.0")
    sel = select(fitter, start, effects, first, 3, {"1.0": 0.1}, "1.0")
    assert sel.rounds[0][0]["effect"] == "sensor_latency"  # it led the first round's group
    assert [s.effects for s in sel.steps] == [["actuation_lag"], ["background_flow"]]
    lag, flow = sel.steps
    assert lag.given == ["background_flow"] and lag.entry["reduction"] == pytest.approx(1.0 - 0.14 / 0.77)
    assert flow.given == ["actuation_lag"] and flow.entry["reduction"] == pytest.approx(1.0 - 0.14 / 0.752)
    assert sel.final.model.effects == {"actuation_lag", "background_flow"}


@pytest.mark.parametrize("wall_with_drag, named", [(0.3, False), (0.6, True)])
def test_a_group_outside_the_look_alike_families_is_weighed_given_the_others(wall_with_drag, named):
    """A flow and a wall drag tie in the first round (a group outside the lag family), a quadratic drag is chosen
    given them. Weighed again given the drag: when the wall drag then leaves twice the flow's error, the flow is
    named alone; when the two still tie, the group keeps both members and a fit for each (the experiment that
    tells them apart is designed from those fits)."""
    from types import SimpleNamespace

    from cosim_plugins.diagnose.stepwise import rank, select

    names = ("background_flow", "wall_drag", "quadratic_drag")
    fitter = _Told({(): 1.0, ("background_flow",): 0.6, ("wall_drag",): 0.601, ("quadratic_drag",): 0.9,
                    ("background_flow", "quadratic_drag"): 0.3, ("wall_drag", "quadratic_drag"): wall_with_drag,
                    ("background_flow", "wall_drag"): 0.6, ("background_flow", "wall_drag", "quadratic_drag"): 0.3})
    effects = [SimpleNamespace(name=n) for n in names]
    start = fitter._fit(())
    sel = select(fitter, start, effects, rank(fitter, start, effects, "1.0"), 3, {"1.0": 0.1}, "1.0")
    if named:
        assert [s.effects for s in sel.steps] == [["background_flow"], ["quadratic_drag"]]
        flow = sel.steps[0]
        assert flow.given == ["quadratic_drag"] and flow.entry["reduction"] == pytest.approx(1.0 - 0.3 / 0.9)
        return
    assert [s.effects for s in sel.steps] == [["background_flow", "wall_drag"], ["quadratic_drag"]]
    assert set(sel.steps[0].member_fits) == {"background_flow", "wall_drag"}


@pytest.mark.parametrize("lag_with_form, named", [(0.14, True), (0.30, False)])
def test_a_look_alike_group_is_named_once_the_discovered_form_tells_its_members_apart(lag_with_form, named):
    """A latency and an actuation lag tie (0.75 mm each, beside a turning flow outside the library) and are
    declared a group, led by the latency. Given the discovered swirl, the lag leaves 0.14 mm and the latency 0.30:
    the lag is named alone, its drop given the form, and the model with the form takes it. When the two still
    leave the same error given the form, the group stays as declared."""
    from types import SimpleNamespace

    from cosim_plugins.diagnose.stepwise import groups_on_top, rank, select

    names = ("sensor_latency", "actuation_lag", "heading_lag")
    errors = {(): 1.0, ("sensor_latency",): 0.75, ("actuation_lag",): 0.752, ("heading_lag",): 0.9,
              ("swirl",): 0.7, ("sensor_latency", "swirl"): 0.30, ("actuation_lag", "swirl"): lag_with_form,
              ("heading_lag", "swirl"): 0.5}
    fitter = _Told(errors)
    effects = [SimpleNamespace(name=n) for n in names]
    start = fitter._fit(())
    sel = select(fitter, start, effects, rank(fitter, start, effects, "1.0"), 3, {"1.0": 0.1}, "1.0")
    assert [s.effects for s in sel.steps] == [["sensor_latency", "actuation_lag"]]
    on_top = _Told(errors)  # its models keep the form wherever it takes chosen effects out
    on_top.without = lambda final, keep: on_top._fit({"swirl", *(e.name for e in keep)})
    found = on_top._fit({"sensor_latency", "swirl"})
    said = []
    got, model = groups_on_top(on_top, sel, found, {e.name: e for e in effects}, 0.1, "1.0", said.append)
    if not named:
        assert got == [] and sel.steps[0].effects == ["sensor_latency", "actuation_lag"] and model is found
        assert said[-1] == "  given the discovered form, sensor_latency ~ actuation_lag stay a group"
        return
    step, = sel.steps
    assert got == [0] and step.effects == ["actuation_lag"] and step.given == ["discovered"]
    assert step.entry["reduction"] == pytest.approx(1.0 - 0.14 / 0.7) and step.before.error("1.0") == 0.7
    assert model.model.effects == {"actuation_lag", "swirl"} and step.fit is model


def _a_stand_in_gone(second: str, errors: dict):
    """(fitter, selection, effects by name): a uniform flow chosen first (1.0 -> 0.6 mm) and ``second`` given it
    (0.6 -> 0.4 mm; ``errors`` the other sets'), the flow then taken out as a stand-in (standin.stand_ins)."""
    from types import SimpleNamespace

    from cosim_plugins.diagnose.stepwise import rank, select

    fitter = _Told({(): 1.0, ("background_flow",): 0.6, ("background_flow", second): 0.4, **errors})
    effects = [SimpleNamespace(name=n) for n in ("background_flow", second)]
    by_name = {e.name: e for e in effects}
    start = fitter._fit(())
    sel = select(fitter, start, effects, rank(fitter, start, effects, "1.0"), 3, {"1.0": 0.1}, "1.0")
    assert sel.chosen == ["background_flow", second]
    sel.steps.pop(0)
    sel.final = fitter.without(sel.final, [by_name[second]])
    return fitter, sel, by_name


@pytest.mark.parametrize("force_alone, named", [(0.95, []), (0.65, ["gradient_force"])])
def test_an_effect_chosen_given_a_stand_in_is_measured_again_once_it_is_out(force_alone, named):
    """A uniform flow chosen first (1.0 -> 0.6 mm) and a gradient force given it (0.6 -> 0.4 mm); the flow then
    goes as a stand-in for a form outside the library. The force's drop given the flow says nothing of the force
    without it: measured again against the model without either, a force that lowers the error by 5 % is dropped
    (nothing is named), one that lowers it by 35 % stays, its drop given nothing."""
    from cosim_plugins.diagnose.stepwise import left_after_removal

    fitter, sel, by_name = _a_stand_in_gone("gradient_force", {("gradient_force",): force_alone})
    said = []
    left_after_removal(fitter, sel, by_name, 0.1, "1.0", said.append)
    assert sel.chosen == named
    if not named:
        assert sel.dropped[-1]["effect"] == "gradient_force" and sel.final.error("1.0") == 1.0
        assert said[-1].startswith("backward: gradient_force dropped once the others are in "
                                   "(it lowers the error by only 5%")
        return
    force, = sel.steps
    assert force.given == [] and force.entry["reduction"] == pytest.approx(0.35) and force.before.error("1.0") == 1.0


@pytest.mark.parametrize("force_with_form, kept", [(0.35, True), (0.69, False)])
def test_an_effect_left_once_a_stand_in_is_out_is_measured_given_the_form_that_took_its_place(force_with_form, kept):
    """A uniform flow chosen first (1.0 -> 0.6 mm) and a step-out given it (0.6 -> 0.4 mm); the flow goes as a
    stand-in for a shear, whose form is found on what is left (0.7 mm without the step-out). Alone the step-out
    lowers the error by 5 %; given the form it leaves ``force_with_form``: at 0.35 mm (50 %) it stays, its drop
    given the form, and the model left has no form in it; at 0.69 mm it is dropped."""
    from types import SimpleNamespace

    from cosim_plugins.diagnose.stepwise import left_after_removal

    fitter, sel, by_name = _a_stand_in_gone("step_out", {("step_out",): 0.95, ("shear",): 0.7,
                                                         ("shear", "step_out"): force_with_form})
    bare = sel.final
    found = fitter._fit({"shear", "step_out"})
    found.model.effects = [SimpleNamespace(name="shear")]  # the discovered form comes last
    left_after_removal(fitter, sel, by_name, 0.1, "1.0", lambda m: None, found)
    if not kept:
        assert sel.chosen == [] and sel.dropped[-1]["effect"] == "step_out" and sel.final.error("1.0") == 1.0
        return
    step, = sel.steps
    assert step.given == ["discovered"] and step.entry["reduction"] == pytest.approx(0.5)
    assert step.before.error("1.0") == 0.7 and sel.final is bare


@pytest.mark.parametrize("lag_with_form, dropped", [(0.31, True), (0.5, False)])
def test_an_effect_chosen_first_is_measured_again_given_those_chosen_on_top_of_the_form(lag_with_form, dropped):
    """A heading lag chosen first (1.0 -> 0.75 mm) beside a thrust varying with position; the discovered form holds
    the thrust (0.5 mm) and an actuation lag is chosen on top of both (0.3 mm). Given the form and the actuation lag
    without the heading lag the error is ``lag_with_form``: at 0.31 mm the heading lag adds 3 % and is dropped (the
    verdict's set is the actuation lag); at 0.5 mm it stays beside it."""
    from types import SimpleNamespace

    from cosim_plugins.diagnose.stepwise import given_later, rank, select

    errors = {(): 1.0, ("heading_lag",): 0.75, ("actuation_lag",): 0.9, ("heading_lag", "thrust"): 0.5,
              ("actuation_lag", "heading_lag", "thrust"): 0.3, ("actuation_lag", "thrust"): lag_with_form}
    effects = [SimpleNamespace(name=n) for n in ("heading_lag", "actuation_lag")]
    by_name = {e.name: e for e in effects}
    fitter = _Told(errors)
    start = fitter._fit(())
    sel = select(fitter, start, effects[:1], rank(fitter, start, effects[:1], "1.0"), 3, {"1.0": 0.1}, "1.0")
    assert sel.chosen == ["heading_lag"]
    on_top = _Told(errors)  # the search on top of the form keeps the form and the first choice in its models
    on_top.without = lambda final, keep: on_top._fit({"thrust", "heading_lag", *(e.name for e in keep)})
    found = on_top._fit({"heading_lag", "thrust"})
    later = select(on_top, found, effects[1:], rank(on_top, found, effects[1:], "1.0"), 2, {"1.0": 0.1}, "1.0")
    assert later.chosen == ["actuation_lag"] and later.final.error("1.0") == 0.3
    form_kept = _Told(errors)  # given_later's fitter keeps only the form
    form_kept.without = lambda final, keep: form_kept._fit({"thrust", *(e.name for e in keep)})
    said = []
    gone = given_later(form_kept, sel, later, by_name, 0.1, "1.0", said.append)
    assert later.chosen == ["actuation_lag"] and later.dropped == []
    if not dropped:
        assert gone == [] and sel.chosen == ["heading_lag"] and later.final.error("1.0") == 0.3
        return
    assert sel.chosen == [] and [d["effect"] for d in gone] == ["heading_lag"]
    assert gone[0]["reduction"] == pytest.approx(1.0 - 0.3 / 0.31)
    assert later.final.error("1.0") == pytest.approx(0.31) and later.final.model.effects == {"actuation_lag", "thrust"}
    assert said[-1].startswith("backward: heading_lag dropped once the others are in (it lowers the error by only 3%")
