"""Several missing effects, chosen stepwise: forward selection with conditional re-ranking, then a backward check.

Round r refits every remaining candidate jointly with the model of round
r - 1 (the baseline's parameters, the effects chosen so far and the
candidate's, all free; the candidate's parameters start at its own listed
and data-driven starts, everything else at the last solution) and ranks them
by the held-out error at the reference horizon. The best candidate is chosen
when it passes the verdict's gates *given* the model before it
(:func:`cosim_plugins.diagnose.verdict.passes`: relative drop, paired t and
share of the remaining excess over the noise floor). When rivals explain the
error about as well (:mod:`.lookalike`) and add nothing to it once refitted
together (two effects present at once each explain a part, and each adds to
the other), the round's choice is the group; its best member stands in for it
in later rounds. The chosen model is then
re-polished from its own solution (so a later candidate gains nothing from
extra iterations alone) and the next round starts.

From the second round on, every remaining candidate is screened by a quick
joint fit first and only the most promising get the full one (:func:`rank`).

Two effects present at once can each explain little alone and much together
(the baseline's parameters, fitted without either, take up part of the
other's absence: a flow and a quadratic drag each lowered a case's error by
6 % and 0 %, together by 66 %). So when nothing passes, the round's best is
taken tentatively if it lowers the error by at least :data:`SCREEN_MIN` (a
look-ahead): the next round, with full fits for every
candidate, runs given it, and the tentative step is kept only when that
round's choice passes given it, the two together pass against the model
before them, and the tentative effect still passes once the other is in
(:func:`_confirmed`); its look-alikes are then weighed in its place given the
other (:func:`_given_family`). Otherwise it is dropped; the other effect (if
one was chosen), refitted without it from the pair's solution, is named alone
when it passes against the model before the tentative step
(:func:`_partner_alone`: its own fit alone may have ended in a poorer basin),
and the search goes on; else the round's next
hopeful candidate is taken tentatively in its place (:func:`_tentative`, at
most :data:`LOOKAHEADS` in all), and when none is left the search stops.

Selection stops at the noise floor, when nothing passes, when no candidate
is left or after ``max_effects`` rounds. Then the backward check refits the
model without each chosen effect in turn and drops an effect that no longer
passes the gates against the model without it; a look-alike group, declared
given the steps before it, is weighed again given all the others
(:func:`_groups_given_others`): an effect chosen after it can tell its
members apart (a lag from a latency, a wall drag from a uniform flow). Once
a form outside the library is discovered on what the search leaves,
:func:`groups_on_top` weighs each group again given it too.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from cosim_plugins.diagnose.lookalike import FAMILIES, evidence_of, group_of
from cosim_plugins.diagnose.result import DISCOVERED
from cosim_plugins.diagnose.verdict import AT_FLOOR, MIN_REDUCTION, MIN_T, fails_by, passes
from cosim_plugins.diagnose.wording import given_words

MAX_EFFECTS = 3  # default of --max-effects
SCREEN_KEEP = 3  # rounds after the first: candidates given a full fit after the quick screen
SCREEN_MIN = 0.03  # ... and only those whose quick fit lowers the error by at least this share
SCREEN_FAILED = 0.10  # ... and those whose quick fit raises it by this share or more (a fit that failed)
LOOKAHEADS = 2  # candidates of one round taken tentatively in turn when none passes alone (see _tentative)
#: Why a search stopped, in words.
STOPS = {"noise_floor": "the error is at the noise floor", "none_passes": "no remaining candidate passes",
         "max_effects": "--max-effects reached", "no_candidates": "no candidate left"}


@dataclass
class Fit:
    """A model and its held-out evaluation: ``ev`` {horizon: {"valid", "err"}}, ``summary`` {"rollout_mm", ...}."""

    model: object
    ev: dict
    summary: dict
    fitted: object = None  # the joint fit's outcome (parameters, standard errors), when a fit made it

    def error(self, key: str) -> float | None:
        """Mean held-out error [mm] at horizon ``key``."""
        return self.summary["rollout_mm"][key]


def t_text(entry: dict) -> str:
    """"t = 2.4", or "t = 3.5 over 3 folds" when the t was taken on every fold of the split (:mod:`.crossfold`)."""
    folds = entry.get("t_folds")
    return f"t = {entry['t_stat']:.1f}" + (f" over {folds} folds" if folds else "")


@dataclass
class Step:
    """One round's choice: ``effects`` is one name, or a look-alike group (best member first).

    ``entry`` is the best member's rank entry given the model before (reduction, t, parameters);
    ``fit`` the model with it; ``before`` the model it was compared with.
    """

    effects: list
    entry: dict
    fit: Fit
    before: Fit
    group_evidence: dict = field(default_factory=dict)  # {member: {"t_stat", "differ_mm", ...}} for a group
    member_fits: dict = field(default_factory=dict)  # {member: Fit} of every member, given the model before
    alone: dict | None = None  # a look-ahead's step: its rank entry alone, which did not pass (see select)
    given: list | None = None  # the effects ``entry``'s drop is conditional on (None: the steps before it)

    @property
    def is_group(self) -> bool:
        """True when the logs cannot tell the members of this step apart."""
        return len(self.effects) > 1


@dataclass
class Selection:
    """What the stepwise search chose, the ranking of every round, what the backward check dropped."""

    steps: list
    rounds: list  # [[rank entry, ...] per round], each sorted best first
    final: Fit
    start: Fit  # the reference the first round compared with
    stop: str  # "noise_floor" | "none_passes" | "max_effects" | "no_candidates"
    dropped: list = field(default_factory=list)  # [{"effect", "reduction", "t_stat"}] by the backward check
    rounds_given: list = field(default_factory=list)  # [[effect, ...] per round]: the model each round was given
    tentative: list = field(default_factory=list)  # [Step, ...] taken tentatively and dropped, in that order

    @property
    def chosen(self) -> list:
        """The effects in the final model: every named effect and each group's stand-in."""
        return [s.effects[0] for s in self.steps]


