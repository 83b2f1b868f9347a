"""Mutation testing of the modules where a silent bug is dangerous (mutmut 3).

Each module is mutated on its own, in a private copy of the project under
``build/mutation/NAME/`` (mutmut keeps its state there, so a second run only
tests what changed, then tests the last run's survivors again against the
current tests), and only its own tests run against each mutant. A mutant is
*killed* when a test fails or hangs with it in place: each test runs under a
watchdog (``tests/hang_guard.py``, ``Target.timeout_s``) that ends a test
still running after that many seconds, even one blocked in native code, and
keeps its stacks in ``build/mutation/NAME/hung/``. A survivor that no input
the module can receive tells from the original is listed in
:data:`EQUIVALENT` with the reason; the score is killed / (mutants -
equivalent). ``mutmut show NAME`` in that directory prints a mutant's change.

    python benchmarks/mutation.py                      # every module
    python benchmarks/mutation.py --only interlocks ekf --children 1

prints ``{"modules": {PATH: {"mutants", "killed", "hung", "equivalent",
"score", "survived", "seconds"}}, "seconds"}`` (``hung``: of the killed, those
ended by the watchdog). Needs the ``mutation`` extra (``pip install -e
'.[test,mutation]'``) and the plant FMU (``make fmu``) for the tests that run
a scenario. It takes tens of minutes: it is not part of ``make test``.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / "build" / "mutation"
#: What a private copy holds: the packages (mutmut copies them into mutants/), the tests and what they read.
COPIED = ("cosim", "cosim_plugins", "tests", "examples", "docs", "pyproject.toml", "README.md")
#: Copied if present: the plant FMU the scenario tests run, the short paper dataset and the models trained on it
#: (made once here rather than inside a test, where a first run on a busy machine could pass the watchdog's limit).
OPTIONAL = ("build/swimmer_plant.fmu", "cache/paper_dataset_quick", "cache/models_quick")


@dataclass(frozen=True)
class Target:
    """One module to mutate and the tests that must catch its mutants (pytest arguments)."""

    name: str
    path: str
    tests: tuple[str, ...]
    #: seconds one test may run with a mutant in place before the watchdog ends it (a hang: killed)
    timeout_s: float = 60.0


COIL_TESTS = ("tests/coil_driver/test_coil_interlocks.py", "tests/coil_driver/test_coil_boundaries.py",
              "tests/coil_driver/test_coil_properties.py", "tests/controllers/test_controllers_nan_safety.py",
              "-k", "not stops_the_run and not recorded_trace and not readme and not cosim_validate")
EKF_TESTS = ("tests/estimators/test_kf_filter.py", "tests/estimators/test_ekf_jacobian.py",
             "tests/estimators/test_ekf_parts.py", "tests/estimators/test_kf_noise.py",
             "tests/estimators/test_kf_noise_parts.py", "tests/estimators/test_kf_noise_fit.py")
# the stepper and the port store in-process (the node layout's store of received rows, a step's inputs over
# delayed edges, publishing, timeouts, closing: milliseconds a test), what a component is given at set-up, and
# the loop in one process, delays 0 to 3 on each edge once (each run starts a zenoh session: a second)
DELAY_TESTS = ("tests/core/test_stepper.py", "tests/core/test_portcache.py", "tests/core/test_component_setup.py",
               "tests/core/test_delays.py",
               "-k", "test_stepper or test_portcache or test_component_setup or reference"
                     " or one_process and (1-0 or 2-1 or 3-2 or 1-3)")
TARGETS = (  # cheap and most dangerous first: a run cut short still has their figures
    # the hypothesis property test takes ~17 s alone and neared 60 s on a loaded machine: a slow run is no hang
    Target("interlocks", "cosim_plugins/coil_driver/interlocks.py", COIL_TESTS, timeout_s=180.0),
    Target("wiring", "cosim/runtime/wiring.py", ("tests/core/test_wiring.py",)),
    Target("ekf", "cosim_plugins/estimators/ekf.py", EKF_TESTS),
    Target("noise", "cosim_plugins/estimators/noise.py", EKF_TESTS),
    # a mutant that loses a message makes a run wait on the bus for ever: a delay test takes ~1 s
    Target("stepper", "cosim/runtime/stepper.py", DELAY_TESTS, timeout_s=30.0),
    Target("portcache", "cosim/runtime/portcache.py", DELAY_TESTS, timeout_s=30.0),
    Target("raw_log", "cosim_plugins/raw_log.py",
           ("tests/identify/test_identify_data.py", "tests/identify/test_raw_log_outliers.py",
            "tests/identify/test_raw_log_format.py")),
    Target("convert", "cosim_plugins/identify/convert.py", ("tests/identify/test_convert.py",)),
    # the verdict on hand-made results (milliseconds a test): its gates at their edges and its words, case by case
    Target("verdict", "cosim_plugins/diagnose/verdict.py",
           ("tests/diagnose/test_verdict.py", "tests/diagnose/test_stepwise_parts.py",
            "tests/diagnose/test_diagnose_parts.py",
            "-k", "test_verdict or naming_gates or unidentifiable or verdict_names")),
    Target("inverse", "cosim_plugins/coil_driver/inverse.py",
           ("tests/coil_driver/test_coil_visa.py", "tests/coil_driver/test_coil_daq.py", *COIL_TESTS),
           timeout_s=180.0),
    # the component on its own; test_kf_plant.py (30 s loops with the plant, a minute each here) is left out
    Target("kalman", "cosim_plugins/estimators/kalman.py",
           ("tests/estimators/test_kf_component.py", "tests/estimators/test_kf_params.py",
            "tests/estimators/test_kf_setup.py"), timeout_s=120.0),
)

#: Survivors that no input the module can receive tells from the original: {mutant: why}.
EQUIVALENT: dict[str, str] = {
    # verdict.py
    'cosim_plugins.diagnose.verdict.x__clues_text__mutmut_3':
        "localisation without clues read as None for []: both are false, 'none stand out' either way",
    'cosim_plugins.diagnose.verdict.x__clues_text__mutmut_5':
        "localisation without clues read as None (get without a default) for []: both false, the same words",
    'cosim_plugins.diagnose.verdict.x__verdict__mutmut_37':
        "_steps_text called without steps too: with none chosen none is dropped, and it returns ''",
    'cosim_plugins.diagnose.verdict.x_fit_notes__mutmut_30':
        'a missing condition number read as 1.0 for 0.0: both are far below NOTE_CONDITION (1e8)',
    'cosim_plugins.diagnose.verdict.x__experiment_text__mutmut_9':
        "the circle's words start as None for '': an experiment always has a path (ExperimentResult.path is "
        "required), so they are set before use",
    'cosim_plugins.diagnose.verdict.x__experiment_text__mutmut_10':
        "the circle's words start as 'XXXX' for '': an experiment always has a path, so they are set before use",
    # convert.py
    'cosim_plugins.identify.convert.x_read_positions__mutmut_46':
        'pixel_mm < 0 for <= 0: a zero pixel size is refused by `not pixel_mm` just before',
    'cosim_plugins.identify.convert.x_read_commands__mutmut_82':
        'a zero axis divided by 2.0 for 1.0: such a row has freq_hz 0 (others are refused), so the numerator is 0',
    # interlocks.py
    'cosim_plugins.coil_driver.interlocks.x_limit_scale__mutmut_2':
        "the NaN test of the amplitudes disabled: the driver never hands limit_scale a NaN (a non-finite omega trips "
        "unsafe_command before any amplitude is computed; a finite omega gives finite amplitudes)",
    'cosim_plugins.coil_driver.interlocks.x_limit_scale__mutmut_10':
        'max(*amp_v) for max(0.0, *amp_v): the six amplitudes are magnitudes, never below zero',
    'cosim_plugins.coil_driver.interlocks.x_limit_scale__mutmut_36':
        'amp / scale > prev + rise for amp * scale: a coil this adds has (prev + rise) / amp >= scale, so the '
        'minimum, the scale, is unchanged',
    'cosim_plugins.coil_driver.interlocks.x_limit_scale__mutmut_37':
        'amp * scale >= prev + rise for >: a coil this adds has (prev + rise) / amp == scale, the minimum unchanged',
    'cosim_plugins.coil_driver.interlocks.xǁThermalBudgetǁ__init____mutmut_19':
        'ring rows of 7 entries: zip stops at the six coils',
    'cosim_plugins.coil_driver.interlocks.xǁThermalBudgetǁ__init____mutmut_25':
        'an energy list of 7 entries: zip stops at the six coils',
    'cosim_plugins.coil_driver.interlocks.xǁThermalBudgetǁadd__mutmut_18':
        'the ring walked backwards: the slot replaced is still the one written window_ticks ticks ago',
    'cosim_plugins.coil_driver.interlocks.xǁThermalBudgetǁadd__mutmut_21':
        '< for <= against the budget: at exact equality it falls through to the coils over budget, an empty list',
    'cosim_plugins.coil_driver.interlocks.xǁThermalBudgetǁadd__mutmut_24':
        '>= in the list of coils over budget: it runs only when a coil is strictly over, and the hottest, the one '
        'named, is then strictly over too',
    # ekf.py
    'cosim_plugins.estimators.ekf.x_linear_step__mutmut_3':
        "a linear model's matrices with dtype=None: used in products and sums with float matrices, integers give "
        "the same numbers",
    'cosim_plugins.estimators.ekf.x_linear_step__mutmut_5':
        "a linear model's matrices without dtype: integers give the same products and sums",
    'cosim_plugins.estimators.ekf.x_linear_step__mutmut_12':
        "getattr(model, 'dt_s') without a default: every model has dt_s (the base class sets it)",
    'cosim_plugins.estimators.ekf.x_linear_step__mutmut_25':
        '>= 1e-9 for > 1e-9 in the period check: differs only when the rounding slack is met exactly',
    'cosim_plugins.estimators.ekf.xǁMultiStepEKFǁ__init____mutmut_8':
        'q with dtype=None: integer variances give the same float covariances (P is float, Q scaled by a float)',
    'cosim_plugins.estimators.ekf.xǁMultiStepEKFǁ__init____mutmut_10':
        'q without dtype: integer variances give the same float covariances',
    'cosim_plugins.estimators.ekf.xǁMultiStepEKFǁ__init____mutmut_31':
        'R with dtype=None: integer variances add to the float P alike',
    'cosim_plugins.estimators.ekf.xǁMultiStepEKFǁ__init____mutmut_33':
        'R without dtype: integer variances add to the float P alike',
    'cosim_plugins.estimators.ekf.xǁMultiStepEKFǁ__init____mutmut_78':
        '_since = None before start: start() sets it to 0 before any predict',
    'cosim_plugins.estimators.ekf.xǁMultiStepEKFǁ__init____mutmut_79':
        '_since = 1 before start: start() sets it to 0 before any predict',
    'cosim_plugins.estimators.ekf.xǁMultiStepEKFǁstart__mutmut_12':
        '_since = 1 at start: a nonlinear model starts without a Jacobian, which forces a refresh that resets '
        '_since; a linear model never reads it',
    'cosim_plugins.estimators.ekf.xǁMultiStepEKFǁpredict__mutmut_33':
        "-pz in the finiteness sum: positions are within the tank (checked beside it), far too small to tip a "
        "sum's overflow (float spacing near 1e308 is ~1e292)",
    'cosim_plugins.estimators.ekf.xǁMultiStepEKFǁpredict__mutmut_34':
        "-py in the finiteness sum: positions within the tank cannot tip a sum's overflow",
    'cosim_plugins.estimators.ekf.xǁMultiStepEKFǁpredict__mutmut_100':
        'speed2 >= v_max**2 for >: at equality the scale factor is 1',
    'cosim_plugins.estimators.ekf.xǁMultiStepEKFǁupdate__mutmut_3':
        'adapt_rate >= 0 for > 0: with rate 0 the adaptation leaves the scale at exp(0) and rebuilds the same Q '
        '(the NIS is finite: the component passes only finite frames)',
    # raw_log.py
    'cosim_plugins.raw_log.x__clean__mutmut_6':
        'raw[:, 4:8] for 4:7: the array has 7 columns, slicing past the last is the same',
    'cosim_plugins.raw_log.x__clean__mutmut_54':
        'p_mm[gap] = None: numpy stores None as NaN in a float array',
    'cosim_plugins.raw_log.x__clean__mutmut_78':
        'p_mm[repeat] = None: numpy stores None as NaN in a float array',
    'cosim_plugins.raw_log.x__clean__mutmut_84':
        'p_mm[outlier] = None: numpy stores None as NaN in a float array',
    'cosim_plugins.raw_log.x__clean__mutmut_67':
        "~gap[:+1] in the repeat test: a gap row's p is NaN, never equal to the next row's",
    'cosim_plugins.raw_log.x__parse__mutmut_15':
        "lstrip('XX<BOM>XX'): strips X too, and a header that starts with X is refused anyway",
    'cosim_plugins.raw_log.x__parse__mutmut_33':
        "a third pass filling ',,': two passes leave none (each fills every other one)",
    'cosim_plugins.raw_log.x__parse__mutmut_41':
        "',NAN,' for ',nan,': numpy's parser reads NAN as NaN",
    'cosim_plugins.raw_log.x__parse__mutmut_49':
        "',NAN<newline>' for ',nan<newline>': numpy's parser reads NAN as NaN",
    'cosim_plugins.raw_log.x__parse__mutmut_55':
        "'NAN' for 'nan': numpy's parser reads NAN as NaN",
    'cosim_plugins.raw_log.x__parse__mutmut_59':
        "loadtxt(dtype=None): loadtxt's default dtype is float",
    'cosim_plugins.raw_log.x__parse__mutmut_63':
        'loadtxt without dtype: its default is float',
    'cosim_plugins.raw_log.x__parse__mutmut_64':
        'loadtxt without ndmin: a log has at least 3 rows, so the array is 2-D anyway',
    'cosim_plugins.raw_log.x__parse__mutmut_70':
        "ValueError(None) for ValueError('shape'): caught two lines below, its text never read",
    'cosim_plugins.raw_log.x__parse__mutmut_71':
        "ValueError('XXshapeXX'): caught two lines below, its text never read",
    'cosim_plugins.raw_log.x__parse__mutmut_72':
        "ValueError('SHAPE'): caught two lines below, its text never read",
    'cosim_plugins.raw_log.x__parse_slow__mutmut_17':
        'out[i, j] = None: numpy stores None as NaN in a float array',
    'cosim_plugins.raw_log.xǁLogWriterǁ__init____mutmut_6':
        'open(newline=None): writes a newline as itself on POSIX, the platforms the project runs on',
    'cosim_plugins.raw_log.xǁLogWriterǁ__init____mutmut_9':
        'open() without newline=: writes a newline as itself on POSIX',
    'cosim_plugins.raw_log.xǁLogWriterǁappend__mutmut_2':
        'reshape(None) for reshape(-1) of the times: the same for the documented (n,) times',
    'cosim_plugins.raw_log.xǁLogWriterǁappend__mutmut_8':
        'reshape(-2) for reshape(-1): numpy takes any negative size as the unknown one',
    'cosim_plugins.raw_log.xǁLogWriterǁappend__mutmut_4':
        'asarray(t, dtype=None): integer times print alike; the table is made float by + 0.0',
    'cosim_plugins.raw_log.xǁLogWriterǁappend__mutmut_6':
        'asarray(t) without dtype: integer times print alike; the table is made float by + 0.0',
    'cosim_plugins.raw_log.xǁLogWriterǁappend__mutmut_16':
        'asarray(omega, dtype=None): the table is made float by + 0.0',
    'cosim_plugins.raw_log.xǁLogWriterǁappend__mutmut_18':
        'asarray(omega) without dtype: the table is made float by + 0.0',
    'cosim_plugins.raw_log.xǁLogWriterǁappend__mutmut_26':
        'asarray(p, dtype=None): the table is made float by + 0.0',
    'cosim_plugins.raw_log.xǁLogWriterǁappend__mutmut_28':
        'asarray(p) without dtype: the table is made float by + 0.0',
    'cosim_plugins.raw_log.xǁLogWriterǁappend__mutmut_41':
        '<= 2**53 for < 2**53: differs at 2**53 ms (285,000 years), where %d is exact too',
    'cosim_plugins.raw_log.xǁLogWriterǁappend__mutmut_43':
        '3**53 for 2**53: differs only for times beyond 2**53 ms (285,000 years)',
    'cosim_plugins.raw_log.xǁLogWriterǁappend__mutmut_44':
        '2**54 for 2**53: differs only for times beyond 2**53 ms (285,000 years)',
    'cosim_plugins.raw_log.xǁLogWriterǁappend__mutmut_52':
        "%.12G for %.12g: only the exponent's letter, E or e, which float() reads alike",
    # noise.py
    'cosim_plugins.estimators.noise.x_fit_process_noise__mutmut_114':
        'Fi[:7, :6] for Fi[:6, :6] in the known variance: np.diag of a 7x6 product is the same 6 entries',
    'cosim_plugins.estimators.noise.x_fit_process_noise__mutmut_116':
        'Fi[:7, :6].T for Fi[:6, :6].T: np.diag of the 6x7 product is the same 6 entries',
    'cosim_plugins.estimators.noise.x_fit_process_noise__mutmut_132':
        'Fi[:6, 6:10] for 6:9: F has 9 columns, slicing past the last is the same',
    'cosim_plugins.estimators.noise.x_fit_process_noise__mutmut_140':
        'acc[:, 6:10] for 6:9: acc has 9 columns, slicing past the last is the same',
    'cosim_plugins.estimators.noise.x_fit_process_noise__mutmut_80':
        '9 unknowns without drift: the 3 extra columns are zero, NNLS gives them 0, q and drift0 the same',
    'cosim_plugins.estimators.noise.x_fit_process_noise__mutmut_82':
        '7 unknowns without drift: the extra column is zero, NNLS gives it 0',
    'cosim_plugins.estimators.noise.x_fit_process_noise__mutmut_91':
        'np.eye(F.shape[1]) for shape[0]: F is square',
    'cosim_plugins.estimators.noise.x_fit_process_noise__mutmut_95':
        'acc of F.shape[1] columns for shape[0]: F is square',
    'cosim_plugins.estimators.noise.x_fit_process_noise__mutmut_152':
        'use[0, 3:] = None: numpy stores None as False in a bool array',
    'cosim_plugins.estimators.noise.x_fit_process_noise__mutmut_158':
        'weights 2 / V for 1 / V: scaling every row alike leaves the least-squares solution',
    'cosim_plugins.estimators.noise.x_fit_process_noise__mutmut_197':
        'horizons from range(horizon + 1): 0 is not among {1, 2, 5, ...}, the set intersected',
    'cosim_plugins.estimators.noise.x_mean_jacobian__mutmut_2':
        "a linear model's matrix with dtype=None: integers give the same products with the float covariances",
    'cosim_plugins.estimators.noise.x_mean_jacobian__mutmut_4':
        "a linear model's matrix without dtype: integers give the same products with the float covariances",
    'cosim_plugins.estimators.noise.x_measured_residuals__mutmut_8':
        '>= max_windows: drawing all n of n windows and sorting them gives the same windows',
    'cosim_plugins.estimators.noise.x_measured_residuals__mutmut_13':
        'choice(replace=None): None is false, as False is',
    'cosim_plugins.estimators.noise.x_robust_second_moment__mutmut_10':
        'out[j] = None: numpy stores None as NaN in a float array',
    # kalman.py
    'cosim_plugins.estimators.kalman.xǁKalmanEstimatorǁstep__mutmut_5':
        'asarray(omega, dtype=None): the bus delivers float64 arrays',
    'cosim_plugins.estimators.kalman.xǁKalmanEstimatorǁstep__mutmut_7':
        'asarray(omega) without dtype: the bus delivers float64 arrays',
    'cosim_plugins.estimators.kalman.xǁKalmanEstimatorǁstep__mutmut_12':
        'asarray(position, dtype=None): the bus delivers float64 arrays',
    'cosim_plugins.estimators.kalman.xǁKalmanEstimatorǁstep__mutmut_14':
        'asarray(position) without dtype: the bus delivers float64 arrays',
    'cosim_plugins.estimators.kalman.xǁKalmanEstimatorǁstep__mutmut_53':
        'out[6:10] for out[6:9]: the state has 9 entries, slicing past the last is the same',
    'cosim_plugins.estimators.kalman.xǁKalmanEstimatorǁstep__mutmut_57':
        'out[3:7] for out[3:6] without drift: the state has 6 entries',
    'cosim_plugins.estimators.kalman.x__dataset__mutmut_1':
        "_dataset's default profile: its one caller always passes the scenario's",
    'cosim_plugins.estimators.kalman.x__dataset__mutmut_2':
        "_dataset's default profile: its one caller always passes the scenario's",
    'cosim_plugins.estimators.kalman.x__dataset__mutmut_6':
        'glob() for a pattern without wildcards too: it returns the name when the file exists, [] when not',
    'cosim_plugins.estimators.kalman.xǁKalmanEstimatorǁstep__mutmut_24':
        'a snapshot of the unstarted filter kept for a tick before the first frame: that entry is read only by '
        'the first frame (restore leaves started False, so it starts the filter alike); later entries are '
        'rewritten with started snapshots when a frame is fused, and a constant latency delivers no frame older',
    'cosim_plugins.estimators.kalman.xǁKalmanEstimatorǁ_frame__mutmut_4':
        'the history sliced with latency 0 too: with latency 0 nothing is appended, the slice of it is []',
    'cosim_plugins.estimators.kalman.x__resolve__mutmut_1':
        "_resolve's default profile: both callers pass the scenario's",
    'cosim_plugins.estimators.kalman.x__resolve__mutmut_2':
        "_resolve's default profile: both callers pass the scenario's",
    'cosim_plugins.estimators.kalman.xǁKalmanEstimatorǁ_frame__mutmut_8':
        'the history sliced one entry further back: it holds latency + 1 entries (its maxlen), the slice is the same',
    'cosim_plugins.estimators.kalman.xǁKalmanEstimatorǁ_frame__mutmut_14':
        'started = None for False: only ever read as a truth value',
    'cosim_plugins.estimators.kalman.xǁKalmanEstimatorǁsetup__mutmut_80':
        'gate_prob > 1.0 for >= 1.0: at 1.0 the chi-square quantile is inf too, and gate_prob is at most 1',
    'cosim_plugins.estimators.kalman.xǁKalmanEstimatorǁsetup__mutmut_81':
        'gate_prob >= 2.0 for >= 1.0: gate_prob is at most 1 (its range), and chi2.ppf(1.0, 3) is inf',
    'cosim_plugins.estimators.kalman.xǁKalmanEstimatorǁ_process_noise__mutmut_5':
        'q_diag with dtype=None: its entries are checked to be numbers; integers give the same float covariances',
    'cosim_plugins.estimators.kalman.xǁKalmanEstimatorǁ_process_noise__mutmut_7':
        'q_diag without dtype: integers give the same float covariances',
    'cosim_plugins.estimators.kalman.xǁKalmanEstimatorǁ_process_noise__mutmut_40':
        ">= 1e-6 for > 1e-6 in the logs' period check: differs only when the rounding slack is met exactly",
    'cosim_plugins.estimators.kalman.xǁKalmanEstimatorǁsetup__mutmut_76':
        'the quantile computed at gate_prob 1.0 too: chi2.ppf(1.0, 3) is inf, the gate an inf stands for',
    'cosim_plugins.coil_driver.inverse.xǁInverseMagneticsǁsetup__mutmut_6':
        "dt's default None: the framework always passes dt (a component's parameters hold the scenario's period)",
    'cosim_plugins.coil_driver.inverse.xǁInverseMagneticsǁsetup__mutmut_8':
        "dt's default dropped: the framework always passes dt",
    'cosim_plugins.coil_driver.inverse.xǁInverseMagneticsǁsetup__mutmut_11':
        "dt's default 1.02 for 0.02: the framework always passes dt",
    'cosim_plugins.coil_driver.inverse.xǁInverseMagneticsǁsetup__mutmut_45':
        'the centre matrix pseudo-inverse left real (astype(None)): it is real, and its products with the complex '
        'field phasors are the same complex numbers',
    'cosim_plugins.coil_driver.inverse.xǁInverseMagneticsǁsetup__mutmut_141':
        'closed = None for False: only ever read as a truth value',
    'cosim_plugins.coil_driver.inverse.xǁInverseMagneticsǁsetup__mutmut_143':
        '_reported = None for False: only ever read as a truth value',
    'cosim_plugins.coil_driver.inverse.xǁInverseMagneticsǁclose__mutmut_21':
        "the unreported trip inserted at 1 for 0: a trip stops the rig when it latches and Rig.stop is idempotent, "
        "so at close an unreported trip comes with no failures and is the list's only entry",
    # stepper.py
    'cosim.runtime.stepper.x_setup_component__mutmut_8':
        "getattr(component, 'uses_path', None): None is false, as False is",
    'cosim.runtime.stepper.x_setup_component__mutmut_26':
        "getattr(component, 'uses_run_dir', None): None is false, as False is",
    'cosim.runtime.stepper.xǁStepperǁ__init____mutmut_1':
        'self.name = None: nothing reads a stepper\'s name (the scheduler and nodes key steppers by it)',
    'cosim.runtime.stepper.xǁStepperǁ__init____mutmut_5':
        'self.period = None: nothing reads it (the scheduler and nodes take periods from the wiring)',
    'cosim.runtime.stepper.xǁStepperǁstep__mutmut_27':
        "always value.reshape(shape): a vector's shape is None, and ndarray.reshape(None) returns it as it is",
    'cosim.runtime.stepper.xǁStepperǁ_publish__mutmut_13':
        "a scalar's float fast path never taken: the general path makes it a 0-d array of shape (), the same value",
    'cosim.runtime.stepper.xǁStepperǁ_publish__mutmut_19':
        'every value through np.asarray(dtype=float): a float64 array comes back as it is',
    'cosim.runtime.stepper.xǁStepperǁ_publish__mutmut_21':
        'arrays of other dtypes left unconverted: assigning them into the float64 row converts them alike',
    'cosim.runtime.stepper.xǁStepperǁ_publish__mutmut_24':
        'np.asarray(value, dtype=None): assigning into the float64 row converts alike, the shape checked the same',
    'cosim.runtime.stepper.xǁStepperǁ_publish__mutmut_26':
        'np.asarray(value) without dtype: assigning into the float64 row converts alike, the shape checked the same',
    'cosim.runtime.stepper.xǁStepperǁ_publish__mutmut_30':
        'always value.reshape(-1): a 0-d or 1-d value flattened fills its slot with the same numbers',
    'cosim.runtime.stepper.xǁStepperǁ_publish__mutmut_36':
        'reshape(-2) for reshape(-1): numpy takes any negative size as the unknown one',
    # portcache.py
    'cosim.runtime.portcache.xǁPortStoreǁrow__mutmut_1':
        "a plain store's row(timeout_s=1.0): a plain store never waits, the argument is unread",
    'cosim.runtime.portcache.xǁPortStoreǁstore_payload__mutmut_3':
        "np.frombuffer(dtype=None): its default is float64 in the host's order, little-endian on the hosts supported",
    'cosim.runtime.portcache.xǁPortStoreǁstore_payload__mutmut_5':
        "np.frombuffer without dtype: float64 in the host's order, little-endian on the hosts supported",
    'cosim.runtime.portcache.xǁPortCacheǁ_drain__mutmut_11':
        "np.frombuffer(dtype=None): its default is float64 in the host's order, little-endian on the hosts supported",
    'cosim.runtime.portcache.xǁPortCacheǁ_drain__mutmut_13':
        "np.frombuffer without dtype: float64 in the host's order, little-endian on the hosts supported",
    'cosim.runtime.portcache.xǁPortCacheǁrow__mutmut_3':
        "the first look-up skipped: the drain's look-up finds the row (a fast path's saving lost, not its result)",
    'cosim.runtime.portcache.xǁPortCacheǁrow__mutmut_4':
        "the first look-up of stamp None (never stored): the drain's look-up finds the row",
    'cosim.runtime.portcache.xǁPortCacheǁrow__mutmut_7':
        "the look-up after the drain skipped: poll's first fetch, before any wait, finds the row",
    'cosim.runtime.portcache.xǁPortCacheǁrow__mutmut_8':
        "the look-up after the drain of stamp None: poll's first fetch, before any wait, finds the row",
    # inverse.py
    'cosim_plugins.coil_driver.inverse.xǁInverseMagneticsǁ_latch__mutmut_3':
        "rotation = '' for None at a trip: the fault stays latched, no later step computes a rotation",
    'cosim_plugins.coil_driver.inverse.xǁInverseMagneticsǁ_latch__mutmut_4':
        'prev_amp = None for zeros at a trip: the fault stays latched, no later step reads it',
    'cosim_plugins.coil_driver.inverse.xǁInverseMagneticsǁ_start_monitor__mutmut_3':
        "the monitor thread's name: shown in stack dumps only",
    'cosim_plugins.coil_driver.inverse.xǁInverseMagneticsǁ_start_monitor__mutmut_6':
        "the monitor thread's name: shown in stack dumps only",
    'cosim_plugins.coil_driver.inverse.xǁInverseMagneticsǁ_start_monitor__mutmut_8':
        "the monitor thread's name: shown in stack dumps only",
    'cosim_plugins.coil_driver.inverse.xǁInverseMagneticsǁ_start_monitor__mutmut_9':
        "the monitor thread's name: shown in stack dumps only",
    'cosim_plugins.coil_driver.inverse.xǁInverseMagneticsǁ_phasors__mutmut_70':
        'scale <= 1.0: at exactly 1 the voltages are multiplied by 1, which changes no bit',
    'cosim_plugins.coil_driver.inverse.xǁInverseMagneticsǁ_phasors__mutmut_71':
        'scale < 2.0: limit_scale never exceeds 1, and multiplying by 1 changes no bit',
}

#: mutmut's statuses that count as caught (a failing test, or one that no longer finishes).
CAUGHT = {"killed", "timeout"}
RESULT_LINE = re.compile(r"^\s+(\S+): (.+)$")


def prepare(target: Target) -> Path:
    """A private copy of the project for ``target``, its pyproject naming what to mutate and which tests run."""
    work = WORK / target.name
    work.mkdir(parents=True, exist_ok=True)
    for item in (*COPIED, *OPTIONAL):
        src, dst = ROOT / item, work / item
        if not src.exists():
            continue
        if src.is_dir():
            shutil.copytree(src, dst, dirs_exist_ok=True,
                            ignore=shutil.ignore_patterns("__pycache__", "*.pyc", ".hypothesis", "build"))
        else:
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst)
    config = "\n".join([
        "", "[tool.mutmut]",
        'source_paths = ["cosim", "cosim_plugins"]',  # whole packages in mutants/, so every import resolves there
        f"only_mutate = [{json.dumps(target.path)}]",
        f"pytest_add_cli_args_test_selection = {json.dumps(list(target.tests))}",
        'pytest_add_cli_args = ["-p", "no:cacheprovider"]',
        # each mutant's tests fork from a server that has only collected them: forked from mutmut's own process,
        # which ran the suite, a test's zenoh session never closes (its runtime's threads stay in the parent)
        'process_isolation = "forkserver"',
        # mutmut's own limit (10x the clean time plus 10 s) stays as a backstop behind the watchdog
        "timeout_multiplier = 10.0", "timeout_constant = 10.0",
        'also_copy = ["examples", "docs", "README.md", "build", "cache"]',
        "",
    ])
    pyproject = work / "pyproject.toml"
    text = (ROOT / "pyproject.toml").read_text()
    pyproject.write_text(text.split("\n[tool.mutmut]")[0] + config)
    return work


def results(work: Path) -> dict[str, str]:
    """{mutant name: status} of the last run in ``work`` (empty before the first)."""
    if not (work / "mutants").exists():
        return {}
    out = subprocess.run([sys.executable, "-m", "mutmut", "results", "--all", "true"], cwd=work,
                         capture_output=True, text=True, check=True).stdout
    return {m.group(1): m.group(2).strip() for line in out.splitlines() if (m := RESULT_LINE.match(line))}


def run_mutmut(target: Target, work: Path, children: int, names: list[str], log) -> None:
    """``mutmut run`` in ``work`` (every mutant not yet tested, or just ``names``), each test under the watchdog."""
    env = {**os.environ, "COSIM_TEST_TIMEOUT": str(target.timeout_s), "COSIM_TEST_TIMEOUT_DIR": str(work / "hung")}
    proc = subprocess.run([sys.executable, "-m", "mutmut", "run", "--max-children", str(children), *names],
                          cwd=work, stdout=log, stderr=subprocess.STDOUT, env=env)
    if proc.returncode != 0:
        raise RuntimeError(f"mutmut run for {target.path} exited {proc.returncode}; see {log.name}")


def mutate(target: Target, children: int) -> dict:
    """Run mutmut on ``target``, then its last survivors again; the figures, survivors named."""
    t0 = time.perf_counter()
    work = prepare(target)
    before = results(work)
    with open(WORK / f"{target.name}.log", "w") as log:
        run_mutmut(target, work, children, [], log)
        # a survivor of an earlier run, with its code unchanged, meets the tests added since
        again = [name for name, s in results(work).items() if s not in CAUGHT and before.get(name) == s]
        if again:
            run_mutmut(target, work, children, again, log)
    return figures(work, time.perf_counter() - t0)


def figures(work: Path, seconds: float | None = None) -> dict:
    """The figures of the mutants tested in ``work`` so far (``untested``: not reached yet, a run cut short)."""
    status = results(work)
    untested = {name for name, s in status.items() if s == "not checked"}
    status = {name: s for name, s in status.items() if name not in untested}
    killed = {name for name, s in status.items() if s in CAUGHT}
    hung = {p.stem for p in (work / "hung").glob("*.txt")} & killed
    survived = sorted(set(status) - killed)
    equivalent = [name for name in survived if name in EQUIVALENT]
    tested = len(status) - len(equivalent)
    return {"mutants": len(status), "killed": len(killed), "hung": len(hung), "equivalent": len(equivalent),
            "score": round(len(killed) / tested, 3) if tested else None,
            "survived": [name for name in survived if name not in EQUIVALENT],
            **({"untested": len(untested)} if untested else {}),
            **({"seconds": round(seconds, 1)} if seconds is not None else {})}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="+", metavar="NAME", choices=[t.name for t in TARGETS],
                        help="these modules only (names: " + ", ".join(t.name for t in TARGETS) + ")")
    parser.add_argument("--children", type=int, default=2, help="mutants tested at once (default 2)")
    parser.add_argument("--report", action="store_true",
                        help="print the figures of the runs so far (build/mutation/NAME/), run nothing")
    args = parser.parse_args(argv)
    targets = [t for t in TARGETS if not args.only or t.name in args.only]
    if args.report:
        report = {t.path: figures(WORK / t.name) for t in targets if (WORK / t.name / "mutants").exists()}
        print(json.dumps({"modules": report}, indent=1))
        return 0
    WORK.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    modules = {}
    for target in targets:  # mutmut's own output: build/mutation/NAME.log
        modules[target.path] = mutate(target, args.children)
        print(f"{target.path}: {modules[target.path]['killed']} of {modules[target.path]['mutants']} killed",
              file=sys.stderr, flush=True)
    print(json.dumps({"modules": modules, "seconds": round(time.perf_counter() - t0, 1)}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
