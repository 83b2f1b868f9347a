"""The Model contract: a discrete-time swimmer dynamics model.

State x = [p (mm), v (mm/s)] (``state_dim = 6``), input u = omega (Hz,
``input_dim = 3``), applied over one control period. ``v`` is the paper's
backward-difference velocity V_i = (P_i - P_{i-1}) / dt.

Subclasses set ``name`` (the registry name, also the file's ``kind``) and
``version`` (bump it when the saved state changes) and implement ``fit``,
``_step`` (or ``predict``), ``_state`` / ``_restore`` and ``params``.
``predict`` is plain numpy, vectorised over a batch: it is called inside the
estimator and the MPC every 20 ms.

Model files are ``.npz`` archives holding a JSON ``meta`` entry (format,
kind, version, options, scalars) and the numeric arrays; :func:`load_model`
opens any registered kind.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from cosim.contract.errors import UserError

FORMAT = "cosim-model"


class Model:
    """Base class; see the module docstring."""

    name: str = "model"
    version: int = 1
    state_dim: int = 6
    input_dim: int = 3
    #: Control period the model was fitted at [s] (discrete models only accept multiples).
    dt_s: float | None = None

    def __init__(self, **options):
        self.options = dict(options)
        self.train_time_s: float | None = None
        #: Optional ``progress(message)`` callback for long fits (not saved).
        self.progress = None

    def _report(self, message: str) -> None:
        if self.progress is not None:
            self.progress(message)

    # ------------------------------------------------------------ to implement

    def fit(self, dataset) -> "Model":
        """Fit to a :class:`cosim_plugins.identify.dataset.Dataset`; return self."""
        raise NotImplementedError

    def _step(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """One step of ``self.dt_s``: x (n, 6), u (n, 3) -> (n, 6)."""
        raise NotImplementedError

    def _state(self) -> tuple[dict, dict]:
        """(JSON-able meta, {name: ndarray}) describing the fitted model."""
        raise NotImplementedError

    def _restore(self, meta: dict, arrays: dict) -> None:
        raise NotImplementedError

    def params(self) -> dict:
        """Fitted parameters (or a summary) for reports."""
        return {}

    @property
    def n_params(self) -> int:
        raise NotImplementedError

    # ------------------------------------------------------------ provided

    def predict(self, x, u, dt_s: float) -> np.ndarray:
        """Next state. x (n, 6) [mm, mm/s], u (n, 3) [Hz], dt_s [s] -> (n, 6).

        Discrete models step ``dt_s / self.dt_s`` times holding u (the ratio
        must be a positive integer). 1-D x, u give a 1-D result.
        """
        x = np.asarray(x, dtype=float)
        u = np.asarray(u, dtype=float)
        single = x.ndim == 1
        x2, u2 = np.atleast_2d(x), np.atleast_2d(u)
        for _ in range(self._n_substeps(dt_s)):
            x2 = self._step(x2, u2)
        return x2[0] if single else x2

    def rollout(self, x0, U, dt_s: float) -> np.ndarray:
        """Open-loop simulation feeding commands U.

        Args:
            x0: (6,) or (n, 6) initial state.
            U: (k, 3) or (n, k, 3) commands [Hz].
        Returns:
            (k + 1, 6) or (n, k + 1, 6) states, starting with x0.
        """
        x = np.asarray(x0, dtype=float)
        U = np.asarray(U, dtype=float)
        single = x.ndim == 1
        x = np.atleast_2d(x)
        if single:
            U = U[None]
        out = np.empty((x.shape[0], U.shape[1] + 1, self.state_dim))
        out[:, 0] = x
        for j in range(U.shape[1]):
            x = self.predict(x, U[:, j], dt_s)
            out[:, j + 1] = x
        return out[0] if single else out

    def linear_matrices(self):
        """(A (6, 6), B (6, 3), c (6,)) with x_next = A x + B u + c; linear models only."""
        raise NotImplementedError(f"model {self.name!r} is not linear")

    def jacobians(self, x, u, dt_s: float, eps: float = 1e-4):
        """Finite-difference linearisation at (x (6,), u (3,)): (A (6, 6), B (6, 3), c (6,))."""
        x = np.asarray(x, dtype=float)
        u = np.asarray(u, dtype=float)
        z = np.concatenate([x, u])
        d = np.eye(9) * eps
        zs = np.concatenate([z[None], z + d, z - d])
        f = self.predict(zs[:, :6], zs[:, 6:], dt_s)
        J = (f[1:10] - f[10:]).T / (2 * eps)
        A, B = J[:, :6], J[:, 6:]
        return A, B, f[0] - A @ x - B @ u

    def _n_substeps(self, dt_s: float) -> int:
        if self.dt_s is None:
            raise RuntimeError(f"model {self.name!r} is not fitted")
        r = dt_s / self.dt_s
        k = int(round(r))
        if k < 1 or abs(r - k) > 1e-6:
            raise ValueError(f"model {self.name!r} steps {self.dt_s * 1e3:g} ms; "
                             f"dt {dt_s * 1e3:g} ms is not a multiple")
        return k

    # ------------------------------------------------------------ files

    def save(self, path: str | Path) -> Path:
        """Write the fitted model to ``path`` (.npz)."""
        meta, arrays = self._state()
        header = {
            "format": FORMAT,
            "kind": self.name,
            "version": self.version,
            "dt_s": self.dt_s,
            "options": self.options,
            "train_time_s": self.train_time_s,
            "meta": meta,
        }
        path = Path(path)
        with open(path, "wb") as fh:
            np.savez(fh, __meta__=np.array(json.dumps(header)), **arrays)
        return path

    @classmethod
    def load(cls, path: str | Path) -> "Model":
        """Read a file written by :meth:`save` of this class; wrong kind/version raise UserError."""
        header, arrays = read_model_file(path)
        if header["kind"] != cls.name:
            raise UserError(f"model file {path} holds a {header['kind']!r} model, not {cls.name!r}")
        if header["version"] != cls.version:
            raise UserError(
                f"model file {path}: {cls.name!r} format version {header['version']} "
                f"is not supported (this code reads version {cls.version}); refit the model"
            )
        model = cls(**header["options"])
        model.dt_s = header["dt_s"]
        model.train_time_s = header.get("train_time_s")
        try:
            model._restore(header["meta"], arrays)
        except UserError as exc:
            raise UserError(f"model file {path}: {exc}") from exc
        return model


def read_model_file(path: str | Path) -> tuple[dict, dict]:
    """(header dict, {name: ndarray}) of a model file; UserError if it is not one."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"model file {path} does not exist")
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        header = json.loads(str(arrays.pop("__meta__")))
    except Exception as exc:  # zip/npz/json errors: not a model file
        raise UserError(f"model file {path} is not a cosim model file ({type(exc).__name__})") from exc
    if not isinstance(header, dict) or header.get("format") != FORMAT or "kind" not in header:
        raise UserError(f"model file {path} is not a cosim model file")
    return header, arrays


def load_model(path: str | Path) -> Model:
    """Open a model file of any registered kind."""
    from cosim.contract.plugins import lookup

    header, _ = read_model_file(path)
    return lookup("model", header["kind"]).load(path)
