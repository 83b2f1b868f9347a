"""The held-out and training windows of ``cosim diagnose``, for the twin's open-loop replay.

The calibration scores the plant FMU on exactly the windows and horizons a diagnosis
scores its host models on (:mod:`cosim_plugins.diagnose.pipeline`): the held-out data
are the ``--validate`` logs or every third 5 s block of each log; a window starts at a
row, fits the initial state on a lead-in of ``lead`` rows (rows start..start + lead) and
is scored ``steps[h]`` rows after the lead-in, at each horizon h. Units: mm, Hz, s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cosim.contract.errors import UserError
from cosim_plugins.diagnose import pipeline
from cosim_plugins.diagnose.render import to_json
from cosim_plugins.identify.dataset import Dataset
from cosim_plugins.identify.timeline import Timeline


@dataclass
class Windows:
    """The diagnosis' data split and windows.

    Attributes:
        train, test: timelines of the training and held-out data (rows of every log, stacked).
        train_starts: (w_tr,) training window starts (the open-loop polish's sample, as diagnose's).
        test_starts: (w_te,) held-out window starts (diagnose's, at most ``MAX_EVAL_WINDOWS``).
        lead: lead-in rows; steps: {horizon key: rows after the lead-in}; reference: the key of 1.0 s.
        split: diagnosis.json's ``split``; dt_s: control period [s].
    """

    train: Timeline
    test: Timeline
    train_starts: np.ndarray
    test_starts: np.ndarray
    lead: int
    steps: dict
    reference: str
    split: dict
    dt_s: float


def diagnose_windows(logs, validate=None, train_windows: int = pipeline.POLISH_WINDOWS, seed: int = 0) -> Windows:
    """The windows ``cosim diagnose`` would use on these cleaned logs (:class:`cosim_plugins.raw_log.Log`).

    ``train_windows``: how many training windows to sample (diagnose's polish takes
    :data:`~cosim_plugins.diagnose.pipeline.POLISH_WINDOWS`, with seed + 1).
    """
    train_logs, test_logs, split = pipeline.split_logs(logs, validate)
    split = to_json(split)  # twin.json holds it as diagnosis.json does
    dtr, dte, dall = Dataset.from_logs(train_logs), Dataset.from_logs(test_logs), Dataset.from_logs(logs)
    ttr, tte, tall = (Timeline.from_dataset(d) for d in (dtr, dte, dall))
    dt = dall.dt_s
    lead = max(pipeline.MIN_LEAD_ROWS, int(round(pipeline.LEAD_S / dt)))
    steps = {h: max(1, int(round(v / dt))) for h, v in pipeline.HORIZONS_S.items()}
    frac = float(np.mean(tall.measured))
    # diagnose's held-out windows (pipeline.run: test_starts) and its polish sample of training windows
    test_starts = pipeline.evenly(pipeline.open_loop_starts(tte, lead, frac), pipeline.MAX_EVAL_WINDOWS)
    train_starts = pipeline.sample_starts(pipeline.open_loop_starts(ttr, lead, frac), train_windows, seed + 1)
    ref = pipeline.REFERENCE
    k_ref = steps[ref]
    n_ref = int(np.sum((tte.run[test_starts] >= lead + k_ref)
                       & tte.measured[np.minimum(test_starts + lead + k_ref, tte.n - 1)]))
    if n_ref < pipeline.MIN_EVAL_WINDOWS or len(train_starts) < pipeline.MIN_EVAL_WINDOWS:
        raise UserError(f"logs too short to calibrate: {n_ref} held-out and {len(train_starts)} training windows "
                        f"reach the {k_ref * dt:g} s horizon (need {pipeline.MIN_EVAL_WINDOWS} of each); give "
                        "longer logs (>= 30 s in total) or --validate logs")
    return Windows(train=ttr, test=tte, train_starts=train_starts, test_starts=test_starts, lead=lead, steps=steps,
                   reference=ref, split=split, dt_s=dt)
