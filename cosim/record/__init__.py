"""Recording: what a run leaves behind, and the figures made of it.

:mod:`~cosim.record.trace_files` writes and reads the trace in chunks (so no
stop loses it), :mod:`~cosim.record.rerun_log` the rerun recording (the
domain's views, :mod:`cosim.contract.views`, draw into it);
:mod:`~cosim.record.figures` computes the run's figures as it goes
(:mod:`~cosim.record.streaming`); :mod:`~cosim.record.summary` says what they
are and makes a sweep's table, plot and pooled curves;
:mod:`~cosim.record.web_viewer` serves a recording to a browser. The
recorder that feeds them tick by tick is the runtime's
(:mod:`cosim.runtime.recorder`).
"""
