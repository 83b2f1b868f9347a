"""Scale: many runs at once, on this machine or on a cluster.

:mod:`~cosim.scale.options` says how a sweep's runs execute
(:class:`~cosim.scale.options.SweepOptions`, ``--jobs``);
:mod:`~cosim.scale.sweep` expands a scenario's sweep into jobs and collects
their rows; :mod:`~cosim.scale.jobs` runs one job anywhere (its sources
shipped with it); :mod:`~cosim.scale.executors` hands jobs to local worker
processes or to a Dask cluster; :mod:`~cosim.scale.certs` makes the
certificates for the mutual TLS of a run over machines (placed by
:mod:`cosim.runtime.hosts`).
"""