def select(fitter, start: Fit, candidates, first: tuple, max_effects: int, floor: dict, key: str,
           say=None) -> Selection:
    """Choose up to ``max_effects`` of ``candidates`` (Effects) stepwise on top of ``start``; see the module doc.

    ``first`` is the first round, (entries sorted best first, {effect: Fit}), from :func:`rank` (the noise
    floor is measured on its fits); ``fitter`` provides ``with_effects(fit, effects) -> (Fit, identifiable)``,
    ``refit(model) -> Fit``, ``entry(effect, fit, identifiable, fit_before) -> rank entry``,
    ``without(final, keep) -> Fit`` and ``paired_t``; ``floor`` is {horizon: noise floor [mm] or None}.
    """
    say = say or (lambda msg: None)
    current, steps, rounds, given, remaining = start, [], [], [], list(candidates)
    tentative = []  # the steps taken tentatively and dropped (tried again beside a form: standin.beside_form)
    by_name = {e.name: e for e in candidates}
    stop = "max_effects"
    pending = None  # a look-ahead: its tentative step's index in steps, its round and what came before it
    round_no = 0
    while round_no < max_effects:
        round_no += 1
        if not remaining:
            stop = "no_candidates"
            break
        if _at_floor(current.error(key), floor.get(key)):
            stop = "noise_floor"
            break
        if round_no == 1:
            entries, fits = first
        else:
            say(f"round {round_no}: {len(remaining)} candidates given {', '.join(s.effects[0] for s in steps)}")
            # after a tentative step every candidate gets the full fit: a quick fit on short windows can miss
            # the partner that only shows over the longer horizons
            # every remaining candidate, those not identifiable in an earlier round too: a step-out fitted beside a
            # missing flow can run to f_so = 100 Hz (never steps out), and given the flow it is found
            entries, fits = rank(fitter, current, remaining, key, say, screen=pending is None)
        rounds.append(entries)
        given.append([s.effects[0] for s in steps])  # a tentative step too: it may be dropped later
        best = next((e for e in entries if e["identifiable"]), None)
        if best is not None and passes(best, current.error(key), floor.get(key), key):
            entries, best = _full_family(fitter, current, entries, fits, best, by_name, key, say)
        failed = best is None or not passes(best, current.error(key), floor.get(key), key)
        if failed and pending is None and round_no < max_effects:
            pending = _Lookahead(index=len(steps), round_no=round_no, before=current, remaining=remaining,
                                 entries=entries, fits=fits)
        elif failed and pending is not None:  # nothing passes given the tentative step: it goes
            say(f"{steps[pending.index].effects[0]}, taken tentatively, is dropped: nothing passes given it")
            tentative.append(steps[pending.index])
            steps, current, remaining = pending.undo(steps)
            round_no = pending.round_no
        if failed:
            taken = pending and _tentative(fitter, pending, steps, remaining, by_name, key, say)
            if taken is None:
                pending, stop = None, "none_passes"
                break
            steps, current, remaining = taken
            continue
        members, evidence = group_of(fitter, best, entries, fits, floor.get(key), key)
        lead = next(e for e in entries if e["effect"] == members[0])
        if lead is not best and not passes(lead, current.error(key), floor.get(key), key):
            rival, lead = lead["effect"], best  # better over the horizons, but not enough to be named alone
            members, evidence = [best["effect"], rival], {rival: evidence_of(fitter, fits[best["effect"]],
                                                                            fits[rival], key)}
        members, evidence = _interchangeable(fitter, members, evidence, fits, by_name, key, say)
        chosen = fitter.refit(fits[lead["effect"]].model)
        steps.append(Step(effects=members, entry=lead, fit=chosen, before=current, group_evidence=evidence,
                          member_fits={m: fits[m] for m in members}))
        say(f"round {round_no}: chose {' ~ '.join(members)}: {current.error(key):.3f} -> {chosen.error(key):.3f} mm")
        current = chosen
        remaining = [e for e in remaining if e.name not in members]
        if pending is not None:
            ok, without = _confirmed(fitter, steps, pending, by_name, floor.get(key), key, say)
            if ok:
                confirmed = steps[pending.index]
                remaining = [e for e in remaining if e.name not in confirmed.effects]
                if confirmed.fit is not chosen:  # a look-alike explains more in the tentative step's place
                    current = fitter.refit(confirmed.fit.model)
                pending = None
                continue
            partner = steps[-1]
            alone = _partner_alone(fitter, partner, without, pending.before, by_name, floor.get(key), key, say)
            tentative.append(steps[pending.index])
            steps, current, remaining = pending.undo(steps)
            if alone is not None:
                pending = None  # the tentative step went, and nothing tentative is left to drop below
                steps.append(alone)
                current = alone.fit
                remaining = [e for e in remaining if e.name not in alone.effects]
                continue
            say(f"  {partner.effects[0]} dropped too")
            round_no = pending.round_no
            taken = _tentative(fitter, pending, steps, remaining, by_name, key, say)  # another may be the way in
            if taken is None:
                pending, stop = None, "none_passes"
                break
            steps, current, remaining = taken
    if pending is not None:  # the search stopped before the look-ahead's round chose: the tentative step goes
        say(f"{steps[pending.index].effects[0]}, taken tentatively, is dropped: the search stopped first")
        tentative.append(steps[pending.index])
        steps, current, _ = pending.undo(steps)
    selection = Selection(steps=steps, rounds=rounds, final=current, start=start, stop=stop, rounds_given=given,
                          tentative=tentative)
    if len(steps) >= 2:
        _backward(fitter, selection, by_name, floor.get(key), key, say)
    return selection


