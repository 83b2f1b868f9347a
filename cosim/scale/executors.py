"""Where the runs of a parallel sweep execute: local worker processes or a Dask cluster.

Both are driven through ``concurrent.futures`` (``submit`` returns a
:class:`concurrent.futures.Future` of :func:`cosim.scale.jobs.run_job`'s result):

* :class:`LocalLanes` (``--jobs N``): N single-worker
  :class:`~concurrent.futures.ProcessPoolExecutor` "lanes" (spawned, so a
  worker shares nothing with the client but what a job carries), each
  running one job at a time and reused for the next, so the imports and
  in-process caches are paid once per lane. A job that crashes its process
  breaks only its own lane, which is replaced; a job past its deadline has
  its process killed. With ``--processes`` each lane and the nodes its runs
  start are placed on CPUs of their own (:func:`cpu_groups`).
* :class:`DaskLanes` (``--executor dask`` or ``dask://HOST:PORT``): a
  :class:`distributed.LocalCluster` of N single-threaded worker processes,
  or an existing Dask scheduler, through ``Client.get_executor()``. Jobs
  ship their scenario and return their run folder as bytes, as the
  workers may be other machines. Needs the ``cluster`` extra.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import threading
import time
import uuid
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

from cosim.contract.errors import UserError
from cosim.scale.jobs import warm_up

#: How long ``dask://HOST:PORT`` waits for the scheduler to answer, and for a worker to join it.
DASK_CONNECT_TIMEOUT_S = 10.0
DASK_WORKERS_TIMEOUT_S = 30.0


def cpu_groups(n: int) -> list[set[int]]:
    """``n`` disjoint groups of the CPUs this process may use (contiguous, as even as can be);
    with more groups than CPUs, the CPUs are dealt round."""
    cpus = sorted(os.sched_getaffinity(0))
    if n > len(cpus):
        return [{cpus[i % len(cpus)]} for i in range(n)]
    size, extra = divmod(len(cpus), n)
    groups, start = [], 0
    for i in range(n):
        end = start + size + (i < extra)
        groups.append(set(cpus[start:end]))
        start = end
    return groups


def _start_worker(pid_box, cpus: set[int] | None) -> None:
    """A lane's worker, at its start: say its pid; keep to its CPUs (threads started later inherit them).
    A Ctrl-C at the terminal reaches the workers too: an idle one ignores it, a run stops after its
    tick (:func:`cosim.runtime.runner.stop_on_signals` while it runs) and the sweep starts no further one."""
    pid_box.value = os.getpid()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if cpus:
        os.sched_setaffinity(0, cpus)


class _Lane:
    def __init__(self, cpus: set[int] | None):
        ctx = multiprocessing.get_context("spawn")
        self.cpus = cpus
        self.pid = ctx.RawValue("q", 0)
        self.pool = ProcessPoolExecutor(1, mp_context=ctx, initializer=_start_worker, initargs=(self.pid, cpus))
        #: when the worker had made its imports (monotonic s; None: not yet): a job starts no earlier
        self.warm_at: float | None = None
        # imports while the client prepares the caches; a job queues behind them
        self.pool.submit(warm_up).add_done_callback(lambda _: setattr(self, "warm_at", time.monotonic()))
        self.future: Future | None = None

    def retire(self) -> None:
        """Stop this lane's process at once (it holds a stuck thread, or a job past its deadline)."""
        self.pool.shutdown(wait=False, cancel_futures=True)
        if self.pid.value:
            try:
                os.kill(self.pid.value, signal.SIGKILL)
            except ProcessLookupError:
                pass


