"""The form of a missing effect: sparse regression of the force the reference model leaves unexplained.

When no listed effect explains the error (or on ``cosim diagnose --discover``),
the residual force is regressed on a library of candidate force terms
(:data:`TERMS`: constants, position, velocity and command, |v| v, |u| u,
position x command, drag near a wall, quadratic position terms, a turning
about the vertical axis, (-y, x, 0), as one term, and the thrust scaled along
each axis, x_b u, as one term each; not the model's own drag, thrust and
weight terms) by sparse regression: forward
orthogonal least squares (FROLS, :func:`forward_selection`: one
term at a time, the one that explains most of what is left), in the same
output-error setting as the effect fits:

1. each term j, a force ``coefficient x feature_j(p, v, u) e_axis``, is added
   to the reference model with coefficient 0, and the sensitivity of the
   open-loop predictions of the training windows (initial state solved on
   the lead-in, every step up to the reference horizon) to its coefficient
   is taken by a finite difference; the host model's own parameters get
   columns too and are projected out (they stay free);
2. forward selection fits the training windows' open-loop errors with
   1, 2, ... :data:`MAX_TERMS` terms; the number of terms is chosen on the
   *held-out* windows (the sparsest form that keeps 80 % of the largest drop
   of held-out error, then the path's further terms while each lowers it by
   :data:`TERM_MIN_GAIN` with a significant paired t); a linearised drop
   that is not significant (paired t over blocks of windows below the
   verdict's MIN_T) is refitted all
   the same, and the caller keeps it only when the refit passes the verdict's
   tests: the linearisation about a baseline that two missing effects pull
   far off can understate a form several times (11 % linearised against
   70 % refitted for a swirl beside a quadratic drag);
3. a form whose linear terms make a flow varying with position (a swirl or
   a shear, :func:`pattern`) takes the horizontal constants too: its value
   at the tank's origin (:data:`FLOW_PATTERNS`);
4. the chosen terms become an effect (parameters = coefficients) refitted
   jointly with the model; its drop of held-out error is reported with the
   form in words (:func:`describe`) and written as an effect file
   (:func:`effect_source`) that ``--effects-file`` loads and ``--add`` refits.
   A flow's form is refitted a second time as a flow of the water
   (:data:`FLOW_TERMS`, :func:`as_flow`): the water's velocity w(p) in the
   same terms, acting through the model's own drag and lift, H(v - w) - H(v).
   A force fixed in space is the same only when the drag is isotropic and
   linear; across an anisotropic swimmer the flow's force turns with the
   heading (a shear found as forces left 0.80 mm of error, as a flow
   0.33 mm, and the camera latency beside it showed only then). The one with
   the smaller held-out error is kept.

Units: p mm, v mm/s, u Hz, force uN; a flow term's coefficient is in mm/s
per the feature's unit.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from cosim_plugins.diagnose.rebuild import rebuilt
from cosim_plugins.diagnose.verdict import BLOCK_S, MIN_T, paired_t
from cosim_plugins.identify.effect import Effect, EffectParam
from cosim_plugins.models.physical import flow_force

AXES = "xyz"
WALL_MM = 75.0  # the tank's half size: walls at +-75 mm
FD_STEP = 1e-3  # coefficient perturbation for the sensitivities, in units of the term's scale
MIN_TRAIN_WINDOWS = 300
MIN_TEST_WINDOWS = 60
MAX_TEST_WINDOWS = 400  # held-out windows of the regression (an even sample)
CHOICE_TOLERANCE = 0.2  # sparsest form keeping 80 % of the best held-out gain
# ... and the path's next terms while each lowers the held-out error by this share, paired t >= MIN_T: a thrust
# changing along x, y and z beside a missing actuation lag was chosen as x u and y u (80 % of the gain); given the
# lag, the z u left out made the form leave 1.0 mm instead of 0.2 (the lag hidden under it)
TERM_MIN_GAIN = 0.05
MAX_TERMS = 12  # a form with more terms is not an explanation
NO_FORM = ("no combination of the candidate terms lowers the held-out error significantly: what is left looks like "
           "noise, or a form the candidates cannot express (a time-varying disturbance, a delay)")
COLLINEAR = 1e-3  # a term whose part outside the chosen ones is below this share of it ends the selection


@dataclass(frozen=True)
class Term:
    """A candidate force term: ``coef * feature(p, v, u)`` along ``axis`` (0, 1, 2), and along each axis of
    ``more`` ((axis, feature) pairs) with the same coefficient: a force with a direction of its own (the swirl's
    (-y, x, 0) is one term, so that a turning of the water costs one coefficient, not two).

    ``expr`` is the feature as a numpy expression in the names of :func:`_namespace`
    (also written into the effect file), ``words`` its reading, ``unit`` the feature's unit.
    """

    key: str
    expr: str
    words: str
    unit: str
    axis: int
    more: tuple[tuple[int, str], ...] = ()
    flow: bool = False  # the feature is the water's velocity [mm/s per unit], acting through the drag (FLOW_TERMS)

    @property
    def parts(self) -> tuple[tuple[int, str], ...]:
        """((axis, feature expression), ...): the force's components."""
        return ((self.axis, self.expr), *self.more)

    @property
    def name(self) -> str:
        return f"{'w' if self.flow else 'f'}{''.join(AXES[a] for a, _ in self.parts)}_{self.key}"


