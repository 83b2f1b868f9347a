"""The Effect contract: a named physical term a parametric model can include.

Units everywhere are the physical model's: position p [mm], velocity v
[mm/s], command u = omega [Hz], force [uN], time [s].

An effect is one of three kinds:

``force``
    ``force(p, v, u, params) -> (n, 3)`` [uN], vectorised over n samples
    (p, v, u are (n, 3) arrays). The force is added to the model's own
    forces and fitted jointly with them. ``params`` maps the effect's own
    parameter names (short: ``"c"``, not ``"quadratic_drag.c"``) to floats
    and also holds the host model's parameters by their names (for the
    physical model: ``k, Cd0, Cd1, Cl0, Fvs, Fmax``), so an effect may reuse
    e.g. the drag coefficient (background flow: drag acts on v - w). A
    flow names its water-velocity parameters in ``water``; in a model that
    holds it, every force effect's ``params`` also hold ``water_x`` and
    ``water_y`` [mm/s], the water's horizontal velocity, so an extra drag
    acts on the velocity relative to the water as the host's drag does
    (:func:`water_params`). A flow that varies with position (a discovered
    shear or swirl) gives ``water_at(p, params) -> (n, 3)`` [mm/s] instead;
    the other effects' ``params`` then hold ``water_at``, the water's
    velocity as a function of p (n, 3) [mm]
    (:func:`cosim_plugins.effects.forces.through_water` subtracts both).
``input``
    ``transform(u, dt_s, params) -> (n, 3)``: the command the plant actually
    follows, from the logged command timeline u (n, 3) [Hz] of one
    contiguous segment (no gaps), causal (row i may use rows <= i).
``sensor``
    ``transform(traj, dt_s, params) -> (w, L + 1, 3)``: what the camera
    reports along predicted trajectories ``traj`` (w, L + 1, 3) [mm]
    (row 0 is the start of each trajectory, rows are control periods apart).
    A sensor effect that reports earlier positions (a latency) declares
    ``lookback(params) -> steps``: the rollout then starts that many rows
    before each window, so the transform reads a trajectory, not an
    extrapolation, and the first rows it returns are dropped.

Parameters are :class:`EffectParam` (initial value, bounds, unit, typical scale). ``starts``
lists further initial values ``{param: value}`` that a fit tries first (it
keeps the one with the lowest cost), for effects whose cost is flat at
their default start (a step-out frequency above every command).

Effects are registered through the ``cosim_register_effects`` hook with
``register(effect)``; :func:`known_effects` returns them by name,
:func:`load_effect_files` adds a user's files, and :func:`check_effect`
tells a valid effect from anything else with a one-line error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from cosim.contract.errors import UserError

KINDS = ("force", "input", "sensor")


@dataclass(frozen=True)
class EffectParam:
    """A fitted scalar: name, initial value, bounds, unit (for reports), and a typical magnitude.

    ``scale`` is the size of a meaningful change of the parameter (the
    optimiser works on parameter / scale); None takes a tenth of a finite
    range, else the larger of |init| and 1e-3.
    """

    name: str
    init: float
    lo: float = -math.inf
    hi: float = math.inf
    unit: str = ""
    scale: float | None = None

    def typical(self) -> float:
        """The scale the optimiser uses (see the class doc)."""
        if self.scale is not None:
            return float(self.scale)
        if math.isfinite(self.hi - self.lo):
            return 0.1 * (self.hi - self.lo)
        return max(abs(self.init), 1e-3)


#: The class's name before it was renamed (``cosim.Param`` declares a component's parameters): effect files
#: written earlier, e.g. by ``cosim diagnose``'s discovery, import it under this name.
Param = EffectParam


@dataclass(frozen=True, eq=False)
class Effect:
    """A named physical effect; see the module docstring for the three kinds.

    Attributes:
        name: registry name (``"background_flow"``); also the prefix of the
            parameter names in a model (``"background_flow.w_x"``).
        params: the effect's parameters.
        force: force callable (kind ``"force"``), else None.
        kind: ``"force"``, ``"input"`` or ``"sensor"``.
        doc: one paragraph: the physics and the form, with units.
        transform: transform callable (kinds ``"input"`` and ``"sensor"``).
        starts: further initial values to try, ``({param: value}, ...)``.
        data_starts: optional ``data_starts(u, dt_s) -> [{param: value}, ...]``:
            starts that depend on the logged commands u (n, 3) [Hz] (NaN rows
            possible), e.g. step-out frequencies spread over the commanded band.
        lookback: optional ``lookback(params) -> int`` (kind ``"sensor"``): rows of
            trajectory before row 0 that the transform reads (see the module doc).
        terms: for a discovered effect, the names of its candidate terms (:mod:`.discover`):
            a model file stores these and the coefficients, not code.
        water: for a flow, the names of its two parameters that are the water's horizontal velocity
            (x, y) [mm/s] (see the module doc).
        water_at: for a flow that varies with position, ``water_at(p, params) -> (n, 3)``: the water's
            velocity [mm/s] at p (n, 3) [mm], ``params`` the effect's own by short name (see the module doc).
    """

    name: str
    params: tuple[EffectParam, ...]
    force: Callable | None = None
    kind: str = "force"
    doc: str = ""
    transform: Callable | None = None
    starts: tuple[dict, ...] = field(default=())
    data_starts: Callable | None = None
    lookback: Callable | None = None
    terms: tuple[str, ...] = field(default=())
    water: tuple[str, ...] = field(default=())
    water_at: Callable | None = None

    def param_names(self) -> list[str]:
        """Fully qualified names ``effect.param`` used in models, reports and files."""
        return [f"{self.name}.{p.name}" for p in self.params]

    def qualified_starts(self, u: np.ndarray | None = None, dt_s: float | None = None) -> list[dict]:
        """:attr:`starts` (and, given the commands u (n, 3) [Hz], :attr:`data_starts`) by qualified names."""
        starts = list(self.starts)
        if self.data_starts is not None and u is not None:
            starts += list(self.data_starts(u, dt_s))
        return [{f"{self.name}.{k}": float(v) for k, v in s.items()} for s in starts]

    def summary(self) -> str:
        """The doc's opening phrase, up to its first colon (for listings, <= 90 characters)."""
        head = (self.doc or "").strip().split(":")[0].split(". ")[0].rstrip(".")
        return head if len(head) <= 90 else head[:87] + "..."


