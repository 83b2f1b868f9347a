"""A throwaway plugin for framework tests: a kinematic swimmer and faulty components.

The kinematic plant swims along the field's rotation axis at a speed
proportional to the drive frequency; it needs no FMU, so the scheduler can
be tested quickly and on its own.
"""

from __future__ import annotations

import os
import time

import numpy as np

from cosim import Component, ComponentError, InputEnded, Port, hookimpl


class KinematicPlant(Component):
    """Swims along the commanded rotation axis at 2.5 mm/s per Hz (no inertia).

    ``tick_file``: if given, a file to which each step appends its tick number (a line, flushed), so a
    test can tell how far the run got without a clock.
    """

    inputs = (Port("omega", (3,), "rad/s"),)
    outputs = (Port("position", (3,), "m"),)

    def setup(self, params, rng):
        self.dt = params["dt"]
        self.p = np.array(params.get("p0", [-0.015, -0.040, 0.0]), dtype=float)
        self.t = 0.0
        self.ticks = open(params["tick_file"], "a") if params.get("tick_file") else None

    def close(self):
        if self.ticks is not None:
            self.ticks.close()

    def initial_outputs(self):
        return {"position": self.p.copy()}

    def step(self, t, inputs):
        if self.ticks is not None:
            self.ticks.write(f"{int(round(t / self.dt))}\n")
            self.ticks.flush()
        if t > self.t:
            w = inputs["omega"]
            self.p = self.p + 2.5e-3 * w / (2 * np.pi) * (t - self.t)
            self.t = t
        return {"position": self.p.copy()}


class Faulty(Component):
    """Passes position through; at ``fail_at_s`` raises, hangs, ends its process, or says its
    replayed input has ended (``mode``: raise, hang, exit, end);
    or (``close_fault``) steps well and sets a fault when closed; or (``setup``) fails its set-up.
    ``setup_s``: how long its set-up takes [s]."""

    inputs = (Port("position", (3,), "m"),)
    outputs = (Port("position", (3,), "m"),)

    def setup(self, params, rng):
        self.fail_at, self.mode = params.get("fail_at_s", 1.0), params.get("mode", "raise")
        time.sleep(params.get("setup_s", 0.0))
        if self.mode == "setup":
            raise ComponentError("deliberate set-up failure")

    def close(self):
        if self.mode == "close_fault":
            self.fault = "deliberate fault on close"

    def step(self, t, inputs):
        if t >= self.fail_at and self.mode != "close_fault":
            if self.mode == "raise":
                raise ComponentError("deliberate failure")
            if self.mode == "exit":
                os._exit(3)
            if self.mode == "end":
                raise InputEnded("the recording replayed has no more rows")
            time.sleep(3600)
        return {"position": inputs["position"]}


class Summer(Component):
    """A discrete integrator for loop tests: each step adds its input to its output, y_k = y_(k-1) + u_k.

    ``y0``: its initial output. Time plays no part: one step, one addition.
    """

    inputs = (Port("u", (1,), "1"),)
    outputs = (Port("y", (1,), "1"),)

    def setup(self, params, rng):
        self.y = np.array([float(params.get("y0", 0.0))])

    def initial_outputs(self):
        return {"y": self.y.copy()}

    def step(self, t, inputs):
        self.y = self.y + inputs["u"]
        return {"y": self.y.copy()}


class Gain(Component):
    """A proportional law for loop tests: u_k = gain (ref - y_k); initial output ``u0``."""

    inputs = (Port("y", (1,), "1"),)
    outputs = (Port("u", (1,), "1"),)

    def setup(self, params, rng):
        self.gain, self.ref = float(params.get("gain", 0.5)), float(params.get("ref", 1.0))
        self.u0 = float(params.get("u0", 0.0))

    def initial_outputs(self):
        return {"u": np.array([self.u0])}

    def step(self, t, inputs):
        return {"u": self.gain * (self.ref - inputs["y"])}


class VoltGain(Gain):
    """The gain law with its output in volts (a port of another unit, for wiring tests)."""

    outputs = (Port("u", (1,), "V"),)


class Source(Component):
    """A constant for wiring tests: no inputs, output u = ``u0``."""

    inputs = ()
    outputs = (Port("u", (1,), "1"),)

    def setup(self, params, rng):
        self.u = np.array([float(params.get("u0", 0.0))])

    def initial_outputs(self):
        return {"u": self.u.copy()}

    def step(self, t, inputs):
        return {"u": self.u.copy()}


class Adder(Component):
    """A sink for wiring tests: two inputs a, b, no outputs (it only reads)."""

    inputs = (Port("a", (1,), "1"), Port("b", (1,), "1"))
    outputs = ()

    def setup(self, params, rng):
        pass

    def initial_outputs(self):
        return {}

    def step(self, t, inputs):
        return {}


@hookimpl
def cosim_register_components(register):
    register("test.kinematic", KinematicPlant)
    register("test.faulty", Faulty)
    register("test.summer", Summer)
    register("test.gain", Gain)
    register("test.volt_gain", VoltGain)
    register("test.source", Source)
    register("test.adder", Adder)
