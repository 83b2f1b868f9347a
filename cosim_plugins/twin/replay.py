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

import ctypes
import math
from dataclasses import dataclass, field
from pathlib import Path

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
_FMI_WARNING = 1  # fmi2Status: OK 0, Warning 1, Discard 2, Error 3, Fatal 4
_DOUBLE_P = ctypes.POINTER(ctypes.c_double)


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


class FmuBank:
    """Instances of the plant FMU that replay many chunks under many settings in lockstep.

    One FMU is loaded; :meth:`run` takes as many instances as (setting, chunk) pairs (kept
    and reset between calls) and steps them row by row together, so each setting's force
    effects are evaluated once per row for all its chunks (one batched call instead of one
    per chunk and row: the effects, not the FMU, dominate a row's cost otherwise). The FMI
    calls of the stepping loop go straight to the FMU's library with preallocated buffers.
    """

    def __init__(self, fmu_path=None):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave

        from cosim_plugins.plant.build import ensure_fmu

        path = str(fmu_path or ensure_fmu())
        md = read_model_description(path)
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.types = {v.name: v.type for v in md.modelVariables}
        self._dir = extract(path)
        self._master = FMU2Slave(guid=md.guid, unzipDirectory=self._dir,
                                 modelIdentifier=md.coSimulation.modelIdentifier, instanceName="twin_replay")
        self._master.instantiate(loggingOn=False)
        self._dll = self._master.dll
        self._components = [self._master.component]
        self._in = (ctypes.c_uint * len(_INPUTS))(*(self.vr[n] for n in _INPUTS))
        self._out = (ctypes.c_uint * len(_OUTPUTS))(*(self.vr[n] for n in _OUTPUTS))

    def _instances(self, n: int) -> list:
        """n FMU instances (more instantiated as needed)."""
        m = self._master
        while len(self._components) < n:
            c = m.fmi2Instantiate(f"twin_replay_{len(self._components)}".encode(), 1, m.guid.encode(),
                                  Path(m.unzipDirectory, "resources").as_uri().encode(), ctypes.byref(m.callbacks),
                                  0, 0)
            if not c:
                raise RuntimeError(f"the plant FMU refused a {len(self._components) + 1}th instance")
            self._components.append(c)
        return self._components[:n]

    def _start(self, comp, params: dict, chunk: Chunk) -> bool:
        """Reset ``comp`` and initialise it with FMU ``params`` at the chunk's start; False on an FMI error."""
        dll = self._dll
        values = {**params, "p0_x": chunk.p0_m[0], "p0_y": chunk.p0_m[1], "p0_z": chunk.p0_m[2],
                  "axis0_x": chunk.axis0[0], "axis0_y": chunk.axis0[1], "axis0_z": chunk.axis0[2]}
        reals = {self.vr[k]: float(v) for k, v in values.items() if self.types[k] == "Real"}
        bools = {self.vr[k]: int(bool(v)) for k, v in values.items() if self.types[k] == "Boolean"}
        status = dll.fmi2Reset(comp)
        status = max(status, dll.fmi2SetupExperiment(comp, 0, 0.0, 0.0, 0, 0.0))
        status = max(status, dll.fmi2SetReal(comp, (ctypes.c_uint * len(reals))(*reals), len(reals),
                                             (ctypes.c_double * len(reals))(*reals.values())))
        if bools:
            status = max(status, dll.fmi2SetBoolean(comp, (ctypes.c_uint * len(bools))(*bools), len(bools),
                                                    (ctypes.c_int * len(bools))(*bools.values())))
        status = max(status, dll.fmi2EnterInitializationMode(comp))
        status = max(status, dll.fmi2ExitInitializationMode(comp))
        return status <= _FMI_WARNING

    def run(self, chunks: list, settings: list, dt: float) -> list:
        """[[traj (r1 - r0 + 1, 6) per chunk] per setting]: the FMU's [p (mm), v (mm/s)] at rows r0..r1 of
        each chunk under each setting (FMU parameters by FMI name, AppliedEffects or None); all NaN for a
        run the FMU refused (absurd parameters in a fit's trial)."""
        n_c, n_s = len(chunks), len(settings)
        comps = self._instances(n_c * n_s)
        lengths = np.array([c.r1 - c.r0 for c in chunks])
        n_max = int(lengths.max()) if n_c else 0
        drive = np.zeros((n_c, n_max, 13))
        omega = np.zeros((n_c, n_max, 3))
        for i, c in enumerate(chunks):
            drive[i, :lengths[i]], omega[i, :lengths[i]] = c.drive, c.omega
        n_in, n_out = len(_INPUTS), len(_OUTPUTS)
        buf = np.zeros((n_s, n_c, n_in))
        cur = np.zeros((n_s, n_c, n_out))
        in_ptr = [[buf[s, i].ctypes.data_as(_DOUBLE_P) for i in range(n_c)] for s in range(n_s)]
        out_ptr = [[cur[s, i].ctypes.data_as(_DOUBLE_P) for i in range(n_c)] for s in range(n_s)]
        traj = np.full((n_s, n_c, n_max + 1, n_out), np.nan)
        alive = np.zeros((n_s, n_c), dtype=bool)
        dll, vin, vout = self._dll, self._in, self._out
        set_real, get_real, do_step = dll.fmi2SetReal, dll.fmi2GetReal, dll.fmi2DoStep
        for s, (params, _) in enumerate(settings):
            for i, c in enumerate(chunks):
                comp = comps[s * n_c + i]
                alive[s, i] = self._start(comp, params, c) and get_real(comp, vout, n_out, out_ptr[s][i]) <= 1
        traj[:, :, 0] = cur
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            for j in range(n_max):
                going = lengths > j  # (n_c,)
                buf[:, :, :13] = drive[:, j]
                for s, (_, applied) in enumerate(settings):
                    if applied is not None:
                        f, dfdp, dfdv = applied.force_si_batch(cur[s, :, :3], cur[s, :, 3:], omega[:, j])
                        buf[s, :, 13:16], buf[s, :, 16:25], buf[s, :, 25:34] = (f, dfdp.reshape(n_c, 9),
                                                                                 dfdv.reshape(n_c, 9))
                    for i in np.flatnonzero(going & alive[s]):
                        comp = comps[s * n_c + i]
                        if (set_real(comp, vin, n_in, in_ptr[s][i]) > _FMI_WARNING
                                or do_step(comp, j * dt, dt, 1) > _FMI_WARNING
                                or get_real(comp, vout, n_out, out_ptr[s][i]) > _FMI_WARNING):
                            alive[s, i] = False
                traj[:, :, j + 1] = cur
        traj[~alive] = np.nan
        return [[traj[s, i, :lengths[i] + 1] * 1e3 for i in range(n_c)] for s in range(n_s)]

    def close(self) -> None:
        """Free every instance and the library."""
        for comp in self._components[1:]:
            self._dll.fmi2FreeInstance(comp)
        self._components = self._components[:1]
        try:
            self._master.terminate()
            self._master.freeInstance()
        except Exception:  # noqa: BLE001  (already failed: nothing to free)
            pass