#: the names under which a force effect's parameters hold the water's horizontal velocity [mm/s]
WATER_NAMES = ("water_x", "water_y")


def water_params(effects, params: dict) -> dict:
    """{"water_x", "water_y"}: the water's horizontal velocity [mm/s] that the uniform flows among ``effects``
    (those naming ``water``) set, summed, read from the fully qualified ``params``; and "water_at" (a
    :class:`WaterAt`) when flows vary with position (those with ``water_at``). {} when no effect is a flow."""
    out = {}
    flows = [e for e in effects if getattr(e, "water", ())]
    if flows:
        out = {key: sum(float(params[f"{e.name}.{e.water[i]}"]) for e in flows) for i, key in enumerate(WATER_NAMES)}
    varying = [e for e in effects if getattr(e, "water_at", None) is not None]
    if varying:
        out["water_at"] = WaterAt(tuple((e.water_at, tuple((q.name, float(params[f"{e.name}.{q.name}"]))
                                                          for q in e.params)) for e in varying))
    return out


@dataclass(frozen=True)
class WaterAt:
    """The water's velocity that flows varying with position set: ``WaterAt(p)`` -> (n, 3) [mm/s] at p (n, 3)
    [mm], summed over ``flows`` ((each flow's ``water_at``, its own parameters as (name, value) pairs), ...).
    Equal when the flows and their values are: a model's parameter groups that agree on them share a call."""

    flows: tuple

    def __call__(self, p: np.ndarray) -> np.ndarray:
        w = np.zeros(np.shape(p))
        for water_at, own in self.flows:
            w = w + water_at(p, dict(own))
        return w


def check_effect(obj, source: str = "") -> Effect:
    """Return ``obj`` if it follows the contract, else raise a one-line UserError.

    Checks the name, the kind, the parameters (names unique, finite initial
    values inside their bounds) and calls the force or transform once on a
    small sample to check the shape and finiteness of the result.
    """
    where = f" (from {source})" if source else ""
    name = getattr(obj, "name", None)
    if not isinstance(name, str) or not name.isidentifier():
        raise UserError(f"effect {obj!r}{where} has no valid name (a Python identifier)")
    label = f"effect {name!r}{where}"
    kind = getattr(obj, "kind", "force")
    if kind not in KINDS:
        raise UserError(f"{label}: kind {kind!r} is not one of {', '.join(KINDS)}")
    params = getattr(obj, "params", None)
    if not isinstance(params, (tuple, list)) or not all(isinstance(p, EffectParam) for p in params):
        raise UserError(f"{label}: params must be a tuple of cosim_plugins.identify.effect.EffectParam")
    names = [p.name for p in params]
    if len(set(names)) != len(names):
        raise UserError(f"{label}: duplicate parameter names {names}")
    for p in params:
        if not (math.isfinite(p.init) and p.lo <= p.init <= p.hi):
            raise UserError(f"{label}: parameter {p.name!r} initial value {p.init} is not within [{p.lo}, {p.hi}]")
    water = tuple(getattr(obj, "water", ()) or ())
    if water and (kind != "force" or len(water) != 2 or not set(water) <= set(names)):
        raise UserError(f"{label}: water {water!r} must name two of a force effect's parameters (the water's x and "
                        f"y velocity), of {names}")
    fn = getattr(obj, "force" if kind == "force" else "transform", None)
    if not callable(fn):
        what = "force(p, v, u, params)" if kind == "force" else "transform(...)"
        raise UserError(f"{label}: a {kind} effect needs a callable {what}")
    _try_call(obj, fn, kind, label)
    return obj


