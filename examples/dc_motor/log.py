"""The motor's view of a run: ``log.csv``, one row per tick, written as the run goes.

Columns: ``t_s``, the controller's ``command`` (``voltage_V``,
``setpoint_rad_s``, ``demand_V``: the PI's demand before the clip) and the
motor's ``state`` (``current_A``, ``speed_rad_s``, ``angle_rad``). A
:class:`cosim.contract.views.RunView`: it applies to a run that records the
roles ``motor_command`` and ``motor_state`` (by default
``controller.command`` and ``motor.state``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cosim.contract.views import RunView

HEADER = "t_s,voltage_V,setpoint_rad_s,demand_V,current_A,speed_rad_s,angle_rad"


class MotorLogFile:
    """The motor's raw log (``log.csv``), written a row per tick as the run goes."""
    def __init__(self, path: Path):
        self.path = Path(path)
        self._fh = open(self.path, "w", newline="\n")
        self._fh.write(HEADER + "\n")
        self._fh.flush()

    def append(self, recorder, start: int, stop: int) -> None:
        rows = np.column_stack([recorder.t_s[start:stop], recorder.signal("motor_command", start, stop),
                                recorder.signal("motor_state", start, stop)])
        self._fh.write("".join(",".join(f"{v:.9g}" for v in row) + "\n" for row in rows.tolist()))
        self._fh.flush()

    def close(self) -> None:
        self._fh.close()


class MotorLog(RunView):
    """The DC motor's view of a run: its raw log, from the roles ``motor_command`` and ``motor_state``."""
    roles = {"motor_command": "controller.command", "motor_state": "motor.state"}
    files = {"log": "log.csv"}

    def open_files(self, recorder, out_dir: Path) -> dict:
        return {"log": MotorLogFile(out_dir / self.files["log"])}
