"""Recording: what a run leaves behind, written as it goes so no stop loses it.

:mod:`~cosim.record.recorder` keeps every port's value at every tick and
streams the trace, the files domain views write (see
:mod:`~cosim.record.views`) and the rerun recording
(:mod:`~cosim.record.rerun_log`) to the run's folder in batches;
:mod:`~cosim.record.summary` computes a run's figures (``summary.json``) and a
sweep's table, plot and pooled curves.
"""
