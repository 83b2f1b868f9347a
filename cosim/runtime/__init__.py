"""The runtime: the path of one tick, in one process or spread over many.

:mod:`~cosim.runtime.wiring` turns a scenario into components, edges and a
step order (:mod:`~cosim.runtime.check` checks a scenario as a run would);
:mod:`~cosim.runtime.scheduler` grants ticks to a group of components
(:mod:`~cosim.runtime.groups`: local, or nodes) and gathers replies;
:mod:`~cosim.runtime.stepper` steps one component (its inputs from
:mod:`~cosim.runtime.portcache`, its outputs to :mod:`~cosim.runtime.bus`,
one zenoh message per component and tick, stamped); :mod:`~cosim.runtime.recorder`
streams every tick to the run's files; :mod:`~cosim.runtime.node` runs a
component in a process of its own, :mod:`~cosim.runtime.launch` and
:mod:`~cosim.runtime.placement` start and pin those processes,
:mod:`~cosim.runtime.hosts` places them on machines and
:mod:`~cosim.runtime.rights` limits what each may send;
:mod:`~cosim.runtime.pacing` follows the wall clock in real-time runs,
:mod:`~cosim.runtime.fingerprint` makes sure every process runs the same
code (and keys :mod:`~cosim.runtime.cache`'s entries), and
:mod:`~cosim.runtime.runner` ties one run of a :class:`~cosim.runtime.request.RunRequest`
together (set-up, recording, signals, summary).
"""
