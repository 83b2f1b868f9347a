"""Step-out: the magnet's spin under a rotating field it may not follow, with its phase as state.

The magnet lags the field by an angle phi; its rotational drag against the magnetic torque gives Adler's
equation phi' = 2 pi (f - f_so sin phi) [rad/s], f = |u| the field's rate [Hz], f_so = m B / (2 pi c_rot) the
step-out frequency. Below f_so phi settles at asin(f / f_so) and the magnet turns at f; above it phi slips by
2 pi every 1 / sqrt(f^2 - f_so^2) seconds, so the mean spin is f - sqrt(f^2 - f_so^2). Near f_so the settling
slows and a slip is long: the spin over a control period is not its long-run mean, which is why the phase is
carried from row to row instead of using the mean law alone.

Solution over a period of constant f: z = tan(phi / 2) obeys the Riccati equation z' = (a/2)(1 + z^2) - b z
(a = 2 pi f, b = 2 pi f_so), so w = (sin(phi/2), cos(phi/2)) follows the linear flow
w' = A w, A = [[-b/2, a/2], [-a/2, b/2]], A^2 = D I with D = (b^2 - a^2) / 4, hence exp(A h) = C I + S A
with C = cosh(r h), S = sinh(r h) / r (r = sqrt(D), locked) or cos, sin with r = sqrt(-D) (slipping).
"""

from __future__ import annotations

import math

import numpy as np

from cosim_plugins.identify.effect import Effect, EffectParam


def _flow_maps(f: np.ndarray, f_so: np.ndarray, dt_s: float) -> np.ndarray:
    """(4, k, n) entries m00, m01, m10, m11 of exp(A dt) for each row's rate f (n,) [Hz] and each step-out
    frequency f_so (k, 1) [Hz], scaled to a largest entry of 1 (only w's direction matters)."""
    a, b = 2.0 * math.pi * f, 2.0 * math.pi * f_so
    d = 0.25 * (b * b - a * a)
    lock = d > 0
    r = np.sqrt(np.abs(d))
    x = r * dt_s
    c = np.where(lock, np.cosh(np.minimum(x, 300.0)), np.cos(x))
    s = np.where(r > 1e-12, np.where(lock, np.sinh(np.minimum(x, 300.0)), np.sin(x)) / np.where(r > 1e-12, r, 1.0),
                 dt_s)
    m = np.stack(np.broadcast_arrays(c - 0.5 * b * s, 0.5 * a * s, -0.5 * a * s, c + 0.5 * b * s))
    return m / np.abs(m).max(axis=0)


def _prefix_states(m: np.ndarray, w0: np.ndarray) -> np.ndarray:
    """(2, k, n + 1) unit states w_0 .. w_n (components sin(phi/2), cos(phi/2)) with w_{i+1} along
    m[:, :, i] w_i, from the maps' entries m (4, k, n) (:func:`_flow_maps`) and w0 (2, k): the products of the
    maps by doubling (log2 n passes of elementwise 2 x 2 products instead of n Python steps), each product
    rescaled (a contracting map's products would underflow)."""
    p = m.copy()  # p[:, :, i]: the product maps[i] ... maps[max(0, i - j + 1)] after the pass of width j
    j, n = 1, m.shape[2]
    while j < n:
        x, y = p[:, :, j:], p[:, :, :-j]  # later rows times the rows j before them
        q = np.stack([x[0] * y[0] + x[1] * y[2], x[0] * y[1] + x[1] * y[3],
                      x[2] * y[0] + x[3] * y[2], x[2] * y[1] + x[3] * y[3]])
        q /= np.abs(q).sum(axis=0)
        p[:, :, j:] = q
        j *= 2
    w = np.empty((2, m.shape[1], n + 1))
    w[:, :, 0] = w0
    w[0, :, 1:] = p[0] * w0[0, :, None] + p[1] * w0[1, :, None]
    w[1, :, 1:] = p[2] * w0[0, :, None] + p[3] * w0[1, :, None]
    return w / np.sqrt(w[0] ** 2 + w[1] ** 2)


