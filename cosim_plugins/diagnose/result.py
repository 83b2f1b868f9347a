"""The result of a diagnosis, typed: what :func:`cosim_plugins.diagnose.pipeline.run` finds.

:class:`DiagnosisResult` holds every figure a diagnosis reports; :mod:`.render` turns it into
diagnosis.json (:func:`~.render.to_json`), the terminal summary and report.md. Each field's name is
its diagnosis.json key, so the file reads like the classes below.

Conventions: errors are mean open-loop errors on the held-out windows [mm]; a ``{horizon: ...}`` mapping
is keyed by the horizon's name as given (``"0.1"``, ``"1.0"``: seconds, as text) and holds None where no
window reaches that horizon; a reduction is ``1 - after / before`` (a share, not a percent); a t is the
paired t over blocks of windows (:func:`~.verdict.paired_t`; a candidate's, the larger of it and the trimmed
t, :func:`~.verdict.gain_t`). ``params`` of a fitted effect map each
parameter's name to ``{"value", "std", "unit"}``.

The pipeline builds the result step by step (the verdict reads what is there so far); once
``run`` returns it, nothing changes it. A field marked ``omit`` in its metadata is left out of
diagnosis.json when it is None (an optional section); every other field is always written.
"""

from __future__ import annotations

import types
from dataclasses import MISSING, dataclass, field, fields, is_dataclass
from typing import Union, get_args, get_origin, get_type_hints

Horizons = dict  # {horizon name: value}, see the module doc
#: In a step's ``given`` and a dropped effect's: the discovered form (a step weighed given it; an effect standing in
#: for it).
DISCOVERED = "discovered"


def _optional():
    """A field left out of diagnosis.json when it is None."""
    return field(default=None, metadata={"omit": True})


@dataclass
class Split:
    """Which data are held out: ``kind`` "time_blocks" (every ``held_out`` block of ``block_s`` seconds of each
    log) or "validate" (``validate_logs`` --validate logs, the ``train_logs`` given logs train)."""

    kind: str
    block_s: float | None = _optional()
    held_out: str | None = _optional()
    train_logs: int | None = _optional()
    validate_logs: int | None = _optional()


@dataclass
class Baseline:
    """The baseline model: ``rollout_mm`` {horizon: error [mm]}, ``windows`` {horizon: held-out windows valid
    there}, ``params`` {name: value} (the host model's units), ``std`` {name: standard error or None},
    ``conditioning`` the fit's Jacobian diagnostics ({"condition", "at_bound", "tradeoffs", ...})."""

    model: str
    rollout_mm: Horizons
    windows: Horizons
    params: dict
    std: dict
    conditioning: dict


@dataclass
class Reference:
    """The model the effects are refitted into when it is not the baseline (the physical model, with the
    ``--add`` effects): ``rollout_mm`` and ``windows`` as :class:`Baseline`'s."""

    model: str
    effects: list
    rollout_mm: Horizons
    windows: Horizons


@dataclass
class Noise:
    """The camera noise and the noise floor: ``sigma_mm`` {"x", "y", "z": sigma [mm]} or None (too few
    consecutive frames), ``floor_mm`` {horizon: the error a perfect model would show [mm] or None},
    ``tau_s`` the velocity time constant the floor assumes [s], ``tau_from`` where it came from (words);
    ``reached_by`` the candidate whose refit went below the floor estimated from the noise, at the reference
    horizon, and ``estimated_mm`` that estimate {horizon: mm or None}, when the floor was lowered to that refit's
    errors (:func:`.pipeline.floor_reached`), else None (then left out of diagnosis.json)."""

    sigma_mm: dict | None
    floor_mm: Horizons
    tau_s: float
    tau_from: str
    reached_by: str | None = _optional()
    estimated_mm: Horizons | None = _optional()


@dataclass
class Localisation:
    """Where, when and under which conditions the error concentrates (:mod:`.localise`), of ``model``:
    ``windows`` windows of all logs, ``mean_mm`` their mean error [mm], ``mean_error_vector_mm`` (3,),
    ``direction_coherence`` |mean vector| / mean norm, ``bins`` {feature: {"edges", "mean_mm", "count", "eta2",
    ...}}, ``ranked_features`` strongest first, ``clues`` sentences, ``groups`` {group: [feature, ...]}."""

    windows: int
    mean_mm: float
    mean_error_vector_mm: list
    direction_coherence: float
    bins: dict
    ranked_features: list
    clues: list
    groups: dict
    model: str


