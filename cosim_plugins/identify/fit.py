"""Fit registered models to a dataset, save them, and summarise (a Table II analog).

``DIR/fit.json``::

    {"dt_s": 0.02, "seed": 0, "n_pairs": N, "data": [quality per log],
     "models": {NAME: {"file": "NAME.npz", "train_time_s": s, "n_params": n,
                       "params": {...}}}}
"""

from __future__ import annotations

import inspect
import json
import time
from pathlib import Path

from cosim.contract.errors import UserError
from cosim.contract.plugins import lookup, registry
from cosim_plugins.commands import output_folder

SUMMARY = "fit.json"


def resolve_names(spec: str | list[str]) -> list[str]:
    """Model names from ``"all"``, a name, or a comma-separated list; unknown names raise UserError."""
    known = registry("model")
    items = spec if isinstance(spec, list) else [s.strip() for s in spec.split(",") if s.strip()]
    if not items or "all" in items:
        return list(known)
    for name in items:
        lookup("model", name)  # raises with the known names listed
    return list(dict.fromkeys(items))


def takes_effects(name: str) -> bool:
    """True if the registered model ``name`` can include force effects (its constructor takes ``terms``)."""
    return "terms" in inspect.signature(lookup("model", name).__init__).parameters


def make_model(name: str, seed: int | None = None, effects=()):
    """Instantiate a registered model, passing ``seed`` when it takes one and ``effects`` as its terms."""
    cls = lookup("model", name)
    kwargs = {}
    if seed is not None and "seed" in inspect.signature(cls.__init__).parameters:
        kwargs["seed"] = seed
    if effects:
        kwargs["terms"] = list(effects)
    return cls(**kwargs)


def fit_models(dataset, names: list[str], seed: int | None = None, progress=None, effects=()) -> dict:
    """Fit each named model on ``dataset``; returns ``{name: fitted model}``.

    ``effects``: force effects the models that take them (:func:`takes_effects`) include and fit jointly.
    """
    models = {}
    for name in names:
        model = make_model(name, seed, effects if takes_effects(name) else ())
        model.progress = progress
        if progress:
            progress(f"fitting {name} ...")
        t0 = time.perf_counter()
        model.fit(dataset)
        if model.train_time_s is None:
            model.train_time_s = time.perf_counter() - t0
        models[name] = model
    return models


def summarise(models: dict, dataset, seed: int | None = None) -> dict:
    """The ``fit.json`` content for fitted ``models``."""
    return {
        "dt_s": dataset.dt_s,
        "seed": seed,
        "n_pairs": int(len(dataset.pair_index())),
        "data": dataset.quality(),
        "models": {
            name: {
                "file": f"{name}.npz",
                "train_time_s": round(float(m.train_time_s), 4),
                "n_params": int(m.n_params),
                "params": m.params(),
            }
            for name, m in models.items()
        },
    }


def save_models(models: dict, summary: dict, out_dir: str | Path) -> Path:
    """Write ``NAME.npz`` per model and ``fit.json`` into ``out_dir``; returns the summary path."""
    out = output_folder(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for name, model in models.items():
        model.save(out / f"{name}.npz")
    path = out / SUMMARY
    path.write_text(json.dumps(summary, indent=2, default=json_default) + "\n")
    return path


def load_models(model_dir: str | Path) -> dict:
    """Load every model of a fit directory (``fit.json`` order, else all ``*.npz``)."""
    from cosim_plugins.identify.model import load_model

    d = Path(model_dir)
    if not d.is_dir():
        raise UserError(f"model directory {d} does not exist")
    summary = d / SUMMARY
    if summary.is_file():
        try:
            names = list(json.loads(summary.read_text())["models"])
        except (ValueError, KeyError, TypeError) as exc:
            raise UserError(f"{summary} is not a fit summary ({exc})") from exc
        files = [d / f"{n}.npz" for n in names]
    else:
        files = sorted(d.glob("*.npz"))
    if not files:
        raise UserError(f"model directory {d} holds no model files (*.npz)")
    return {f.stem: load_model(f) for f in files}


def json_default(obj):
    """``json.dumps(default=...)`` for numpy scalars and arrays."""
    import numpy as np

    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")
