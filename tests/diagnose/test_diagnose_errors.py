"""Bad input gives one clear error: invalid effect files, unknown effects, logs too short."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cosim.cli import main
from cosim.contract.errors import UserError
from cosim_plugins.diagnose.pipeline import Settings, run
from cosim_plugins.identify.effect import load_effect_files
from cosim_plugins.raw_log import write_log

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def short_log(tmp_path_factory):
    """A 4 s raw log: far too short to fit and diagnose."""
    path = tmp_path_factory.mktemp("short") / "short.csv"
    n = 200
    t = np.arange(n) * 20.0
    omega = np.tile([50.0, 0.0, 0.0], (n, 1))
    p = np.column_stack([np.linspace(-0.02, 0.02, n), np.zeros(n), np.zeros(n)])
    write_log(path, t, omega, p)
    return path


def test_file_registering_an_invalid_effect(fresh_plugins):
    with pytest.raises(UserError, match="broken_effect.*needs a callable force"):
        load_effect_files([DATA / "not_an_effect.py"])


def test_file_defining_no_effect(fresh_plugins):
    with pytest.raises(UserError, match="registers no effect"):
        load_effect_files([DATA / "no_hook.py"])


def test_effect_file_that_does_not_import(tmp_path, fresh_plugins):
    bad = tmp_path / "bad.py"
    bad.write_text("def broken(:\n")
    with pytest.raises(UserError, match="bad.py"):
        load_effect_files([bad])
    with pytest.raises(UserError, match="does not exist"):
        load_effect_files([tmp_path / "missing.py"])


def test_unknown_effect_lists_the_known_ones(short_log, fresh_plugins):
    with pytest.raises(UserError, match="unknown effect 'vortex'.*background_flow.*wall_drag"):
        run([short_log], settings=Settings(add=["vortex"]))
    with pytest.raises(UserError, match="unknown effect 'vortex'"):
        run([short_log], settings=Settings(candidates=["vortex"]))


def test_logs_too_short(short_log, fresh_plugins):
    with pytest.raises(UserError, match="too short"):
        run([short_log])


def test_cli_prints_one_line_and_exits_2(short_log, tmp_path, capsys, fresh_plugins):
    assert main(["diagnose", str(short_log), "--out", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("cosim diagnose: error:") and "too short" in err[0]
    assert main(["diagnose", str(short_log), "--effects-file", str(DATA / "not_an_effect.py"),
                 "--out", str(tmp_path / "d")]) == 2
    assert "not_an_effect.py" in capsys.readouterr().err
