"""Stand-ins: a chosen library force that only stands in for a form outside the library.

A flow that grows with depth (a shear) or turns about an axis is no library
effect, but a uniform flow and the coils' gradient force, both linear in
position at most, take up part of it: the stepwise search names them, and
discovery then finds the rest of the same flow in what they leave. Naming
them sends the lab after a pump or a coil that is not there.

The check runs when the form discovered on what the chosen effects leave
lowers their error by >= 10 % with t >= 3. For each chosen force E (not a group, not a lag or latency:
the discovered terms are forces of position, velocity and command, so they
can take the place of a force only), the model without E is refitted and
discovery runs on what it leaves, finding a form D without E's help. Then E
and D are refitted together with the others; E is a stand-in when

- E no longer passes the verdict's gates given D (the others and D in), and
- D still passes given E (the others and E in): D holds something E cannot
  express.

A uniform flow that is really there fails the first test. D may not use
the terms that express E's own form (:data:`OWN_TERMS`: a constant for the
uniform flow, |v| v and |u| u for the quadratic drag, the wall decays for the
wall drag): found without them, D cannot take E's place, and E still passes
given it; were they allowed, D would find E again beside what lies outside,
and E would look like a stand-in.

The weakest stand-in is dropped and the check starts again on the effects
left, until none is a stand-in; the pipeline then discovers the form on what
is left.
"""

from __future__ import annotations

from cosim_plugins.diagnose.result import Dropped
from cosim_plugins.diagnose.verdict import passes

#: Discovery terms (:data:`.discover.TERMS`) that express a library force's own form or its look-alike: a uniform
#: flow's force is a constant (Cd w, nearly: Cd0 sin(alpha) is small); a quadratic drag is -c |v| v, and since the
#: speed follows the spin rate along a path, |u| u looks the same; a wall drag is v times a decay with the distance
#: to the wall. Discovered without the force, they would only find it again, so the form that tests it may not use
#: them.
OWN_TERMS = {
    "background_flow": ("fx_1", "fy_1"),
    "quadratic_drag": tuple(f"f{c}_{k}_{q}{c}" for c in "xyz" for k, q in (("speed", "v"), ("spin", "u"))),
    "wall_drag": tuple(f"f{c}_v{c}_wall{ell}" for c in "xyz" for ell in (3, 10)),
}


def stand_ins(fitter, selection, by_name: dict, discover_on, floor: float | None, key: str, say) -> list:
    """Drop from ``selection`` (in place: ``steps``, ``final``) every chosen force that stands in for a form
    outside the library (see the module doc); returns a :class:`~.result.Dropped` (``given`` "discovered") for
    each, in the order dropped.

    ``discover_on(fit, exclude) -> (Discovered, effect file source, Fit or None)`` runs discovery on what ``fit``
    leaves without the terms ``exclude`` (:func:`.pipeline._discover`), the Fit being ``fit``'s model refitted
    with the discovered form; ``by_name`` maps a candidate's name to its Effect.
    """
    gone = []
    while True:
        trials = []
        for i, step in enumerate(selection.steps):
            effect = by_name.get(step.effects[0])
            if step.is_group or effect is None or effect.kind != "force":
                continue
            keep = [by_name[s.effects[0]] for j, s in enumerate(selection.steps) if j != i]
            without = fitter.without(selection.final, keep)
            found, _, with_form = discover_on(without, OWN_TERMS.get(effect.name, ()))
            if with_form is None:
                say(f"stand-in: {effect.name}: nothing discovered without it")
                continue
            form = with_form.model.effects[-1]
            both, _ = fitter.with_effects(selection.final, [form], fresh=False)
            given_form = fitter.entry(effect, both, True, with_form)
            form_given = fitter.entry(form, both, True, selection.final)
            stands_in = (not passes(given_form, with_form.error(key), floor, key)
                         and passes(form_given, selection.final.error(key), floor, key))
            say(f"stand-in: {effect.name} given the form found without it {given_form['reduction']:+.1%} "
                f"(t = {given_form['t_stat']:.1f}); the form given {effect.name} {form_given['reduction']:+.1%} "
                f"(t = {form_given['t_stat']:.1f})" + (": a stand-in" if stands_in else ""))
            if stands_in:
                trials.append((given_form["reduction"], i, given_form, form_given, found, without))
        if not trials:
            return gone
        _, i, given_form, form_given, found, without = min(trials, key=lambda x: x[0])
        step = selection.steps.pop(i)
        gone.append(Dropped(effect=step.effects[0], reduction=given_form["reduction"], t_stat=given_form["t_stat"],
                            given="discovered", terms=list(found.terms or ()),
                            form_reduction=form_given["reduction"], form_t_stat=form_given["t_stat"]))
        say(f"stand-in: {step.effects[0]} dropped: a form outside the library ({', '.join(found.terms or ())}) "
            "explains what it did, and more")
        selection.final = without
