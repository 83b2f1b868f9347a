"""Building the FMU: compiler errors, staleness, COSIM_FMU, command line."""

from __future__ import annotations

import os
import shutil
import zipfile

import pytest

from cosim.contract.errors import UserError
from cosim_plugins.plant import build


@pytest.mark.parametrize("how", ["which", "PATH"])
def test_missing_compiler_gives_a_clear_error(monkeypatch, tmp_path, how):
    if how == "which":
        monkeypatch.setattr(shutil, "which", lambda name, *a, **k: None)
    else:
        monkeypatch.setenv("PATH", str(tmp_path))
    with pytest.raises(build.FmuBuildError) as exc:
        build.ensure_fmu(tmp_path / "plant.fmu")
    assert isinstance(exc.value, UserError)
    assert "apt-get install gcc" in str(exc.value)
    assert not (tmp_path / "plant.fmu").exists()


def test_failed_compile_shows_the_compiler_output(monkeypatch, tmp_path):
    broken = tmp_path / "broken.c"
    broken.write_text("int main(void) { return not_declared; }\n")
    monkeypatch.setattr(build, "source_files", lambda: [broken])
    with pytest.raises(build.FmuBuildError) as exc:
        build.build_fmu(tmp_path / "plant.fmu")
    assert "not_declared" in str(exc.value)
    assert "apt-get install gcc" in str(exc.value)


def test_ensure_fmu_builds_once_and_rebuilds_when_stale(tmp_path):
    fmu = tmp_path / "plant.fmu"
    assert build.ensure_fmu(fmu) == fmu.resolve()
    with zipfile.ZipFile(fmu) as zf:
        names = set(zf.namelist())
    assert {"modelDescription.xml", "binaries/linux64/swimmer_plant.so"} <= names
    built = fmu.stat().st_mtime_ns
    build.ensure_fmu(fmu)
    assert fmu.stat().st_mtime_ns == built                 # up to date: not rebuilt
    os.utime(fmu, (1_000_000, 1_000_000))                  # older than the sources
    build.ensure_fmu(fmu)
    assert fmu.stat().st_mtime_ns > 1_000_000 * 10**9


def test_cosim_fmu_environment_variable(monkeypatch, plant_fmu, tmp_path):
    monkeypatch.setenv("COSIM_FMU", str(plant_fmu))
    assert build.ensure_fmu() == plant_fmu.resolve()
    monkeypatch.setenv("COSIM_FMU", str(tmp_path / "missing.fmu"))
    with pytest.raises(build.FmuBuildError, match="COSIM_FMU"):
        build.ensure_fmu()


def test_command_line(monkeypatch, tmp_path, capsys):
    out = tmp_path / "sub" / "plant.fmu"
    assert build.main(["--out", str(out)]) == 0
    assert out.is_file()
    monkeypatch.setenv("PATH", str(tmp_path))
    assert build.main(["--out", str(tmp_path / "other.fmu")]) == 2
    assert "apt-get install gcc" in capsys.readouterr().err