def window_errors(tl, chunk: Chunk, traj_mm: np.ndarray, lead: int, ks, latency_s: float = 0.0,
                  tau_s: float | None = None):
    """(valid (w, H) bool, err (w, H, 3) [mm]): each window's error ``ks`` (H,) rows after its lead-in.

    ``traj_mm`` (r1 - r0 + 1, >= 3): the replayed positions [mm] at rows r0..r1 (:meth:`FmuBank.run`).
    ``tau_s``: the plant's velocity time constant [s]; given, each window's initial velocity is solved on
    its lead-in too (a velocity offset dv at the window's start moves the positions by
    dv tau (1 - exp(-t / tau)) as the drag damps it), as diagnose solves a host model's initial state;
    else only the position offset.
    """
    ks = np.asarray(ks, dtype=np.int64)
    p_rep = _delayed(traj_mm[:, :3], latency_s / tl.dt_s)
    n_rep = len(p_rep)
    starts = np.asarray(chunk.starts, dtype=np.int64)
    w = len(starts)
    valid = np.zeros((w, len(ks)), dtype=bool)
    err = np.full((w, len(ks), 3), np.nan)
    if w == 0:
        return valid, err
    lag = np.arange(lead + 1)
    fit = starts[:, None] + lag  # (w, L + 1) lead-in rows
    meas = tl.p[np.minimum(fit, tl.n - 1)]  # (w, L + 1, 3)
    inside = fit - chunk.r0 < n_rep
    use = np.all(np.isfinite(meas), axis=2) & inside & (fit < tl.n)
    resid = np.where(use[..., None], meas - p_rep[np.clip(fit - chunk.r0, 0, n_rep - 1)], 0.0)  # (w, L + 1, 3)
    m = use.sum(axis=1)  # (w,) measured lead-in rows
    wt = use.astype(float)
    offset0 = resid.sum(axis=1) / np.maximum(m, 1)[:, None]  # (w, 3): the position offset alone
    offset = np.broadcast_to(offset0[:, None], (w, len(ks), 3)).copy()  # (w, H, 3)
    if tau_s is not None and tau_s > 0:
        t_rel = np.arange(lead + int(ks.max()) + 1) * tl.dt_s
        shape = tau_s * -np.expm1(-t_rel / tau_s)  # (L + 1 + k_max,) [s]: position per unit initial velocity offset
        x = shape[lag]
        s0, s1, s2 = m.astype(float), wt @ x, wt @ (x * x)  # (w,) sums of the normal equations
        b0, b1 = resid.sum(axis=1), np.einsum("wl,l,wlc->wc", wt, x, resid)  # (w, 3)
        det = s0 * s2 - s1 * s1
        two = (m >= 3) & (det > 1e-12 * np.maximum(s0 * s2, 1e-300))  # position and velocity offsets solvable
        d = np.where(two, det, 1.0)[:, None]
        c0, c1 = (s2[:, None] * b0 - s1[:, None] * b1) / d, (s0[:, None] * b1 - s1[:, None] * b0) / d
        at = shape[np.minimum(lead + ks, len(shape) - 1)]  # (H,)
        offset[two] = c0[two][:, None] + at[None, :, None] * c1[two][:, None]
    rows = starts[:, None] + lead + ks  # (w, H)
    rows_c = np.minimum(rows, tl.n - 1)
    ok = ((rows - chunk.r0 < n_rep) & (tl.run[starts][:, None] >= lead + ks)
          & np.all(np.isfinite(tl.p[rows_c]), axis=2) & (m > 0)[:, None])
    e = p_rep[np.clip(rows - chunk.r0, 0, n_rep - 1)] + offset - tl.p[rows_c]  # (w, H, 3)
    bad = ~(np.linalg.norm(e, axis=2) <= DIVERGED_MM)
    e[bad] = DIVERGED_MM / math.sqrt(3.0)
    valid[ok] = True
    err[ok] = e[ok]
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
