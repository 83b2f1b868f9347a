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


def test_the_default_fmu_is_built_once_into_the_user_cache_keyed_by_the_sources(monkeypatch, tmp_path):
    """No checkout needed: without COSIM_FMU the FMU is built from the package's own sources into
    $XDG_CACHE_HOME/cosim-swimmer/fmu, once; other sources get a file of their own."""
    monkeypatch.delenv("COSIM_FMU", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    fmu = build.ensure_fmu()
    assert fmu.parent == tmp_path / "cache" / "cosim-swimmer" / "fmu"
    assert fmu.name == f"swimmer_plant-{build.sources_digest()}.fmu" and fmu.is_file()
    built = fmu.stat().st_mtime_ns
    assert build.ensure_fmu() == fmu and fmu.stat().st_mtime_ns == built   # found, not rebuilt
    assert build.main([]) == 0 and fmu.stat().st_mtime_ns == built          # `make fmu` likewise
    changed = tmp_path / "changed.c"
    changed.write_text("/* another version of the sources */\n")
    sources = build.source_files()
    monkeypatch.setattr(build, "source_files", lambda: [*sources, changed])
    assert build.default_fmu() != fmu
