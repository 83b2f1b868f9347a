"""A throwaway plugin for the placement tests: a component that outputs the CPUs its process may use."""

from __future__ import annotations

import os

import numpy as np

from cosim import Component, Port, hookimpl


class CpuProbe(Component):
    """Outputs the CPUs the stepping thread may use, as a bit mask (CPU n: bit n)."""

    outputs = (Port("cpus", (), "1"),)

    def step(self, t, inputs):
        return {"cpus": np.array(float(sum(1 << cpu for cpu in os.sched_getaffinity(0))))}


@hookimpl
def cosim_register_components(register):
    register("test.cpu_probe", CpuProbe)
