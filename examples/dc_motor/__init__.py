"""A second system on the cosim framework: a DC motor under PI speed control.

The motor is an FMU exported with pythonfmu (``dc_motor_fmu.py``, built and
cached by ``build.py``) and run by fmpy in the component ``dc_motor.fmu``
(``motor.py``); ``dc_motor.pi_speed`` (``controller.py``) computes the
voltage, ``dc_motor.steps`` (``steps.py``) gives the setpoint and the load
torque, and ``dc_motor.scope`` (``scope.py``) plots them in the run's rerun
recording. ``plugin.py`` registers the four; ``scenario.yaml`` wires them.
It imports nothing from the swimmer's package, only cosim's public names.
"""
