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

A uniform flow that is really there fails the first test, unless D is a flow
that varies with position (a swirl or a shear, :data:`.discover.FLOW_PATTERNS`)
and the two vanish together inside the tank (:func:`.discover.holds_uniform_part`):
then the uniform flow is a stand-in when D passes given it, whatever it adds
given D. The uniform part of such a flow is its value at the tank's origin, an
arbitrary point: a swirl about an axis off the origin is a swirl about the
origin plus a uniform flow, one flow and not two causes. D may not use
the terms that express E's own form (:data:`OWN_TERMS`: a constant for the
uniform flow, |v| v and |u| u for the quadratic drag, the wall decays for the
wall drag): found without them, D cannot take E's place, and E still passes
given it; were they allowed, D would find E again beside what lies outside,
and E would look like a stand-in.

The weakest stand-in is dropped and the check starts again on the effects
left, until none is a stand-in; the pipeline then discovers the form on what
is left.

The converse (:func:`in_place_of_terms`): a library effect the search did not
name, whose own terms the discovered form holds (a quadratic drag's |u| u
beside a shear's terms), takes their place when its one law does as well as
they do; the form without them is refitted, and the search on top of it
names the effect if it passes the gates there.

A tentative step (:func:`beside_form`): a library effect the search took
tentatively and dropped, since nothing passed given it, may have needed the
form outside the library beside it. A wall drag beside a strong shear
lowered the error by 13 % alone (t = 1.6), and discovery on the bare model
read the shear, amplified near the wall, as a thrust varying with position
(55 %); given the wall drag, discovery found the shear itself (72 % of what
the drag left) and the two left a quarter of the error. The effect is named
when it and the form found beside it pass the verdict's gates against the
form found without it, and it still passes them given that form.

The last case (:func:`own_law_misfit`): a chosen effect whose own terms the
discovered form holds, and which do what the whole form does. A wall drag
whose decay law is not the library's 1/d (an exponential) leaves a remainder
near the walls that v exp(-d/3 mm) terms take up: that is the effect's law
misfitting these logs, not another effect, and the verdict says so.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from cosim_plugins.diagnose.discover import FLOW_PATTERNS, TERM_TABLE, holds_uniform_part, library_effect, term_force
from cosim_plugins.diagnose.result import DISCOVERED, Dropped
from cosim_plugins.diagnose.stepwise import LOOKAHEADS, t_text
from cosim_plugins.diagnose.verdict import MIN_REDUCTION, MIN_T, passes

#: Discovery terms (:data:`.discover.TERM_TABLE`) that express a library force's own form or its look-alike: a uniform
#: flow's force is nearly a constant (Cd1 w: the angle terms' change is small); a quadratic drag is -c |v| v, and
#: since the speed follows the spin rate along a path, |u| u looks the same; a wall drag is v times a decay with the
#: distance to the wall. Discovered without the force, they would only find it again, so the form that tests it may
#: not use them.
OWN_TERMS = {
    "background_flow": ("fx_1", "fy_1", "wx_1", "wy_1"),  # as a force or as the water's velocity
    "quadratic_drag": tuple(f"f{c}_{k}_{q}{c}" for c in "xyz" for k, q in (("speed", "v"), ("spin", "u"))),
    "wall_drag": tuple(f"f{c}_v{c}_wall{ell}" for c in "xyz" for ell in (3, 10)),
}


def form_passes(found) -> bool:
    """True when the discovered form (a :class:`~.result.Discovered`) lowers what the chosen effects leave by
    >= MIN_REDUCTION with t >= MIN_T: then a chosen force may be standing in for it (reporting the form asks for
    more, :func:`.verdict.discovered_explains`)."""
    return found.status == "found" and found.reduction >= MIN_REDUCTION and found.t_stat >= MIN_T


def holds_own_form(name: str, terms) -> bool:
    """Whether the discovered ``terms`` (names) hold every own term (:data:`OWN_TERMS`) of the effect ``name``,
    as forces or as the water's velocity (``fx_1, fy_1`` or ``wx_1, wy_1`` for a uniform flow)."""
    own = OWN_TERMS.get(name, ())
    kinds = {n[0] for n in own}
    return any({n for n in own if n[0] == k} <= set(terms) for k in kinds)


def stand_ins(fitter, selection, by_name: dict, discover_on, floor: float | None, key: str, say,
              keep=()) -> tuple[list, list]:
    """Drop from ``selection`` (in place: ``steps``, ``final``) every chosen force that stands in for a form
    outside the library (see the module doc), those named in ``keep`` excepted; returns (a
    :class:`~.result.Dropped` (``given`` "discovered") for each, in the order dropped; for each, the Fit of the
    model without it refitted with the form found without it, that form its last effect).

    ``discover_on(fit, exclude) -> (Discovered, effect file source, Fit or None)`` runs discovery on what ``fit``
    leaves without the terms ``exclude`` (:func:`.pipeline._discover`), the Fit being ``fit``'s model refitted
    with the discovered form; ``by_name`` maps a candidate's name to its Effect.
    """
    gone, forms = [], []
    while True:
        trials = []
        for i, step in enumerate(selection.steps):
            effect = by_name.get(step.effects[0])
            if step.is_group or effect is None or effect.kind != "force" or effect.name in keep:
                continue
            others = [by_name[s.effects[0]] for j, s in enumerate(selection.steps) if j != i]
            without = fitter.without(selection.final, others)
            found, _, with_form = discover_on(without, OWN_TERMS.get(effect.name, ()))
            if with_form is None:
                say(f"stand-in: {effect.name}: nothing discovered without it")
                continue
            form = with_form.model.effects[-1]
            both, _ = fitter.with_effects(selection.final, [form], fresh=False)
            given_form = fitter.entry(effect, both, True, with_form)
            form_given = fitter.entry(form, both, True, selection.final)
            part_of_flow = (effect.name == "background_flow" and found.pattern in FLOW_PATTERNS
                            and _uniform_part(both, effect.name, form))
            stands_in = ((part_of_flow or not passes(given_form, with_form.error(key), floor, key))
                         and passes(form_given, selection.final.error(key), floor, key))
            say(f"stand-in: {effect.name} given the form found without it {given_form['reduction']:+.1%} "
                f"(t = {given_form['t_stat']:.1f}); the form given {effect.name} {form_given['reduction']:+.1%} "
                f"(t = {form_given['t_stat']:.1f})" + (": a stand-in" if stands_in else "")
                + (f" (the uniform part of the {found.pattern} found)" if stands_in and part_of_flow else ""))
            if stands_in:
                trials.append((given_form["reduction"], i, given_form, form_given, found, without,
                               found.pattern if part_of_flow else None, with_form))
        if not trials:
            return gone, forms
        _, i, given_form, form_given, found, without, part_of, with_form = min(trials, key=lambda x: x[0])
        step = selection.steps.pop(i)
        gone.append(Dropped(effect=step.effects[0], reduction=given_form["reduction"], t_stat=given_form["t_stat"],
                            given="discovered", terms=list(found.terms or ()),
                            form_reduction=form_given["reduction"], form_t_stat=form_given["t_stat"],
                            part_of=part_of))
        forms.append(with_form)
        say(f"stand-in: {step.effects[0]} dropped: a form outside the library ({', '.join(found.terms or ())}) "
            "explains what it did, and more")
        selection.final = without


def drop_stand_ins(fitter, selection, by_name: dict, discover_on, after_removal, floor: float | None, key: str,
                   say, keep=()) -> tuple[list, tuple | None]:
    """(gone, the discovery on what is left) once the stand-ins are out of ``selection`` (:func:`stand_ins`, in
    place), the form discovered again on what they leave (``discover_on(fit)``, no term excluded;
    ``discover_on(fit, exclude)`` as in :func:`stand_ins`) and the steps left measured again without them but
    given that form (``after_removal(selection, the Fit with the form or None) -> [drop dict]``,
    :func:`.stepwise.left_after_removal`; the form found again when one fails);
    ``gone``: a :class:`~.result.Dropped` for each stand-in, then for each step that failed without them. ([],
    None) when none goes.

    The sparse regression on what is left, free to take the stand-in's own terms again, may choose worse than it
    did without them (a step-out beside a shear: the constants first, then terms that lower the held-out error
    by 1 %, where the shear's terms found without them had lowered it by 40 %). Each form found without a
    stand-in is refitted on what is left too (``discover_on(fit, form=(terms, scales, coefficients))``), and the
    form that errs least there is the one discovered.

    A uniform flow dropped as the uniform part of a swirl or shear found without it must be in the form found
    once it is out (:func:`holds_a_flow`). When it is not, that swirl was the flow's own push spread over terms
    near constant on the paths (a wall drag's law misfit beside a flow of 0.6 mm/s: ``fx_z``, ``fy_z`` and
    their uniform part): the drops are undone and the flow is kept. The effects named in ``keep`` are not tried
    (one named beside the form found with it, :func:`beside_form`)."""
    kept: set = set(keep)
    while True:
        saved = (list(selection.steps), selection.final, len(selection.dropped))
        gone, forms = stand_ins(fitter, selection, by_name, discover_on, floor, key, say, keep=kept)
        if not gone:
            return [], None
        again = _form_on(selection.final, gone, forms, discover_on, key, say)
        failed = after_removal(selection, again[2])
        if failed:
            again = _form_on(selection.final, gone, forms, discover_on, key, say)
        lost = set() if holds_a_flow(again[0], again[2]) else {d.effect for d in gone if d.part_of}
        if not lost:
            return gone + [Dropped(**d) for d in failed], again
        say(f"stand-in: {', '.join(sorted(lost))} kept: the form found once it is out holds no flow with it as "
            "its uniform part")
        selection.steps, selection.final = saved[0], saved[1]
        del selection.dropped[saved[2]:]
        kept |= lost


def _form_on(final, gone: list, forms: list, discover_on, key: str, say) -> tuple:
    """The discovery on what ``final`` leaves (``discover_on(final)``), or the form found without a stand-in of
    ``gone`` (its Fit in ``forms``) refitted there when that errs less (:func:`drop_stand_ins`)."""
    again = discover_on(final)
    for dropped, with_form in zip(gone, forms):
        trial = discover_on(final, form=form_of(with_form))
        if trial[2] is not None and (again[2] is None or trial[2].error(key) < again[2].error(key)):
            say(f"stand-in: the form found without {dropped.effect} ({', '.join(trial[0].terms or ())}) errs "
                f"less on what is left ({trial[2].error(key):.3f} mm) than the form found there: it is kept")
            again = trial
    return again


def beside_form(fitter, selection, by_name: dict, discover_on, bare: tuple, floor: float | None, key: str,
                say) -> tuple[tuple | None, tuple]:
    """(named, discovery): ``named`` is (a :class:`~.stepwise.Step`, the final model with it (a Fit), the
    discovery beside it) for an effect the search took tentatively and dropped (``selection.tentative``, at most
    :data:`~.stepwise.LOOKAHEADS`, those taken on the final model) that earns its place once a form outside the
    library is discovered beside it (see the module doc), or None; ``discovery`` is ``bare``, or a better form
    for the final model alone (below).

    For each, discovery runs on what the final model plus it leaves (``discover_on(fit) -> (Discovered, effect
    file source, Fit or None)``, quietly); it is named when the two pass the verdict's gates against the form
    found without it (``bare``: that discovery's (Discovered, source, Fit or None); the final model when it
    found nothing that passes) and it passes them given the form, refitted without it. Its step's drop is that
    last one (``given`` ends with :data:`~.result.DISCOVERED`). The one whose model with the form errs least
    wins.

    An effect that is not named may still have shown the form the bare discovery missed: beside a step-out, the
    regression chose a shear along both axes, which refitted without the step-out left 0.42 mm, where the form
    found on the bare model (the shear along one axis) left 1.42 mm. That form is refitted on the final model,
    from the parameters it had there (``discover_on(fit, form_fit)``: the form of ``form_fit``, its last effect,
    refitted on ``fit`` from ``form_fit``'s parameters, its drop measured against ``fit``), and
    becomes the discovery when it passes the verdict's gates against the form found there."""
    rival = _fit_of(bare, selection.final)
    others = [by_name[n] for n in selection.chosen]
    best, unnamed = None, []
    for step in [st for st in selection.tentative if st.before is selection.final][:LOOKAHEADS]:
        name = step.effects[0]
        say(f"discover: again given {name}, taken tentatively and dropped: the form beside it may be what it "
            "needed")
        again = discover_on(step.fit)
        found, _, with_form = again
        if with_form is None or not form_passes(found):
            say(f"  given {name}: no form passes")
            continue
        without = fitter.without(with_form, [*others, with_form.model.effects[-1]])
        over = fitter.entry(by_name[name], with_form, True, rival)
        given = fitter.entry(by_name[name], with_form, True, without)
        ok = passes(over, rival.error(key), floor, key) and passes(given, without.error(key), floor, key)
        say(f"  given {name}, the form ({', '.join(found.terms or ())}): {with_form.error(key):.3f} mm against "
            f"{rival.error(key):.3f} mm without {name} ({over['reduction']:+.1%}, {t_text(over)}); {name} given "
            f"the form {given['reduction']:+.1%} ({t_text(given)})" + (": named" if ok else ""))
        if ok and (best is None or with_form.error(key) < best[2][2].error(key)):
            best = (replace(step, entry=given, fit=with_form, before=without, alone=step.alone or step.entry,
                            given=[*selection.chosen, DISCOVERED]), step.fit, again)
        elif not ok:
            unnamed.append((name, without))
    return best, bare if best is not None else _better_form(fitter, selection.final, unnamed, bare, floor, key,
                                                           discover_on, say)


def _better_form(fitter, final, unnamed: list, bare: tuple, floor: float | None, key: str, discover_on,
                 say) -> tuple:
    """:func:`beside_form`'s discovery when no effect is named: ``bare``, or the form found beside an effect of
    ``unnamed`` ([(its name, the model with the form, refitted without it)], in the search's order) refitted on
    ``final`` from there, when that passes the verdict's gates against the form found so far."""
    for name, without in unnamed:
        current = _fit_of(bare, final)
        if without.error(key) >= current.error(key):
            continue
        trial = discover_on(final, without)
        better = (trial[2] is not None and form_passes(trial[0]) and passes(
            fitter.entry(trial[2].model.effects[-1], trial[2], True, current), current.error(key), floor, key))
        say(f"  the form found beside {name}, refitted without it from there: "
            + (f"{trial[2].error(key):.3f} mm against {current.error(key):.3f} mm with the form found so far"
               if trial[2] is not None else "no form that lowers the error")
            + (": it is the one discovered" if better else ""))
        if better:
            bare = trial
    return bare


def _fit_of(discovery: tuple, fallback):
    """A discovery's model with its form (its Fit) when the form passes, else ``fallback`` (the model without a
    form)."""
    return discovery[2] if discovery[2] is not None and form_passes(discovery[0]) else fallback


def form_of(with_form) -> tuple:
    """(Terms, scales, coefficients): the discovered form of the Fit ``with_form`` (its last effect), at its
    coefficients there: what ``discover_on(fit, form=...)`` refits on another model."""
    return _as_form(with_form.model.effects[-1], with_form.model.params())


def holds_a_flow(found, with_form) -> bool:
    """Whether the discovered form (``found``: Discovered; ``with_form``: the model refitted with it, its last
    effect) is a flow varying with position that holds its constants as its uniform part: what a background flow
    dropped as that uniform part (:func:`stand_ins`) must find in the form discovered once it is out."""
    return (with_form is not None and found.pattern in FLOW_PATTERNS
            and _uniform_part(with_form, None, with_form.model.effects[-1]))


def in_place_of_terms(fitter, final, found, with_form, candidates, floor: float | None, key: str, say) -> tuple:
    """(the library effect's name, the form less its terms: (Terms, scales, coefficients)) or (): a listed effect
    whose own form (:data:`OWN_TERMS`) the discovered form holds, and which explains the data as well as those
    terms.

    Discovery on what ``final`` leaves may take up a library effect the search did not name beside the form
    outside the library: a quadratic drag beside a shear flow, found as |u| u terms next to the shear's. For each
    such candidate E (of ``candidates``, not in ``final``), the form less E's own terms is refitted with E (E's
    starts as in the search, and :func:`matched_start`); when the whole form (``with_form``: ``final`` plus it)
    does not pass the verdict's gates against that model, E's one law does what its terms did: the form less them (its
    coefficients as fitted beside E) replaces the form, and the search given the form then judges E. (Found again
    by the regression without E's terms, the form is poorer: linearised on a model without E, the regression
    picks other terms.) A uniform flow is not tried when the form is a swirl or shear that holds its constants
    as its uniform part (:func:`.discover.holds_uniform_part`); nor is a candidate whose own terms are the whole
    form. The candidate whose model errs least wins.
    """
    form = with_form.model.effects[-1]
    terms = set(form.terms or ())
    taken = {e.name for e in final.model.effects}
    prm = with_form.model.params()
    best = None
    for effect in candidates:
        own = set(OWN_TERMS.get(effect.name, ()))
        if effect.name in taken or not own & terms or (effect.name == "background_flow"
                                                        and found.pattern in FLOW_PATTERNS
                                                        and _uniform_part(with_form, None, form)):
            continue
        rest = [q for q in form.params if q.name not in own]
        if not rest:
            continue
        reduced = _part_of(form, rest, prm)
        gone = [q.name for q in form.params if q.name in own]
        start = matched_start(effect, fitter.ttr, [_term(n) for n in gone], [prm[f"{form.name}.{n}"] for n in gone],
                              {k: v for k, v in prm.items() if "." not in k})
        fit, _ = fitter.with_effects(final, [reduced, replace(effect, starts=(start, *effect.starts)) if start
                                             else effect])
        whole = fitter.entry(form, with_form, True, fit)
        say(f"in place of its terms: {effect.name} with the form less {', '.join(sorted(own & terms))}: "
            f"{fit.error(key):.3f} mm; the whole form {with_form.error(key):.3f} mm ({whole['reduction']:+.1%}, "
            f"t = {whole['t_stat']:.1f})")
        if not passes(whole, fit.error(key), floor, key) and (best is None or fit.error(key) < best[0]):
            best = (fit.error(key), effect.name, _as_form(form, fit.model.params(), rest))
    if best is None:
        return ()
    say(f"in place of its terms: {best[1]} takes the place of {', '.join(sorted(terms - {t.name for t in best[2][0]}))}"
        "; the form without them is refitted")
    return best[1:]


def own_law_misfit(fitter, final, with_form, chosen, floor: float | None, key: str, say) -> str | None:
    """The name of a chosen effect (of ``chosen``, Effects in ``final``) whose own terms (:data:`OWN_TERMS`) in the
    discovered form do what the whole form does, or None: refitted on top of ``final`` with the form's terms of
    that effect alone (their coefficients as fitted in ``with_form``: ``final`` plus the form), the whole form no
    longer passes the verdict's gates against them. The form then corrects that effect's law."""
    form = with_form.model.effects[-1]
    terms = set(form.terms or ())
    prm = with_form.model.params()
    for effect in chosen:
        own = set(OWN_TERMS.get(effect.name, ())) & terms
        if not own:
            continue
        if own == terms:
            say(f"own law: the form is {effect.name}'s own terms alone")
            return effect.name
        part = _part_of(form, [q for q in form.params if q.name in own], prm)
        fit, _ = fitter.with_effects(final, [part], fresh=False)
        whole = fitter.entry(form, with_form, True, fit)
        misfit = not passes(whole, fit.error(key), floor, key)
        say(f"own law: {effect.name}'s terms of the form ({', '.join(sorted(own))}) leave {fit.error(key):.3f} mm; "
            f"the whole form {with_form.error(key):.3f} mm ({whole['reduction']:+.1%}, t = {whole['t_stat']:.1f})"
            + (f": the form corrects {effect.name}'s law" if misfit else ""))
        if misfit:
            return effect.name
    return None


def matched_start(effect, tl, terms, coefs, host: dict, rows: int = 2000) -> dict:
    """{param: value}: ``effect``'s parameters whose force best matches, in least squares over ``rows`` rows of the
    timeline ``tl`` spread over it, the force of the discovered ``terms`` with coefficients ``coefs`` that the
    effect is to replace, from each of its starts (the host's parameters ``host`` held). The joint fit's own starts
    may lie far from the law's values (a wall drag of 1.3 uN s/mm against its start at 0.05)."""
    from scipy.optimize import least_squares

    at = np.unique(np.linspace(0, tl.n - 1, min(rows, tl.n)).astype(int))
    x, u = tl.x_lin[at], tl.u[at]
    ok = np.all(np.isfinite(x), axis=1) & np.all(np.isfinite(u), axis=1)
    p, v, u = x[ok, :3], x[ok, 3:], u[ok]
    target = term_force(terms, coefs, p, v, u, host)
    names = [q.name for q in effect.params]
    lo, hi = np.array([q.lo for q in effect.params]), np.array([q.hi for q in effect.params])

    def misfit(theta):
        return (effect.force(p, v, u, {**host, **dict(zip(names, theta))}) - target).ravel()

    best = None
    for st in ({q.name: q.init for q in effect.params}, *effect.starts):
        x0 = np.clip([st.get(n, q.init) for n, q in zip(names, effect.params)], lo, hi)
        with np.errstate(all="ignore"):
            res = least_squares(misfit, x0, bounds=(lo, hi), x_scale=[q.typical() for q in effect.params],
                                max_nfev=60)
        if np.isfinite(res.cost) and (best is None or res.cost < best.cost):
            best = res
    return {} if best is None else {n: float(t) for n, t in zip(names, best.x)}


def _uniform_part(fit, flow: str | None, form) -> bool:
    """Whether the flow that ``form`` (a swirl or shear) finds in ``fit`` holds its constants, and the uniform flow
    ``flow``'s force there too (Cd1 w; the drag across the swimmer is small), as its uniform part
    (:func:`.discover.holds_uniform_part`)."""
    prm = fit.model.params()
    push = (np.zeros(2) if flow is None else
            prm.get("Cd1", 0.0) * np.array([prm[f"{flow}.w_x"], prm[f"{flow}.w_y"]]))
    return holds_uniform_part([_term(n) for n in form.terms], {n: prm[f"{form.name}.{n}"] for n in form.terms},
                              push, prm)


def _as_form(form, prm: dict, params=None) -> tuple:
    """(Terms, scales, coefficients): the discovered ``form`` (an Effect), or its parameters ``params`` alone (its
    terms' coefficients), with the coefficients in ``prm`` (a model's parameters, the form's qualified by its
    name)."""
    params = form.params if params is None else params
    return ([_term(q.name) for q in params], np.array([q.scale for q in params]),
            np.array([prm[f"{form.name}.{q.name}"] for q in params]))


def _part_of(form, params, prm: dict):
    """The discovered ``form`` with only its parameters ``params`` (its terms' coefficients), started at their
    values in ``prm`` (a model's parameters, the form's qualified by its name)."""
    terms, scales, coefs = _as_form(form, prm, params)
    return library_effect(terms, scales, name=form.name, coefs=coefs)


def _term(name: str):
    return TERM_TABLE[name]