@dataclass
class _Lookahead:
    """A look-ahead under way: the round ``round_no`` where nothing passed (its ``entries`` and ``fits``), the
    model ``before`` it and the candidates ``remaining`` then; its tentative step is ``steps[index]``; ``tried``:
    the candidates taken tentatively from that round so far."""

    index: int
    round_no: int
    before: Fit
    remaining: list
    entries: list
    fits: dict
    tried: list = field(default_factory=list)

    def undo(self, steps: list) -> tuple[list, Fit, list]:
        """(steps, current model, remaining candidates) as they were before the tentative step."""
        return steps[:self.index], self.before, self.remaining


def _tentative(fitter, ahead: _Lookahead, steps: list, remaining: list, by_name: dict, key: str,
               say) -> tuple[list, Fit, list] | None:
    """(steps, current model, remaining candidates) with the next candidate of the look-ahead's round taken
    tentatively, or None when there is none: the best not tried yet whose full fit lowers the error by at least
    :data:`SCREEN_MIN`, at most :data:`LOOKAHEADS` in all. Two effects present at once can each explain little
    alone and much together (the baseline's parameters take up the other's absence): the step is kept only if
    the next round's choice passes given it and the two then earn their places together (:func:`_confirmed`).
    The round's best is not always the way in: a step-out (3.9 %) and a quadratic drag (0.3 %) lowered a case's
    error by 86 % together, but an anisotropic drag led the round (4.6 %) and nothing passed given it; taken
    second, the step-out let the drag pass."""
    if len(ahead.tried) >= LOOKAHEADS:
        return None
    for entry in ahead.entries:
        name = entry["effect"]
        if name in ahead.tried or not entry["identifiable"] or entry["reduction"] < SCREEN_MIN:
            continue
        if entry.get("screened"):  # the look-ahead needs its full fit
            (fit, identifiable), = fitter.with_each(ahead.before, [by_name[name]])
            ahead.fits[name], entry = fit, fitter.entry(by_name[name], fit, identifiable, ahead.before)
            if not entry["identifiable"] or entry["reduction"] < SCREEN_MIN:
                continue
        ahead.tried.append(name)
        say(f"round {ahead.round_no}: none passes alone; {name} ({entry['reduction']:+.1%}, {t_text(entry)}) "
            "taken tentatively, to be kept only with the next round's choice")
        step = Step(effects=[name], entry=entry, fit=fitter.refit(ahead.fits[name].model), before=ahead.before,
                    alone=entry)
        return [*steps, step], step.fit, [e for e in remaining if e.name != name]
    return None


