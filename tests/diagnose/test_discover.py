"""Discovery: the forward selection and the reading of a form in words on synthetic data; a form the linearisation
understates, on logs of the blind bench's simulator."""

from __future__ import annotations

import numpy as np
import pytest

from cosim_plugins.diagnose import discover as D


def test_forward_selection_finds_a_sparse_support_among_correlated_columns():
    """Three true columns among forty, the others correlated with them: the first three steps pick the truth,
    and the three-term fit recovers the coefficients."""
    rng = np.random.default_rng(3)
    n, m = 4000, 40
    base = rng.normal(size=(n, 8))
    X = base @ rng.normal(size=(8, m)) / 4 + rng.normal(size=(n, m))  # columns share eight directions
    X *= rng.uniform(0.01, 100.0, size=m)  # scales over four decades: selection must not depend on them
    truth = {5: 2.0 / np.linalg.norm(X[:, 5]), 17: -1.5 / np.linalg.norm(X[:, 17]), 31: 1.0 / np.linalg.norm(X[:, 31])}
    y = sum(c * X[:, j] for j, c in truth.items()) + 0.01 * rng.normal(size=n)
    path = list(D.forward_selection(X, y, 12))
    assert [len(sel) for sel, _ in path] == list(range(1, 13))
    sel, coef = path[2]
    assert sorted(sel.tolist()) == sorted(truth)
    for j, c in zip(sel, coef):
        assert c == pytest.approx(truth[int(j)], rel=0.02)


def test_forward_selection_never_takes_a_column_the_chosen_ones_already_span():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(2, 500))
    X = np.stack([a, b, a + b, 2 * a], axis=1)  # columns 2 and 3 lie in the span of 0 and 1
    y = a + b + 0.1 * rng.normal(size=500)
    picked = [sel.tolist() for sel, _ in D.forward_selection(X, y, 4)]
    assert picked[0] == [2]  # a + b explains most of y
    assert len(picked) == 2 and set(picked[1]) in ({2, 0}, {2, 1}, {2, 3})  # then one more; nothing is left


def test_forward_selection_chooses_in_the_order_of_pysindys_frols():
    """An independent reference: on random sparse problems with correlated columns of mixed scales, the
    order of choice is pysindy's FROLS's on the same unit-norm columns (FROLS yields one term fewer)."""
    import warnings

    from pysindy.optimizers import FROLS

    rng = np.random.default_rng(11)
    for _ in range(40):
        n, m = int(rng.integers(40, 300)), int(rng.integers(6, 30))
        X = (rng.normal(size=(n, m)) @ (np.eye(m) + 0.4 * rng.normal(size=(m, m)))) * rng.uniform(0.01, 100, m)
        w = np.zeros(m)
        w[rng.choice(m, 4, replace=False)] = rng.normal(size=4) / np.linalg.norm(X, axis=0)[:4]
        y = X @ w + 0.05 * rng.normal(size=n) * np.std(X @ w)
        ours = [sel.tolist() for sel, _ in D.forward_selection(X, y, 8)]
        opt = FROLS(max_iter=8, alpha=1e-12, normalize_columns=False)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            opt.fit(X / np.linalg.norm(X, axis=0), y[:, None])
        order: list[int] = []
        for coef in opt.history_[1:]:
            order += [int(j) for j in np.flatnonzero(np.asarray(coef).reshape(-1)) if j not in order]
        assert ours[len(order) - 1] == order


def _form(**coefs):
    """Terms and coefficients from names like fx_y=..., the host's drag and thrust."""
    by_name = {t.name: t for t in D.TERMS}
    return [by_name[k] for k in coefs], coefs, {"Cd1": 0.2, "k": 1.0}