@dataclass
class Added:
    """The ``--add`` effects fitted into the reference model: ``params`` {name: {"value", "std", "unit"}},
    ``std`` {name: standard error}, the error before (``before_mm``) and after (``rollout_mm``) and the
    ``reduction`` at every horizon."""

    effects: list
    params: dict
    std: dict
    before_mm: Horizons
    rollout_mm: Horizons
    conditioning: dict
    reduction: Horizons


@dataclass
class RunnerUp:
    """The second identifiable candidate of the first round, and the paired t of the best against it."""

    effect: str
    reduction: float
    t_stat: float


@dataclass
class RankEntry:
    """A candidate refitted jointly with the reference model (the first round of the stepwise search).

    ``kind``: the effect's kind ("force", "input", "sensor", or "drift" for the --per-log fit);
    ``rollout_mm`` {horizon: error [mm]}; ``reduction`` at the reference horizon, ``reduction_by_horizon``
    at each; ``t_stat`` against the reference; ``identifiable``: its parameters change the predictions;
    ``fit`` the fit's figures ({"rms_mm", "evaluations", "status", "start"}); ``doc`` the effect's words;
    ``screened``: True when only the quick screen's fit was made; ``runner_up`` on the best entry only;
    ``t_folds``: the folds of the split ``t_stat`` was taken over, when more than one (:mod:`.crossfold`).
    """

    effect: str
    kind: str
    rollout_mm: Horizons
    reduction: float
    reduction_by_horizon: Horizons
    t_stat: float
    identifiable: bool
    params: dict
    fit: dict
    conditioning: dict
    doc: str
    screened: bool | None = _optional()
    runner_up: RunnerUp | None = _optional()
    t_folds: int | None = _optional()


@dataclass
class RoundEntry:
    """A candidate in a round of the stepwise search, compact: its error at the reference horizon [mm]."""

    effect: str
    rollout_mm: float | None
    reduction: float
    t_stat: float
    identifiable: bool


@dataclass
class GroupEvidence:
    """How far the logs tell a group's leader from a rival (:mod:`.lookalike`): paired t at the reference
    horizon and over every horizon (positive: the leader is better), their predictions' mean distance [mm] over
    all held-out windows and on the log that separates them most (``differ_weighted_mm``: that distance weighted
    by the log's length, see :func:`.lookalike.evidence_of`), and what the rival ``adds`` (reduction, with its t
    ``adds_t``) once refitted together with the leader."""

    t_stat: float
    t_horizons: float
    differ_mm: float
    differ_log_mm: float | None = _optional()
    differ_weighted_mm: float | None = _optional()
    adds: float | None = _optional()
    adds_t: float | None = _optional()


@dataclass
class StepResult:
    """One round's choice: ``effects`` one name, or a look-alike group (best member first, ``group`` True);
    the errors at the reference horizon before and after it [mm], its ``reduction`` and ``t_stat`` against the
    model before, the best member's ``params``; ``group_evidence`` {rival: evidence} for a group; ``given`` the
    effects that drop is conditional on (the steps before it, or for a look-ahead's step the others; None in a
    diagnosis.json written before it was kept: the steps before; :data:`DISCOVERED` among them: a look-alike
    group named given the discovered form, :func:`.stepwise.groups_on_top`); ``alone`` a look-ahead's step's own entry,
    which did not pass (:mod:`.stepwise`), else None."""

    effects: list
    group: bool
    rollout_before_mm: float | None
    rollout_mm: float | None
    reduction: float
    t_stat: float
    params: dict
    group_evidence: dict[str, GroupEvidence]
    given: list | None = _optional()
    alone: RoundEntry | None = _optional()


@dataclass
class Dropped:
    """An effect the backward check took out again; ``given`` "drift": the drift test did, "on_top": it failed
    given the discovered form and the effects chosen on top of it (:func:`.stepwise.given_later`), "discovered": it
    stands in for a form outside the library (:mod:`.standin`), whose ``terms`` were found without it and lower
    the error by ``form_reduction`` (paired t ``form_t_stat``) given it; ``part_of`` the pattern of that form
    (a "swirl" or "shear", :data:`.discover.FLOW_PATTERNS`) when the effect, a uniform flow, is its uniform part.
    ``reduction``, ``t_stat``: the effect's drop given the others (and the drift, or the form)."""

    effect: str
    reduction: float
    t_stat: float
    given: str | None = _optional()
    terms: list | None = _optional()
    form_reduction: float | None = _optional()
    form_t_stat: float | None = _optional()
    part_of: str | None = _optional()


@dataclass
class Joint:
    """The chosen effects together: the final model's ``rollout_mm`` and ``reduction`` against the reference,
    at every horizon."""

    effects: list
    rollout_mm: Horizons
    reduction: Horizons


