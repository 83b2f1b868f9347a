"""A hung test ends its process, when asked: what mutation testing needs of a test that never returns.

With ``COSIM_TEST_TIMEOUT=S`` in the environment (``benchmarks/mutation.py`` sets it), a test still
running ``S`` seconds after it started has every thread's stack written to a file and the process
exits with status 1, the status of a failed test. The watchdog is faulthandler's: a C thread that
needs neither the interpreter lock nor a signal handler, so a test blocked in native code (a zenoh
wait, a lock) is ended as surely as a Python loop. The stack goes to
``$COSIM_TEST_TIMEOUT_DIR/NAME.txt``, ``NAME`` being the mutant under test (mutmut's
``MUTANT_UNDER_TEST``), so a run can tell a hang from a failure; a test that returns in time
leaves no file. Without the variable, nothing is armed; nor in mutmut's runs that test no mutant (the
clean run, and the stats run, which traces every call and is several times slower than the tests).
"""

from __future__ import annotations

import faulthandler
import os
from pathlib import Path

import pytest

#: MUTANT_UNDER_TEST in mutmut's runs that test no mutant (unset: a plain pytest run, armed).
NO_MUTANT = {"", "stats", "fail", "list_all_tests", "mutant_generation"}


def _stack_file(folder: str):
    """The open file a hang's stacks go to (a file named after the mutant under test, or the process)."""
    Path(folder).mkdir(parents=True, exist_ok=True)
    name = os.environ.get("MUTANT_UNDER_TEST") or f"pid{os.getpid()}"
    return open(Path(folder) / f"{name}.txt", "w")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """Arm the watchdog for one test (set-up, call and teardown); disarm it when the test returns."""
    seconds = float(os.environ.get("COSIM_TEST_TIMEOUT") or 0)
    if seconds <= 0 or os.environ.get("MUTANT_UNDER_TEST") in NO_MUTANT:
        yield
        return
    folder = os.environ.get("COSIM_TEST_TIMEOUT_DIR")
    out = _stack_file(folder) if folder else None
    faulthandler.dump_traceback_later(seconds, exit=True, file=out if out is not None else 2)
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()
        if out is not None:
            out.close()
            Path(out.name).unlink(missing_ok=True)
