"""Open-loop replay of logged commands through the plant FMU, scored on diagnose's windows.

A log row i holds the position measured at t_i and the command applied over
[t_i, t_{i+1}) (``cosim_plugins.raw_log``). The replay feeds the commands through
the lab's coil driver (``coil_driver.inverse``, default parameters) to the FMU, as
the closed loop does, with the FMU's external force input carrying any force
effects (:class:`cosim_plugins.twin.applied.AppliedEffects`, linear coupling).

Windows are replayed in **chunks**: consecutive windows of one log share one FMU
run, started ``settle_rows`` before the first window's lead-in at the measured
position (at rest, the long axis along the command) and run to the last window's
longest horizon. The commands before the lead-in settle the velocity, the axis and
the coil currents (velocity time constants 0.1-0.2 s, coil envelope 64 ms), so the
state at the lead-in is the FMU's own answer to the logged commands. Each window's
position offset is then solved on its lead-in (the mean of measured less replayed
positions over the lead-in's measured rows) and its error read ``k`` rows after the
lead-in: the replayed position plus the offset less the measured one, as
:meth:`cosim_plugins.identify.joint.JointModel.evaluate` scores a host model on the
same rows. A camera latency L shifts the replayed positions: the camera at t_i
reports the plant at t_i - L (interpolated between rows). Units: the FMU's are SI,
the windows' mm, mm/s, Hz, s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from cosim.contract.errors import UserError
from cosim_plugins.identify.joint import DIVERGED_MM

SETTLE_S = 0.6   # commands replayed before a chunk's first lead-in [s]
CHUNK_S = 1.0    # window starts one FMU run covers at most [s]
_AXES = "xyz"
_INPUTS = (*(f"V_amp_{i}" for i in range(1, 7)), *(f"V_phase_{i}" for i in range(1, 7)), "freq",
           *(f"F_ext_{a}" for a in _AXES), *(f"F_ext_dp_{a}{b}" for a in _AXES for b in _AXES),
           *(f"F_ext_dv_{a}{b}" for a in _AXES for b in _AXES))
_OUTPUTS = ("p_x", "p_y", "p_z", "v_x", "v_y", "v_z")


@dataclass
class Chunk:
    """One FMU run: it steps the commands of rows r0..r1-1 (states at rows r0..r1) of a timeline.

    ``starts``: the window starts (timeline rows) it scores; ``drive`` (r1 - r0, 13): the coil
    driver's voltage amplitudes [V], phases [rad] and frequency [Hz] per row (the driver restarted
    at r0, FMU time 0 at row r0); ``omega`` (r1 - r0, 3) the commands [rad/s]; ``p0_m`` (3,) the
    start position [m]; ``axis0`` (3,) the start axis.
    """

    r0: int
    r1: int
    starts: np.ndarray
    drive: np.ndarray
    omega: np.ndarray
    p0_m: np.ndarray
    axis0: np.ndarray
    index: np.ndarray = field(default=None)  # positions of ``starts`` in the caller's array of windows


def make_chunks(tl, starts: np.ndarray, lead: int, k_max: int, settle_rows: int | None = None,
                span_rows: int | None = None, driver_params: dict | None = None) -> list[Chunk]:
    """The chunks that replay windows ``starts`` (sorted or not) up to ``k_max`` rows after their lead-in."""
    dt = tl.dt_s
    settle = int(round(SETTLE_S / dt)) if settle_rows is None else settle_rows
    span = max(1, int(round(CHUNK_S / dt))) if span_rows is None else span_rows
    order = np.argsort(starts, kind="stable")
    first = tl.segment_start
    chunks, i = [], 0
    while i < len(order):
        s0 = int(starts[order[i]])
        group = [order[i]]
        j = i + 1
        while (j < len(order) and starts[order[j]] - s0 <= span and first[starts[order[j]]] == first[s0]
               and tl.log[starts[order[j]]] == tl.log[s0]):
            group.append(order[j])
            j += 1
        i = j
        r0 = max(int(first[s0]), s0 - settle)
        while r0 < s0 and not np.all(np.isfinite(tl.x_lin[r0, :3])):
            r0 += 1
        last = int(starts[group[-1]])
        r1 = min(last + lead + k_max, r0 + int(tl.run[r0]))
        if r1 <= s0:
            continue
        u_hz = tl.u[r0:r1]
        omega = u_hz * 2.0 * math.pi
        w = np.asarray(group)
        chunks.append(Chunk(r0=r0, r1=r1, starts=starts[w], drive=_drive(omega, dt, driver_params), omega=omega,
                            p0_m=tl.x_lin[r0, :3] * 1e-3, axis0=_axis(u_hz), index=w))
    return chunks


def _axis(u_hz: np.ndarray) -> np.ndarray:
    """The first non-zero command's direction (the swimmer's long axis follows the spin axis), else x."""
    for u in u_hz:
        n = float(np.linalg.norm(u))
        if np.isfinite(n) and n > 1e-9:
            return u / n
    return np.array([1.0, 0.0, 0.0])


def _drive(omega: np.ndarray, dt: float, driver_params: dict | None) -> np.ndarray:
    """(n, 13) the coil driver's outputs for the commands omega (n, 3) [rad/s], one per row from t = 0."""
    from cosim_plugins.coil_driver.inverse import InverseMagnetics

    drv = InverseMagnetics()
    drv.setup({**(driver_params or {}), "watchdog_clock": "sim", "dt": dt}, np.random.default_rng(0))
    out = np.zeros((len(omega), 13))
    try:
        for j, w in enumerate(omega):
            o = drv.step(j * dt, {"omega": np.asarray(w, dtype=float)})
            if drv.tripped is not None:
                raise UserError(f"the coil driver refused a logged command ({drv.tripped}) at t = {j * dt:g} s "
                                "after a chunk's start")
            out[j, :6], out[j, 6:12], out[j, 12] = o["coil_voltage_amp"], o["coil_voltage_phase"], o["drive_freq"]
    finally:
        drv.close()
    return out


