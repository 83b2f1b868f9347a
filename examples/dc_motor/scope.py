"""``dc_motor.scope``: plots the motor's signals in the run's rerun recording.

It writes its own part of the recording, ``recording.<name>.rrd`` in the run
folder, which the framework folds into ``recording.rrd`` when the run ends,
and adds one time-series view per quantity to the recording's layout. Rows
are sent in columns about once a second of simulated time and when the
scope is closed, so a run cut short keeps what was plotted.
"""

from __future__ import annotations

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from cosim import Component, Port

#: What the framework's recording uses (the application id, the timeline of
#: simulated time [s]); a part must share them to join the run's recording.
APPLICATION_ID = "cosim"
TIMELINE = "sim_time"
FLUSH_EVERY_S = 1.0
#: view (an entity under the scope's name) -> (title, {series: input port}); a lone series is the view itself
VIEWS = {
    "speed_rad_s": ("speed [rad/s]", {"measured": "speed_rad_s", "setpoint": "setpoint_rad_s"}),
    "voltage_V": ("armature voltage [V]", {"": "voltage_V"}),
    "current_A": ("armature current [A]", {"": "current_A"}),
    "load_torque_Nm": ("load torque [N m]", {"": "load_torque_Nm"}),
}


class Scope(Component):
    """Records its inputs as time series; no outputs."""

    inputs = (
        Port("speed_rad_s", (), "rad/s", "measured speed"),
        Port("setpoint_rad_s", (), "rad/s", "speed setpoint"),
        Port("voltage_V", (), "V", "armature voltage"),
        Port("current_A", (), "A", "armature current"),
        Port("load_torque_Nm", (), "N m", "load torque"),
    )
    uses_run_dir = True
    params_spec: dict = {}  # none

    @classmethod
    def recording_views(cls, name):
        return [rrb.TimeSeriesView(origin=f"{name}/{view}", name=title) for view, (title, _) in VIEWS.items()]

    def setup(self, params, rng):
        self.name = params["name"]
        self.rows: list[tuple[float, list[float]]] = []
        self.flush_ticks = max(1, round(FLUSH_EVERY_S / params["dt"]))
        self.rec = None
        if params["run_dir"] is not None:  # None outside a run: nothing to write to
            self.rec = rr.RecordingStream(application_id=APPLICATION_ID, recording_id=params["recording_id"])
            self.rec.save(str(params["run_dir"] / f"recording.{self.name}.rrd"))

    def step(self, t, inputs):
        self.rows.append((t, [float(inputs[p.name]) for p in self.inputs]))
        if len(self.rows) >= self.flush_ticks:
            self._send()
        return {}

    def _send(self) -> None:
        if self.rec is None or not self.rows:
            self.rows = []
            return
        t_s = np.array([t for t, _ in self.rows])
        table = np.array([values for _, values in self.rows])
        column = {p.name: table[:, i] for i, p in enumerate(self.inputs)}
        for view, (_, series) in VIEWS.items():
            for label, port in series.items():
                entity = f"{self.name}/{view}" + (f"/{label}" if label else "")
                self.rec.send_columns(entity, indexes=[rr.TimeColumn(TIMELINE, duration=t_s)],
                                      columns=rr.Scalars.columns(scalars=column[port]))
        self.rows = []

    def close(self):
        if self.rec is not None:
            self._send()
            self.rec.flush()
            self.rec.disconnect()
            self.rec = None