def _confirmed(fitter, steps: list, pending: _Lookahead, by_name: dict, floor: float | None, key: str,
               say) -> tuple[bool, Fit]:
    """(whether a look-ahead's tentative step (``steps[pending.index]``) and the step just chosen given it (the last)
    earn their places together, the model refitted without the tentative step): the two lower the error of the
    model before them by the verdict's gates, and the tentative one still passes them once the other is in. If
    so, the tentative step's entry becomes its drop given the others (in place)."""
    index, before = pending.index, pending.before
    tentative, final = steps[index], steps[-1].fit
    pair = fitter.entry(by_name[steps[-1].effects[0]], final, True, before)
    others = [st.effects[0] for i, st in enumerate(steps) if i != index]
    without = fitter.without(final, [by_name[n] for n in others])
    given = fitter.entry(by_name[tentative.effects[0]], final, True, without)
    ok = passes(pair, before.error(key), floor, key) and passes(given, without.error(key), floor, key)
    name = tentative.effects[0]
    say(f"  together with {steps[-1].effects[0]}: {before.error(key):.3f} -> {final.error(key):.3f} mm "
        f"({pair['reduction']:+.1%}, {t_text(pair)}); {name} given the others {given['reduction']:+.1%} "
        f"({t_text(given)}): " + ("both kept" if ok else f"{name} dropped"))
    if ok:
        steps[index] = _given_family(fitter, replace(tentative, entry=given, before=without, given=others,
                                                     fit=steps[-1].fit, member_fits={name: steps[-1].fit}),
                                     by_name, floor, key, say)
    return ok, without


def _partner_alone(fitter, partner: Step, without: Fit, before: Fit, by_name: dict, floor: float | None, key: str,
                   say) -> Step | None:
    """The step chosen given a tentative one that was not confirmed, on its own: when the model refitted without
    the tentative effect (``without``: from the pair's solution) passes the gates against the model before the
    tentative step (``before``), that effect is named alone, else None. A step-out whose first-round fit ran to
    f_so = 100 Hz (acting on nothing) lowered the error by 68 % given a quadratic drag taken tentatively, the
    drag then adding nothing given it; refitted alone from the pair's solution it lowers the baseline's error by
    86 %. A look-alike group is not named this way (its members were weighed given the tentative effect)."""
    if len(partner.effects) != 1:
        return None
    name = partner.effects[0]
    entry = fitter.entry(by_name[name], without, True, before)
    if not passes(entry, before.error(key), floor, key):
        return None
    say(f"  {name} alone, refitted from the pair's solution: {before.error(key):.3f} -> {without.error(key):.3f} mm "
        f"({entry['reduction']:+.1%}, {t_text(entry)}): kept")
    return Step(effects=[name], entry=entry, fit=without, before=before)