class FmuRunner:
    """One instance of the plant FMU, reset for every run (see the module docstring)."""

    def __init__(self, fmu_path=None):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave

        from cosim_plugins.plant.build import ensure_fmu

        path = str(fmu_path or ensure_fmu())
        md = read_model_description(path)
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.types = {v.name: v.type for v in md.modelVariables}
        self._dir = extract(path)
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=self._dir, modelIdentifier=md.coSimulation.modelIdentifier,
                             instanceName="twin_replay")
        self.fmu.instantiate(loggingOn=False)
        self._in = [self.vr[n] for n in _INPUTS]
        self._out = [self.vr[n] for n in _OUTPUTS]
        self._fresh = True

    def run(self, chunk: Chunk, params: dict, dt: float, applied=None) -> np.ndarray:
        """(r1 - r0 + 1, 6) the FMU's [p (mm), v (mm/s)] at rows r0..r1 with FMU ``params`` (by FMI name)."""
        fmu = self.fmu
        if not self._fresh:
            fmu.reset()
        self._fresh = False
        values = {**params, "p0_x": chunk.p0_m[0], "p0_y": chunk.p0_m[1], "p0_z": chunk.p0_m[2],
                  "axis0_x": chunk.axis0[0], "axis0_y": chunk.axis0[1], "axis0_z": chunk.axis0[2]}
        reals = {k: float(v) for k, v in values.items() if self.types[k] == "Real"}
        bools = {k: bool(v) for k, v in values.items() if self.types[k] == "Boolean"}
        try:
            fmu.setupExperiment(startTime=0.0)
            fmu.setReal([self.vr[k] for k in reals], list(reals.values()))
            if bools:
                fmu.setBoolean([self.vr[k] for k in bools], list(bools.values()))
            fmu.enterInitializationMode()
            fmu.exitInitializationMode()
            n = chunk.r1 - chunk.r0
            out = np.empty((n + 1, 6))
            out[0] = fmu.getReal(self._out)
            buf = np.zeros(len(_INPUTS))
            for j in range(n):
                buf[:13] = chunk.drive[j]
                if applied is not None:
                    f, dfdp, dfdv = applied.force_si(out[j, :3], out[j, 3:], chunk.omega[j])
                    buf[13:16], buf[16:25], buf[25:34] = f, dfdp.reshape(9), dfdv.reshape(9)
                fmu.setReal(self._in, buf.tolist())
                fmu.doStep(currentCommunicationPoint=j * dt, communicationStepSize=dt)
                out[j + 1] = fmu.getReal(self._out)
        except Exception as exc:  # fmpy raises on an error status: absurd parameters in a fit's trial
            self._fresh = False
            return np.full((chunk.r1 - chunk.r0 + 1, 6), np.nan) if _is_fmi_error(exc) else _reraise(exc)
        return out * 1e3

    def close(self) -> None:
        try:
            self.fmu.terminate()
            self.fmu.freeInstance()
        except Exception:  # noqa: BLE001  (already failed: nothing to free)
            pass


