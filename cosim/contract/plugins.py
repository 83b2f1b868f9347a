"""The one plugin manager: every plugin, the project's own domain included, registered alike.

Kinds of things plugins provide (see :mod:`cosim.contract.hookspecs`): components,
paths, profiles, recording views, shipped scenarios, and the kinds a domain adds with hooks of its
own. ``registry(kind)`` returns ``{name: object}``; ``command_groups()`` the CLI
commands plugins add.
Plugins come from the ``cosim`` entry-point group of installed packages, or from a
Python file loaded with :func:`load_plugin_file`.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from typing import Any

import pluggy

from cosim.contract import hookspecs
from cosim.contract.errors import PluginError

#: The kinds of things the framework's own hooks provide, in the order ``cosim plugins`` lists
#: them; kind ``K`` is provided by the hook ``cosim_register_Ks``, and a domain adds kinds with
#: hooks of its own named so (see ``cosim_addhooks``).
KINDS = ("component", "path", "profile", "view", "scenario")

#: The module name of a plugin file loaded by :func:`load_plugin_file` starts so.
USER_PLUGIN_PREFIX = "cosim_user_plugin_"

_pm: pluggy.PluginManager | None = None


def get_plugin_manager() -> pluggy.PluginManager:
    """The process-wide plugin manager (created on first use)."""
    global _pm
    if _pm is None:
        pm = pluggy.PluginManager(hookspecs.PROJECT)
        pm.add_hookspecs(hookspecs)
        # every plugin registered from now on adds its hook specifications at once
        pm.hook.cosim_addhooks.call_historic(kwargs={"pluginmanager": pm})
        pm.load_setuptools_entrypoints(hookspecs.PROJECT)
        _pm = pm
    return _pm


def reset() -> None:
    """Forget the plugin manager (tests use this after registering throwaway plugins)."""
    global _pm
    _pm = None


def registry(kind: str) -> dict[str, Any]:
    """All things of ``kind`` ('component', 'path', 'profile', 'view', or a kind a domain adds) by name.

    Raises :class:`PluginError` when two plugins register the same name.
    """
    hook = getattr(get_plugin_manager().hook, hook_name(kind), None)
    if hook is None:
        raise PluginError(f"no plugin provides {kind}s (no hook {hook_name(kind)})")
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


def hook_name(kind: str) -> str:
    """The name of the hook that provides things of ``kind``: ``cosim_register_<kind>s``."""
    return f"cosim_register_{kind}s"


def kinds() -> list[str]:
    """Every kind some hook provides: the framework's, then those domains added."""
    hooks = vars(get_plugin_manager().hook)
    added = [name[len("cosim_register_"):-1] for name in hooks
             if name.startswith("cosim_register_") and name.endswith("s") and name != "cosim_register_commands"]
    return [*KINDS, *(k for k in added if k not in KINDS)]


def command_groups() -> list:
    """The ``add_commands(subparsers)`` callables plugins register (see :mod:`cosim.contract.hookspecs`)."""
    found: list = []
    get_plugin_manager().hook.cosim_register_commands(register=found.append)
    return found


def figure_sets() -> list:
    """The :class:`~cosim.contract.figures.FigureSet` objects plugins provide (hook ``cosim_summary_figures``)."""
    found: list = []
    get_plugin_manager().hook.cosim_summary_figures(register=found.append)
    return found


def environment_keys() -> tuple[str, ...]:
    """The environment variables plugins name as changing what a run does (hook ``cosim_register_environment``)."""
    found: list[str] = []
    get_plugin_manager().hook.cosim_register_environment(register=found.append)
    return tuple(dict.fromkeys(found))


def lookup(kind: str, name: str) -> Any:
    """One registered thing; an unknown name raises an error listing the known ones."""
    known = registry(kind)
    if name not in known:
        listing = ", ".join(sorted(known)) or "(none)"
        raise PluginError(f"unknown {kind} {name!r}; known {kind}s: {listing}")
    return known[name]


def plugin_file_sources(path: str | Path) -> list[Path]:
    """The files a plugin file brings: itself and the Python files beside it, which it may import
    from its folder (as the DC motor example's does); its code fingerprint and what a sweep ships
    to other machines."""
    path = Path(path)
    return [path, *sorted(f for f in path.parent.glob("*.py") if f.is_file() and f.name != path.name)]


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