@dataclass
class Stepwise:
    """The stepwise search (:mod:`.stepwise`): ``stop`` why it stopped (a key of ``stepwise.STOPS``),
    ``rounds`` each round's candidates best first, the ``steps`` chosen, the effects ``dropped``, the
    ``joint`` model; ``given_discovered``: the search again on top of a discovered form, when it ran;
    ``rounds_given``: the effects each round was given (a tentative step dropped later among them; absent in
    files written before it was recorded)."""

    max_effects: int
    stop: str
    rounds: list[list[RoundEntry]]
    steps: list[StepResult]
    dropped: list[Dropped]
    joint: Joint
    given_discovered: Stepwise | None = _optional()
    rounds_given: list[list[str]] | None = _optional()

    def named_on_top(self) -> set[str]:
        """The effects the search on top of the discovered form chose (each member of a group)."""
        return {m for st in (self.given_discovered.steps if self.given_discovered else ()) for m in st.effects}


@dataclass
class DriftExplains:
    """The drift fit a flag shows (``fit``: "per log", "a trend from log to log", "a trend within the logs"):
    its held-out ``rollout_mm`` {horizon: error [mm]}, ``reduction`` and ``t_stat`` at the reference horizon."""

    fit: str
    rollout_mm: Horizons
    reduction: float
    t_stat: float


@dataclass
class GivenDrift:
    """A chosen effect checked again once the drift is in: its ``reduction`` and ``t_stat``, and whether it
    still passes the verdict's tests (``kept``)."""

    effect: str
    reduction: float
    t_stat: float
    kept: bool


@dataclass
class DriftResult:
    """The drift test (:mod:`.drift`). Either ``skipped`` (why) with nothing ``flagged``, or: ``params`` fitted
    per log and per block of time, ``order`` of the logs ("file order" or "t_start"), ``flagged`` quantities
    ("within:NAME" for a trend within the logs), ``per_log`` {param: [value per log]}, ``t`` {quantity: trend
    t}, ``words`` one sentence per flag; ``between`` / ``within`` the per-log and per-block fits' held-out
    figures and per-quantity tests (dicts: {"rollout_mm", "reduction", "t_stat", "quantities": {quantity:
    {"values", "std", "p", "slope_t", ...}}, ...}); ``explains`` the flag's fit; ``given_drift`` each chosen
    effect checked again."""

    params: list | None = _optional()
    order: str | None = _optional()
    flagged: list = field(default_factory=list)
    per_log: dict | None = _optional()
    t: dict | None = _optional()
    words: list | None = _optional()
    between: dict | None = _optional()
    within: dict | None = _optional()
    explains: DriftExplains | None = _optional()
    given_drift: list[GivenDrift] | None = _optional()
    skipped: str | None = _optional()


@dataclass
class Discovered:
    """A form outside the library (:mod:`.discover`): ``status`` "found", "none", "too_short" or
    "unsupported", with an ``explanation`` unless found; when found the chosen ``terms``, their
    ``expressions``, fitted ``params``, ``words``, the ``file`` written, and the refit's ``rollout_mm``,
    ``reduction`` (reference horizon), ``reduction_by_horizon`` and ``t_stat`` against the chosen effects;
    ``pattern`` the kind its linear terms make (:func:`.discover.pattern`: "swirl", "thrust", "shear",
    "gradient", "push"); ``path`` [[term, error], ...] the forward selection's steps; ``refines`` the chosen
    effect whose own terms do what the form does (:func:`.standin.own_law_misfit`: its law, not a new effect)."""

    status: str
    explanation: str | None = _optional()
    terms: list | None = _optional()
    expressions: dict | None = _optional()
    params: dict | None = _optional()
    words: list | None = _optional()
    pattern: str | None = _optional()
    path: list | None = _optional()
    rollout_mm: Horizons | None = _optional()
    file: str | None = _optional()
    reduction: float | None = _optional()
    reduction_by_horizon: Horizons | None = _optional()
    t_stat: float | None = _optional()
    refines: str | None = _optional()


@dataclass
class ExperimentPath:
    """The experiment's path: a circle of ``radius_mm`` around ``center_mm`` (x, y, z) [mm]."""

    plugin: str
    radius_mm: float
    center_mm: list


@dataclass
class ExperimentFiles:
    """The experiment's files, relative to the output folder: the scenario and the spin-rate schedule."""

    scenario: str
    excitation: str