def _given_family(fitter, step: Step, by_name: dict, floor: float | None, key: str, say) -> Step:
    """A look-ahead's confirmed step with its look-alikes weighed as a normal round weighs them, but given the
    effects chosen with it (``step.before``): each look-alike (:data:`.lookalike.FAMILIES`, and the members of a
    group the step already declares: a wall drag tied with a flow) is refitted in its place, and a group is
    declared when the logs cannot tell them apart (:func:`.lookalike.group_of`), led by a look-alike that explains
    more; a look-alike among those effects (``step.given``) is not weighed. ``step.fit`` is the model with the
    step's effect and the others."""
    name = step.effects[0]
    family = set(next((f for f in FAMILIES if name in f), ())) | set(step.effects)
    # a look-alike chosen as one of the other steps is already in the model: refitted in this step's place it
    # would stand in the model twice
    taken = set(step.given or ())
    rivals = [by_name[n] for n in sorted(family) if n != name and n in by_name and n not in taken]
    if not rivals:
        return step
    say(f"  {name}'s look-alikes in its place, given {given_words(step.given, ', ')}: "
        f"{', '.join(e.name for e in rivals)}")
    entries, fits = [step.entry], {name: step.fit}
    for effect, (fit, identifiable) in zip(rivals, fitter.with_each(step.before, rivals)):
        entries.append(fitter.entry(effect, fit, identifiable, step.before))
        fits[effect.name] = fit
        say(f"  {effect.name}: {entries[-1]['reduction']:+.1%} at {key} s ({t_text(entries[-1])})")
    entries.sort(key=lambda r: (r["identifiable"], r["reduction"]), reverse=True)
    members, evidence = group_of(fitter, step.entry, entries, fits, floor, key)
    members, evidence = _interchangeable(fitter, members, evidence, fits, by_name, key, say)
    lead = next(e for e in entries if e["effect"] == members[0])
    return replace(step, effects=members, entry=lead, fit=fits[members[0]], group_evidence=evidence,
                   member_fits={m: fits[m] for m in members})


def _full_family(fitter, current: Fit, entries: list, fits: dict, best: dict, by_name: dict, key: str, say):
    """(entries, best) once every look-alike of ``best`` (:data:`.lookalike.FAMILIES`) that only had the quick
    screen's fit has its full fit too: a quick fit of a lag can miss what the full fit of a latency finds, and
    the group test needs both at their best. ``fits`` is updated in place."""
    family = next((f for f in FAMILIES if best["effect"] in f), ())
    todo = [by_name[e["effect"]] for e in entries if e.get("screened") and e["effect"] in family]
    if not todo:
        return entries, best
    say(f"  full fits of {best['effect']}'s look-alikes: {', '.join(e.name for e in todo)}")
    done = {}
    for effect, (fit, identifiable) in zip(todo, fitter.with_each(current, todo)):
        done[effect.name] = fitter.entry(effect, fit, identifiable, current)
        fits[effect.name] = fit
        got = done[effect.name]
        say(f"  {effect.name}: {got['reduction']:+.1%} at {key} s ({t_text(got)})")
    entries = sorted((done.get(e["effect"], e) for e in entries), key=lambda r: (r["identifiable"], r["reduction"]),
                     reverse=True)
    return entries, next(e for e in entries if e["identifiable"])


def _interchangeable(fitter, members: list, evidence: dict, fits: dict, by_name: dict, key: str, say):
    """(members, evidence) without the rivals that add to the leader: each rival is refitted jointly with the
    leader, and one that still lowers the error (>= MIN_REDUCTION, t >= MIN_T) explains something else (two
    effects present at once), so it is left to the next round instead of grouped."""
    kept = [members[0]]
    for name in members[1:]:
        both, identifiable = fitter.with_effects(fits[members[0]], [by_name[name]])
        entry = fitter.entry(by_name[name], both, identifiable, fits[members[0]])
        if entry["reduction"] >= MIN_REDUCTION and entry["t_stat"] >= MIN_T:
            say(f"  {name} adds {entry['reduction']:+.1%} to {members[0]} ({t_text(entry)}): "
                "not a look-alike")
            evidence = {k: v for k, v in evidence.items() if k != name}
            continue
        evidence[name] = {**evidence[name], "adds": entry["reduction"], "adds_t": entry["t_stat"]}
        kept.append(name)
    return kept, evidence