@pytest.mark.parametrize("coefs, kind, words", [
    ({"fx_1": 0.2, "fx_y": -0.01, "fy_x": 0.01}, "swirl", "turns about a vertical axis through about (+0, +20) mm"),
    ({"fx_1": 0.35, "fy_1": 0.15, "fx_y": -0.01, "fy_x": 0.01}, "swirl", "through about (-15, +35) mm"),
    ({"fx_1": 0.35, "fy_1": 0.15, "fxy_swirl": 0.01}, "swirl", "through about (-15, +35) mm"),
    ({"fx_z": 0.006, "fy_z": 0.008}, "shear", "grows with height, pointing along (+0.60, +0.80) in (x, y): a shear "
                                              "flow (about 0.05 mm/s per mm of height)"),
    ({"fx_x_ux": 0.01}, "thrust", "the thrust along x changes with x by about +10 % per 10 mm"),
    ({"fxyz_y_u": -0.02, "fxyz_z_u": 0.005}, "thrust", "the thrust changes with position by about (+0, -20, +5) % "
                                                        "per 10 mm along (x, y, z)"),
    ({"fx_1": 0.1, "fy_1": -0.05}, "push", "a steady horizontal push (a drift of the water of about (+0.5, -0.25) "
                                           "mm/s)"),
])
def test_a_form_is_read_as_the_physics_it_looks_like(coefs, kind, words):
    """A swirl about (x0, y0) is f = r (-(y - y0), x - x0): its constants put the axis where it is."""
    terms, c, host = _form(**coefs)
    reading = D.describe(terms, c, np.ones(len(terms)), host)[-1]
    assert reading.startswith("reading:") and words in reading, reading
    assert D.pattern(terms, c, host)[0] == kind


def test_the_swirl_term_is_the_turning_pair_with_one_coefficient(tmp_path, fresh_plugins):
    """fxy_swirl = c is fx_y = -c with fy_x = +c: the same force at any point, in the regression's term and in the
    effect file written for it."""
    from cosim_plugins.identify.effect import known_effects, load_effect_files

    rng = np.random.default_rng(5)
    p, v, u = (rng.normal(0, 30, (50, 3)) for _ in range(3))
    (swirl,), c, host = _form(fxy_swirl=0.02)
    pair, cp, _ = _form(fx_y=-0.02, fy_x=0.02)
    want = D.term_force(pair, list(cp.values()), p, v, u)
    assert D.term_force([swirl], [0.02], p, v, u) == pytest.approx(want, abs=1e-12)
    assert want[:, 2] == pytest.approx(0.0) and np.abs(want[:, :2]).max() > 0.5
    path = tmp_path / "discovered_effect.py"
    path.write_text(D.effect_source([swirl], c, [0.01], D.describe([swirl], c, [0.01], host)))
    assert load_effect_files([path]) == ["discovered"]
    assert known_effects()["discovered"].force(p, v, u, {"fxy_swirl": 0.02}) == pytest.approx(want, abs=1e-12)


@pytest.mark.parametrize("coefs, push, point, inside", [
    ({"fx_1": 0.35, "fy_1": 0.15, "fx_y": -0.01, "fy_x": 0.01}, (0.0, 0.0), (-15.0, 35.0, 0.0), True),
    ({"fx_y": -0.01, "fy_x": 0.01}, (1.0, 0.0), (0.0, 100.0, 0.0), False),  # the axis beyond the wall at 75 mm
    ({"fx_z": 0.006, "fy_z": 0.008}, (-0.06, -0.08), (0.0, 0.0, 10.0), True),  # a shear, no flow at z = 10 mm
    ({"fx_z": 0.006, "fy_z": 0.008}, (0.08, -0.06), None, False),  # a push across the shear: a flow of its own
])
def test_a_flow_holds_its_uniform_part_when_it_vanishes_inside_the_tank(coefs, push, point, inside):
    terms, c, _ = _form(**coefs)
    found = D.stagnation(terms, c, push)
    assert (found is None) == (point is None)
    if point is not None:
        assert found == pytest.approx(point, abs=1e-9)
    assert D.holds_uniform_part(terms, c, push) == inside