class LocalLanes:
    """``n`` local worker processes, one job each at a time (see the module doc)."""

    ships = False

    def __init__(self, n: int, place: bool = False):
        self.groups = cpu_groups(n) if place else [None] * n
        self.lanes = [_Lane(cpus) for cpus in self.groups]

    def describe(self) -> str:
        return f"{len(self.lanes)} local worker processes"

    def free(self) -> bool:
        return any(lane.future is None for lane in self.lanes)

    def running(self) -> int:
        return sum(lane.future is not None for lane in self.lanes)

    def submit(self, fn, job) -> Future:
        lane = next(lane for lane in self.lanes if lane.future is None)
        lane.future = lane.pool.submit(fn, job)
        return lane.future

    def started_at(self, future: Future, submitted: float) -> float | None:
        """When the job of ``future``, submitted at ``submitted`` (monotonic s), started: once its lane's
        worker had made its imports; None while it is still making them."""
        warm = self.lanes[self._lane_of(future)].warm_at
        return None if warm is None else max(warm, submitted)

    def _lane_of(self, future: Future) -> int:
        return next(i for i, lane in enumerate(self.lanes) if lane.future is future)

    def release(self, future: Future) -> None:
        """The job of ``future`` is over: free its lane, replacing the process if it broke or holds
        a thread stuck in a component's step."""
        i = self._lane_of(future)
        broken = future.exception() is not None and isinstance(future.exception(), BrokenProcessPool)
        stuck = future.exception() is None and future.result().get("stuck")
        if broken or stuck:
            self.lanes[i].retire()
            self.lanes[i] = _Lane(self.groups[i])
        else:
            self.lanes[i].future = None

    def stop_running(self, reason: str) -> None:
        """Stop the runs under way after their tick. A Ctrl-C at the terminal has reached the workers
        already; any other stop (a SIGTERM to ``cosim run``) is passed on to them as a SIGTERM."""
        if reason == "stopped by SIGINT":
            return
        for lane in self.lanes:
            if lane.future is not None and lane.pid.value:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(lane.pid.value, signal.SIGTERM)

    def abandon(self, future: Future) -> str:
        """Give up on a job past its deadline: kill its process (its lane is replaced)."""
        i = self._lane_of(future)
        self.lanes[i].retire()
        self.lanes[i] = _Lane(self.groups[i])
        return "its worker process was killed"

    @staticmethod
    def crash_text(exc: BaseException) -> str | None:
        if isinstance(exc, BrokenProcessPool):
            return "its worker process ended abruptly (crashed or was killed)"
        return None

    def close(self) -> None:
        for lane in self.lanes:
            lane.pool.shutdown(wait=True, cancel_futures=True)


class DaskLanes:
    """Jobs on a Dask cluster: a local one of ``n`` workers, or the scheduler at ``address``."""

    ships = True

    def __init__(self, n: int, address: str | None = None, tls=None):
        try:
            import dask
            from distributed import Client, LocalCluster
        except ImportError:
            raise UserError("--executor dask needs Dask distributed: pip install 'dask[distributed]' "
                            "(with this project: pip install -e '.[cluster]')") from None
        self.address, self.cluster = address, None
        if address is None:
            import logging

            # a run that kills its worker fails at once instead of being retried on the others; the
            # workers ignore a Ctrl-C at the terminal (the sweep stops their runs through stop_running)
            with dask.config.set({"distributed.scheduler.allowed-failures": 0}), _sigint_ignored():
                self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                            dashboard_address=None, silence_logs=logging.ERROR)
            self.client = Client(self.cluster)
        else:
            security = None
            if tls is not None:  # mutual TLS with the run's certificates (cosim certs)
                from distributed.security import Security

                tls.check(f"--executor dask://tls://{address}")
                security = Security(tls_ca_file=str(tls.ca), tls_client_cert=str(tls.cert),
                                    tls_client_key=str(tls.key), require_encryption=True)
            try:
                self.client = Client(f"{'tls' if tls else 'tcp'}://{address}", timeout=DASK_CONNECT_TIMEOUT_S,
                                     security=security)
            except (OSError, TimeoutError) as exc:
                raise UserError(f"--executor dask://{address}: no Dask scheduler answered at {address} within "
                                f"{DASK_CONNECT_TIMEOUT_S:g} s ({exc})") from None
            try:
                self.client.wait_for_workers(1, timeout=DASK_WORKERS_TIMEOUT_S)
            except (OSError, TimeoutError):
                self.client.close()
                raise UserError(f"--executor dask://{address}: the Dask scheduler there has no worker "
                                f"(none joined within {DASK_WORKERS_TIMEOUT_S:g} s)") from None
        self.executor = self.client.get_executor(pure=False)
        self.in_flight: set[Future] = set()
        #: the Dask event a job watches: set, its run stops after the tick under way
        self.stop_name = f"cosim-stop-{uuid.uuid4().hex}"

    def describe(self) -> str:
        where = f"the Dask scheduler at {self.address}" if self.address else "a local Dask cluster"
        return f"{where} ({self.slots()} worker threads)"

    def slots(self) -> int:
        return max(sum(self.client.nthreads().values()), 1)

    def free(self) -> bool:
        """Only as many jobs in flight as the workers have threads, so a job's deadline counts from its start."""
        return len(self.in_flight) < self.slots()

    def running(self) -> int:
        return len(self.in_flight)

    def submit(self, fn, job) -> Future:
        future = self.executor.submit(fn, job)
        self.in_flight.add(future)
        return future

    def release(self, future: Future) -> None:
        self.in_flight.discard(future)

    @staticmethod
    def started_at(future: Future, submitted: float) -> float:
        """A job starts when it is submitted: no more are in flight than the workers have threads."""
        return submitted

    def stop_running(self, reason: str) -> None:
        """Stop the runs under way after their tick (the workers ignore the terminal's Ctrl-C)."""
        from distributed import Event

        Event(self.stop_name, client=self.client).set()

    def abandon(self, future: Future) -> str:
        """A task cannot be killed on its worker: stop waiting for it (its own timeout stops the run)."""
        self.in_flight.discard(future)
        return "no longer waited for (a Dask task cannot be killed; the run's own timeout stops it)"

    @staticmethod
    def crash_text(exc: BaseException) -> str | None:
        if type(exc).__name__ == "KilledWorker":
            return "its Dask worker process died running it (crashed or was killed)"
        return None

    def close(self) -> None:
        self.executor.shutdown(wait=False)
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