def adler_mean_spin(f: np.ndarray, dt_s: float, f_so) -> np.ndarray:
    """Mean spin [Hz] over each control period of a magnet driven at the rates f (n,) [Hz], each held for
    ``dt_s`` [s], step-out frequency ``f_so`` [Hz] (a float: (n,); k of them: (k, n)); the magnet starts settled
    at the first row's rate."""
    f = np.asarray(f, dtype=float)
    f_so = np.asarray(f_so, dtype=float)
    if len(f) == 0:
        return np.zeros(f_so.shape + (0,))
    fso = f_so.reshape(-1, 1)
    half0 = 0.5 * np.arcsin(np.minimum(f[0] / fso[:, 0], 1.0))  # phi / 2 settled (or at a slip's slow point)
    w = _prefix_states(_flow_maps(f, fso, dt_s), np.stack([np.sin(half0), np.cos(half0)]))
    n0, c0, n1, c1 = w[0, :, :-1], w[1, :, :-1], w[0, :, 1:], w[1, :, 1:]
    turn = np.arctan2(c0 * n1 - n0 * c1, c0 * c1 + n0 * n1)  # the change of phi / 2, modulo 2 pi
    slip_rate = np.sqrt(np.maximum(f * f - fso * fso, 0.0))  # slips per second when slipping
    # slipping, phi only grows: whole slips (pi each in phi / 2) from the beat period, the rest modulo pi
    turn = np.where(slip_rate > 0, math.pi * np.floor(dt_s * slip_rate) + np.mod(turn, math.pi), turn)
    spin = f - turn / (math.pi * dt_s)
    return spin.reshape(f_so.shape + f.shape)


#: The spread of the step-out frequency the mean spin is averaged over: f_so (1 + SPREAD z) at the nodes z [sigma]
#: of a normal law, weighted by its density. The field's magnitude varies over the workspace and ripples, and the
#: command is noisy, so on a rig the beat's phase is lost within a few slips while the first slip after a change of
#: rate keeps its timing; a single f_so would predict every later slip's phase too, and a phase a few percent off
#: after a few seconds predicts worse than the mean law (on the blind simulator's step-out at 8.4 Hz: 15 % gives
#: 12-55 % lower held-out errors at 0.1-1 s than the mean law's -2-47 %; 5 % and 30 % do worse than either).
SPREAD = 0.15
_NODES = np.array([-1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5])
_WEIGHTS = np.exp(-0.5 * _NODES**2) / np.exp(-0.5 * _NODES**2).sum()


def _step_out(u, dt_s, prm):
    f = np.linalg.norm(u, axis=1)
    spin = _WEIGHTS @ adler_mean_spin(f, dt_s, prm["f_so"] * (1.0 + SPREAD * _NODES))
    return u * (spin / np.where(f > 1e-12, f, 1.0))[:, None]


def _step_out_starts(u, dt_s):
    """f_so spread over the commanded band: percentiles of |u| [Hz] from the 20th to the 95th, closer together at
    the top. Just below the band's top only the fastest commands slip, and the slip sqrt(f^2 - f_so^2) grows
    steeply there: a start 1 Hz off lets the brief refinement of the start trade the thrust against the drag
    instead (a step-out at 15.5 Hz in a 4-17 Hz band was missed with starts at the 70th and 95th only)."""
    f = np.linalg.norm(u[np.all(np.isfinite(u), axis=1)], axis=1)
    f = f[f > 0.05]
    if len(f) < 10:
        return []
    return [{"f_so": float(q)} for q in np.percentile(f, [20, 45, 70, 80, 88, 95])]


STEP_OUT = Effect(
    name="step_out",
    kind="input",
    params=(EffectParam("f_so", 100.0, 1.0, 100.0, "Hz", 5.0),),
    transform=_step_out,
    doc="Step-out: above f_so = m B / (2 pi c_rot) the magnet cannot follow the field and slips. Its lag phi "
        "behind the field obeys Adler's equation phi' = 2 pi (f - f_so sin phi), solved exactly over each "
        "control period with phi carried from row to row: the swimmer follows the command's direction at the "
        "magnet's mean spin over the period (f below f_so once settled, f - sqrt(f^2 - f_so^2) on average "
        "above, with a beat and a slow settling near f_so). f_so [Hz] is fitted (100 Hz = never steps out).",
    starts=({"f_so": 30.0},),
    data_starts=_step_out_starts,
)
