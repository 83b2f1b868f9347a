"""Everything checked of a scenario before anything runs or is written: ``cosim validate`` and
``cosim run`` call the same :func:`check_runs`.

Checked: the fields (on loading), the plugins named, every component's parameters
(``Component.validate_params``), the wiring, and the path and its parameters; for a sweep,
each of its runs.
"""

from __future__ import annotations

from pathlib import Path

from cosim.contract.errors import UserError
from cosim.runtime.wiring import Wiring, build_wiring
from cosim.scenario.paths import make_path
from cosim.scenario.schema import Scenario, load_scenario, sweep_overrides


def check_scenario(scenario: Scenario) -> Wiring:
    """The scenario's wiring, once its plugins, parameters and path are checked."""
    wiring = build_wiring(scenario)
    if scenario.path:
        make_path(scenario.path.plugin, scenario.path.params)
    return wiring


def check_runs(scenario: Scenario, scenario_file: str | Path, overrides: list[str] | tuple[str, ...] = ()) -> Wiring:
    """:func:`check_scenario` on the run, or on every run of its sweep (the error names the sweep
    run); returns the wiring of the scenario as loaded."""
    wiring = check_scenario(scenario)
    for labels, extra in sweep_overrides(scenario) if scenario.sweep else []:
        try:
            check_scenario(load_scenario(scenario_file, [*overrides, *extra, "sweep={}"]))
        except UserError as exc:
            row = " ".join(f"{k}={v}" for k, v in labels.items())
            raise UserError(f"sweep run {row}: {exc}") from None
    return wiring
