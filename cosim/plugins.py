"""The one plugin manager: built-ins and external plugins registered alike.

Kinds of things plugins provide (see :mod:`cosim.hookspecs`): components,
paths, models, effects. ``registry(kind)`` returns ``{name: object}``;
``command_groups()`` the CLI commands plugins add.
External plugins come from the ``cosim`` entry-point group, or from a Python
file loaded with :func:`load_plugin_file`.
"""

from __future__ import annotations

from cosim.errors import UserError

import importlib
import importlib.util
import sys
from pathlib import Path
from typing import Any

import pluggy

from cosim import hookspecs

#: Built-in plugin modules, registered exactly like external plugins.
BUILTIN_PLUGINS: tuple[str, ...] = (
    "cosim_plugins.plant",
    "cosim_plugins.camera",
    "cosim_plugins.coil_driver",
    "cosim_plugins.estimators",
    "cosim_plugins.controllers",
    "cosim_plugins.paths",
    "cosim_plugins.models",
    "cosim_plugins.effects",
    "cosim_plugins.profiles",
)

KINDS = {
    "component": "cosim_register_components",
    "path": "cosim_register_paths",
    "model": "cosim_register_models",
    "effect": "cosim_register_effects",
    "profile": "cosim_register_profiles",
}

#: The module name of a plugin file loaded by :func:`load_plugin_file` starts so.
USER_PLUGIN_PREFIX = "cosim_user_plugin_"

_pm: pluggy.PluginManager | None = None


class PluginError(UserError):
    """A plugin could not be loaded, or registered something invalid."""


def get_plugin_manager() -> pluggy.PluginManager:
    """The process-wide plugin manager (created on first use)."""
    global _pm
    if _pm is None:
        pm = pluggy.PluginManager(hookspecs.PROJECT)
        pm.add_hookspecs(hookspecs)
        for name in BUILTIN_PLUGINS:
            try:
                module = importlib.import_module(name)
            except ModuleNotFoundError as exc:
                if exc.name != name:
                    raise
                continue  # a built-in room not written yet
            pm.register(module, name)
        pm.load_setuptools_entrypoints(hookspecs.PROJECT)
        _pm = pm
    return _pm


def reset() -> None:
    """Forget the plugin manager (tests use this after registering throwaway plugins)."""
    global _pm
    _pm = None


def registry(kind: str) -> dict[str, Any]:
    """All things of ``kind`` ('component', 'path', 'model', 'effect') by name.

    Raises :class:`PluginError` when two plugins register the same name.
    """
    hook = getattr(get_plugin_manager().hook, KINDS[kind])
    found: dict[str, Any] = {}
    owners: dict[str, str] = {}

    def register(name_or_obj, obj=None):
        if obj is None:  # effects register themselves: register(effect)
            obj, name = name_or_obj, getattr(name_or_obj, "name", None)
        else:
            name = name_or_obj
        if not isinstance(name, str) or not name:
            raise PluginError(f"a plugin registered a {kind} without a name: {obj!r}")
        if name in found:
            raise PluginError(f"{kind} {name!r} is registered twice ({owners[name]} and another plugin)")
        found[name] = obj
        owners[name] = getattr(obj, "__module__", "?")

    hook(register=register)
    return found


def command_groups() -> list:
    """The ``add_commands(subparsers)`` callables plugins register (see :mod:`cosim.hookspecs`)."""
    found: list = []
    get_plugin_manager().hook.cosim_register_commands(register=found.append)
    return found


def lookup(kind: str, name: str) -> Any:
    """One registered thing; an unknown name raises an error listing the known ones."""
    known = registry(kind)
    if name not in known:
        listing = ", ".join(sorted(known)) or "(none)"
        raise PluginError(f"unknown {kind} {name!r}; known {kind}s: {listing}")
    return known[name]


def load_plugin_file(path: str | Path) -> Any:
    """Import a user's Python file and register it as a plugin; return the module.

    Errors (missing file, syntax error, exception at import) name the file.
    """
    path = Path(path)
    if not path.is_file():
        raise PluginError(f"plugin file {path} does not exist")
    mod_name = f"{USER_PLUGIN_PREFIX}{abs(hash(str(path.resolve())))}"
    pm = get_plugin_manager()
    if pm.has_plugin(mod_name):
        return pm.get_plugin(mod_name)
    spec = importlib.util.spec_from_file_location(mod_name, path)
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except Exception as exc:  # the user's file: report it whatever it raised
        raise PluginError(f"plugin file {path} failed to load: {type(exc).__name__}: {exc}") from exc
    sys.modules[mod_name] = module
    pm.register(module, mod_name)
    return module
