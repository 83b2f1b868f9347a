"""The DC motor as an FMI 2.0 co-simulation FMU, exported with pythonfmu (``build.py`` builds it).

A permanent-magnet DC motor: the armature circuit (resistance ``R_ohm``,
inductance ``L_H``, back EMF ``k * speed``) drives a rotor (inertia
``J_kgm2``) against viscous friction (``b_Nms_per_rad * speed``) and a load
torque (an input)::

    L di/dt     = voltage - R i - k speed          [V]
    J dspeed/dt = k i - b speed - load_torque      [N m]
    dangle/dt   = speed                            [rad/s]

``k_Nm_per_A`` is both the torque constant [N m/A] and the back-EMF constant
[V s/rad] (equal in SI units). A positive load torque acts against positive
speed. The inputs are held over each communication step (zero-order hold);
the state is integrated with classic Runge-Kutta (RK4) on equal sub-steps of
at most ``max_substep_s`` (default 0.1 ms, a tenth of the default L/R time
constant). The defaults describe a small 24 V motor: L/R = 1 ms,
J R / k^2 = 16 ms, no-load speed 472 rad/s at 24 V, stall torque 0.6 N m.

This file runs inside the FMU, in whatever Python interpreter loads it: it
imports nothing but pythonfmu (which the FMU carries) and the standard library.

No FMI call here raises. pythonfmu 0.7.0's native wrapper, on a Python
exception, releases its references to the model class and instance
(``handle_py_exception`` calls ``cleanPyObject``) and releases them again
when the instance is freed (``~PySlaveInstance``), so one exception leaves
freed objects in the interpreter that loaded the FMU, which later crashes
(a segmentation fault in the garbage collector). A bad parameter or step is
therefore logged with status error and the call does nothing (``do_step``
returns False: the importer gets ``fmi2Discard``).
"""

import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Status

#: name -> (default, description); fixed parameters, set before initialisation
PARAMETERS = {
    "R_ohm": (2.0, "armature resistance [ohm]"),
    "L_H": (2.0e-3, "armature inductance [H]"),
    "k_Nm_per_A": (0.05, "torque constant [N m/A] = back-EMF constant [V s/rad]"),
    "J_kgm2": (2.0e-5, "rotor and load inertia [kg m^2]"),
    "b_Nms_per_rad": (2.0e-5, "viscous friction [N m s/rad]"),
    "max_substep_s": (1.0e-4, "longest RK4 sub-step [s]"),
    "current0_A": (0.0, "initial armature current [A]"),
    "speed0_rad_s": (0.0, "initial speed [rad/s]"),
    "angle0_rad": (0.0, "initial angle [rad]"),
}
#: parameters that must be > 0; the others must be finite and b_Nms_per_rad >= 0
POSITIVE = ("R_ohm", "L_H", "k_Nm_per_A", "J_kgm2", "max_substep_s")
#: most RK4 sub-steps in one communication step
MAX_SUBSTEPS = 1_000_000
INPUTS = {
    "voltage_V": "armature voltage [V], held over the step",
    "load_torque_Nm": "load torque on the shaft [N m], against positive speed, held over the step",
}
OUTPUTS = {
    "current_A": "armature current [A]",
    "speed_rad_s": "rotor speed [rad/s]",
    "angle_rad": "rotor angle [rad], not wrapped",
}


def parameter_problem(values: dict) -> str:
    """What is wrong with the parameter ``values`` ({name: value}), or "" if nothing is."""
    bad = [name for name in POSITIVE if not 0 < values[name] < math.inf]
    bad += [name for name, value in values.items() if not math.isfinite(value) and name not in bad]
    if not values["b_Nms_per_rad"] >= 0 and "b_Nms_per_rad" not in bad:
        bad.append("b_Nms_per_rad")
    if not bad:
        return ""
    return (f"bad parameter(s) {', '.join(f'{n}={values[n]!r}' for n in bad)}: {', '.join(POSITIVE)} "
            f"must be > 0, b_Nms_per_rad >= 0, all finite")


class DcMotor(Fmi2Slave):
    """Armature circuit + rotor inertia, viscous friction and a load torque (see the module docstring)."""

    author = "cosim examples"
    description = "Permanent-magnet DC motor: states current_A, speed_rad_s, angle_rad; input voltage_V"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for name, (default, doc) in PARAMETERS.items():
            setattr(self, name, default)
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed, description=doc))
        for name, doc in INPUTS.items():
            setattr(self, name, 0.0)
            self.register_variable(Real(name, causality=Fmi2Causality.input, description=doc))
        for name, doc in OUTPUTS.items():
            setattr(self, name, 0.0)
            self.register_variable(Real(name, causality=Fmi2Causality.output, description=doc))
        self.problem = ""  # set when the parameters are bad: the FMU then refuses to step

    def exit_initialization_mode(self):
        self.problem = parameter_problem({name: getattr(self, name) for name in PARAMETERS})
        if self.problem:
            self.log(self.problem, Fmi2Status.error)
            return
        self.current_A, self.speed_rad_s, self.angle_rad = self.current0_A, self.speed0_rad_s, self.angle0_rad

    def derivatives(self, i, w):
        """(di/dt [A/s], dspeed/dt [rad/s^2]) at current ``i`` [A] and speed ``w`` [rad/s]."""
        k = self.k_Nm_per_A
        di = (self.voltage_V - self.R_ohm * i - k * w) / self.L_H
        dw = (k * i - self.b_Nms_per_rad * w - self.load_torque_Nm) / self.J_kgm2
        return di, dw

    def do_step(self, current_time, step_size):
        substeps = step_size / self.max_substep_s if not self.problem else math.nan
        if not 0 <= substeps <= MAX_SUBSTEPS:
            self.log(self.problem or f"cannot step {step_size!r} s in sub-steps of at most "
                     f"{self.max_substep_s!r} s", Fmi2Status.error)
            return False
        n = max(1, math.ceil(substeps - 1e-9))
        h = step_size / n
        i, w, a = self.current_A, self.speed_rad_s, self.angle_rad
        f = self.derivatives
        for _ in range(n):
            di1, dw1 = f(i, w)
            di2, dw2 = f(i + 0.5 * h * di1, w + 0.5 * h * dw1)
            di3, dw3 = f(i + 0.5 * h * di2, w + 0.5 * h * dw2)
            di4, dw4 = f(i + h * di3, w + h * dw3)
            a += h / 6.0 * (w + 2.0 * (w + 0.5 * h * dw1) + 2.0 * (w + 0.5 * h * dw2) + (w + h * dw3))
            i += h / 6.0 * (di1 + 2.0 * di2 + 2.0 * di3 + di4)
            w += h / 6.0 * (dw1 + 2.0 * dw2 + 2.0 * dw3 + dw4)
        self.current_A, self.speed_rad_s, self.angle_rad = i, w, a
        return True