def rank(fitter, before: Fit, effects, key: str, say=None, screen: bool = False) -> tuple[list, dict]:
    """(rank entries sorted best first, {effect: Fit}): each effect refitted jointly with ``before``'s model.

    ``screen``: every effect first gets a quick fit (``fitter.with_effects(..., quick=True)``); the full fit
    goes to the :data:`SCREEN_KEEP` best whose quick drop reaches :data:`SCREEN_MIN` (the :data:`SCREEN_KEEP`
    best when none does: an actuation lag given a quadratic drag gained 0.0 % by its quick fit, 81 % by its
    true form), and so does every effect whose quick fit changed nothing (not identifiable); the others keep
    their quick entry (marked ``"screened": True``), except those whose quick fit raised the error by
    :data:`SCREEN_FAILED` or more: the effect at its null value reproduces the reference, so such a fit failed
    rather than measured the effect. A quick fit stops sooner and
    skips the open-loop polish that ``before`` had, so its drop is measured against ``before`` refitted the same
    quick way, with no effect added (``fitter.with_effects(before, [], quick=True)``): against the polished
    ``before`` every quick fit would look worse, the polish's gain counted as the candidate's loss.
    :data:`SCREEN_MIN` is well below the verdict's own threshold.
    """
    entries, fits = {}, {}
    todo = list(effects)
    if screen and len(effects) > SCREEN_KEEP:
        # the quick fits' reference (no effect added) first, in the same processes as the candidates'
        (same_way, _), *quick = fitter.with_each(before, [None, *effects], quick=True)
        for effect, (fit, identifiable) in zip(effects, quick):
            entries[effect.name] = {**fitter.entry(effect, fit, identifiable, same_way), "screened": True}
            fits[effect.name] = fit
        ranked = sorted((e for e in entries.values() if e["identifiable"]), key=lambda e: -e["reduction"])
        # when no quick fit reaches SCREEN_MIN the quick fits are least to be trusted: the best still get the full one
        hopeful = [e for e in ranked if e["reduction"] >= SCREEN_MIN][:SCREEN_KEEP] or ranked[:SCREEN_KEEP]
        # a quick fit that changes nothing says little: a step-out's six evaluations left f_so above the band,
        # where it acts on nothing, while its full fit lowered the error by 77 % given the same model
        hopeful += [e for e in entries.values() if not e["identifiable"]]
        # nor does one that ends far above the reference it started from (the effect at its null value is that
        # reference): a step-out's quick fit beside a uniform flow standing in for a shear lost 25 %, its full fit
        # gained 23 % given the same model (t = 6.4)
        hopeful += [e for e in entries.values() if e["identifiable"] and e["reduction"] <= -SCREEN_FAILED]
        todo = [e for e in effects if e.name in {h["effect"] for h in hopeful}]
        if say:
            say(f"  screened {len(effects)} candidates by a quick fit; refitting "
                + (", ".join(e.name for e in todo) or "none"))
    for effect, (fit, identifiable) in zip(todo, fitter.with_each(before, todo)):
        entries[effect.name] = fitter.entry(effect, fit, identifiable, before)
        fits[effect.name] = fit
    ordered = sorted(entries.values(), key=lambda r: (r["identifiable"], r["reduction"]), reverse=True)
    if say:
        for e in ordered:
            say(f"  {e['effect']}: " + (f"{e['reduction']:+.1%} at {key} s ({t_text(e)})"
                                        if e["identifiable"] else "not identifiable from these logs")
                + (" (quick fit)" if e.get("screened") else ""))
    return ordered, fits


def _backward(fitter, sel: Selection, by_name: dict, floor: float | None, key: str, say) -> None:
    """Drop, one at a time, a chosen effect that no longer earns its place once the others are in; when one went,
    the steps left are measured again given what is left (:func:`_measured_again`): a drop measured given an
    effect no longer in the model is not one. A quadratic drag chosen first (64 %) and a step-out given it,
    the step-out dropped: the drag alone, refitted from the pair's solution, erred 0.14 mm, not the 0.27 mm its
    first round had quoted."""
    before = len(sel.dropped)
    while len(sel.steps) >= 2:
        trials = _given_the_others(fitter, sel, by_name)
        if not _drop_weakest(sel, trials, floor, key, say):
            _groups_given_others(fitter, sel, trials, by_name, floor, key, say)
            break
    if len(sel.dropped) > before:
        _measured_again(fitter, sel, by_name, floor, key, say)


def _given_the_others(fitter, sel: Selection, by_name: dict) -> list:
    """[(reduction, step index, entry, model without the step)]: each step's drop given every other step."""
    trials = []
    for i, step in enumerate(sel.steps):
        keep = [by_name[s.effects[0]] for j, s in enumerate(sel.steps) if j != i]
        without = fitter.without(sel.final, keep)
        entry = fitter.entry(by_name[step.effects[0]], sel.final, True, without)
        trials.append((entry["reduction"], i, entry, without))
    return trials


