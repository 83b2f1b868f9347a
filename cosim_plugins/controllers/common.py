"""What every controller shares: its output ports and the solve timer."""

from __future__ import annotations

import time

import numpy as np

from cosim import Component, Port

#: Every path-following controller reads the estimator's position and velocity.
CONTROLLER_INPUTS = (
    Port("position", (3,), "m", "estimated position (NaN: none yet)"),
    Port("velocity", (3,), "m/s", "estimated velocity"),
)
#: Every controller outputs the rotation vector and the CPU time its computation took.
CONTROLLER_OUTPUTS = (
    Port("omega", (3,), "rad/s", "commanded rotation vector of the field"),
    Port("solve_time", (), "s", "wall time of this step's computation (diagnostic only)"),
)


class PathController(Component):
    """Base of the path-following controllers: they get the scenario's path and share ports."""

    uses_path = True
    inputs = CONTROLLER_INPUTS
    outputs = CONTROLLER_OUTPUTS


class SolveTimer:
    """Measures a controller's computation as the CPU time of its thread, so waiting for
    the interpreter lock or for other processes does not count. The one clock reading a
    component makes: it is reported, never fed back into the run, so logs stay deterministic."""

    def __enter__(self):
        self._t0 = time.thread_time()
        return self

    def __exit__(self, *exc):
        self.elapsed = np.array(time.thread_time() - self._t0)
