"""Recording: what a run leaves behind, written as it goes so no stop loses it.

:mod:`~cosim.runtime.recorder` holds the ports' values of the ticks not yet
written out (one chunk at most, whatever the run's length) and streams the
trace (:mod:`~cosim.record.trace_files`), the files domain views write (see
:mod:`~cosim.contract.views`) and the rerun recording
(:mod:`~cosim.record.rerun_log`) to the run's folder in batches;
:mod:`~cosim.record.figures` computes the run's figures as it goes
(:mod:`~cosim.record.streaming`); :mod:`~cosim.record.summary` says what they
are and makes a sweep's table, plot and pooled curves.
"""
