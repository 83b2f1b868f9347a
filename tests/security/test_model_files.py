"""Model files are data: the code a model file carries runs only when the user allows it.

Each check opens the model in a fresh Python process (what `cosim compare`, `cosim validate` and a
run's nodes do), with the payload of an edited model file writing a marker file if it ever runs.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

from cosim.contract import plugins

ROOT = Path(__file__).resolve().parents[2]
SWIRL = ROOT / "tests" / "diagnose" / "data" / "swirl_effect.py"


def _open_in_fresh_process(model: Path, *, effects_file: Path | None = None, trust: bool = False):
    """(returncode, stdout + stderr) of a fresh process loading ``model`` and printing one prediction."""
    code = ("import sys\n"
            "from cosim_plugins.identify.effect import load_effect_files\n"
            "from cosim_plugins.identify.model import load_model\n"
            "from cosim.contract.errors import UserError\n"
            "if len(sys.argv) > 2: load_effect_files([sys.argv[2]])\n"
            "try:\n"
            "    m = load_model(sys.argv[1])\n"
            "except UserError as exc:\n"
            "    print('REFUSED', exc); sys.exit(3)\n"
            "x = m.predict([10., -20., 5., 1., 2., 0.], [3., 0., 4.], 0.02)\n"
            "print('LOADED', [t.name for t in m.terms], repr(float(x[0])))\n")
    env = {k: v for k, v in os.environ.items() if k != "COSIM_TRUST_MODEL_CODE"}
    env["PYTHONPATH"] = str(ROOT)
    if trust:
        env["COSIM_TRUST_MODEL_CODE"] = "1"
    argv = [sys.executable, "-c", code, str(model)] + ([str(effects_file)] if effects_file else [])
    done = subprocess.run(argv, capture_output=True, text=True, env=env, timeout=120)
    return done.returncode, done.stdout + done.stderr


@pytest.fixture
def swirl_model(tmp_path):
    """(model file with the swirl user effect, its edited twin whose carried code writes a marker, marker path)."""
    from cosim_plugins.identify.effect import load_effect_files, resolve
    from cosim_plugins.models.physical import PhysicalModel

    src = tmp_path / "swirl_effect.py"
    shutil.copy(SWIRL, src)
    plugins.reset()
    try:
        load_effect_files([src])
        model = PhysicalModel.from_params({"k": 0.2, "Cd1": 0.07, "swirl.omega": 0.3}, terms=resolve(["swirl"]))
        path = model.save(tmp_path / "swirl.npz")
    finally:
        plugins.reset()
    marker = tmp_path / "payload-ran"
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    header = json.loads(str(arrays.pop("__meta__")))
    header["meta"]["effect_sources"]["swirl"] += f"\nopen({str(marker)!r}, 'w').write('ran')\n"
    edited = tmp_path / "edited.npz"
    with open(edited, "wb") as fh:
        np.savez(fh, __meta__=np.array(json.dumps(header)), **arrays)
    return path, edited, marker, src


def test_carried_code_does_not_run_and_the_refusal_says_how_to_allow_it(swirl_model):
    _, edited, marker, _ = swirl_model
    rc, out = _open_in_fresh_process(edited)
    assert rc == 3, out
    assert "effect 'swirl' is Python code carried inside the model file" in out
    assert "--effects-file" in out and "--trust-model-code" in out and str(edited) in out
    assert not marker.exists()


def test_a_named_effect_file_is_used_and_the_carried_code_is_not(swirl_model):
    _, edited, marker, src = swirl_model
    rc, out = _open_in_fresh_process(edited, effects_file=src)
    assert rc == 0 and "LOADED ['swirl']" in out, out
    assert not marker.exists()


def test_trust_runs_the_carried_code_from_memory_not_from_a_shared_folder(swirl_model):
    original, edited, marker, _ = swirl_model
    shared = Path(tempfile.gettempdir()) / "cosim-effects"
    before = set(shared.glob("*")) if shared.is_dir() else set()
    rc, out = _open_in_fresh_process(original, trust=True)
    assert rc == 0 and "LOADED ['swirl']" in out, out
    rc, out = _open_in_fresh_process(edited, trust=True)
    assert rc == 0 and marker.read_text() == "ran"  # the user allowed it: it runs
    after = set(shared.glob("*")) if shared.is_dir() else set()
    assert after == before  # nothing written to (or read from) a shared temporary folder


def test_a_discovered_effect_is_stored_as_terms_and_coefficients(tmp_path):
    """No source in the file; a fresh process rebuilds it from the term table and predicts the same: force terms
    and a flow term (the water's velocity, through the model's drag)."""
    from cosim_plugins.identify.effect import term_library
    from cosim_plugins.models.physical import PhysicalModel

    table, library_effect = term_library()

    terms = [table["fx_1"], table["fy_y"], table["wx_z"]]
    coefs = [0.01, -0.02, 0.3]
    effect = library_effect(terms, np.array([0.5, 0.2, 0.1]), coefs=coefs)
    model = PhysicalModel.from_params({"k": 0.2, "Cd1": 0.07, "Cd0": 0.05,
                                       **{f"discovered.{t.name}": c for t, c in zip(terms, coefs)}}, terms=[effect])
    path = model.save(tmp_path / "found.npz")
    with np.load(path, allow_pickle=False) as z:
        meta = json.loads(str(z["__meta__"]))["meta"]
    assert meta["effect_sources"] == {}
    assert meta["effect_terms"]["discovered"]["terms"] == ["fx_1", "fy_y", "wx_z"]
    rc, out = _open_in_fresh_process(path)
    assert rc == 0 and "LOADED ['discovered']" in out, out
    want = model.predict(np.array([10., -20., 5., 1., 2., 0.]), np.array([3., 0., 4.]), 0.02)[0]
    assert out.split()[-1] == repr(float(want))
