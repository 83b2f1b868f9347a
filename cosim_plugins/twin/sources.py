"""Where the applied effects come from: library or plugin effects by name, or a saved model.

A saved model (``.npz``) is data: its effects are rebuilt by
:func:`cosim_plugins.identify.effect.restore_effects`, which runs Python the file
carries only with ``--trust-model-code`` (see ``docs/security.md``). Its force
effects come with their fitted parameters and the model's own parameters
(``k``, ``Cd1``, ...) as the host parameters they reuse.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

from cosim.contract.errors import UserError


@dataclass
class EffectSource:
    """Effects to apply, the parameter values they come with and, from a model, its host parameters.

    Attributes:
        effects: the force effects.
        values: fitted effect parameters by qualified name (empty for effects named directly).
        host: the model's host parameters (k, Cd0, ...; uN, mm, s, Hz), None when not from a model.
        origin: where they came from, for messages.
    """

    effects: list
    values: dict = field(default_factory=dict)
    host: dict | None = None
    origin: str = ""


def effects_by_name(names: Sequence[str]) -> EffectSource:
    """Registered effects (the library's, or a user's file loaded as a plugin) or the twin's own
    (:func:`cosim_plugins.twin.fmu_laws.twin_effects`: the plant FMU's laws) by name.

    An unknown name raises a UserError listing the known effects.
    """
    from cosim_plugins.identify.effect import known_effects, resolve
    from cosim_plugins.twin.fmu_laws import twin_effects

    known = {**twin_effects(), **known_effects()}
    return EffectSource(effects=resolve(list(names), known), origin="effects " + ", ".join(names))


def effects_of_model(path: str | Path, names: Sequence[str] = ()) -> EffectSource:
    """The force effects of a saved physical model with their fitted parameters (``names``: only these).

    A model file that is not a physical model, carries no effects, or carries code the user did not
    trust raises a UserError naming the file.
    """
    from cosim_plugins.identify.model import load_model, read_model_file

    header, _ = read_model_file(path)
    if header["kind"] != "physical":
        raise UserError(f"model file {path} holds a {header['kind']!r} model: only a physical model carries "
                        "named force effects to apply to the plant")
    try:
        model = load_model(path)
    except UserError as exc:
        msg = str(exc)
        raise UserError(msg if str(path) in msg else f"model file {path}: {msg}") from exc
    forces = [t for t in model.terms if getattr(t, "kind", "force") == "force"]
    if not forces:
        raise UserError(f"model file {path} has no force effects (its terms: none); fit it with --effects/--add "
                        "or name library effects instead")
    if names:
        by_name = {t.name: t for t in forces}
        unknown = [n for n in names if n not in by_name]
        if unknown:
            raise UserError(f"model file {path} has no effect(s) {', '.join(unknown)}; "
                            f"its force effects: {', '.join(by_name)}")
        forces = [by_name[n] for n in names]
    fitted = model.params()
    from cosim_plugins.twin.units import HOST_UNITS

    values = {q: fitted[q] for t in forces for q in t.param_names()}
    host = {k: fitted[k] for k in HOST_UNITS}
    return EffectSource(effects=forces, values=values, host=host, origin=f"model file {path}")
