"""Scale: many runs at once, and one run over several machines.

:mod:`~cosim.scale.sweep` expands a scenario's sweep into jobs and collects
their rows; :mod:`~cosim.scale.jobs` runs one job anywhere (its sources
shipped with it); :mod:`~cosim.scale.executors` hands jobs to local worker
processes or to a Dask cluster; :mod:`~cosim.runtime.hosts` places one run's
components on machines and :mod:`~cosim.scale.certs` makes the certificates
for their mutual TLS.
"""
