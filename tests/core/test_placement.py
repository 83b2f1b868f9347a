"""Where a distributed run's nodes run: CPU lists, the default, pinning, and bad input."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.cli import main
from cosim.contract.errors import UserError
from cosim.runtime.placement import keep_thread_off, node_cpus, parse_cpu_list
from cosim_plugins.resources import SCENARIOS_DIR

REPO = Path(__file__).parents[2]
linux_only = pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="CPU affinity is Linux-only")


def test_cpu_lists_parse_and_bad_ones_are_named():
    assert parse_cpu_list("0,2-3") == {0, 2, 3}
    assert parse_cpu_list("1") == {1}
    for bad in ("", "a", "3-1", "-1", "1-", "1,,2"):
        with pytest.raises(UserError, match=f"CPU list {bad!r}: expected auto, none or a CPU list"):
            parse_cpu_list(bad)


@linux_only
def test_auto_puts_every_node_on_the_last_cpu_this_process_may_use():
    assert node_cpus("none") is None
    assert node_cpus("auto") == str(max(os.sched_getaffinity(0)))
    with pytest.raises(UserError, match="CPU 4096 is not available"):
        node_cpus("4096")


@linux_only
def test_the_schedulers_thread_keeps_off_the_nodes_cpus_when_others_are_left():
    import threading

    available = os.sched_getaffinity(0)
    seen = {}

    def worker(spec):
        seen[spec] = (keep_thread_off(spec), os.sched_getaffinity(0))

    for spec in (str(max(available)), ",".join(map(str, sorted(available)))):
        thread = threading.Thread(target=worker, args=(spec,))
        thread.start()
        thread.join()
    last, every = str(max(available)), ",".join(map(str, sorted(available)))
    if len(available) > 1:
        assert seen[last] == (True, available - {max(available)})
    assert seen[every] == (False, available)  # no CPU left: the thread stays where it may run
    assert os.sched_getaffinity(0) == available  # the calling thread only: this one is untouched


@linux_only
def test_pinning_moves_every_thread_and_later_ones_under_sched_batch():
    cpu = max(os.sched_getaffinity(0))
    probe = (
        "import os, threading\n"
        "from cosim.runtime.placement import pin_this_process\n"
        "ev = threading.Event(); seen = {}\n"
        "def early():\n"
        "    ev.wait(); seen['early'] = (os.sched_getaffinity(0), os.sched_getscheduler(0))\n"
        "t = threading.Thread(target=early); t.start()\n"
        f"pin_this_process('{cpu}')\n"
        "ev.set(); t.join()\n"
        "late = threading.Thread(target=lambda: seen.__setitem__('late', (os.sched_getaffinity(0), "
        "os.sched_getscheduler(0))))\n"
        "late.start(); late.join()\n"
        "print(all(s == ({" + str(cpu) + "}, os.SCHED_BATCH) for s in seen.values()) and len(seen) == 2)\n"
    )
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "True"


def test_a_bad_node_cpu_list_stops_the_run_before_it_starts(tmp_path, capsys):
    args = ["run", str(SCENARIOS_DIR / "racetrack.yaml"), "--out", str(tmp_path / "r"), "--processes",
            "--node-cpus", "first", "--quiet"]
    assert main(args) == 2
    assert "CPU list 'first': expected auto, none or a CPU list such as 1 or 0,2-3" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_a_node_with_a_bad_cpu_list_fails_before_it_connects(capsys):
    args = ["node", "plant", str(SCENARIOS_DIR / "racetrack.yaml"), "--run-id", "x",
            "--connect", "tcp/127.0.0.1:1", "--cpus", "1-"]
    assert main(args) == 2
    assert "CPU list '1-': expected auto, none or a CPU list" in capsys.readouterr().err
