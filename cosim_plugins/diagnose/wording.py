"""A diagnosis in words: fitted values with the digits their uncertainty allows, and what each figure means.

Used by the verdict, the printed summary and ``report.md``, so the three say
the same thing the same way.
"""

from __future__ import annotations

import math

from cosim_plugins.diagnose.result import DISCOVERED


def given_words(names, sep: str) -> str:
    """What a drop is conditional on, in words: the effect names joined by ``sep``, the discovered form
    (:data:`.result.DISCOVERED`) by name."""
    return sep.join("the discovered form" if n == DISCOVERED else n for n in names)


#: One line per figure of a diagnosis, for the report's legend and the printed one.
GLOSSARY = {
    "held-out error": "mean distance [mm] between the predicted and the measured position after an open-loop "
                      "prediction of that horizon, started from the state fitted over a short lead-in, on data "
                      "the fits never saw",
    "noise floor": "the held-out error a perfect model would still show with this camera noise (estimated from "
                   "the logs): no model can go below it",
    "reduction": "share of the reference model's held-out error (at the reference horizon) that an effect "
                 "removes once refitted jointly with the model: 1 - after / before",
    "t": "paired t statistic of that drop over 1 s blocks of held-out windows (trimmed of the tenth of blocks at "
         "each end when that is larger); from 3 up the drop is real, below it "
         "it may be chance",
    "eta^2": "share of the error's variance that sorting the windows by one condition (speed, height, ...) "
             "explains: 0 none, 1 all",
    "mean error vector": "predicted minus measured position, averaged over the windows: a model that misses a drift "
                         "along +x falls behind and shows a negative x",
    "value ± std": "a fitted parameter and its standard error; 'not distinguishable from 0' when the error is "
                   "larger than the value, 'not determined' when the logs fix no error at all",
}


def value_text(value: float, std: float | None, unit: str = "") -> str:
    """``value ± std unit`` with two significant digits of the error and the value to the same place.

    >>> value_text(3.01712, 0.0291, "mm/s")
    '3.017 ± 0.029 mm/s'
    """
    unit = f" {unit}" if unit else ""
    if std is None or not math.isfinite(std) or std <= 0:
        return f"{value:.3g}{unit} (not determined by these logs)"
    if abs(value) < std:
        return f"{value:.2g} ± {std:.2g}{unit} (not distinguishable from 0)"
    place = -int(math.floor(math.log10(std))) + 1  # decimals that keep two digits of the error
    if place <= 0:
        step = 10.0 ** -place
        return f"{round(value / step) * step:.0f} ± {round(std / step) * step:.0f}{unit}"
    if abs(value) >= 1e5 or abs(value) < 1e-4:
        digits = max(1, int(math.floor(math.log10(abs(value)))) + place)
        return f"{value:.{digits}e} ± {std:.1e}{unit}"
    return f"{value:.{place}f} ± {std:.{place}f}{unit}"


def params_text(params: dict) -> str:
    """``{name: {"value", "std", "unit"}}`` as ``short_name = value ± std unit, ...``."""
    return ", ".join(f"{n.split('.', 1)[-1]} = {value_text(p['value'], p['std'], p['unit'])}"
                     for n, p in params.items())


def legend(keys=("held-out error", "noise floor", "reduction", "t")) -> list[str]:
    """The glossary lines of ``keys`` as ``key: meaning``."""
    return [f"{k}: {GLOSSARY[k]}" for k in keys]
