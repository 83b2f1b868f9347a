"""Every public name of the framework's API says what it is: ``cosim``'s and ``cosim.api``'s names, the
contract modules' public classes and functions, and the public methods those classes define."""

from __future__ import annotations

import importlib
import inspect

import pytest

import cosim
from cosim import api

CONTRACT = ("cosim.contract.component", "cosim.contract.errors", "cosim.contract.figures", "cosim.contract.params",
            "cosim.contract.paths", "cosim.contract.plugins", "cosim.contract.views", "cosim.contract.hookspecs")


def public_objects():
    """``(qualified name, object)`` of every public function and class of the API and the contract."""
    seen = {}
    for module, names in ((cosim, cosim.__all__), (api, api.__all__)):
        for name in names:
            seen[f"{module.__name__}.{name}"] = getattr(module, name)
    for module_name in CONTRACT:
        module = importlib.import_module(module_name)
        for name, obj in vars(module).items():
            if not name.startswith("_") and (inspect.isfunction(obj) or inspect.isclass(obj)) \
                    and obj.__module__ == module_name:
                seen[f"{module_name}.{name}"] = obj
    return {k: v for k, v in seen.items() if inspect.isfunction(v) or inspect.isclass(v)}


def methods(cls):
    """The public methods and properties ``cls`` itself defines."""
    for name, value in vars(cls).items():
        if name.startswith("_"):
            continue
        if isinstance(value, (classmethod, staticmethod)):
            value = value.__func__
        if inspect.isfunction(value) or isinstance(value, property):
            yield name, value


def test_every_public_name_and_method_has_a_docstring():
    missing = []
    for qualified, obj in sorted(public_objects().items()):
        if not (obj.__doc__ or "").strip():
            missing.append(qualified)
        if inspect.isclass(obj) and obj.__module__.startswith("cosim"):
            missing += [f"{qualified}.{name}" for name, m in methods(obj) if not (m.__doc__ or "").strip()]
    assert missing == []


@pytest.mark.parametrize("name", api.__all__)
def test_every_name_the_api_lists_is_there(name):
    assert getattr(api, name) is not None