def _try_call(effect, fn, kind: str, label: str) -> None:
    """Call the effect once on a small deterministic sample; shape/finiteness errors raise UserError."""
    rng = np.random.default_rng(0)
    prm = {"k": 0.2, "Cd0": 0.0, "Cd1": 0.08, "Cl0": 0.0, "Fvs": -0.4, "Fmax": 0.0}  # a host's parameters
    prm.update({p.name: p.init for p in effect.params})
    try:
        if kind == "force":
            n = 5
            out = fn(rng.normal(0, 20, (n, 3)), rng.normal(0, 10, (n, 3)), rng.normal(0, 8, (n, 3)), prm)
            want = (n, 3)
        elif kind == "input":
            n = 8
            out = fn(rng.normal(0, 8, (n, 3)), 0.02, prm)
            want = (n, 3)
        else:
            out = fn(np.cumsum(rng.normal(0, 0.3, (2, 6, 3)), axis=1), 0.02, prm)
            want = (2, 6, 3)
        out = np.asarray(out, dtype=float)
    except Exception as exc:  # the user's code: report whatever it raised
        raise UserError(f"{label}: calling its {'force' if kind == 'force' else 'transform'} failed: "
                        f"{type(exc).__name__}: {exc}") from exc
    if out.shape != want:
        raise UserError(f"{label}: returned shape {out.shape}, expected {want}")
    if not np.all(np.isfinite(out)):
        raise UserError(f"{label}: returned non-finite values at its initial parameters")


def known_effects() -> dict[str, Effect]:
    """All registered effects by name (built-in and loaded files)."""
    from cosim.contract.plugins import registry

    return registry("effect")


def load_effect_files(paths) -> list[str]:
    """Load user effect files (Python files with a ``cosim_register_effects`` hook).

    Returns the names of the effects the files added. A file that fails to
    import, registers nothing new, or registers an invalid effect raises a
    one-line UserError naming the file.
    """
    from cosim.contract.plugins import PluginError, load_plugin_file

    added: list[str] = []
    for path in paths or ():
        path = Path(path)
        before = set(_registry_or_error(path))
        try:
            load_plugin_file(path)
        except PluginError:
            raise
        except Exception as exc:  # pluggy validation of the hook signature, etc.
            raise UserError(f"effect file {path}: {type(exc).__name__}: {exc}") from exc
        now = _registry_or_error(path)
        new = [n for n in now if n not in before]
        if not new:
            raise UserError(f"effect file {path} registers no effect: define "
                            "`@cosim.hookimpl def cosim_register_effects(register): register(Effect(...))`")
        for name in new:
            check_effect(now[name], str(path))
        added += new
    return added


def _registry_or_error(path) -> dict:
    try:
        return known_effects()
    except UserError as exc:
        raise UserError(f"effect file {path}: {exc}") from exc
    except Exception as exc:  # a hook that raised
        raise UserError(f"effect file {path}: registering effects failed: {type(exc).__name__}: {exc}") from exc


def resolve(names, known: dict | None = None) -> list[Effect]:
    """Effects by name; an unknown name raises a UserError listing the known ones."""
    known = known_effects() if known is None else known
    out = []
    for name in names:
        if name not in known:
            listing = ", ".join(sorted(known)) or "(none)"
            raise UserError(f"unknown effect {name!r}; known effects: {listing}")
        out.append(check_effect(known[name]))
    return out


def split_kinds(effects) -> tuple[list[Effect], list[Effect], list[Effect]]:
    """(force, input, sensor) effects of a list, order kept."""
    kinds = {k: [] for k in KINDS}
    for e in effects:
        kinds[getattr(e, "kind", "force")].append(e)
    return kinds["force"], kinds["input"], kinds["sensor"]


# ---------------------------------------------------------------- effects inside model files

USER_MODULE_PREFIX = "cosim_user_plugin_"  # the module names cosim.contract.plugins.load_plugin_file gives user files


def effect_sources(effects) -> dict[str, str]:
    """{effect name: source text of the file that defined it} for effects loaded from users' files.

    A model file keeps these so it opens where that file is not at hand (a
    node's process, another machine); built-in effects need no source.
    """
    import inspect
    import sys

    out = {}
    for e in effects:
        fn = getattr(e, "force", None) or getattr(e, "transform", None)
        module = sys.modules.get(getattr(fn, "__module__", "") or "")
        if getattr(e, "terms", ()):
            continue  # a discovered effect: stored as data (:func:`library_data`)
        if module is not None and module.__name__.startswith(USER_MODULE_PREFIX):
            out[e.name] = _SOURCES.get(module.__name__) or inspect.getsource(module)
    return out


