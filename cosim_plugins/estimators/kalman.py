"""``estimator.kf``: the multi-step Kalman filter on a learned model (paper Sec. III-C/D).

Every control period the filter predicts the swimmer's state with the model
and the command applied over the last period; when a camera frame arrives it
corrects the prediction (paper: "if no measurements are received, the state
of the swimmer is iteratively computed until there is an update"). The
filter itself is :class:`~cosim_plugins.estimators.ekf.MultiStepEKF`.

Why an EKF, not a UKF. Both need only the models' vectorised ``predict``.
Measured (``benchmarks/kf.py``, 2 shared cores): one batched predict of 13
sigma points costs ~6 us (linear SINDy), 15-20 us (nonlinear SINDy, MLP) but
50-90 us for the physical model, whose batched path is dozens of small numpy
calls; a UKF step on it alone misses the 50 us budget. The EKF moves the mean
with one single-state predict (5-20 us) and the covariance with a Jacobian
from one batched call of 13 rows (the state and its +- perturbations), held
for ``relinearize_steps`` periods (default 10 = 0.2 s; the Jacobian follows
the swimmer's heading and speed, slowly next to the period: 1, 5 and 10 gave
the same tracking in the feedback sweep, and the refresh is most of a gap's
cost). For a linear model the Jacobian is the exact state matrix and the
filter is the textbook Kalman filter (tested to 1e-9). Over one period the
models are mildly nonlinear, so sigma points would buy little next to the
models' own errors.

Units: on the bus SI (m, m/s, rad/s); inside, the models' (mm, mm/s, Hz).

Noise:

* R from the camera's pixel noise and pixel size (``noise_px``, ``pixel_mm``;
  :func:`~cosim_plugins.estimators.noise.camera_variance`).
* Q from the model's measured multi-step residuals, fitted at set-up
  (:func:`~cosim_plugins.estimators.noise.fit_process_noise`, ~0.2 s) on raw
  logs: ``q_logs`` (paths or glob patterns), by default the paper dataset's
  training logs on the profile ``dataset`` names (the short ones under ``COSIM_DATASET=quick``), over horizons
  up to ``q_horizon_s``. Or given outright: ``q_diag`` (per-step variances, 6
  or 9 entries in mm^2, (mm/s)^2). ``q_scale`` multiplies it.
* ``drift`` (default on) adds a velocity offset d, the motion the model
  misses (a gain error, a flow, a misfit weight), a Gauss-Markov process with
  correlation time ``drift_tau_s`` whose variance is fitted with Q. The
  velocity output is the model's velocity plus d. The data-driven models
  need it: their velocity state barely drives their position (they map the
  command to the next position), so without d a frame cannot correct their
  course (MLP at 1 s frames: 3.5 mm tracking error with d, 21 mm without).
* ``adapt_rate``: a scale on Q follows the innovations (log NIS averaged to
  its chi-square expectation, bounded to 0.1-100), because the logs Q is
  fitted on (smooth paths at 20 ms) are tamer than a loop closed on 1 s
  frames. Without it the physical model's genuine frames failed the gate at
  0.8 s and the loop went unstable (17 mm); with it, 2.5 mm.

Latency: a frame that arrives with ``latency_s`` was captured that long ago;
the filter keeps that many periods of states and commands, updates at the
capture time and re-predicts to now.

Gating: frames whose normalised innovation squared exceeds the chi-square
(3 dof) quantile ``gate_prob`` are rejected as reflection outliers (the
``innovation`` and ``nis`` outputs still show them); ``max_rejects``
rejections in a row re-initialise the position on the frame.
"""

from __future__ import annotations

import glob
import math
from collections import deque
from pathlib import Path

import numpy as np

from cosim import Component, ComponentError, Port
from cosim.contract.errors import UserError
from cosim.contract.params import Param, read_params, whole_ticks
from cosim_plugins.estimators import noise
from cosim_plugins.estimators.ekf import MultiStepEKF
from cosim_plugins.estimators.model_check import check_model_spec, model_files

