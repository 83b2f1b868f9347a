"""What made a run: fingerprints of its scenario, the code and the files besides code.

A fingerprint says whether two processes (two sweep workers, the scheduler
and a node on another machine) would run the same experiment:

* ``scenario``: the validated scenario with its overrides applied, as
  canonical JSON (so the file's path, comments and layout do not count);
* ``code``: the source of the ``cosim`` package, of every installed plugin
  (built-in or from an entry point: its package's whole source tree) and of
  the plugin files the scenario loads, by path within its package (a file:
  by name), so the same code installed elsewhere hashes the same;
* ``artifacts``: the files besides code the scenario's components depend on
  (:meth:`cosim.contract.component.Component.artifacts`: the plant's FMU, a model
  file), by content.

Each part is a short hex digest; :func:`differences` names the parts in
which two fingerprints differ.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import json
import socket
import sys
from dataclasses import asdict, dataclass
from pathlib import Path

from cosim.contract.plugins import USER_PLUGIN_PREFIX, get_plugin_manager, lookup, plugin_file_sources
from cosim.scenario.schema import Scenario

DIGEST_CHARS = 16


@dataclass(frozen=True)
class Fingerprint:
    """What a run's result depends on: digests of the scenario, of the code and of the artefacts."""
    scenario: str
    code: str
    artifacts: str

    def as_dict(self) -> dict[str, str]:
        """``{"scenario", "code", "artifacts"}``: the digests as a dict (a sweep row's, JSON)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "Fingerprint":
        """The fingerprint of an :meth:`as_dict` dict (a missing part: empty)."""
        return cls(**{k: str(data.get(k, "")) for k in ("scenario", "code", "artifacts")})

    def encode(self) -> str:
        """One token for a command line: ``scenario.code.artifacts``."""
        return f"{self.scenario}.{self.code}.{self.artifacts}"

    @classmethod
    def decode(cls, text: str) -> "Fingerprint":
        """The fingerprint of an :meth:`encode` token; ValueError for anything else."""
        parts = text.split(".")
        if len(parts) != 3 or not all(parts):
            raise ValueError(f"fingerprint {text!r}: expected SCENARIO.CODE.ARTIFACTS (three hex digests)")
        return cls(*parts)


def _digest(h: "hashlib._Hash") -> str:
    return h.hexdigest()[:DIGEST_CHARS]


def scenario_digest(scenario: Scenario) -> str:
    """Digest of the scenario as validated (every field, defaults included)."""
    text = json.dumps(scenario.model_dump(mode="json", by_alias=True), sort_keys=True, separators=(",", ":"))
    return _digest(hashlib.sha256(text.encode()))


def _source_files(module) -> list[tuple[str, Path]]:
    """``(name within its package, file)`` of every source file a plugin module brings:
    its whole top-level package for a package module, else the module's own file."""
    top = module.__name__.split(".")[0]
    package = sys.modules.get(top)
    root = Path(package.__file__).parent if package is not None and hasattr(package, "__path__") else None
    if root is None:
        file = getattr(module, "__file__", None)
        return [(Path(file).name, Path(file))] if file else []
    return [(f"{top}/{f.relative_to(root).as_posix()}", f) for f in root.rglob("*.py")]


def code_digest(plugin_files: list[Path] = ()) -> str:
    """Digest of the ``cosim`` package, every installed plugin's source and ``plugin_files`` (a
    scenario's own) with the Python files beside each (the modules such a file imports from its
    folder). Plugin files this process loaded for other scenarios do not count."""
    import cosim

    files: dict[str, Path] = dict(_source_files(cosim))
    pm = get_plugin_manager()
    for plugin in pm.get_plugins():
        if not (pm.get_name(plugin) or "").startswith(USER_PLUGIN_PREFIX):
            files.update(_source_files(plugin))
    for plugin_file in plugin_files:
        files.update((f"scenario plugin {Path(plugin_file).name}: {f.name}", f)
                     for f in plugin_file_sources(plugin_file))
    return _cached_code_digest(tuple(sorted((name, str(path)) for name, path in files.items())))


@functools.lru_cache(maxsize=8)
def _cached_code_digest(files: tuple[tuple[str, str], ...]) -> str:
    """The code of a process does not change while it runs: hashed once per set of files."""
    h = hashlib.sha256()
    for name, path in files:
        if "__pycache__" in name:
            continue
        h.update(name.encode() + b"\0" + Path(path).read_bytes() + b"\0")
    return _digest(h)


def artifact_files(scenario: Scenario) -> list[Path]:
    """The files besides code the scenario's components name (see ``Component.artifacts``)."""
    files: list[Path] = []
    for name, spec in scenario.components.items():
        cls = lookup("component", spec.plugin)
        files += [Path(f) for f in cls.artifacts({"dt": scenario.dt_s, **spec.params})]
    return files


def artifacts_digest(scenario: Scenario) -> str:
    """Digest of the files besides code the scenario's components depend on (an FMU, model files)."""
    h = hashlib.sha256()
    for file in artifact_files(scenario):
        h.update(file.name.encode() + b"\0" + _file_digest(file).encode())
    return _digest(h)


def _file_digest(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def fingerprint(scenario: Scenario, scenario_file: str | Path) -> Fingerprint:
    """The fingerprint of running ``scenario`` (read from ``scenario_file``, overrides applied) with
    this process's code and files."""
    base = Path(scenario_file).parent
    plugin_files = [Path(p) if Path(p).is_absolute() else base / p for p in scenario.plugins]
    return Fingerprint(scenario_digest(scenario), code_digest(plugin_files), artifacts_digest(scenario))


def differences(mine: Fingerprint, theirs: Fingerprint) -> list[str]:
    """The parts that differ, in words: ``["the code (3f2a... here, 9b1c... there)", ...]``."""
    words = {"scenario": "the scenario with its overrides", "code": "the code (cosim and its plugins)",
             "artifacts": "the files besides code (the plant's FMU, model files)"}
    return [f"{words[k]} ({getattr(mine, k)} here, {getattr(theirs, k)} there)"
            for k in ("scenario", "code", "artifacts") if getattr(mine, k) != getattr(theirs, k)]


def class_sources(cls: type, prefixes: tuple[str, ...]) -> set[str]:
    """The file defining ``cls`` and the files of the modules it imports names from whose module
    names start with one of ``prefixes`` (a domain's own, e.g. ``("mydomain.",)``): the code a cache
    entry made with ``cls`` depends on."""
    module = sys.modules[cls.__module__]
    files = {module.__file__}
    for value in vars(module).values():
        owner = inspect.getmodule(value)
        if owner is not None and owner.__name__.startswith(prefixes) and getattr(owner, "__file__", None):
            files.add(owner.__file__)
    return files


def files_digest(files) -> str:
    """Digest of the contents of ``files`` (paths), taken in sorted order: a cache key."""
    h = hashlib.sha256()
    for file in sorted(map(str, files)):
        h.update(Path(file).read_bytes())
    return h.hexdigest()


def host_name() -> str:
    """This machine's host name."""
    return socket.gethostname()
