"""Where the nodes of a run spread over processes run on this machine (Linux CPU affinity).

A lockstep loop is a chain: within a tick one component works while the
others wait for its output. Handing a message to a process on the same CPU
costs a context switch; handing it to a process on another CPU costs an
inter-processor interrupt that wakes that CPU, which on a virtual machine
is a round trip through the hypervisor. So by default (``auto``) every node
of a run goes on one CPU, the highest-numbered this process may use, while
the scheduler, which records the run, may use them all. On that CPU the
nodes run under ``SCHED_BATCH``: a node woken by a message does not preempt
the node that sent it, it runs once the sender has finished its step.

``none`` leaves placement to the operating system; a CPU list (``1``,
``0,2-3``) puts every node on those CPUs. The scheduler's threads (its
stepping thread, which records the run: tens of ms of work every second,
and its zenoh threads, which take the nodes' replies) keep off the nodes'
CPUs when there are others (:func:`keep_thread_off`, :func:`threads_started_off`):
on theirs they would preempt the node whose output the others wait for.
"""

from __future__ import annotations

import contextlib
import os
import re

from cosim.contract.errors import UserError

_SPEC_HELP = "expected auto, none or a CPU list such as 1 or 0,2-3"


def _available() -> set[int] | None:
    """CPUs this process may use, or None where affinity is not supported (not Linux)."""
    return os.sched_getaffinity(0) if hasattr(os, "sched_setaffinity") else None


def parse_cpu_list(text: str) -> set[int]:
    """``"0,2-3"`` -> ``{0, 2, 3}``; a malformed list is a :class:`UserError`."""
    cpus: set[int] = set()
    for item in text.split(","):
        match = re.fullmatch(r"\s*(\d+)(?:-(\d+))?\s*", item)
        first, last = (int(match[1]), int(match[2] or match[1])) if match else (1, 0)
        if last < first:
            raise UserError(f"CPU list {text!r}: {_SPEC_HELP}")
        cpus.update(range(first, last + 1))
    return cpus


def node_cpus(spec: str) -> str | None:
    """The CPU list to give every node for ``spec`` (auto / none / a list), or None: no pinning."""
    if spec == "none":
        return None
    available = _available()
    if spec == "auto":
        return None if not available else str(max(available))
    cpus = parse_cpu_list(spec)
    if available is None:
        raise UserError(f"--node-cpus {spec}: CPU placement needs Linux (use auto or none)")
    if not cpus <= available:
        raise UserError(f"--node-cpus {spec}: CPU {min(cpus - available)} is not available "
                        f"(this process may use {','.join(map(str, sorted(available)))})")
    return ",".join(map(str, sorted(cpus)))


def pin_this_process(cpu_list: str) -> None:
    """Run every thread of this process, and those it starts later, on ``cpu_list`` under ``SCHED_BATCH``."""
    cpus = parse_cpu_list(cpu_list)
    if _available() is None:
        raise UserError(f"--cpus {cpu_list}: CPU placement needs Linux")
    for tid in map(int, os.listdir("/proc/self/task")):  # affinity and policy are per thread
        try:
            os.sched_setaffinity(tid, cpus)
            os.sched_setscheduler(tid, os.SCHED_BATCH, os.sched_param(0))
        except ProcessLookupError:  # the thread has ended meanwhile
            continue
        except OSError as exc:
            raise UserError(f"--cpus {cpu_list}: {exc.strerror}") from None


def keep_thread_off(cpu_list: str) -> bool:
    """Run the calling thread (and the threads it starts) on the CPUs this process may use other than
    ``cpu_list``; False, and nothing changed, when no other CPU is left or placement is not supported."""
    available = _available()
    if available is None:
        return False
    others = available - parse_cpu_list(cpu_list)
    if not others:
        return False
    try:
        os.sched_setaffinity(0, others)  # 0: the calling thread only (Linux affinity is per thread)
    except OSError:
        return False
    return True


@contextlib.contextmanager
def threads_started_off(cpu_list: str | None):
    """The threads started inside (by zenoh, say) keep off ``cpu_list`` (see :func:`keep_thread_off`);
    the calling thread is back where it was on exit. ``cpu_list`` None: nothing changes."""
    before = _available() if cpu_list is not None else None
    moved = before is not None and keep_thread_off(cpu_list)
    try:
        yield
    finally:
        if moved:
            os.sched_setaffinity(0, before)
