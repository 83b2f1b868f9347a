"""SINDy with control in discrete time (paper Sec. II-B, Eq. 14, 17, 18).

X' = xi theta(X, u) with X = [p mm, v mm/s] (6) and u = omega Hz (3).
``theta`` is a polynomial library of all 9 inputs with a bias: degree 1
gives 10 features (60 coefficients, the paper's linear model), degree 2 gives
55 (330, the nonlinear one). pysindy's ``DiscreteSINDy`` with sequentially
thresholded least squares fits xi; inference evaluates the library in plain
numpy from the stored exponents and coefficients.

Thresholding: columns are normalised to unit L2 norm inside STLSQ, so the
threshold is ``tol * sqrt(n_samples)`` where ``tol`` is the smallest rms
contribution (mm or mm/s per step) a term must make to be kept. The ridge
``alpha`` is tiny, so the final STLSQ pass already is least squares on the
selected terms and pysindy's separate unbiasing pass (6 more full solves) is
skipped.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from cosim.contract.errors import UserError
from cosim_plugins.identify.model import Model

STATE_NAMES = ["px", "py", "pz", "vx", "vy", "vz"]
INPUT_NAMES = ["wx", "wy", "wz"]


class SindyModel(Model):
    """Discrete-time SINDYc with a polynomial library of order ``degree``."""

    name = "sindy"
    version = 1

    def __init__(self, degree=2, tol=1e-4, alpha=1e-9, max_iter=20):
        super().__init__(degree=degree, tol=tol, alpha=alpha, max_iter=max_iter)
        self.coef_: np.ndarray | None = None  # (6, n_features)
        self.powers_: np.ndarray | None = None  # (n_features, 9) exponents
        self._prepare()

    # ------------------------------------------------------------ fitting

    def fit(self, dataset) -> "SindyModel":
        import pysindy as ps  # imported before the clock starts (sklearn takes ~2 s to import)

        t0 = time.perf_counter()
        X, U, Xn = dataset.pairs()
        n_feat = _n_features(9, self.options["degree"])
        if len(X) < n_feat:
            raise UserError(f"{self.name} fit: only {len(X)} valid one-step pairs; need at least {n_feat}")
        lib = ps.PolynomialLibrary(degree=self.options["degree"], include_bias=True)
        opt = ps.STLSQ(threshold=self.options["tol"] * np.sqrt(len(X)), alpha=self.options["alpha"],
                       max_iter=self.options["max_iter"], normalize_columns=True, unbias=False)
        model = ps.DiscreteSINDy(optimizer=opt, feature_library=lib)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model.fit(X, t=dataset.dt_s, x_next=Xn, u=U, feature_names=STATE_NAMES + INPUT_NAMES)
        self.coef_ = np.asarray(model.coefficients(), dtype=float)
        self.powers_ = np.asarray(lib.powers_, dtype=np.int64)
        self.feature_names_ = list(lib.get_feature_names(STATE_NAMES + INPUT_NAMES))
        self.dt_s = dataset.dt_s
        self._prepare()
        self.train_time_s = time.perf_counter() - t0
        self._report(f"{self.name}: {self.n_nonzero} of {self.n_params} coefficients nonzero")
        return self

    def _prepare(self):
        """Index table for numpy evaluation: feature f = prod_j z_aug[:, idx[f, j]]."""
        if self.powers_ is None:
            self._idx = None
            return
        deg = max(1, int(self.powers_.sum(axis=1).max()))
        ones = self.powers_.shape[1]  # index of the constant column in z_aug
        idx = np.full((len(self.powers_), deg), ones, dtype=np.int64)
        for f, row in enumerate(self.powers_):
            factors = np.repeat(np.arange(len(row)), row)
            idx[f, : len(factors)] = factors
        self._idx = idx
        self._coef_t = np.ascontiguousarray(self.coef_.T)
        self._linear = deg == 1

    def library(self, x, u) -> np.ndarray:
        """theta(X, u): x (n, 6), u (n, 3) -> (n, n_features)."""
        n = x.shape[0]
        z = np.empty((n, 10))
        z[:, :6] = x
        z[:, 6:9] = u
        z[:, 9] = 1.0
        g = z[:, self._idx]  # (n, n_features, deg)
        return g[:, :, 0] if self._linear else g.prod(axis=2)

    def _step(self, x, u):
        return self.library(x, u) @ self._coef_t

    # ------------------------------------------------------------ reports

    @property
    def n_params(self) -> int:
        """Library size x outputs (the paper's Table II count)."""
        return 6 * _n_features(9, self.options["degree"])

    @property
    def n_nonzero(self) -> int:
        return int(np.count_nonzero(self.coef_)) if self.coef_ is not None else 0

    def params(self) -> dict:
        return {"degree": self.options["degree"], "n_features": self.n_params // 6, "n_nonzero": self.n_nonzero}

    def equations(self, precision: int = 4) -> list[str]:
        """Human-readable ``x'[k+1] = ...`` lines."""
        out = []
        for name, row in zip(STATE_NAMES, self.coef_):
            terms = [f"{c:+.{precision}g} {f}" for c, f in zip(row, self.feature_names_) if c != 0]
            out.append(f"{name}[k+1] = " + (" ".join(terms) or "0"))
        return out

    # ------------------------------------------------------------ files

    def _state(self):
        return {"feature_names": self.feature_names_}, {"coef": self.coef_, "powers": self.powers_}

    def _restore(self, meta, arrays):
        self.coef_ = np.asarray(arrays["coef"], dtype=float)
        self.powers_ = np.asarray(arrays["powers"], dtype=np.int64)
        self.feature_names_ = list(meta["feature_names"])
        self._prepare()


class SindyLinear(SindyModel):
    """Paper's linear SINDy: polynomial order 1 (60 coefficients)."""

    name = "sindy-linear"

    def __init__(self, degree=1, tol=1e-4, alpha=1e-9, max_iter=20):
        super().__init__(degree=degree, tol=tol, alpha=alpha, max_iter=max_iter)

    def linear_matrices(self):
        """(A (6, 6), B (6, 3), c (6,)) with x_next = A x + B u + c."""
        if self.coef_ is None:
            raise RuntimeError("sindy-linear is not fitted")
        A = np.zeros((6, 6))
        B = np.zeros((6, 3))
        c = np.zeros(6)
        for f, row in enumerate(self.powers_):
            j = np.flatnonzero(row)
            if len(j) == 0:
                c += self.coef_[:, f]
            elif j[0] < 6:
                A[:, j[0]] += self.coef_[:, f]
            else:
                B[:, j[0] - 6] += self.coef_[:, f]
        return A, B, c


class SindyNonlinear(SindyModel):
    """Paper's nonlinear SINDy: polynomial order 2 (330 coefficients)."""

    name = "sindy-nonlinear"

    def __init__(self, degree=2, tol=1e-4, alpha=1e-9, max_iter=20):
        super().__init__(degree=degree, tol=tol, alpha=alpha, max_iter=max_iter)


def _n_features(n_in: int, degree: int) -> int:
    from math import comb

    return comb(n_in + degree, degree)
