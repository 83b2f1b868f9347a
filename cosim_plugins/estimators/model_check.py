"""Cheap checks of an estimator's ``model`` parameter, before any run starts.

:func:`check_model_spec` accepts a registered model kind (trained on demand
later, nothing is trained here) or a model file whose header names a
registered kind at the version this code reads, with the state and input
sizes the estimator needs (6 states [p mm, v mm/s], 3 inputs [Hz]). A file is
read, never written; its arrays are loaded and one zero state is predicted to
catch arrays of the wrong size the header cannot show.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cosim import ComponentError
from cosim.contract.errors import UserError

STATE_DIM = 6
INPUT_DIM = 3


def check_model_spec(spec: str) -> None:
    """Raise :class:`ComponentError` with a clear message if ``spec`` cannot serve the estimator."""
    from cosim.contract.plugins import registry

    kinds = registry("model")
    path = Path(spec)
    if path.suffix != ".npz" and not path.is_file():
        if spec not in kinds:
            raise ComponentError(f"model {spec!r} is neither a model file (.npz) nor a known kind "
                                 f"({', '.join(sorted(kinds))})")
        _check_sizes(kinds[spec], f"model kind {spec!r}", {})
        return
    from cosim_plugins.identify.model import read_model_file

    try:
        header, _ = read_model_file(path)
    except UserError as exc:
        raise ComponentError(str(exc)) from None
    kind = header["kind"]
    if kind not in kinds:
        raise ComponentError(f"model file {path} holds a {kind!r} model, which is not a known kind "
                             f"({', '.join(sorted(kinds))}); load the plugin that defines it")
    cls = kinds[kind]
    if header.get("version") != cls.version:
        raise ComponentError(f"model file {path}: {kind!r} format version {header.get('version')} is not "
                             f"supported (this code reads version {cls.version}); refit the model")
    _check_sizes(cls, f"model file {path} ({kind!r})", header)
    try:
        model = cls.load(path)
        out = np.asarray(model.predict(np.zeros(STATE_DIM), np.zeros(INPUT_DIM), model.dt_s or 0.02))
    except UserError as exc:
        raise ComponentError(str(exc)) from None
    except Exception as exc:  # a broken file of a known kind: say so instead of failing mid-run
        raise ComponentError(f"model file {path} ({kind!r}) cannot predict a {STATE_DIM}-state "
                             f"[p mm, v mm/s] with {INPUT_DIM} inputs: {type(exc).__name__}: {exc}") from None
    if out.shape != (STATE_DIM,):
        raise ComponentError(f"model file {path} ({kind!r}) predicts a state of shape {out.shape}; "
                             f"the estimator needs {STATE_DIM} states [p mm, v mm/s]")


def model_files(spec: str) -> list[Path]:
    """The model file ``spec`` names, as a list (empty for a kind, trained on demand)."""
    path = Path(spec)
    return [path] if path.suffix == ".npz" or path.is_file() else []


def _check_sizes(cls, what: str, header: dict) -> None:
    state = header.get("state_dim", getattr(cls, "state_dim", None))
    inputs = header.get("input_dim", getattr(cls, "input_dim", None))
    if state != STATE_DIM:
        raise ComponentError(f"{what} has state size {state}; the estimator needs {STATE_DIM} "
                             "states [p mm, v mm/s]")
    if inputs != INPUT_DIM:
        raise ComponentError(f"{what} has input size {inputs}; the estimator needs {INPUT_DIM} inputs [Hz]")
