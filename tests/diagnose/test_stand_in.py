"""A library force that stands in for a flow outside the library is dropped; a real one beside it stays.

Logs of the independent simulator (``benchmarks/blind_sim.py``: the seed-55 blind bench's multi_000): the coils'
gradient force and the water turning about a vertical axis 16 mm off the centre (no library effect). The
stepwise search names the gradient force, then a uniform flow, which takes up the turning flow's mean over the
paths; discovery finds the turning in what the two leave. Discovered without the uniform flow, the form is a swirl
that takes its place (the flow then adds almost nothing) and still adds much once the flow is in: the uniform part
of the swirl, dropped. Found again with the constants, the swirl's axis is where the simulator put it. The gradient
force keeps its place given the form found without it.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

from cosim.contract import plugins
from cosim_plugins.diagnose.pipeline import Settings, run

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import blind_sim  # noqa: E402

KEY = "1.0"


def test_a_uniform_flow_standing_in_for_a_turning_one_is_dropped(tmp_path):
    case = blind_sim.draw_multi_case(294117217, ("gradient_force", "rotating_flow"), index=0)
    assert case.truth["rotating_flow"]["x0_mm"] == pytest.approx(-16.24, abs=0.01)
    logs = blind_sim.simulate(case, tmp_path / "logs")
    plugins.reset()
    diag = run(logs, settings=Settings(candidates=["background_flow", "gradient_force"], drift=False,
                                       discover=True, fit_windows=300)).json
    sw = diag["stepwise"]
    assert sw["rounds"][0][0]["effect"] == "gradient_force"
    dropped = {d["effect"]: d for d in sw["dropped"]}
    assert set(dropped) == {"background_flow"}
    stand_in = dropped["background_flow"]
    assert stand_in["given"] == "discovered"
    assert stand_in["reduction"] < 0.10 and stand_in["form_reduction"] > 0.25
    assert diag["verdict"]["effects"] == ["gradient_force"]
    assert diag["discovered"]["status"] == "found"
    assert stand_in["part_of"] == "swirl"
    assert "the uniform part of a swirl flow" in diag["verdict"]["explanation"]
    assert diag["discovered"]["pattern"] == "swirl" and {"fx_1", "fy_1"} <= set(diag["discovered"]["terms"])
    axis = re.search(r"through about \(([-+]\d+), ([-+]\d+)\) mm", diag["discovered"]["words"][-1])
    truth = case.truth["rotating_flow"]
    assert float(axis[1]) == pytest.approx(truth["x0_mm"], abs=3) and float(axis[2]) == pytest.approx(truth["y0_mm"],
                                                                                                      abs=3)


def test_the_check_drops_the_stand_in_and_keeps_the_force_that_adds_to_the_form():
    """A fitter whose models' errors are a table over their sets of effects. A uniform flow and a gradient force
    are chosen over a flow outside the library. Discovered without the flow, the form (D1) takes its place (the
    flow then adds 2 %) and adds 39 % given it: a stand-in. The gradient force adds 36 % to the form found without
    it (D2): it stays, and again once the flow is gone (D3). The lag is never checked, and the form that tests the
    uniform flow may not use the constants that are its own form."""
    from types import SimpleNamespace as NS

    from cosim_plugins.diagnose.standin import OWN_TERMS, stand_ins

    bg, grad, lag = "background_flow", "gradient_force", "actuation_lag"
    errors = {(bg, grad, lag): 0.8, (grad, lag): 0.8, (bg, lag): 0.9, ("D1", grad, lag): 0.5,
              ("D1", bg, grad, lag): 0.49, ("D2", bg, lag): 0.7, ("D2", bg, grad, lag): 0.45, (lag,): 1.6,
              ("D3", lag): 0.5, ("D3", grad, lag): 0.3}
    errors = {frozenset(k): v for k, v in errors.items()}
    effects = {n: NS(name=n, kind="input" if n == lag else "force") for n in (bg, grad, lag, "D1", "D2", "D3")}

    def fit(names):
        names = frozenset(names)
        return NS(names=names, model=NS(effects=[effects[n] for n in sorted(names)]), error=lambda k: errors[names])

    forms = {frozenset({grad, lag}): "D1", frozenset({bg, lag}): "D2", frozenset({lag}): "D3"}
    asked = []

    def discover_on(without, exclude):
        form = forms[without.names]
        asked.append((form, tuple(exclude)))
        with_form = fit(without.names | {form})
        with_form.model.effects.append(effects[form])  # the discovered form comes last
        return NS(terms=[f"{form}_terms"], pattern=None), None, with_form

    def entry(effect, after, identifiable, before):
        red = 1.0 - after.error(KEY) / before.error(KEY)
        return {"reduction": red, "t_stat": 20.0 * red, "rollout_mm": {KEY: after.error(KEY)}, "identifiable": True}

    fitter = NS(without=lambda final, keep: fit({e.name for e in keep}),
                with_effects=lambda before, new, fresh: (fit(before.names | {e.name for e in new}), True),
                entry=entry)
    selection = NS(steps=[NS(effects=[n], is_group=False) for n in (bg, grad, lag)], final=fit({bg, grad, lag}))
    gone = stand_ins(fitter, selection, effects, discover_on, None, KEY, lambda m: None)
    assert [d.effect for d in gone] == [bg]
    assert gone[0].given == "discovered" and gone[0].terms == ["D1_terms"]
    assert gone[0].reduction == pytest.approx(0.02) and gone[0].form_reduction == pytest.approx(1 - 0.49 / 0.8)
    assert [s.effects[0] for s in selection.steps] == [grad, lag] and selection.final.names == {grad, lag}
    assert asked == [("D1", OWN_TERMS[bg]), ("D2", ()), ("D3", ())]


@pytest.mark.parametrize("pattern", ["swirl", "gradient"])
def test_a_uniform_flow_is_part_of_a_swirl_found_without_it(pattern):
    """Table fitter again: found without the uniform flow, a form (D1) leaves it 20 % (it passes given D1) and adds
    40 % given it. When D1 is a swirl, the flow is its uniform part (its value at the tank's origin) and is dropped;
    when D1 is a curl-free field, no flow, the uniform flow keeps its place. The gradient force stays either way."""
    from types import SimpleNamespace as NS

    from cosim_plugins.diagnose.standin import stand_ins

    bg, grad = "background_flow", "gradient_force"
    errors = {(bg, grad): 0.8, (grad,): 1.0, ("D1", grad): 0.6, ("D1", bg, grad): 0.48, (bg,): 1.1,
              ("D2", bg): 0.9, ("D2", bg, grad): 0.7, ("D3",): 0.7, ("D3", grad): 0.5}
    errors = {frozenset(k): v for k, v in errors.items()}
    effects = {n: NS(name=n, kind="force") for n in (bg, grad, "D1", "D2", "D3")}

    def fit(names):
        names = frozenset(names)
        return NS(names=names, model=NS(effects=[effects[n] for n in sorted(names)]), error=lambda k: errors[names])

    forms = {frozenset({grad}): "D1", frozenset({bg}): "D2", frozenset(): "D3"}

    def discover_on(without, exclude):
        form = forms[without.names]
        with_form = fit(without.names | {form})
        with_form.model.effects.append(effects[form])
        return NS(terms=[f"{form}_terms"], pattern=pattern if form == "D1" else "gradient"), None, with_form

    def entry(effect, after, identifiable, before):
        red = 1.0 - after.error(KEY) / before.error(KEY)
        return {"reduction": red, "t_stat": 20.0 * red, "rollout_mm": {KEY: after.error(KEY)}, "identifiable": True}

    fitter = NS(without=lambda final, keep: fit({e.name for e in keep}),
                with_effects=lambda before, new, fresh: (fit(before.names | {e.name for e in new}), True),
                entry=entry)
    selection = NS(steps=[NS(effects=[n], is_group=False) for n in (bg, grad)], final=fit({bg, grad}))
    gone = stand_ins(fitter, selection, effects, discover_on, None, KEY, lambda m: None)
    if pattern == "swirl":
        assert [(d.effect, d.part_of) for d in gone] == [(bg, "swirl")]
        assert gone[0].reduction == pytest.approx(0.2) and gone[0].form_reduction == pytest.approx(0.4)
        assert [s.effects[0] for s in selection.steps] == [grad]
    else:
        assert gone == [] and [s.effects[0] for s in selection.steps] == [bg, grad]
