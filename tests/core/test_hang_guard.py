"""tests/hang_guard.py: with COSIM_TEST_TIMEOUT set, a hung test ends its process and leaves its stacks."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

TESTS = Path(__file__).resolve().parents[1]

CASES = '''
import threading
import time


def test_returns():
    time.sleep(0.1)


def test_waits_for_ever():
    threading.Event().wait()  # blocked in a lock: no Python code runs, no signal handler would
'''


def _pytest(folder: Path, *args: str, **env):
    (folder / "conftest.py").write_text("from hang_guard import pytest_runtest_protocol  # noqa: F401\n")
    (folder / "test_cases.py").write_text(CASES)
    clean = {k: v for k, v in os.environ.items() if not k.startswith("COSIM_TEST_TIMEOUT")}
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *args, str(folder)],
                          cwd=folder, env={**clean, "PYTHONPATH": str(TESTS), **env},
                          capture_output=True, text=True, timeout=120)


def test_a_hung_test_ends_the_run_as_a_failure_and_names_itself(tmp_path):
    stacks = tmp_path / "hung"
    proc = _pytest(tmp_path, COSIM_TEST_TIMEOUT="1", COSIM_TEST_TIMEOUT_DIR=str(stacks),
                   MUTANT_UNDER_TEST="m.x_f__mutmut_7")
    assert proc.returncode == 1
    assert [p.name for p in stacks.iterdir()] == ["m.x_f__mutmut_7.txt"]  # test_returns left no file
    text = (stacks / "m.x_f__mutmut_7.txt").read_text()
    assert text.startswith("Timeout (0:00:01)!") and "in test_waits_for_ever" in text


def test_a_timeout_of_zero_arms_nothing(tmp_path):
    proc = _pytest(tmp_path, "-k", "test_returns", COSIM_TEST_TIMEOUT="0",
                   COSIM_TEST_TIMEOUT_DIR=str(tmp_path / "hung"))
    assert proc.returncode == 0, proc.stdout
    assert not (tmp_path / "hung").exists()


def test_mutmuts_stats_run_is_not_watched(tmp_path):
    """mutmut's stats run traces every call (several times slower): only runs with a mutant in place are timed."""
    proc = _pytest(tmp_path, "-k", "test_returns", COSIM_TEST_TIMEOUT="0.05",
                   COSIM_TEST_TIMEOUT_DIR=str(tmp_path / "hung"), MUTANT_UNDER_TEST="stats")
    assert proc.returncode == 0, proc.stdout