TRUST_ENV = "COSIM_TRUST_MODEL_CODE"  # set to 1 by `--trust-model-code`; node processes inherit it


def trusts_model_code() -> bool:
    """Whether the user allowed code carried inside model files to run (``--trust-model-code``)."""
    import os

    return os.environ.get(TRUST_ENV, "") == "1"


def restore_effects(names, sources: dict, library: dict | None = None) -> list[Effect]:
    """The effects ``names`` of a model file, without running code the file carries unless allowed.

    An effect is taken, in this order: from the registry (built-in, or loaded from a file the user
    named: ``--effects-file``, a scenario's ``plugins``); from ``library`` ({name: {"terms": [term
    names], "scales": [typical sizes]}}, a discovered effect stored as data, rebuilt from the
    table of :mod:`.discover`); from ``sources`` (a user effect's source text, kept for the record)
    only if :func:`trusts_model_code`, imported from memory, never through a file. Otherwise a
    UserError names the effect and the two ways to allow it.
    """
    known = known_effects()
    out = []
    for name in names:
        if name in known:
            out.append(known[name])
        elif name in (library or {}):
            out.append(_library_from_data(name, library[name]))
        elif name in sources and trusts_model_code():
            _import_source(name, sources[name])
            known = known_effects()
            if name not in known:
                raise UserError(f"the code the model file carries for effect {name!r} does not register it")
            out.append(check_effect(known[name], f"the model file's code for {name!r}"))
        elif name in sources:
            raise UserError(f"effect {name!r} is Python code carried inside the model file, which cosim does not "
                            f"run unless told to: load that effect's file (--effects-file FILE.py, or list it in "
                            f"the scenario's plugins), or pass --trust-model-code to run the code the file carries")
        else:
            raise UserError(f"the model uses effect {name!r}, which is not registered and which the model file "
                            "does not describe: load its effect file first (--effects-file FILE.py)")
    return out


def _library_from_data(name: str, entry) -> Effect:
    """A discovered effect from its stored term names and scales (coefficients come with the model's
    parameters); unknown term names raise a UserError."""
    table, library_effect = term_library()
    try:
        names = [str(n) for n in entry["terms"]]
        scales = [float(s) for s in entry["scales"]]
    except (KeyError, TypeError, ValueError) as exc:
        raise UserError(f"effect {name!r}: its stored terms are malformed ({type(exc).__name__})") from exc
    unknown = [n for n in names if n not in table]
    if unknown or len(scales) != len(names):
        raise UserError(f"effect {name!r}: stored terms {unknown or names} are not terms this version knows "
                        f"(known: {', '.join(sorted(table))})")
    return library_effect([table[n] for n in names], np.asarray(scales), name=name)


def term_library():
    """({term name: Term}, library_effect) of :mod:`cosim_plugins.diagnose.discover`, the module of candidate
    terms (imported here, not at the top: discover imports this module)."""
    from cosim_plugins.diagnose import discover

    return discover.TERM_TABLE, discover.library_effect


def library_data(effects) -> dict:
    """{name: {"terms": [...], "scales": [...]}} for effects made by :func:`.discover.library_effect`:
    what a model file stores for them instead of code."""
    return {e.name: {"terms": list(e.terms), "scales": [p.typical() for p in e.params]}
            for e in effects if getattr(e, "terms", ())}


_SOURCES: dict[str, str] = {}  # module name -> source text of effects imported from model files


def _import_source(name: str, text: str) -> None:
    """Import a model file's effect source from memory as a plugin module (no file is written)."""
    import hashlib
    import linecache
    import sys
    import types

    from cosim.contract.plugins import get_plugin_manager

    mod_name = f"{USER_MODULE_PREFIX}model_{hashlib.sha256(text.encode()).hexdigest()[:16]}"
    pm = get_plugin_manager()
    if pm.has_plugin(mod_name):
        return
    filename = f"<model file code: effect {name}>"
    module = types.ModuleType(mod_name)
    module.__file__ = filename
    linecache.cache[filename] = (len(text), None, text.splitlines(keepends=True), filename)  # for inspect.getsource
    try:
        exec(compile(text, filename, "exec"), module.__dict__)  # noqa: S102 (run only with --trust-model-code)
    except Exception as exc:  # the carried code: report whatever it raised
        raise UserError(f"the code the model file carries for effect {name!r} failed: "
                        f"{type(exc).__name__}: {exc}") from exc
    sys.modules[mod_name] = module
    _SOURCES[mod_name] = text
    pm.register(module, mod_name)