def _drop_weakest(sel: Selection, trials: list, floor: float | None, key: str, say) -> bool:
    """True when the step with the smallest drop given the others (``trials``) fails the gates: it is dropped."""
    reduction, i, entry, without = min(trials, key=lambda x: x[0])
    if passes(entry, without.error(key), floor, key):
        return False
    step = sel.steps.pop(i)
    say(f"backward: {step.effects[0]} dropped once the others are in ({fails_by(reduction, entry['t_stat'])})")
    sel.dropped.append({"effect": step.effects[0], "reduction": reduction, "t_stat": entry["t_stat"]})
    sel.final = without
    return True


def left_after_removal(fitter, sel: Selection, by_name: dict, floor: float | None, key: str, say,
                       found=None) -> list:
    """The steps left once others were taken out of ``sel`` (stand-ins for a form outside the library), each
    measured again given the other steps left (in place): a drop measured given an effect no longer in the model
    is not one. A step that then fails the gates is dropped, weakest first, as the backward check drops one;
    returns those drops (``sel.dropped``'s new entries). A background flow chosen first and a gradient force
    given it, the flow then dropped as a stand-in: the force's drop given the flow said nothing of the force
    alone.

    With ``found`` (``sel.final`` refitted with the form discovered once the stand-ins are out, its last effect),
    each is measured given that form too (``given`` ends with :data:`DISCOVERED`), and ``sel.final`` stays
    without it: the form takes the stand-in's place, and a step that earned its place beside the stand-in only
    (a step-out beside the uniform flow standing in for a shear) earns it beside the form, not alone."""
    before, bare, bare_fitter = len(sel.dropped), sel.final, fitter
    if found is not None:
        fitter, sel.final = fitter.beside([found.model.effects[-1]]), found
    _measured_again(fitter, sel, by_name, floor, key, say, [DISCOVERED] if found is not None else [])
    if found is not None:  # the form out again: the model with the steps kept (refitted when some went)
        sel.final = (bare if len(sel.dropped) == before else
                     bare_fitter.without(sel.final, [by_name[s.effects[0]] for s in sel.steps]))
    return sel.dropped[before:]


def _measured_again(fitter, sel: Selection, by_name: dict, floor: float | None, key: str, say,
                    also_given: list = ()) -> None:
    """Every step of ``sel`` but a group's measured given every other step (in place: its entry, the model before
    it, ``given`` those others and ``also_given``), the weakest dropped first while one fails the gates. A step
    left alone is measured against the baseline refitted from the final solution, no longer as a look-ahead."""
    while sel.steps:
        trials = _given_the_others(fitter, sel, by_name)
        if _drop_weakest(sel, trials, floor, key, say):
            continue
        for _, i, entry, without in trials:
            step = sel.steps[i]
            if not step.is_group:
                others = [s.effects[0] for j, s in enumerate(sel.steps) if j != i] + list(also_given)
                sel.steps[i] = replace(step, entry=entry, before=without, fit=sel.final, given=others,
                                       alone=step.alone if others else None)
        return


def given_later(fitter, sel: Selection, later: Selection, by_name: dict, floor: float | None, key: str,
                say) -> list:
    """The drops of ``sel``'s steps once the effects chosen on top of a discovered form (``later``, whose final
    model holds them all and the form; ``fitter`` keeps the form in its models, :meth:`~.fitting.Fitter.beside`)
    are in: every step of both searches measured given all the others and the form, the weakest dropped while it
    fails the gates, as the backward check does. Both are updated in place (``later.final`` without what went,
    ``later.dropped`` its own drops); returns ``sel``'s. A heading lag of 0.23 s chosen first (26 %) beside a
    thrust varying with position was, once the form held the thrust and an actuation lag was chosen on top of it,
    no longer needed."""
    both = Selection(steps=[*sel.steps, *later.steps], rounds=[], final=later.final, start=later.start,
                     stop=later.stop)
    while both.steps and _drop_weakest(both, _given_the_others(fitter, both, by_name), floor, key, say):
        pass
    kept = {id(st) for st in both.steps}
    drops = {d["effect"]: d for d in both.dropped}
    mine = [drops[st.effects[0]] for st in sel.steps if id(st) not in kept]
    later.dropped += [drops[st.effects[0]] for st in later.steps if id(st) not in kept]
    sel.steps = [st for st in sel.steps if id(st) in kept]
    later.steps = [st for st in later.steps if id(st) in kept]
    later.final = both.final
    return mine