def _is_fmi_error(exc) -> bool:
    from fmpy.fmi1 import FMICallException

    return isinstance(exc, FMICallException)


def _reraise(exc):
    raise exc


def window_errors(tl, chunk: Chunk, traj_mm: np.ndarray, lead: int, ks, latency_s: float = 0.0,
                  tau_s: float | None = None):
    """(valid (w, H) bool, err (w, H, 3) [mm]): each window's error ``ks`` (H,) rows after its lead-in.

    ``traj_mm`` (r1 - r0 + 1, >= 3): the replayed positions [mm] at rows r0..r1 (:meth:`FmuRunner.run`).
    ``tau_s``: the plant's velocity time constant [s]; given, each window's initial velocity is solved on
    its lead-in too (a velocity offset dv at the window's start moves the positions by
    dv tau (1 - exp(-t / tau)) as the drag damps it), as diagnose solves a host model's initial state;
    else only the position offset.
    """
    ks = np.asarray(ks, dtype=np.int64)
    p_rep = _delayed(traj_mm[:, :3], latency_s / tl.dt_s)
    if tau_s is not None and tau_s > 0:
        t_rel = np.arange(lead + int(ks.max()) + 1) * tl.dt_s
        shape = tau_s * -np.expm1(-t_rel / tau_s)  # (L + 1,) [s]: position per unit initial velocity offset
    else:
        shape = None
    w = len(chunk.starts)
    valid = np.zeros((w, len(ks)), dtype=bool)
    err = np.full((w, len(ks), 3), np.nan)
    for i, s in enumerate(chunk.starts):
        s = int(s)
        fit = np.arange(s, s + lead + 1)
        meas = tl.p[fit]
        use = np.all(np.isfinite(meas), axis=1) & (fit - chunk.r0 < len(p_rep))
        if not use.any():
            continue
        resid = meas[use] - p_rep[fit[use] - chunk.r0]  # (m, 3)
        rows = s + lead + ks
        if shape is not None and use.sum() >= 3:
            A = np.stack([np.ones(int(use.sum())), shape[fit[use] - s]], axis=1)  # (m, 2)
            coef = np.linalg.lstsq(A, resid, rcond=None)[0]  # (2, 3): position and velocity offsets
            offset = coef[0] + shape[np.minimum(rows - s, len(shape) - 1)][:, None] * coef[1]  # (H, 3)
        else:
            offset = np.broadcast_to(np.mean(resid, axis=0), (len(rows), 3))
        inside = rows - chunk.r0 < len(p_rep)
        ok = inside & (tl.run[s] >= lead + ks) & np.all(np.isfinite(tl.p[np.minimum(rows, tl.n - 1)]), axis=1)
        if not ok.any():
            continue
        e = p_rep[rows[ok] - chunk.r0] + offset[ok] - tl.p[rows[ok]]
        bad = ~(np.linalg.norm(e, axis=1) <= DIVERGED_MM)
        e[bad] = DIVERGED_MM / math.sqrt(3.0)
        valid[i, ok] = True
        err[i, ok] = e
    return valid, err


def _delayed(p: np.ndarray, shift_rows: float) -> np.ndarray:
    """p (n, 3) read ``shift_rows`` rows earlier (linear interpolation; the first row before the start)."""
    if shift_rows <= 0.0:
        return p
    x = np.arange(len(p)) - shift_rows
    lo = np.clip(np.floor(x).astype(np.int64), 0, len(p) - 1)
    hi = np.clip(lo + 1, 0, len(p) - 1)
    a = np.clip(x - np.floor(x), 0.0, 1.0)[:, None]
    out = (1.0 - a) * p[lo] + a * p[hi]
    out[x < 0] = p[0]
    return out