def _library() -> list[Term]:
    pos = {"x": "x", "y": "y", "z": "z"}
    vel = {"vx": "vx", "vy": "vy", "vz": "vz"}
    cmd = {"ux": "ux", "uy": "uy", "uz": "uz"}
    quad = {"xx": "x * x", "yy": "y * y", "zz": "z * z", "xy": "x * y", "xz": "x * z", "yz": "y * z"}
    terms = []
    for a in range(3):
        c = AXES[a]
        if c != "z":  # a vertical constant is the model's own weight F_vs
            terms.append(Term("1", "one", "a constant", "1", a))
        terms += [Term(k, e, k, "mm", a) for k, e in pos.items()]
        # v_a and u_a along a are the model's own drag and thrust: their columns would only trade off with them
        terms += [Term(k, e, f"v_{k[1]}", "mm/s", a) for k, e in vel.items() if k[1] != c]
        terms += [Term(k, e, f"u_{k[1]}", "Hz", a) for k, e in cmd.items() if k[1] != c]
        terms += [Term(k, e, e.replace(" * ", ""), "mm^2", a) for k, e in quad.items()]
        terms.append(Term(f"speed_v{c}", f"speed * v{c}", f"|v| v_{c}", "mm^2/s^2", a))
        terms.append(Term(f"spin_u{c}", f"spin * u{c}", f"|u| u_{c}", "Hz^2", a))
        terms += [Term(f"{b}_u{c}", f"{b} * u{c}", f"{b} u_{c}", "mm Hz", a) for b in "xyz"]
        terms += [Term(f"v{c}_wall{ell}", f"v{c} * np.exp(-wall / {ell}.0)", f"v_{c} exp(-d/{ell} mm)", "mm/s", a)
                  for ell in (3, 10)]
    # the water turning about the vertical axis through the origin (about another axis: this and the constants)
    terms.append(Term("swirl", "-y", "(-y, x, 0)", "mm", 0, more=((1, "x"),)))
    # the thrust scaled by a factor that changes along b (a field whose strength varies with position): x_b u along
    # u, one coefficient for the three axes (as per-axis terms a thrust changing along x took up to three)
    terms += [Term(f"{b}_u", f"{b} * ux", f"{b} u (along the command)", "mm Hz", 0,
                   more=((1, f"{b} * uy"), (2, f"{b} * uz"))) for b in "xyz"]
    return terms


TERMS = _library()


def _flow_library() -> list[Term]:
    horizontal = [Term("1", "one", "a constant", "1", a, flow=True) for a in (0, 1)]
    horizontal += [Term(k, k, k, "mm", a, flow=True) for a in (0, 1) for k in "xyz"]
    return [*horizontal, Term("swirl", "-y", "(-y, x, 0)", "mm", 0, more=((1, "x"),), flow=True)]


#: A horizontal flow of the water, linear in position: w(p) [mm/s] in the terms of :data:`TERMS` that make a flow
#: (:data:`FLOW_PATTERNS`), its force H(v - w) - H(v) through the host's drag and lift
#: (:func:`~cosim_plugins.models.physical.hydrodynamic_force`). Not regression columns: :func:`as_flow` re-expresses
#: a flow found as forces.
FLOW_TERMS = _flow_library()
#: Every term a discovered effect may hold, by name (what a model file stores).
TERM_TABLE = {t.name: t for t in (*TERMS, *FLOW_TERMS)}
_FLOW_OF = {(t.key, t.axis): t for t in FLOW_TERMS}


def _namespace(p, v, u) -> dict:
    x, y, z = p.T
    vx, vy, vz = v.T
    ux, uy, uz = u.T
    return {"np": np, "x": x, "y": y, "z": z, "vx": vx, "vy": vy, "vz": vz, "ux": ux, "uy": uy, "uz": uz,
            "one": np.ones(len(p)), "speed": np.linalg.norm(v, axis=1), "spin": np.linalg.norm(u, axis=1),
            "wall": np.maximum(WALL_MM - np.max(np.abs(p), axis=1), 0.0)}


class _LazyNamespace(dict):
    """:func:`_namespace`'s names, each made when an expression first reads it (a rollout step's force has
    mostly zero coefficients: most names are never needed)."""

    def __init__(self, p, v, u):
        super().__init__(np=np)
        self.pvu = p, v, u

    def __missing__(self, name):
        p, v, u = self.pvu
        if name in _COLUMNS:
            a, k = _COLUMNS[name]
            value = (p, v, u)[a][:, k]
        elif name == "one":
            value = np.ones(len(p))
        elif name in ("speed", "spin"):
            w = v if name == "speed" else u
            value = np.sqrt(w[:, 0] * w[:, 0] + w[:, 1] * w[:, 1] + w[:, 2] * w[:, 2])
        elif name == "wall":
            value = np.maximum(WALL_MM - np.max(np.abs(p), axis=1), 0.0)
        else:
            raise KeyError(name)
        self[name] = value
        return value


_COLUMNS = {n: (a, k) for a, names in enumerate((("x", "y", "z"), ("vx", "vy", "vz"), ("ux", "uy", "uz")))
            for k, n in enumerate(names)}