def _groups_given_others(fitter, sel: Selection, trials: list, by_name: dict, floor: float | None, key: str,
                         say) -> None:
    """Each look-alike group of ``sel`` weighed again given every other chosen effect (:func:`_given_family`, in
    place). A group was declared given the steps before it only; an effect chosen after it can tell its members
    apart: an actuation lag and a latency each lowered a case's error by 25 % beside a missing uniform flow, and
    given the flow the lag left 0.14 mm and the latency 0.25 mm. When another member leads then, the final
    model takes it, and the other steps' drops are measured again given it. ``trials``: the backward check's
    last (reduction, step index, entry given the others, model without the step)."""
    for _, i, entry, without in sorted(trials, key=lambda x: x[1]):
        step = sel.steps[i]
        if not step.is_group:
            continue
        others = [s.effects[0] for j, s in enumerate(sel.steps) if j != i]
        given = replace(step, entry=entry, before=without, given=others, fit=sel.final,
                        member_fits={step.effects[0]: sel.final})
        weighed = _given_family(fitter, given, by_name, floor, key, say)
        sel.steps[i] = weighed
        if weighed.effects[0] == step.effects[0]:
            continue
        say(f"  given {', '.join(others)}, {weighed.effects[0]} leads {step.effects[0]}'s group: "
            + ("named alone" if not weighed.is_group else f"group {' ~ '.join(weighed.effects)}"))
        sel.final = fitter.refit(weighed.fit.model)
        for j, other in enumerate(sel.steps):
            if j == i:
                continue
            keep = [by_name[s.effects[0]] for k, s in enumerate(sel.steps) if k != j]
            before = fitter.without(sel.final, keep)
            sel.steps[j] = replace(other, entry=fitter.entry(by_name[other.effects[0]], sel.final, True, before),
                                   before=before, fit=sel.final,
                                   given=[s.effects[0] for k, s in enumerate(sel.steps) if k != j])


def groups_on_top(fitter, sel: Selection, found: Fit, by_name: dict, floor: float | None, key: str,
                  say) -> tuple[list, Fit]:
    """(the indices of ``sel``'s steps now named, the model with the discovered form): each look-alike group of
    the search weighed again given the other chosen effects and a discovered form (``fitter`` keeps the form in
    its models, :meth:`~.fitting.Fitter.beside`; ``found``: the chosen model with the form). A form outside the
    library beside a lag can hide what tells the lag from a latency: an actuation lag of 0.34 s beside a
    turning flow was grouped with a latency (35 % against 30 %), and the flow, found on what the lag left,
    explained 63 % more. A group is named when, given the form and the others, one member leads alone
    (:func:`_given_family`) and passes the verdict's gates; the step then holds that member, its drop given
    them (``given`` ends with :data:`DISCOVERED`) and the model with the form; a group that stays one stays as
    declared. When another member leads, ``found`` takes it (refitted); ``sel.final`` (without the form) is
    the caller's to refit."""
    named = []
    for i, step in enumerate(sel.steps):
        if not step.is_group:
            continue
        others = [s.effects[0] for j, s in enumerate(sel.steps) if j != i]
        without = fitter.without(found, [by_name[n] for n in others])
        entry = fitter.entry(by_name[step.effects[0]], found, True, without)
        given = replace(step, entry=entry, before=without, given=[*others, DISCOVERED], fit=found,
                        member_fits={step.effects[0]: found})
        weighed = _given_family(fitter, given, by_name, floor, key, say)
        if weighed is given or weighed.is_group or not passes(weighed.entry, without.error(key), floor, key):
            say(f"  given the discovered form, {' ~ '.join(step.effects)} stay a group")
            continue
        say(f"  given the discovered form, {weighed.effects[0]} leads {' ~ '.join(step.effects)} alone: named "
            f"({weighed.entry['reduction']:+.1%}, {t_text(weighed.entry)})")
        if weighed.effects[0] != step.effects[0]:
            found = fitter.refit(weighed.fit.model)
            weighed = replace(weighed, fit=found)
        sel.steps[i] = weighed
        named.append(i)
    return named, found


def _at_floor(err: float | None, floor: float | None) -> bool:
    return err is not None and floor is not None and err <= (1.0 + AT_FLOOR) * floor