PARAMS = {
    "model": Param("sindy-linear", "model file (.npz) or kind (trained on demand), see `cosim plugins`"),
    "dataset": Param("ideal", "profile whose paper dataset trains a model named by kind and gives the default "
                     "logs Q is fitted on (the lab profile sets lab: lab models for a lab scenario)"),
    "latency_s": Param(0.0, "camera latency: capture to delivery [s], a multiple of dt", 0.0, 5.0),
    "noise_px": Param(0.5, "camera pixel noise, standard deviation [pixels]", 0.0, 100.0),
    "pixel_mm": Param(0.19, "camera pixel size in the tank [mm]", 1e-6, 10.0),
    "gate_prob": Param(0.9999, "chi-square (3 dof) probability of the innovation gate (1: no gate)", 0.5, 1.0),
    "max_rejects": Param(3, "rejected frames in a row before the position is re-initialised", 0, 1000),
    "drift": Param(True, "estimate a velocity offset the model misses (9 states instead of 6)"),
    "drift_tau_s": Param(2.0, "correlation time of the velocity offset [s]", 0.02, 1e4),
    "q_logs": Param([], "raw logs (paths or glob patterns) to fit Q on; default: the paper training logs"),
    "q_horizon_s": Param(1.0, "longest prediction horizon Q is fitted over [s]", 0.02, 10.0),
    "q_scale": Param(1.0, "factor on the fitted process noise", 1e-6, 1e6),
    "q_diag": Param([], "per-step process noise variances (6 or 9) in mm^2, (mm/s)^2; skips the fit"),
    "adapt_rate": Param(0.1, "weight of a frame in the adaptive scale of Q (0: Q as fitted)", 0.0, 1.0),
    "v0_mm_s": Param(20.0, "initial velocity standard deviation [mm/s]", 1e-6, 1e4),
    "relinearize_steps": Param(10, "periods between Jacobian refreshes of a nonlinear model", 1, 1000),
    "v_max_mm_s": Param(100.0, "speed limit of the predicted velocity [mm/s]", 1.0, 1e4),
    "tank_mm": Param(75.0, "half-width of the tank; predictions beyond fall back to constant velocity [mm]",
                     1.0, 1e4),
}

_HZ_PER_RAD_S = 1.0 / (2.0 * np.pi)
_NAN0 = np.array(np.nan)
_DATASETS: dict[tuple, object] = {}  # the last raw logs read (a sweep sets up many filters on the same)


def _read(params) -> dict:
    p = read_params(params, PARAMS)
    if not isinstance(p["model"], str) or not p["model"]:
        raise ComponentError(f"parameter model={p['model']!r}: expected a model file path or kind name")
    if not isinstance(p["dataset"], str) or not p["dataset"]:
        raise ComponentError(f"parameter dataset={p['dataset']!r}: expected a profile name (ideal, lab, ...)")
    for key in ("q_logs", "q_diag"):
        if not isinstance(p[key], (list, tuple)):
            raise ComponentError(f"parameter {key}={p[key]!r}: expected a list")
    if p["q_diag"]:
        if len(p["q_diag"]) not in (6, 9) or not all(isinstance(v, (int, float)) and v >= 0 for v in p["q_diag"]):
            raise ComponentError(f"parameter q_diag: expected 6 or 9 non-negative variances, got {p['q_diag']!r}")
        if (len(p["q_diag"]) == 9) != p["drift"]:
            raise ComponentError(f"parameter q_diag has {len(p['q_diag'])} entries but drift is {p['drift']}: "
                                 "give 9 with drift, 6 without")
    if not all(isinstance(f, str) for f in p["q_logs"]):
        raise ComponentError("parameter q_logs: expected a list of file paths or glob patterns")
    if p["max_rejects"] != int(p["max_rejects"]) or p["relinearize_steps"] != int(p["relinearize_steps"]):
        raise ComponentError("max_rejects and relinearize_steps must be whole numbers")
    return p


