"""The runtime: the path of one tick, in one process or spread over many.

:mod:`~cosim.runtime.wiring` turns a scenario into components, edges and a
step order; :mod:`~cosim.runtime.scheduler` grants ticks and gathers replies;
:mod:`~cosim.runtime.stepper` steps one component (its inputs from
:mod:`~cosim.runtime.portcache`, its outputs to :mod:`~cosim.runtime.bus`,
one zenoh message per component and tick, stamped); :mod:`~cosim.runtime.node`
runs a component in a process of its own, :mod:`~cosim.runtime.launch` and
:mod:`~cosim.runtime.placement` start and pin those processes,
:mod:`~cosim.runtime.pacing` follows the wall clock in real-time runs,
:mod:`~cosim.runtime.fingerprint` makes sure every process runs the same
code, and :mod:`~cosim.runtime.runner` ties one run together (set-up,
recording, signals, summary).
"""
