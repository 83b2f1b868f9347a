"""Hand-made diagnosis results for the verdict's tests: a dict holding only what a test needs, typed."""

from __future__ import annotations

import types
from dataclasses import MISSING, fields, is_dataclass
from typing import Union, get_args, get_origin, get_type_hints

from cosim_plugins.diagnose.result import DiagnosisResult, load


def _complete(tp, value):
    """``value`` (diagnosis.json's form of a ``tp``) with every field it leaves out set to an empty value of its
    type: the hand-made results below hold only what the verdict reads."""
    origin = get_origin(tp)
    if origin in (Union, types.UnionType):
        inner = [a for a in get_args(tp) if a is not type(None)]
        return None if value is None else _complete(inner[0], value) if len(inner) == 1 else value
    if origin is list and get_args(tp):
        return [_complete(get_args(tp)[0], v) for v in value]
    if is_dataclass(tp):
        hints = get_type_hints(tp)
        out = dict(value)
        for f in fields(tp):
            if f.name in out:
                out[f.name] = _complete(hints[f.name], out[f.name])
            elif f.default is MISSING and f.default_factory is MISSING:
                optional = type(None) in get_args(hints[f.name])
                out[f.name] = None if optional else _complete(hints[f.name], _EMPTY.get(hints[f.name], {}))
        return out
    return value


_EMPTY = {str: "", int: 0, float: 0.0, bool: True, list: [], dict: {}}


def typed(r: dict) -> DiagnosisResult:
    """A hand-made result dict (diagnosis.json's form, any part left out) as the typed result the verdict
    reads."""
    return load(DiagnosisResult, _complete(DiagnosisResult, r))