_CODE: dict = {}  # expression -> its compiled code


def _compiled(expr: str):
    if expr not in _CODE:
        _CODE[expr] = compile(expr, "<term>", "eval")
    return _CODE[expr]


def term_force(terms, coefs, p, v, u, host: dict | None = None) -> np.ndarray:
    """(n, 3) force [uN] of ``terms`` with coefficients ``coefs`` at p, v, u (n, 3); the flow terms' force goes
    through the drag and lift of ``host`` (its parameters: Cd0, Cd1, Cl0), which they need."""
    f, w = _term_sums(terms, coefs, p, v, u)
    if w is not None:
        if host is None:
            raise ValueError("a flow term's force needs the host model's drag parameters")
        f += flow_force(v, w, u, host)
    return f


def term_water(terms, coefs, p) -> np.ndarray:
    """(n, 3) water velocity [mm/s] at p (n, 3) [mm] that the flow terms among ``terms`` set (coefficients
    ``coefs``); zero without one. Flow terms depend on position only."""
    w = _term_sums(terms, coefs, p, None, None, flows_only=True)[1]
    return np.zeros((len(p), 3)) if w is None else w


def _term_sums(terms, coefs, p, v, u, flows_only: bool = False) -> tuple:
    """(the force terms' sum (n, 3) [uN], the flow terms' water velocity (n, 3) [mm/s] or None without one)."""
    ns = None
    f = np.zeros((len(p), 3))
    w = None
    for t, c in zip(terms, coefs):
        if c != 0.0 and (t.flow or not flows_only):
            ns = _LazyNamespace(p, v, u) if ns is None else ns
            if t.flow and w is None:
                w = np.zeros((len(p), 3))
            out = w if t.flow else f
            for a, expr in t.parts:
                out[:, a] += c * eval(_compiled(expr), {"np": np}, ns)  # noqa: S307 (this module's own table)
    return f, w


def library_effect(terms, scales, name: str = "discovered", coefs=None) -> Effect:
    """An :class:`Effect` whose parameters are the coefficients of ``terms`` (typical sizes ``scales``). With flow
    terms it is a flow varying with position (``water_at``): the other drags act on the velocity through it."""
    coefs = np.zeros(len(terms)) if coefs is None else np.asarray(coefs, dtype=float)
    params = tuple(EffectParam(t.name, float(c), unit=_coef_unit(t), scale=float(s))
                   for t, c, s in zip(terms, coefs, scales))
    flows = [t for t in terms if t.flow]
    names, flow_names = [t.name for t in terms], [t.name for t in flows]  # built once: the force runs every step

    def force(p, v, u, prm):
        return term_force(terms, [prm[n] for n in names], p, v, u, prm)

    def water_at(p, prm):
        return term_water(flows, [prm[n] for n in flow_names], p)

    return Effect(name=name, params=params, force=force, doc="a sparse combination of candidate force terms",
                  terms=tuple(names), water_at=water_at if flows else None)


def _coef_unit(t: Term) -> str:
    if t.flow:
        return "mm/s" if t.unit == "1" else "1/s"
    return "uN" if t.unit == "1" else f"uN/({t.unit})"


def as_flow(terms, scales, coefs, host: dict) -> tuple[list, np.ndarray, np.ndarray] | None:
    """(terms, scales, coefficient starts) of the form with its horizontal constant, linear and swirl terms read
    as a flow of the water (:data:`FLOW_TERMS`), or None when it has none or the host has no drag. The flow
    that exerts a term's force on a swimmer with drag Cd1 + Cd0 sin(alpha) is the force over that drag: the
    start takes sin(alpha) = 1/2 (the fit does the rest)."""
    drag = host.get("Cd1", 0.0) + 0.5 * host.get("Cd0", 0.0)
    if not drag > 0.0:
        return None
    flows = [None if t.flow else _FLOW_OF.get((t.key, t.axis)) for t in terms]
    if not any(flows):
        return None
    per = np.array([1.0 / drag if f else 1.0 for f in flows])  # a flow term's coefficient: the force over the drag
    return [f or t for f, t in zip(flows, terms)], np.asarray(scales) * per, np.asarray(coefs) * per


# ---------------------------------------------------------------- the regression