def test_a_form_the_linearisation_understates_is_kept_when_its_refit_passes(tmp_path, fresh_plugins):
    """The blind bench's seed 73, multi_003 (redrawn): water turning about an off-centre axis beside a quadratic
    drag worth 0.9x the linear drag at cruise. About the baseline, which the two missing effects pull far off, the
    linearised regression's drop was not significant (t = 0.3) while the open-loop polish minimised one-pass
    errors; refitted, the form lowered the held-out error by 73 % (t = 6.4) and is kept when its refit passes.
    With the polish on the evaluation's two-pass errors the linearised drop is t = 4.2 itself; the swirl must
    be found either way."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    import blind_sim

    from cosim_plugins.diagnose.pipeline import Settings, run
    from cosim_plugins.diagnose.verdict import MIN_T

    case = blind_sim.draw_multi_case(1562531378, ["quadratic_drag", "rotating_flow"], index=3)
    assert case.truth["rotating_flow"]["omega_rad_s"] == pytest.approx(0.1088, abs=1e-4)
    found = run(blind_sim.simulate(case, tmp_path), settings=Settings(candidates=[], discover=True, drift=False)
                ).json["discovered"]
    assert found["status"] == "found" and found["pattern"] == "swirl", found
    assert found["reduction"] >= 0.5 and found["t_stat"] >= MIN_T


def test_a_form_hidden_by_a_sluggish_baseline_is_found_about_another_time_constant(tmp_path, fresh_plugins):
    """The blind bench's seed 76, case 8 (redrawn): water turning at 0.059 rad/s about (-26, +11) mm, a swimmer
    with a 31 ms velocity time constant. Without the flow the model's fit took a 1.56 s time constant, which
    carries each lead-in's drift through its window, while the open-loop polish minimised one-pass errors; about
    that model the linearised regression found nothing, and the swirl was found about the model with its time
    constant moved (the speed per Hz kept; :func:`_other_time_constants`, tested on its own in
    ``test_diagnose_parts.py``). With the polish on the evaluation's two-pass errors the first regression finds
    it. Either way it must be found and read where it is."""
    import re
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    import blind_sim

    from cosim_plugins.diagnose.pipeline import Settings, run

    case = blind_sim.draw_case(366384645, "outside", "rotating_flow", index=8)
    assert case.truth["omega_rad_s"] == pytest.approx(0.0591, abs=1e-4)
    found = run(blind_sim.simulate(case, tmp_path), settings=Settings(candidates=[], discover=True, drift=False)
                ).json["discovered"]
    assert found["status"] == "found" and found["pattern"] == "swirl", found
    assert found["reduction"] >= 0.7 and found["t_stat"] >= 3.0
    axis = re.search(r"axis through about \(([-+\d.]+), ([-+\d.]+)\) mm", " ".join(found["words"]))
    assert abs(float(axis.group(1)) + 26.0) <= 4.0 and abs(float(axis.group(2)) - 11.3) <= 4.0, found["words"]


def test_a_flow_term_is_the_water_velocity_acting_through_the_drag(tmp_path, fresh_plugins):
    """A flow term's coefficient is the water's velocity w (mm/s per the feature's unit), its force H(v - w) - H(v)
    through the host's drag and lift. With an isotropic linear drag that is Cd1 w, the force term of coefficient
    Cd1 x the flow's; with a drag across the body (Cd0) it turns with the heading, which no force term does. The
    reading is the same physics in either units, and the effect file written for a flow form gives its force and
    its water, through which every other drag acts (a wall drag on v - w)."""
    from cosim.contract.errors import UserError
    from cosim_plugins.effects.forces import TANK_HALF_MM as WALL_DRAG_HALF_MM
    from cosim_plugins.effects.forces import WALL_DRAG, through_water
    from cosim_plugins.identify.effect import known_effects, load_effect_files, water_params
    from cosim_plugins.models.physical import hydrodynamic_force

    rng = np.random.default_rng(7)
    p, v, u = rng.normal(0, 30, (60, 3)), rng.normal(0, 10, (60, 3)), rng.normal(0, 8, (60, 3))
    flows = [D.TERM_TABLE[n] for n in ("wx_1", "wx_z", "wxy_swirl")]
    forces = [D.TERM_TABLE[n] for n in ("fx_1", "fx_z", "fxy_swirl")]
    w_coefs = [0.5, -0.08, 0.03]  # mm/s, 1/s, rad/s
    linear = {"Cd1": 0.2, "Cd0": 0.0, "Cl0": 0.0}
    assert D.term_force(flows, w_coefs, p, v, u, linear) == pytest.approx(
        D.term_force(forces, [0.2 * c for c in w_coefs], p, v, u), abs=1e-12)
    host = {"Cd1": 0.2, "Cd0": 0.3, "Cl0": 0.05, "k": 1.0}
    w = np.zeros_like(p)
    w[:, 0] = 0.5 - 0.08 * p[:, 2] - 0.03 * p[:, 1]
    w[:, 1] = 0.03 * p[:, 0]
    want = hydrodynamic_force(v - w, u, host) - hydrodynamic_force(v, u, host)
    assert D.term_force(flows, w_coefs, p, v, u, host) == pytest.approx(want, abs=1e-12)
    assert np.abs(want - D.term_force(forces, [0.2 * c for c in w_coefs], p, v, u)).max() > 0.1
    with pytest.raises(ValueError, match="drag parameters"):
        D.term_force(flows, w_coefs, p, v, u)
    shear = [D.TERM_TABLE["wx_z"], D.TERM_TABLE["wy_z"]]
    c = {"wx_z": 0.03, "wy_z": 0.04}
    words = D.describe(shear, c, [0.01, 0.01], host)
    assert D.pattern(shear, c, host)[0] == "shear"
    assert "a shear flow (about 0.05 mm/s per mm of height)" in words[-1], words
    assert "along x the water's velocity is about +0.03 z mm/s" in words
    path = tmp_path / "discovered_effect.py"
    path.write_text(D.effect_source(flows, dict(zip([t.name for t in flows], w_coefs)), [1.0, 0.01, 0.01], words))
    assert load_effect_files([path]) == ["discovered"]
    own = {t.name: c for t, c in zip(flows, w_coefs)}
    loaded = known_effects()["discovered"]
    assert loaded.force(p, v, u, {**host, **own}) == pytest.approx(want, abs=1e-12)
    # a flow varying with position: every other drag acts on the velocity through it, in the file as in the table
    gain = 9.0 / (WALL_DRAG_HALF_MM - np.abs(p).max(axis=1).clip(max=WALL_DRAG_HALF_MM) + 9.0)
    for flow in (loaded, D.library_effect(flows, [1.0, 0.01, 0.01], coefs=w_coefs)):
        assert flow.water_at(p, own) == pytest.approx(w, abs=1e-12)
        prm = {**host, **water_params([flow, WALL_DRAG], {f"discovered.{n}": c for n, c in own.items()}),
               "c": 0.4, "ell": 9.0}
        assert WALL_DRAG.force(p, v, u, prm) == pytest.approx(-0.4 * gain[:, None] * (v - w), abs=1e-12)
    with pytest.raises(UserError, match=r"varies with position: a drag's through_water\(v, params, p\)"):
        through_water(v, prm)  # a drag of one's own that does not pass the position


def test_a_flow_form_is_its_force_form_over_the_drag_and_holds_its_uniform_part_alike():
    """:func:`as_flow` reads the horizontal constant, linear and swirl terms as the water's velocity (the force over
    Cd1 + Cd0 / 2) and leaves the others as forces; the point where the flow vanishes is where its force does."""
    terms, c, _ = _form(fx_1=0.35, fy_1=0.15, fxy_swirl=0.01, fz_z=0.002)
    host = {"Cd1": 0.2, "Cd0": 0.2, "k": 1.0}
    flow, scales, coefs = D.as_flow(terms, np.ones(4), np.array(list(c.values())), host)
    assert [t.name for t in flow] == ["wx_1", "wy_1", "wxy_swirl", "fz_z"]
    assert coefs == pytest.approx([0.35 / 0.3, 0.15 / 0.3, 0.01 / 0.3, 0.002]) and scales[3] == 1.0
    named = dict(zip([t.name for t in flow], coefs))
    assert D.stagnation(flow, named, host=host) == pytest.approx(D.stagnation(terms, c), abs=1e-9)
    assert D.stagnation(flow, named, host=host) == pytest.approx((-15.0, 35.0, 0.0), abs=1e-9)
    assert D.as_flow(flow, scales, coefs, host) is None  # nothing left to read as a flow
    assert D.as_flow(terms, np.ones(4), np.array(list(c.values())), {"k": 1.0}) is None  # no drag


def test_the_form_takes_further_terms_only_while_each_earns_its_place_on_held_out_windows():
    """The sparsest form keeping 80 % of the largest held-out gain, then each next term of the path whose own
    gain is >= 5 % of the error with a paired t >= 3: a thrust changing along x, y and z was taken as x u and y u
    alone, and the actuation lag beside it showed only once z u was in too."""
    path = [(k, err, np.full(1, float(k))) for k, err in enumerate((0.95, 0.67, 0.55, 0.485, 0.474, 0.47))]
    t_of = {(1, 2): 9.0, (2, 3): 5.0, (3, 4): 6.0, (4, 5): 1.0}
    asked = []

    def gain_t(before, after):
        asked.append((int(before[0]), int(after[0])))
        return t_of[asked[-1]]

    assert D.form_size(path, gain_t) == 3  # 80 %: 2 terms; the third's gain is 12 %, t = 5; the fourth's only 2 %
    assert asked == [(2, 3)]
    t_of[(2, 3)] = 2.0  # the same gain, not significant: not taken
    assert D.form_size(path, gain_t) == 2
