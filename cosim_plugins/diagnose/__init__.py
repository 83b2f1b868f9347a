"""Model discrepancy: ``cosim diagnose`` finds where a model fails and which physical effects explain it.

The pipeline (:mod:`.pipeline`) fits a baseline model to raw logs, measures its
open-loop error against the noise floor (:mod:`.noise`), localises it
(:mod:`.localise`), ranks candidate effects by a joint refit, discovers a
form outside the library (:mod:`.discover`), and states a verdict
(:mod:`.verdict`). What it finds is a typed result (:mod:`.result`), rendered in
one place (:mod:`.render`: diagnosis.json, the printed summary, report.md);
:mod:`.report` writes the files with the plots, and diagnosis.rrd (:mod:`.recording`).
"""

from cosim import hookimpl


@hookimpl
def cosim_register_commands(register):
    from cosim_plugins.diagnose import cli

    register(cli.add_commands)


@hookimpl
def cosim_register_components(register):
    from cosim_plugins.diagnose.excitation import SpinSchedule

    register("diagnose.spin_schedule", SpinSchedule)
