"""Base parameters fitted per unit (a log, or a block of time within a log), and the tests of their drift.

The chosen model's base parameters (default :data:`DRIFT_PARAMS`: propulsion
k, axial drag Cd1, net weight Fvs) are refitted free per unit, the rest
shared (:func:`fit_per_unit`): on the same open-loop errors as the
diagnosis's polish, on training windows sampled per unit, all units at once
(one rollout per parameter for the Jacobian: each unit's parameters move
only its own windows), with a damped Gauss-Newton step per unit. Each unit's
covariance is cluster-robust (windows starting within :data:`CLUSTER_S` of
each other share data).

What the logs determine is reported as identifiable combinations
(:data:`QUANTITIES`: the speed per Hz k/Cd1, the velocity time constant
m/Cd1, the sinking speed Fvs/(Cd0 + Cd1)), not k and Cd1 one by one, which
trade off; :func:`between_logs` tests their homogeneity across logs and
their trend in the order recorded, :func:`within_logs` their trend against
time within each log. Units: mm, mm/s, Hz, s, uN (the physical model's).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import chdtrc, ndtr

from cosim_plugins.diagnose.rebuild import rebuilt
from cosim_plugins.identify.joint import JointModel, OpenLoop, UnitOffsets

DRIFT_PARAMS = ("k", "Cd1", "Fvs")
BLOCK_S = 20.0  # within-log units: blocks of about this length (at least one per log)
CLUSTER_S = 1.0  # windows starting within this share data: one cluster of the robust covariance
UNIT_WINDOWS = 40  # training windows per unit (a sample), fewer when there are many units:
MAX_WINDOWS = 3000  # ... at most this many in all, and never fewer than MIN_UNIT_WINDOWS per unit
MIN_UNIT_WINDOWS = 8  # a unit with fewer training windows keeps the shared values
GN_ITERATIONS = 6

# name: (words, unit, function of the base parameters (arrays), the base parameters it reads)
QUANTITIES = {
    "speed_per_hz": ("the speed per Hz (k/Cd1)", "mm/s per Hz", lambda q, m: q["k"] / q["Cd1"], ("k", "Cd1")),
    "time_constant_s": ("the velocity time constant (m/Cd1)", "s", lambda q, m: m / (1000.0 * q["Cd1"]), ("Cd1",)),
    "sink_speed_mm_s": ("the sinking speed (Fvs/(Cd0 + Cd1))", "mm/s", lambda q, m: q["Fvs"] / (q["Cd0"] + q["Cd1"]),
                        ("Fvs", "Cd0", "Cd1")),
}


@dataclass(frozen=True)
class Units:
    """Rows grouped into units whose parameters are fitted apart.

    of_row: (n,) unit of each row of the timeline (-1 on break rows); log: (U,) the log of each unit;
    t_s: (U,) each unit's mid time within its log [s].
    """

    of_row: np.ndarray
    log: np.ndarray
    t_s: np.ndarray

    @property
    def n(self) -> int:
        return len(self.log)


def log_units(tl) -> Units:
    """One unit per log."""
    logs = int(tl.log.max()) + 1
    mid = np.array([np.nanmean(tl.t_s[tl.log == k]) for k in range(logs)])
    return Units(tl.log.copy(), np.arange(logs), mid)


def block_units(tl, block_s: float = BLOCK_S) -> Units:
    """Each log cut into round(duration / block_s) blocks of equal length (at least one)."""
    of_row = np.full(tl.n, -1, dtype=np.int64)
    logs, mids = [], []
    for k in range(int(tl.log.max()) + 1):
        rows = np.flatnonzero(tl.log == k)
        t = tl.t_s[rows]
        span = float(t[-1]) + tl.dt_s if len(t) else 0.0
        nb = max(1, int(round(span / block_s)))
        b = np.minimum((t / (span / nb)).astype(np.int64), nb - 1)
        of_row[rows] = len(logs) + b
        logs += [k] * nb
        mids += [(i + 0.5) * span / nb for i in range(nb)]
    return Units(of_row, np.array(logs), np.array(mids))


@dataclass
class PerUnitFit:
    """Base parameters ``names`` fitted per unit: ``values`` (U, F), ``cov`` (U, F, F) cluster-robust (NaN where
    a unit had too few windows: it keeps the shared values), and ``model``: a copy of the model whose rollouts
    use these values per window (its ``per_unit``)."""

    names: tuple
    units: Units
    values: np.ndarray
    cov: np.ndarray
    model: JointModel


def clone(jm: JointModel) -> JointModel:
    """A copy of ``jm`` (same host options, effects, parameters and per-unit offsets)."""
    out = rebuilt(jm)
    out.per_unit = jm.per_unit
    return out


def sample_per_unit(starts: np.ndarray, units: Units, seed: int) -> np.ndarray:
    """Training window starts, at most :data:`UNIT_WINDOWS` per unit (fewer when there are many units, so at
    most about :data:`MAX_WINDOWS` in all), drawn evenly within each unit; sorted."""
    per = max(MIN_UNIT_WINDOWS, min(UNIT_WINDOWS, MAX_WINDOWS // max(units.n, 1)))
    rng = np.random.default_rng(seed)
    u = units.of_row[starts]
    out = []
    for k in np.unique(u[u >= 0]):
        mine = starts[u == k]
        out.append(mine if len(mine) <= per else np.sort(rng.choice(mine, per, replace=False)))
    return np.sort(np.concatenate(out)) if out else starts[:0]


def fit_per_unit(jm: JointModel, tl, starts: np.ndarray, units: Units, names, lead: int, horizon: int,
                 cluster_rows: int) -> PerUnitFit:
    """Refit the base parameters ``names`` per unit (as offsets from ``jm``'s values) on the open-loop errors
    (every step up to ``horizon`` after a lead-in of ``lead``) of the training windows ``starts``; every other
    parameter stays at ``jm``'s."""
    names = tuple(names)
    model = clone(jm)
    U, F = units.n, len(names)
    idx = [model.names.index(n) for n in names]
    scale = model.scales()[idx]
    shared = model.theta[idx]
    lo, hi = (b[idx] - shared for b in model.bounds())
    off = np.zeros((U, F))
    ol = OpenLoop.upto(starts, lead, horizon)
    uw = units.of_row[starts]
    counts = np.bincount(uw, minlength=U)
    active = counts >= MIN_UNIT_WINDOWS

    def errors(o, held=None):
        model.per_unit = UnitOffsets(names, units.of_row, o)
        e, solve = ol.errors(model, tl, held)
        return np.nan_to_num(e, nan=1e3, posinf=1e3, neginf=-1e3).reshape(len(starts), -1), solve

    def jacobian(o, r0, solve):
        J = np.empty(r0.shape + (F,))
        for j in range(F):
            step = 1e-4 * scale[j]
            o2 = o.copy()
            o2[:, j] += step
            J[..., j] = (errors(o2, solve)[0] - r0) / step
        return J

    def per_unit_cost(r):
        return np.bincount(uw, weights=(r * r).sum(1), minlength=U)

    r, solve = errors(off)
    lam = np.full(U, 1e-3)
    for _ in range(GN_ITERATIONS if active.any() else 0):
        J = jacobian(off, r, solve)
        A = np.zeros((U, F, F))
        np.add.at(A, uw, np.einsum("wkf,wkg->wfg", J, J))
        g = np.zeros((U, F))
        np.add.at(g, uw, np.einsum("wkf,wk->wf", J, r))
        damp = A * np.eye(F) * lam[:, None, None] + np.eye(F) * 1e-12 * (scale ** -2)
        step = -np.linalg.solve(A + damp, g[..., None])[..., 0]
        trial = np.where(active[:, None], np.clip(off + step, lo, hi), off)
        r_new, solve_new = errors(trial)
        better = per_unit_cost(r_new) < per_unit_cost(r)
        off = np.where(better[:, None], trial, off)
        lam = np.where(better, lam / 3.0, lam * 4.0)
        if better.all():
            r, solve = r_new, solve_new
        else:  # the units kept at their old values: their residuals again, the initial states solved anew
            r, solve = errors(off)
    J = jacobian(off, r, solve)
    cov = _robust_cov(J, r, uw, starts // max(cluster_rows, 1), U)
    cov[~active] = np.nan
    model.per_unit = UnitOffsets(names, units.of_row, off)
    return PerUnitFit(names, units, shared + off, cov, model)


def trend_fit(free: PerUnitFit, group: np.ndarray, along: np.ndarray, shared: dict) -> PerUnitFit:
    """``free``'s per-unit values smoothed to straight lines: unit u's values (F,) become a_g + b s_u, with a level
    a_g (F,) per group ``group`` (U,) and one slope b (F,) for all along ``along`` (U,) (units = blocks: group the
    log, along the time within it; units = logs: one group, along the order recorded). Generalised least
    squares, each unit weighted by the inverse of its covariance (units without one follow the lines). Far
    fewer free values than one set per unit: a slow trend shows in prediction where free per-unit values
    scatter too much to. The covariance is the free fit's; the model uses the smoothed values."""
    U, F = free.values.shape
    groups, g_of = np.unique(group, return_inverse=True)
    ok = np.all(np.isfinite(free.cov.reshape(U, -1)), axis=1) & np.all(np.isfinite(free.values), axis=1)
    s = np.asarray(along, dtype=float)
    s = s - (s[ok].mean() if ok.any() else 0.0)
    n = (len(groups) + 1) * F  # unknowns: the levels, then the slope
    A, rhs = np.zeros((n, n)), np.zeros(n)
    for u in np.flatnonzero(ok):
        W = np.linalg.pinv(free.cov[u])
        D = np.zeros((F, n))
        D[:, g_of[u] * F:(g_of[u] + 1) * F] = np.eye(F)
        D[:, -F:] = s[u] * np.eye(F)
        A += D.T @ W @ D
        rhs += D.T @ W @ free.values[u]
    theta = np.linalg.lstsq(A, rhs, rcond=None)[0] if ok.any() else np.zeros(n)
    base = np.array([shared[name] for name in free.names])
    levels = theta[:-F].reshape(len(groups), F)
    seen = np.zeros(len(groups), dtype=bool)
    seen[np.unique(g_of[ok])] = True
    levels[~seen] = base  # a group without a fitted unit keeps the shared values
    values = levels[g_of] + s[:, None] * theta[-F:][None, :]
    model = clone(free.model)
    model.per_unit = UnitOffsets(free.names, free.units.of_row, values - base)
    return PerUnitFit(free.names, free.units, values, free.cov, model)


def _robust_cov(J, r, uw, block, U) -> np.ndarray:
    """(U, F, F) A^-1 B A^-1 per unit: A = J^T J, B the outer products of the score summed per cluster (a unit's
    windows in one block), scaled by G / (G - 1) for G clusters; NaN with fewer than 3 clusters."""
    F = J.shape[-1]
    A = np.zeros((U, F, F))
    np.add.at(A, uw, np.einsum("wkf,wkg->wfg", J, J))
    score = np.einsum("wkf,wk->wf", J, r)
    key = uw * (int(block.max()) + 1) + block
    ids, inv = np.unique(key, return_inverse=True)
    S = np.zeros((len(ids), F))
    np.add.at(S, inv, score)
    unit_of = ids // (int(block.max()) + 1)
    B = np.zeros((U, F, F))
    np.add.at(B, unit_of, S[:, :, None] * S[:, None, :])
    G = np.bincount(unit_of, minlength=U).astype(float)
    Ainv = np.linalg.pinv(A)
    cov = Ainv @ B @ Ainv * np.where(G > 1, G / np.maximum(G - 1, 1), np.nan)[:, None, None]
    cov[G < 3] = np.nan
    return cov


def quantities(fit: PerUnitFit, shared: dict, mass_mg: float) -> dict:
    """{quantity: (values (U,), std (U,))} of the :data:`QUANTITIES` that read a fitted parameter; std by the
    delta method from each unit's covariance."""
    out = {}
    for name, (_, _, fn, reads) in QUANTITIES.items():
        if not set(reads) & set(fit.names) or not set(reads) <= set(shared):
            continue

        def value(vals):
            prm = {n: np.full(fit.units.n, shared[n]) for n in reads}
            for j, n in enumerate(fit.names):
                if n in prm:
                    prm[n] = vals[:, j]
            with np.errstate(all="ignore"):
                return fn(prm, mass_mg)

        q = value(fit.values)
        grad = np.empty(fit.values.shape)
        for j in range(len(fit.names)):
            h = 1e-6 * max(float(np.nanmax(np.abs(fit.values[:, j]))), 1e-9)
            v2 = fit.values.copy()
            v2[:, j] += h
            grad[:, j] = (value(v2) - q) / h
        var = np.einsum("uf,ufg,ug->u", grad, fit.cov, grad)
        out[name] = (q, np.sqrt(np.where(var > 0, var, np.nan)))
    return out


def held(fit: PerUnitFit, quantity: str, shared: dict) -> JointModel | None:
    """A copy of the per-unit model whose ``quantity`` is held at its shared value in every unit, the other
    quantities as fitted (e.g. the time constant held: Cd1 shared, k moved to keep each unit's speed per Hz and
    Fvs its sinking speed); None when the fitted parameters cannot hold it that way."""
    v = {n: fit.values[:, j] for j, n in enumerate(fit.names)}
    full = {n: v.get(n, np.full(fit.units.n, shared[n])) for n in ("k", "Cd0", "Cd1", "Fvs")}
    speed, sink = full["k"] / full["Cd1"], full["Fvs"] / (full["Cd0"] + full["Cd1"])
    new = dict(full)
    if quantity == "speed_per_hz":
        new["k"] = shared["k"] / shared["Cd1"] * full["Cd1"]
    elif quantity == "time_constant_s":
        new["Cd1"] = np.full(fit.units.n, shared["Cd1"])
        new["k"] = speed * new["Cd1"]
        new["Fvs"] = sink * (full["Cd0"] + new["Cd1"])
    elif quantity == "sink_speed_mm_s":
        new["Fvs"] = shared["Fvs"] / (shared["Cd0"] + shared["Cd1"]) * (full["Cd0"] + full["Cd1"])
    else:
        raise ValueError(f"unknown quantity {quantity!r}")
    moved = [n for n in new if not np.allclose(new[n], full[n], rtol=1e-12, atol=0.0)]
    if not moved or not set(moved) <= set(fit.names):
        return None
    model = clone(fit.model)
    off = np.stack([new[n] - shared[n] for n in fit.names], axis=1)
    model.per_unit = UnitOffsets(fit.names, fit.units.of_row, off)
    return model


def between_logs(x: np.ndarray, sd: np.ndarray, order: np.ndarray, scatter: float = 1.0) -> dict:
    """Homogeneity of per-log values ``x`` (L,) with std ``sd`` (L,) and their trend along ``order`` (L,).

    ``scatter`` (>= 1): how much the values of blocks within one log scatter beyond their own uncertainty
    (:func:`within_logs`): conditions that differ from block to block (paths, speeds) move a per-unit fit
    more than its covariance says, and the logs differ at least as much for that alone. The chi-square and
    the trend's t are divided by it (a Birge ratio). Returns {"p" (chi-square of homogeneity), "chi2", "dof",
    "scatter", "mean", "excess_sd" (the std of the values beyond their uncertainty, relative to the mean: how
    much the logs' true values differ), "slope" per unit of order, "slope_t", "change_per_step" (the trend's
    relative change between consecutive logs), "spread" (max/min - 1)}."""
    ok = np.isfinite(x) & np.isfinite(sd) & (sd > 0)
    scatter = max(float(scatter), 1.0)
    if ok.sum() < 2:
        return {"p": 1.0, "chi2": 0.0, "dof": 0, "scatter": scatter, "excess_sd": 0.0,
                "mean": float(np.nanmean(x)) if np.isfinite(x).any() else None,
                "slope": 0.0, "slope_t": 0.0, "change_per_step": 0.0, "spread": 0.0}
    x, sd, o = x[ok], sd[ok], order[ok].astype(float)
    w = 1.0 / sd ** 2
    mean = float(np.sum(w * x) / np.sum(w))
    chi2 = float(np.sum(w * (x - mean) ** 2)) / scatter
    dof = len(x) - 1
    oc = o - np.sum(w * o) / np.sum(w)
    sxx = float(np.sum(w * oc ** 2))
    slope = float(np.sum(w * oc * (x - mean)) / sxx) if sxx > 0 else 0.0
    step = float(np.median(np.diff(np.sort(o)))) if len(o) > 1 else 1.0
    excess = max(float(np.var(x, ddof=1)) - scatter * float(np.mean(sd ** 2)), 0.0)
    return {"p": float(chdtrc(dof, chi2)), "chi2": chi2, "dof": dof, "scatter": scatter, "mean": mean,
            "excess_sd": math.sqrt(excess) / abs(mean) if mean else 0.0,
            "slope": slope, "slope_t": slope * math.sqrt(sxx / scatter) if sxx > 0 else 0.0,
            "change_per_step": slope * step / mean if mean else 0.0,
            "spread": float(np.max(x) / np.min(x) - 1.0) if np.min(x) > 0 else float(np.ptp(x) / abs(mean or 1.0))}


def within_logs(x: np.ndarray, sd: np.ndarray, log: np.ndarray, t_s: np.ndarray) -> dict:
    """Trend of per-block values ``x`` (U,) with std ``sd`` (U,) against time within each log ``t_s`` (U,) [s],
    each log its own offset: {"slope" per second, "slope_t", "p" (two-sided), "change_per_min" relative to the
    mean, "scatter"}. ``scatter`` is the residuals' Birge ratio, sum w r^2 / (U - logs - 1) (at least 1): how
    much the blocks scatter about the trend beyond their own uncertainty; the slope's t is divided by its
    square root."""
    ok = np.isfinite(x) & np.isfinite(sd) & (sd > 0)
    x, sd, log, t = x[ok], sd[ok], log[ok], t_s[ok]
    w = 1.0 / sd ** 2 if len(x) else sd
    xc, tc = x.copy(), t.copy()
    for k in np.unique(log):
        m = log == k
        xc[m] -= np.sum(w[m] * x[m]) / np.sum(w[m])
        tc[m] -= np.sum(w[m] * t[m]) / np.sum(w[m])
    sxx = float(np.sum(w * tc ** 2))
    dof = len(x) - len(np.unique(log)) - 1
    if sxx <= 0 or dof < 1:
        return {"slope": 0.0, "slope_t": 0.0, "p": 1.0, "change_per_min": 0.0, "scatter": 1.0}
    slope = float(np.sum(w * tc * xc) / sxx)
    scatter = max(float(np.sum(w * (xc - slope * tc) ** 2)) / dof, 1.0)
    t_stat = slope * math.sqrt(sxx / scatter)
    mean = float(np.sum(w * x) / np.sum(w))
    return {"slope": slope, "slope_t": t_stat, "p": float(2 * ndtr(-abs(t_stat))),
            "change_per_min": slope * 60.0 / mean if mean else 0.0, "scatter": scatter}
