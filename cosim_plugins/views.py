"""The swimmer's view of a run: the tank, the swimmer's axis and the field in 3D, the
command and the coil currents over time, and the raw log ``log.csv``.

Registered through ``cosim_register_views`` (see :mod:`cosim.contract.views`);
it applies to a run that records the command (role ``omega``) and the
measured position, as every swimmer scenario does. :class:`PositionsView`
draws the true, measured and estimated positions in 3D (the framework draws
the path).
"""

from __future__ import annotations

from pathlib import Path

import rerun as rr
import rerun.blueprint as rrb

from cosim import hookimpl
from cosim.api import log_arrows, log_points, log_scalars
from cosim.contract.views import RunView
from cosim_plugins.figures import SwimmerFigures
from cosim_plugins.raw_log import LogWriter

TANK_HALF_M = 0.075
AXIS_LEN_M = 0.006  # the swimmer's length
FIELD_SCALE_M_PER_T = 5.0  # 1 mT draws 5 mm
#: arrows drawn at the true position: (entity, role, colour, length [m] per unit of the role)
ARROWS = (
    ("world/swimmer/axis", "axis", [40, 200, 80], AXIS_LEN_M),
    ("world/field", "field", [230, 80, 230], FIELD_SCALE_M_PER_T),
)


#: the positions drawn in 3D: (entity, recorded role, colour, point radius [m])
POINTS = (
    ("world/truth", "truth", [40, 200, 80], 1.25e-3),
    ("world/measured", "measured", [255, 80, 60], 0.8e-3),
    ("world/estimate", "estimate", [60, 140, 255], 0.8e-3),
)


def _is_position(values) -> bool:
    return values is not None and values.shape[1:] == (3,)


class PositionsView(RunView):
    """The true, measured and estimated positions as points in 3D, those of them recorded as 3-vectors."""

    spatial = True

    def applies(self, recorder) -> bool:
        return any(_is_position(recorder.signal(role, 0, 0)) for _, role, _, _ in POINTS)

    def start(self, rec, recorder) -> None:
        for entity, role, color, radius in self._points(recorder):
            rec.log(entity, rr.Points3D.from_fields(colors=[color], radii=[radius]), static=True)

    def draw(self, rec, recorder, start, stop, t_s) -> None:
        for entity, role, _, _ in self._points(recorder):
            log_points(rec, entity, t_s, recorder.signal(role, start, stop))

    @staticmethod
    def _points(recorder) -> list:
        return [pt for pt in POINTS if _is_position(recorder.signal(pt[1], 0, 0))]


class RawLogFile:
    """``log.csv`` in the raw log format (:mod:`cosim_plugins.raw_log`), appended batch by batch."""

    def __init__(self, path: Path):
        self._writer = LogWriter(path)
        self.path = self._writer.path

    def append(self, recorder, start: int, stop: int) -> None:
        t_ms = (recorder.t_s[start:stop] * 1e3).round(6)
        self._writer.append(t_ms, recorder.signal("omega", start, stop), recorder.signal("measured", start, stop))

    def close(self) -> None:
        self._writer.close()


class SwimmerView(RunView):
    """The tank, the swimmer's axis and the field in 3D, the command and coil currents over time, log.csv."""

    roles = {"omega": "controller.omega", "axis": "plant.axis",
             "field": "plant.field", "coil_current": "plant.coil_current_amp"}
    files = {"log": "log.csv"}

    def applies(self, recorder) -> bool:
        return recorder.signal("omega") is not None and recorder.signal("measured") is not None

    def layout(self) -> list:
        return [rrb.TimeSeriesView(origin="plots/omega", name="omega [rad/s]"),
                rrb.TimeSeriesView(origin="plots/coil_current", name="coil current amplitude [A]")]

    def start(self, rec, recorder) -> None:
        rec.log("world/tank", rr.Boxes3D(half_sizes=[[TANK_HALF_M] * 3], colors=[[120, 160, 255, 60]]),
                static=True)
        for entity, _, color, _ in ARROWS:
            rec.log(entity, rr.Arrows3D.from_fields(colors=[color]), static=True)

    def draw(self, rec, recorder, start, stop, t_s) -> None:
        truth = recorder.signal("truth", start, stop)
        if truth is not None:
            for entity, role, _, scale in ARROWS:
                values = recorder.signal(role, start, stop)
                if values is not None:
                    log_arrows(rec, entity, t_s, truth, values * scale)
        omega = recorder.signal("omega", start, stop)
        for i, axis_name in enumerate("xyz"):
            log_scalars(rec, f"plots/omega/{axis_name}", t_s, omega[:, i])
        current = recorder.signal("coil_current", start, stop)
        if current is not None:
            for i in range(current.shape[1]):
                log_scalars(rec, f"plots/coil_current/{i + 1}", t_s, current[:, i])

    def open_files(self, recorder, out_dir: Path) -> dict:
        return {"log": RawLogFile(out_dir / self.files["log"])}


#: The swimmer's ports of the framework's recorded roles (a scenario's ``record:`` rebinds them).
DEFAULT_ROLES = {
    "measured": "camera.position",
    "truth": "plant.position",
    "estimate": "estimator.position",
    "solve_time": "controller.solve_time",
    "prediction_error": "estimator.innovation",
    "capture_time": "camera.capture_time",
}


@hookimpl
def cosim_summary_figures(register):
    register(SwimmerFigures())


@hookimpl
def cosim_default_roles(register):
    for role, port in DEFAULT_ROLES.items():
        register(role, port)


@hookimpl
def cosim_register_views(register):
    register("positions", PositionsView())
    register("swimmer", SwimmerView())