def discover(reference, ttr, tte, train, test, fit_fn, say=None, jobs: int = 1, exclude=()) -> dict:
    """Sparse residual-force regression on top of ``reference`` (a fitted JointModel).

    ``train`` and ``test`` are :class:`~cosim_plugins.identify.joint.OpenLoop` windows of the training and
    held-out timelines ``ttr`` and ``tte``: the residuals are their open-loop errors, what the diagnosis
    measures (on short windows whose whole initial state is fitted, a slow drift hides in that state).
    ``fit_fn(effect) -> (_Fitted, summary, ev)`` refits the reference with an effect and evaluates it
    on the held-out data (the diagnosis's own refit). Returns a dict with ``status`` ("found",
    "none", "too_short"), ``explanation`` (a sentence), and when found ``terms``, ``params``,
    ``words``, ``source`` (the effect file) and the refit's ``fitted``/``summary``/``ev``. The sensitivities'
    columns are shared among ``jobs`` forked processes. ``exclude``: names of terms the form may not use.
    """
    from cosim_plugins.identify.joint import OpenLoop

    say = say or (lambda m: None)
    span = train.lead + max(train.steps)
    if len(train.starts) < MIN_TRAIN_WINDOWS or len(test.starts) < MIN_TEST_WINDOWS:
        return {"status": "too_short",
                "explanation": f"the logs are too short to discover the form of a missing effect: "
                               f"{len(train.starts)} training and {len(test.starts)} held-out windows of "
                               f"{span * ttr.dt_s:g} s (need {MIN_TRAIN_WINDOWS} and {MIN_TEST_WINDOWS}); "
                               "give longer logs (a few minutes in all)"}
    test = OpenLoop(test.starts[:: max(1, len(test.starts) // MAX_TEST_WINDOWS)], test.lead, test.steps)
    test_win = test.starts
    scales = _term_scales(ttr, train.starts, span)
    lib = library_effect(TERMS, scales, name="_library")
    jm = rebuilt(reference, [*reference.effects, lib])
    n_terms = len(TERMS)
    host_idx = [i for i, n in enumerate(jm.names) if "." not in n]
    term_idx = [jm.names.index(f"_library.{t.name}") for t in TERMS]
    say(f"discover: sensitivities of {n_terms} candidate terms on {len(train.starts)} training windows")
    r_tr, J_tr, H_tr = _sensitivities(jm, ttr, train, term_idx, host_idx, jobs)
    # the host's own parameters stay free: project their columns out of the training problem
    Q, _ = np.linalg.qr(H_tr)
    Jp = J_tr - Q @ (Q.T @ J_tr)
    rp = r_tr - Q @ (Q.T @ r_tr)
    norms = np.linalg.norm(Jp, axis=0)
    keep = (norms > 1e-6 * max(norms.max(), 1e-300)) & np.array([t.name not in exclude for t in TERMS])
    cols = np.flatnonzero(keep)
    steps = list(forward_selection(Jp[:, cols], rp, MAX_TERMS))
    # the held-out windows need the sensitivities of the terms on the path only (each step adds one)
    used = cols[steps[-1][0]] if steps else np.zeros(0, dtype=int)
    r_te, J_used, H_te = _sensitivities(jm, tte, test, [term_idx[j] for j in used], host_idx, jobs)
    J_te = np.zeros((len(r_te), n_terms))
    J_te[:, used] = J_used
    base_err = _rms(r_te)
    path = [(0, base_err, np.zeros(n_terms))]
    for sel, coef in steps:
        xi = np.zeros(n_terms)
        xi[cols[sel]] = coef
        eta = np.linalg.lstsq(H_tr, r_tr - J_tr @ xi, rcond=None)[0]  # host adjustment for these terms
        path.append((len(sel), _rms(r_te - J_te @ xi - H_te @ eta), xi))
    block = max(1, int(round(BLOCK_S / ttr.dt_s)))

    def held_out(coefs):  # the held-out windows' errors left by the terms' coefficients (the host adjusted)
        eta = np.linalg.lstsq(H_tr, r_tr - J_tr @ coefs, rcond=None)[0]
        return _errors(r_te - J_te @ coefs - H_te @ eta, len(test_win))

    n_sel, err_sel, xi = path[form_size(path, lambda a, b: paired_t(held_out(a), held_out(b), test_win, block))]
    t = paired_t(_errors(r_te, len(test_win)), held_out(xi), test_win, block)
    say(f"discover: {n_sel} terms chosen on held-out windows (linearised rms {base_err:.4f} -> {err_sel:.4f} mm, "
        f"t = {t:.1f})")
    if n_sel == 0 or err_sel >= base_err:
        return {"status": "none", "explanation": NO_FORM, "path": [[n, e] for n, e, _ in path]}
    chosen = [i for i in range(n_terms) if xi[i] != 0.0]
    kind = pattern([TERMS[i] for i in chosen], {TERMS[i].name: xi[i] for i in chosen}, reference.prm)
    uniform = [c for c in cols if TERMS[c].key == "1" and c not in chosen]
    if kind and kind[0] in FLOW_PATTERNS and uniform:  # the flow's uniform part belongs to it
        chosen = sorted(chosen + uniform)
        xi = np.zeros(n_terms)
        xi[chosen] = np.linalg.lstsq(Jp[:, chosen], rp, rcond=None)[0]
        say(f"discover: a flow varying with position ({kind[0]}): its uniform part, "
            f"{', '.join(TERMS[c].name for c in uniform)}, added to the form")
    found = refit_form([TERMS[i] for i in chosen], scales[chosen], xi[chosen], fit_fn, [[n, e] for n, e, _ in path],
                       flow_host=reference.prm if kind and kind[0] in FLOW_PATTERNS else None, say=say)
    found["linear_t"] = t  # below the verdict's MIN_T: the refit must pass its tests itself (the caller checks)
    return found


def form_size(path: list, gain_t) -> int:
    """The number of terms of the forward selection's ``path`` ([(k terms, held-out rms [mm], coefficients)] for
    k = 0, 1, ...) that the form takes: the sparsest that keeps 1 - :data:`CHOICE_TOLERANCE` of the largest drop of
    held-out error (the held-out windows' error is mostly camera noise: compare gains, not errors), then each
    further term of the path that lowers the held-out error by :data:`TERM_MIN_GAIN` with ``gain_t(coefficients
    before, coefficients after)``, the paired t of its gain, >= MIN_T."""
    base_err, best_err = path[0][1], min(e for _, e, _ in path)
    enough = best_err + CHOICE_TOLERANCE * (base_err - best_err)
    n = min((p for p in path if p[1] <= enough), key=lambda p: (p[0], p[1]))[0]
    while (n + 1 < len(path) and path[n + 1][1] <= (1.0 - TERM_MIN_GAIN) * path[n][1]
           and gain_t(path[n][2], path[n + 1][2]) >= MIN_T):
        n += 1
    return n


def refit_form(terms, scales, coefs, fit_fn, path=(), flow_host: dict | None = None, say=None) -> dict:
    """:func:`discover`'s result for the form ``terms`` (Terms) with coefficients ``coefs`` (starts) and typical
    sizes ``scales``: refitted by ``fit_fn``, read in words and written as an effect file. With ``flow_host``
    (the host's parameters), the form is refitted as a flow of the water too (:func:`as_flow`) and the one with
    the smaller held-out error (summed over the horizons) is kept."""
    effect = library_effect(terms, scales, coefs=coefs)
    fitted, summary, ev = fit_fn(effect)
    flow = as_flow(terms, scales, coefs, flow_host) if flow_host is not None else None
    if flow is not None:
        again = fit_fn(library_effect(flow[0], flow[1], coefs=flow[2]))
        errs = [_total(summary), _total(again[1])]
        if say:
            say(f"discover: the form as forces {errs[0]:.3f} mm, as a flow of the water through the drag "
                f"{errs[1]:.3f} mm (summed over the horizons): "
                + ("the flow kept" if errs[1] < errs[0] else "the forces kept"))
        if errs[1] < errs[0]:
            (terms, scales, _), (fitted, summary, ev) = flow, again
    coefs = {t.name: fitted.params[f"discovered.{t.name}"]["value"] for t in terms}
    words = describe(terms, coefs, scales, fitted.model.prm)
    kind = pattern(terms, coefs, fitted.model.prm)
    return {"status": "found", "terms": [t.name for t in terms],
            "expressions": {t.name: ", ".join(e for _, e in t.parts) for t in terms},
            "params": fitted.params, "words": words, "source": effect_source(terms, coefs, scales, words),
            "pattern": kind[0] if kind else None, "path": list(path), "fitted": fitted, "summary": summary,
            "ev": ev}


def _total(summary: dict) -> float:
    """Held-out error summed over the horizons [mm] (inf when a horizon has none)."""
    errs = list(summary["rollout_mm"].values())
    return float(sum(errs)) if errs and all(e is not None and np.isfinite(e) for e in errs) else np.inf


def _errors(r: np.ndarray, windows: int) -> dict:
    """Residuals ``r`` of ``windows`` held-out windows as an evaluation (``valid``, ``err`` (windows, -1))."""
    return {"valid": np.ones(windows, bool), "err": r.reshape(windows, -1)}


def _rms(r: np.ndarray) -> float:
    return float(np.sqrt(np.mean(r * r))) if r.size else 0.0


def forward_selection(X: np.ndarray, y: np.ndarray, max_terms: int):
    """Forward orthogonal least squares: the terms chosen one at a time, each step's least-squares fit.

    ``X`` (N, M) candidate columns, ``y`` (N,) target. Each step takes the
    column whose part orthogonal to the columns chosen so far explains most of
    what ``y`` still leaves (the largest error reduction ratio
    ``(w.y)^2 / (w.w)``, ``w`` the column's orthogonal part: forward regression
    orthogonal least squares, as in pysindy's ``FROLS``), then refits ``y`` on
    all chosen columns. The columns are scaled to unit norm first and the
    problem is reduced to its (M, M) triangular factor (``X = Q R``: same
    projections, same order of choice, in a fraction of the time). Yields
    ``(chosen (k,) column indices, coefficients (k,))`` for k = 1 ..
    ``max_terms`` (fewer when the columns run out, or when the best remaining
    column is (nearly) spanned by the chosen ones: its coefficients would be arbitrary).
    """
    norms = np.linalg.norm(X, axis=0)
    q, r = np.linalg.qr(X / np.where(norms > 0, norms, 1.0))
    b = q.T @ y
    w = r.copy()  # (M, M): each column's part orthogonal to the chosen ones
    seen: list[int] = []
    for _ in range(min(max_terms, X.shape[1])):
        ww = np.einsum("ij,ij->j", w, w)
        err = np.where(ww > 0, (w.T @ b) ** 2 / np.where(ww > 0, ww, 1.0), -1.0)
        err[seen] = -1.0
        best = int(np.argmax(err))
        if err[best] < 0 or (seen and _outside_share(r[:, seen], r[:, best]) < COLLINEAR):
            return
        seen.append(best)
        unit = w[:, best] / np.sqrt(ww[best])
        w -= np.outer(unit, unit @ w)
        chosen = np.array(seen)
        yield chosen, np.linalg.lstsq(X[:, chosen], y, rcond=None)[0]


def _outside_share(A: np.ndarray, b: np.ndarray) -> float:
    """Share of ``b``'s norm outside the span of the columns of ``A``."""
    left = b - A @ np.linalg.lstsq(A, b, rcond=None)[0]
    return float(np.linalg.norm(left) / max(np.linalg.norm(b), 1e-300))


def _term_scales(tl, starts, length) -> np.ndarray:
    """(M,) coefficient scales: the force of each term at the data's typical feature size is ~0.1 uN."""
    rows = np.minimum(starts[:, None] + np.arange(length)[None, :], tl.n - 1).reshape(-1)
    x = tl.x_lin[rows]
    u = np.nan_to_num(tl.u[rows])
    ns = _namespace(x[:, :3], x[:, 3:], u)
    rms = np.array([float(np.sqrt(np.mean(sum(np.asarray(eval(e, ns), dtype=float) ** 2  # noqa: S307
                                              for _, e in t.parts)))) for t in TERMS])
    return 0.1 / np.maximum(rms, 1e-9)


def _sensitivities(jm, tl, windows, term_idx, host_idx, jobs: int = 1):
    """(r (N,), J (N, M), H (N, K)): measured minus predicted positions of the open-loop ``windows`` and their
    sensitivities to the term coefficients and the host parameters (forward differences of :data:`FD_STEP`
    scales, the initial-state solve held: :class:`~cosim_plugins.identify.joint.HeldJacobian`), the columns
    shared among ``jobs`` forked processes (:func:`~cosim_plugins.diagnose.fitting.fork_map`)."""
    from cosim_plugins.diagnose.fitting import fork_map
    from cosim_plugins.identify.joint import HeldJacobian

    def errors(held):  # predicted - measured
        with np.errstate(all="ignore"):
            e, solve = windows.errors(jm, tl, held)
        return np.nan_to_num(e), solve

    theta0 = jm.theta.copy()
    fd = HeldJacobian(jm, errors, step=FD_STEP)
    e0 = fd(theta0)
    cols = np.array([*term_idx, *host_idx])
    parts = np.array_split(cols, max(1, min(jobs, len(cols))))
    J = np.hstack(fork_map(lambda i: fd.jac(theta0, parts[i]), len(parts), jobs, "discovery sensitivities"))
    return -e0, J[:, : len(term_idx)], J[:, len(term_idx):]


# ---------------------------------------------------------------- words and the effect file


def describe(terms, coefs: dict, scales, host_params: dict) -> list[str]:
    """Sentences: the force of each term with a direction of its own (the swirl), the force along each axis, the
    same for the water's velocity of flow terms, then the pattern they make (rotation, gradient, drift...)."""
    size = {t.name: abs(coefs[t.name]) / s for t, s in zip(terms, scales)}  # force at the typical size, x10 uN
    lines = []
    for flow, what, unit in ((False, "the missing force", "uN"), (True, "the water's velocity", "mm/s")):
        mine = [t for t in terms if t.flow == flow]
        lines += [f"{what} is about {coefs[t.name]:+.3g} {_coef_unit(t)} x {t.words}" for t in mine if t.more]
        for a in range(3):
            along = sorted((t for t in mine if t.axis == a and not t.more), key=lambda t: -size[t.name])
            if along:
                parts = [f"{coefs[t.name]:+.3g} {t.words if t.expr != 'one' else ''}".rstrip() for t in along[:4]]
                more = f" (and {len(along) - 4} smaller terms)" if len(along) > 4 else ""
                lines.append(f"along {AXES[a]} {what} is about {' '.join(parts)} {unit}{more}")
    if any(t.flow for t in terms):
        lines.append("the water's velocity w acts through the model's own drag and lift: H(v - w) - H(v)")
    reading = _reading(terms, coefs, host_params)
    if reading:
        lines.append(reading)
    return lines


def _linear_parts(terms, coefs: dict, cd1: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(M (3, 3) uN/mm, c0 (3,) uN, G (3, 3) uN/(mm Hz)): the form's force linear in position (f_a ~ M[a, b] p_b),
    its constants, and its position x command terms along the command's own axis (f_a ~ G[a, b] p_b u_a). A flow
    term counts as the force ``cd1`` (the host's linear drag, uN s/mm) x its water velocity."""
    M, c0, G = np.zeros((3, 3)), np.zeros(3), np.zeros((3, 3))
    for t in terms:
        c = coefs[t.name] * (cd1 if t.flow else 1.0)
        if t.key == "swirl":
            M[0, 1] -= c
            M[1, 0] += c
        elif t.key in ("x", "y", "z"):
            M[t.axis, "xyz".index(t.key)] += c
        elif t.key == "1":
            c0[t.axis] = c
        elif t.key.endswith(f"_u{AXES[t.axis]}") and t.key[0] in "xyz":
            G[t.axis, "xyz".index(t.key[0])] += c
        elif t.key.endswith("_u") and t.key[0] in "xyz":  # along the command itself, on every axis
            G[:, "xyz".index(t.key[0])] += c
    return M, c0, G


def pattern(terms, coefs: dict, host: dict) -> tuple[str, dict] | None:
    """(kind, figures) of the strongest linear-in-position, constant and command terms, or None: "swirl" (the
    horizontal force turns about a vertical axis: ``rot`` uN/mm, ``centre`` (x, y) mm), "thrust" (the thrust
    changes with position: ``along``, ``with`` axes, ``per_10mm`` share), "shear" (a horizontal force growing
    with height: ``g`` (2,) uN/mm), "gradient" (curl-free, linear in position) or "push" (a constant: ``c0``
    (2,) uN). ``coefs``: term name -> coefficient [uN per the term's unit]; ``host``: the host's parameters."""
    M, c0, G = _linear_parts(terms, coefs, _cd1(host))
    k = host.get("k", 0.0)
    A = 0.5 * (M - M.T)
    S = 0.5 * (M + M.T)
    rot = A[1, 0]  # f_x ~ -rot y, f_y ~ +rot x: a rotation about z
    if abs(rot) > 0 and abs(rot) >= 2 * max(np.abs(S[:2, :2]).max(), abs(A[2, 0]), abs(A[2, 1])):
        centre = np.array([-c0[1] / rot, c0[0] / rot]) if abs(rot) > 1e-12 else np.zeros(2)
        return "swirl", {"rot": rot, "centre": centre}
    if np.abs(G).max() > 0 and k > 0 and np.abs(G).max() * 40 >= 0.05 * k:
        a, b = np.unravel_index(np.argmax(np.abs(G)), G.shape)
        return "thrust", {"along": AXES[a], "with": AXES[b], "per_10mm": G[a, b] * 10 / k,
                          "row_per_10mm": G[a] * 10 / k}
    if np.abs(M[:2, 2]).max() > 2 * max(np.abs(M[:2, :2]).max(), 1e-300):
        return "shear", {"g": M[:2, 2]}
    if np.abs(S).max() > 0 and np.abs(S).max() >= 2 * np.abs(A).max():
        return "gradient", {}
    if np.abs(c0[:2]).max() > 0:
        return "push", {"c0": c0[:2]}
    return None


#: Patterns of a flow of the water that varies with position. Its uniform part, the flow at the tank's origin,
#: belongs to it: the origin is an arbitrary point (a swirl about an axis off the origin is a swirl about the
#: origin plus a uniform flow), so the form takes the horizontal constants too (:func:`discover`), and a library
#: uniform flow beside it is not a cause of its own when the two vanish together inside the tank
#: (:func:`holds_uniform_part`, :mod:`.standin`).
FLOW_PATTERNS = ("swirl", "shear")


def _cd1(host: dict) -> float:
    """The host's linear drag [uN s/mm] that turns a flow term's velocity into a force (1 when it has none)."""
    cd1 = host.get("Cd1", 0.0) if host else 0.0
    return cd1 if cd1 > 0.0 else 1.0


def stagnation(terms, coefs: dict, push_uN=(0.0, 0.0), host: dict | None = None) -> np.ndarray | None:
    """(3,) [mm]: the point nearest the origin where the horizontal force of the form's position and constant terms
    (plus a constant ``push_uN`` (2,), a uniform flow's force) vanishes, or None when the constants cannot be
    taken up by the position terms: what is left of them wherever the swimmer is exceeds both a quarter of their
    size and a tenth of the position terms' force at the walls (a constant too small to matter is taken up).
    ``host``: the host model's parameters (its Cd1 weighs flow terms, :func:`_linear_parts`)."""
    M, c0, _ = _linear_parts(terms, coefs, _cd1(host))
    M, c = M[:2], c0[:2] + np.asarray(push_uN, dtype=float)
    p = np.linalg.lstsq(M, -c, rcond=None)[0]
    left = np.linalg.norm(M @ p + c)
    return p if left <= max(0.25 * np.linalg.norm(c), 0.1 * np.linalg.norm(M, 2) * WALL_MM) else None


def holds_uniform_part(terms, coefs: dict, push_uN=(0.0, 0.0), host: dict | None = None) -> bool:
    """Whether a flow varying with position (:data:`FLOW_PATTERNS`) holds the constant force (its own constants
    plus ``push_uN``) as its uniform part: the flow vanishes at a point inside the tank (a swirl's axis, a shear's
    height of no flow). A constant it cannot take up, or one that puts that point outside the tank, is a uniform
    flow of its own. ``host``: as for :func:`stagnation`."""
    point = stagnation(terms, coefs, push_uN, host)
    return point is not None and bool(np.all(np.abs(point) <= WALL_MM))


def _reading(terms, coefs: dict, host: dict) -> str | None:
    """The physical pattern of the form (:func:`pattern`), in words."""
    found = pattern(terms, coefs, host)
    if found is None:
        return None
    kind, f = found
    cd1 = host.get("Cd1", 0.0)
    if kind == "swirl":
        centre = np.round(f["centre"]) + 0.0
        spin = f", the water turning at about {f['rot'] / cd1:+.3g} rad/s" if cd1 > 0 else ""
        return (f"reading: the horizontal force turns about a vertical axis through about "
                f"({centre[0]:+.0f}, {centre[1]:+.0f}) mm (a rotation about z{spin}: a swirl of the water)")
    if kind == "thrust" and any(t.key.endswith("_u") for t in terms):  # a factor on the thrust, one per axis
        g = 100 * f["row_per_10mm"]
        return (f"reading: the thrust changes with position by about ({g[0]:+.2g}, {g[1]:+.2g}, {g[2]:+.2g}) % per "
                "10 mm along (x, y, z): the propulsion varies with position (a non-uniform field)")
    if kind == "thrust":
        return (f"reading: the thrust along {f['along']} changes with {f['with']} by about "
                f"{100 * f['per_10mm']:+.2g} % per 10 mm: the propulsion varies with position (a non-uniform "
                "field)")
    if kind == "shear":
        g = f["g"]  # horizontal force per mm of height, uN/mm
        size = float(np.hypot(*g))
        shear = f" (about {size / cd1:.3g} mm/s per mm of height)" if cd1 > 0 else ""
        return (f"reading: a horizontal force that grows with height, pointing along ({g[0] / size:+.2f}, "
                f"{g[1] / size:+.2f}) in (x, y): a shear flow{shear}")
    if kind == "gradient":
        return "reading: a force field linear in position and curl-free, like a magnetic gradient or a centring force"
    c0 = f["c0"]
    drift = f" (a drift of the water of about ({c0[0] / cd1:+.2g}, {c0[1] / cd1:+.2g}) mm/s)" if cd1 > 0 else ""
    return f"reading: a steady horizontal push{drift}"


def effect_source(terms, coefs: dict, scales, words) -> str:
    """An effect file registering ``discovered`` with these terms (initial values: the fitted coefficients); its
    flow terms, if any, in a ``discovered_water(p, params)`` that is also the effect's ``water_at``."""
    flows = any(t.flow for t in terms)
    lines = [
        '"""A missing effect discovered by `cosim diagnose --discover`: a sparse combination of force terms'
        + (" and a flow of the water." if flows else "."),
        "",
        *[f"{w[0].upper()}{w[1:]}." for w in words],
        "",
        "Rename it and edit its form (a physical law usually needs fewer parameters), then refit:",
        "",
        "    cosim diagnose LOGS --effects-file discovered_effect.py --add discovered --out DIR",
        "",
        "Units: p [mm], v [mm/s], u = omega [Hz], force [uN]" + (", the water's velocity w [mm/s]." if flows else "."),
        '"""',
        "",
        "import numpy as np",
        "",
        "from cosim import hookimpl",
        "from cosim_plugins.identify.effect import Effect, EffectParam",
        *(["from cosim_plugins.models.physical import hydrodynamic_force"] if flows else []),
        "",
        f"TANK_HALF_MM = {WALL_MM}",
        "",
    ]
    if flows:  # the water's velocity: the flow's own force, and every other drag acts through it
        lines += ["", "def discovered_water(p, params):",
                  '    """(n, 3) the water\'s velocity [mm/s] at p (n, 3) [mm]."""',
                  *_term_lines([t for t in terms if t.flow], "w"), "    return w", ""]
    lines += ["", "def discovered_force(p, v, u, params):", '    """(n, 3) force [uN] at p, v, u (n, 3)."""',
              *_term_lines([t for t in terms if not t.flow], "f")]
    if flows:  # drag and lift act on the velocity through the water
        lines += ["    w = discovered_water(p, params)",
                  "    f += hydrodynamic_force(v - w, u, params) - hydrodynamic_force(v, u, params)"]
    lines += ["    return f", "", "", "DISCOVERED = Effect(", '    name="discovered",', "    params=("]
    for t, s in zip(terms, scales):
        lines.append(f'        EffectParam("{t.name}", {coefs[t.name]!r}, unit="{_coef_unit(t)}", scale={float(s)!r}),')
    lines += ["    ),", "    force=discovered_force,", *(["    water_at=discovered_water,"] if flows else []),
              f"    doc={' '.join(words)!r},", ")", "", "", "@hookimpl", "def cosim_register_effects(register):",
              "    register(DISCOVERED)", ""]
    return "\n".join(lines)


def _term_lines(terms, out: str) -> list:
    """An effect file's lines that sum ``terms`` into ``out`` (n, 3) from p, v, u (n, 3), defining only the names
    the terms read."""
    names = [
        "    x, y, z = p[:, 0], p[:, 1], p[:, 2]",
        "    vx, vy, vz = v[:, 0], v[:, 1], v[:, 2]",
        "    ux, uy, uz = u[:, 0], u[:, 1], u[:, 2]",
        "    one = np.ones(len(p))",
        "    speed = np.linalg.norm(v, axis=1)",
        "    spin = np.linalg.norm(u, axis=1)",
        "    wall = np.maximum(TANK_HALF_MM - np.max(np.abs(p), axis=1), 0.0)  # distance to the nearest wall [mm]",
    ]
    used = set(re.findall(r"[a-z]+", " ".join(e for t in terms for _, e in t.parts)))
    lines = [ln for ln in names if used & set(ln.split("=")[0].replace(",", " ").split())]
    lines.append(f"    {out} = np.zeros_like(p, dtype=float)")
    for t in terms:
        lines += [f'    {out}[:, {a}] += params["{t.name}"] * {"(" + e + ")" if e.startswith("-") else e}'
                  f"  # along {AXES[a]}: {t.words}" for a, e in t.parts]
    return lines