@contextlib.contextmanager
def _sigint_ignored():
    """SIGINT ignored while processes are started (they inherit it; Python then installs no handler)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _loopback(host: str) -> bool:
    import ipaddress

    try:
        return host == "localhost" or ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


@contextlib.contextmanager
def workers(jobs: int, spec: str | None = None):
    """Worker processes shared by several sweeps (``cosim reproduce``, ``cosim dataset``): pass
    what this yields as ``RunRequest.workers``; None with ``jobs == 1`` and no ``spec`` (serial)."""
    executor = None if jobs == 1 and spec is None else open_executor(spec, jobs)
    try:
        yield executor
    finally:
        if executor is not None:
            executor.close()


def open_executor(spec: str | None, jobs: int, place: bool = False, tls=None) -> LocalLanes | DaskLanes:
    """The executor for ``--executor SPEC`` (None or ``local``: :class:`LocalLanes`; ``dask``;
    ``dask://HOST:PORT``, plain TCP, on loopback only; ``dask://tls://HOST:PORT``, mutual TLS with
    ``tls``, :class:`cosim.runtime.bus.TlsFiles` made by ``cosim certs``) with ``jobs`` workers (a local
    Dask cluster's size); ``place``: give each local lane CPUs of its own (runs with ``--processes``).

    Whoever reaches a Dask scheduler runs code on its workers: a scheduler beyond this machine is
    reached with TLS only, and it must require the run's certificates of its clients too."""
    if spec in (None, "local"):
        return LocalLanes(jobs, place)
    if spec == "dask":
        return DaskLanes(jobs)
    if spec.startswith("dask://"):
        address = spec[len("dask://"):]
        secure = address.startswith("tls://")
        address = address[len("tls://"):] if secure else address
        host, _, port = address.rpartition(":")
        if not host or not port.isdigit():
            raise UserError(f"--executor {spec}: expected dask://tls://HOST:PORT (or dask://HOST:PORT on "
                            "loopback), e.g. dask://tls://10.0.0.5:8786")
        if secure and tls is None:
            raise UserError(f"--executor {spec}: a TLS scheduler needs the run's certificates: --tls-ca, --tls-cert "
                            "and --tls-key (cosim certs HOSTS.yaml makes them)")
        if not secure and not _loopback(host):
            raise UserError(f"--executor {spec}: plain TCP to a Dask scheduler beyond this machine lets anyone "
                            f"who reaches it run code on its workers: use dask://tls://{address} with the run's "
                            "certificates (--tls-ca, --tls-cert, --tls-key)")
        return DaskLanes(jobs, address, tls if secure else None)
    raise UserError(f"--executor {spec}: expected local, dask or dask://HOST:PORT")