class KalmanEstimator(Component):
    """Multi-step EKF on any model: predicts every period, updates at frames; see the module doc."""

    inputs = (
        Port("position", (3,), "m", "camera measurement; NaN when no frame arrived"),
        Port("omega", (3,), "rad/s", "command applied over the previous period (wire with delay: 1)"),
    )
    outputs = (
        Port("position", (3,), "m", "estimated position (NaN before the first frame)"),
        Port("velocity", (3,), "m/s", "estimated velocity (model velocity plus drift)"),
        Port("innovation", (3,), "m", "frame minus predicted position at each frame (NaN otherwise)"),
        Port("nis", (), "1", "normalised innovation squared of this step's frame (NaN otherwise)"),
    )

    @classmethod
    def validate_params(cls, params) -> None:
        p = _read(params)
        check_model_spec(p["model"])

    @classmethod
    def prepare(cls, params) -> None:
        """Train a model named by kind and generate the logs Q is fitted on, if not cached yet."""
        p = _read(params)
        _resolve(p["model"], p["dataset"])
        if not p["q_diag"] and not p["q_logs"]:
            from cosim_plugins.identify.cache import quick_data
            from cosim_plugins.paper.dataset import ensure_dataset

            ensure_dataset(quick=quick_data(), profile=p["dataset"])

    @classmethod
    def artifacts(cls, params) -> list:
        return model_files(_read(params)["model"])

    def setup(self, params, rng):
        p = self.p = _read(params)
        check_model_spec(p["model"])
        self.dt = float(params["dt"])
        self.latency = whole_ticks(p["latency_s"], self.dt, "latency_s")
        model = _resolve(p["model"], p["dataset"])
        r = noise.camera_variance(p["noise_px"], p["pixel_mm"])
        tau = p["drift_tau_s"] if p["drift"] else None
        self.noise = self._process_noise(model, p, r, tau)
        phi = noise.drift_decay(self.dt, tau) if tau else None
        p_init = np.concatenate([r, np.full(3, p["v0_mm_s"] ** 2), self.noise.drift0 if tau else []])
        gate = math.inf if p["gate_prob"] >= 1.0 else _chi2_3dof(p["gate_prob"])
        self.filter = MultiStepEKF(model, self.dt, self.noise.q, r, p_init, phi=phi, gate=gate,
                                   max_rejects=int(p["max_rejects"]), relinearize_steps=int(p["relinearize_steps"]),
                                   v_max=p["v_max_mm_s"], tank=p["tank_mm"], adapt_rate=p["adapt_rate"])
        self.history: deque = deque(maxlen=self.latency + 1)  # [filter snapshot or None, command after it]
        self.nan3 = np.full(3, np.nan)

    def _process_noise(self, model, p, r, tau) -> noise.ProcessNoise:
        if p["q_diag"]:
            q = np.asarray(p["q_diag"], dtype=float)
            drift0 = q[6:] / (1.0 - noise.drift_decay(self.dt, tau) ** 2) if tau else np.zeros(3)
            return noise.ProcessNoise(q=q, drift0=drift0)
        dataset = _dataset(p["q_logs"], p["dataset"])
        if abs(dataset.dt_s - self.dt) > 1e-6:
            raise ComponentError(f"the logs for Q are sampled every {dataset.dt_s * 1e3:g} ms but the scenario "
                                 f"steps {self.dt * 1e3:g} ms; give logs at the scenario's period or q_diag")
        horizon = max(2, int(round(p["q_horizon_s"] / self.dt)))
        try:
            fitted = noise.fit_process_noise(model, dataset, r, self.dt, tau, horizon)
        except ValueError as exc:
            raise ComponentError(f"model {p['model']!r}: {exc}") from None
        fitted.q = fitted.q * p["q_scale"]
        return fitted

    def initial_outputs(self):
        return {"position": self.nan3, "velocity": np.zeros(3), "innovation": self.nan3, "nis": _NAN0}

    def step(self, t, inputs):
        f = self.filter
        u = np.asarray(inputs["omega"], dtype=float) * _HZ_PER_RAD_S
        z = np.asarray(inputs["position"], dtype=float)
        if self.history:
            self.history[-1][1] = u  # the command applied since the last entry
        if f.started:
            f.predict(u)
        if self.latency:
            self.history.append([f.snapshot() if f.started else None, None])
        innovation, nis = self.nan3, _NAN0
        if math.isfinite(sum(z.tolist())):
            innovation, nis = self._frame(z * 1e3)
        if not f.started:
            return {"position": self.nan3, "velocity": np.zeros(3), "innovation": innovation, "nis": nis}
        out = f.x * 1e-3
        vel = out[3:6] + out[6:9] if f.n == 9 else out[3:6]
        return {"position": out[:3], "velocity": vel, "innovation": innovation, "nis": nis}

    def _frame(self, z_mm: np.ndarray):
        """Fuse a frame captured ``latency`` periods ago; returns (innovation [m], NIS)."""
        f = self.filter
        entries = list(self.history)[-1 - self.latency:] if self.latency else []
        if entries:
            snap = entries[0][0]
            if snap is not None:
                f.restore(snap)
            else:
                f.started = False
        nu, nis = self.nan3, _NAN0
        if f.started:
            nu_mm, nis_value, _ = f.update(z_mm)
            nu, nis = nu_mm * 1e-3, np.array(nis_value)
        else:
            f.start(z_mm)
        for k in range(1, len(entries)):  # re-predict to now with the commands applied since the capture
            f.predict(entries[k - 1][1])
            entries[k][0] = f.snapshot()
        return nu, nis


def _chi2_3dof(prob: float) -> float:
    from scipy.stats import chi2

    return float(chi2.ppf(prob, 3))


def _resolve(spec: str, profile: str = "ideal"):
    from cosim_plugins.identify.cache import resolve_model

    try:
        return resolve_model(spec, profile=profile)
    except UserError as exc:
        raise ComponentError(f"model {spec!r}: {exc}") from None


def _dataset(patterns: list[str], profile: str = "ideal"):
    """The raw logs named by ``patterns`` (default: the paper training logs on ``profile``), read once per
    process."""
    from cosim_plugins.identify.cache import quick_data
    from cosim_plugins.identify.dataset import Dataset

    if patterns:
        files = []
        for pattern in patterns:
            hits = sorted(glob.glob(pattern)) if glob.has_magic(pattern) else [pattern]
            if not hits or not all(Path(h).is_file() for h in hits):
                raise ComponentError(f"q_logs: no log file matches {pattern!r}")
            files += hits
    else:
        from cosim_plugins.paper.dataset import ensure_dataset

        try:
            files = [str(f) for f in ensure_dataset(quick=quick_data(), profile=profile).training]
        except UserError as exc:
            raise ComponentError(f"dataset: {exc}") from None
    key = tuple((f, Path(f).stat().st_mtime_ns) for f in files)  # a regenerated log is read again
    if key not in _DATASETS:
        try:
            _DATASETS.clear()
            _DATASETS[key] = Dataset.from_paths(files)
        except UserError as exc:
            raise ComponentError(f"q_logs: {exc}") from None
    return _DATASETS[key]