@dataclass
class Tried:
    """An excitation the experiment design tried (words) on the circle at ``place`` (the workspace's "centre" or
    a side, e.g. "+z") and the predicted ``separation_mm`` of the members."""

    excitation: str
    separation_mm: float
    place: str = "centre"


@dataclass
class ExperimentResult:
    """The experiment designed to tell a look-alike group's ``members`` apart (:mod:`.experiment`): the
    excitation's ``kind`` (words) and ``params``, ``duration_s``, the predicted ``separation_mm`` against the
    ``floor_mm`` and their ratio, every excitation ``tried``."""

    members: list
    kind: str
    params: dict
    duration_s: float
    separation_mm: float
    floor_mm: float | None
    separation_over_floor: float | None
    path: ExperimentPath
    files: ExperimentFiles
    tried: list[Tried]


@dataclass
class Verdict:
    """What the diagnosis concludes: ``effect`` the first effect named (or None), ``effects`` every effect named
    in the order chosen, ``lookalikes`` groups the logs cannot tell apart, ``status`` ("explained",
    "discovered", "drift", "noise_floor", "unexplained") and the ``explanation`` in words."""

    effect: str | None
    effects: list
    lookalikes: list
    status: str
    explanation: str


@dataclass
class DiagnosisResult:
    """Everything a diagnosis finds; diagnosis.json is :func:`.render.to_json` of it.

    ``logs`` / ``validate`` the log paths; ``dt_s`` the control period [s]; ``horizons_s`` {name: horizon [s]};
    ``reference_horizon_s`` the ranking's [s]; ``lead_in_s`` the lead-in the initial state is solved on [s];
    ``effects_files`` the --effects-file paths and ``file_effects`` the effects they registered;
    ``noise_floor_mm`` the floor at the reference horizon [mm]; ``ranking`` the first round, best first;
    ``fit_notes`` sentences on the fits; ``timing_s`` the diagnosis' wall time [s].
    """

    logs: list
    validate: list
    split: Split
    dt_s: float
    horizons_s: Horizons
    reference_horizon_s: float
    lead_in_s: float
    effects_files: list
    file_effects: list
    baseline: Baseline
    reference: Reference | None
    noise: Noise
    noise_floor_mm: float | None
    localisation: Localisation
    added: Added | None
    ranking: list[RankEntry]
    stepwise: Stepwise
    drift: DriftResult | None = None
    fit_notes: list | None = None
    verdict: Verdict | None = None
    discovered: Discovered | None = _optional()
    experiment: ExperimentResult | None = _optional()
    timing_s: float | None = None

    @property
    def reference_key(self) -> str:
        """The name of the reference horizon (a key of ``horizons_s``)."""
        return next(k for k, v in self.horizons_s.items() if v == self.reference_horizon_s)

    @property
    def effects_model(self) -> Baseline | Reference:
        """The model the candidates were refitted into: the reference, or the baseline when it takes effects."""
        return self.reference or self.baseline

    @classmethod
    def from_json(cls, data: dict) -> DiagnosisResult:
        """The result a diagnosis.json holds (``json.load`` of it); a ValueError names a key that does not fit."""
        return load(cls, data)


def load(cls, data: dict, where: str = "diagnosis.json"):
    """An instance of the dataclass ``cls`` from its JSON form ``data`` (nested dataclasses, lists of them and
    optional ones included); a ValueError names an unknown or missing key and where it is."""
    if not isinstance(data, dict):
        raise ValueError(f"{where}: expected an object for {cls.__name__}, got {type(data).__name__}")
    hints = get_type_hints(cls)
    known = {f.name: f for f in fields(cls)}
    unknown = sorted(set(data) - set(known))
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {', '.join(unknown)} for {cls.__name__}")
    kwargs = {}
    for name, f in known.items():
        if name not in data:
            if f.default is MISSING and f.default_factory is MISSING:
                raise ValueError(f"{where}: missing key {name!r} of {cls.__name__}")
            continue
        kwargs[name] = _load_value(hints[name], data[name], f"{where}.{name}")
    return cls(**kwargs)


def _load_value(tp, value, where: str):
    if value is None:
        return None
    origin = get_origin(tp)
    if origin in (Union, types.UnionType):
        inner = [a for a in get_args(tp) if a is not type(None)]
        return _load_value(inner[0], value, where) if len(inner) == 1 else value
    if origin is list and get_args(tp):
        return [_load_value(get_args(tp)[0], v, f"{where}[{i}]") for i, v in enumerate(value)]
    if origin is dict and get_args(tp):
        return {k: _load_value(get_args(tp)[1], v, f"{where}.{k}") for k, v in value.items()}
    if is_dataclass(tp):
        return load(tp, value, where)
    return value
