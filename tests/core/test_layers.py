"""The framework's layers point down only, with no import cycle; the domain uses only the public API.

Every import in ``cosim/`` (at module level or inside a function) is read
with ``ast`` and checked against the declared order of the layers; a module
may import its own layer and those below. ``cosim_plugins`` and the examples
may import ``cosim`` itself, ``cosim.api`` and the contract (``cosim.contract.*``).
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

#: The layers of ``cosim``, lowest first; packages on one rank may not import each other.
LAYERS = {"contract": 0, "scenario": 1, "components": 1, "record": 2, "runtime": 3, "scale": 4, "api": 5, "cli": 6}
#: What the domain and the examples may import of the framework.
PUBLIC = ("cosim", "cosim.api", "cosim.contract")


def _module_name(file: Path) -> str:
    parts = file.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(file: Path) -> list[tuple[int, str]]:
    """``(line, module)`` of every absolute import in ``file`` (``from X import y`` counts ``X.y`` too,
    since ``y`` may be a module)."""
    found = []
    for node in ast.walk(ast.parse(file.read_text(), str(file))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.lineno, node.module))
            found += [(node.lineno, f"{node.module}.{alias.name}") for alias in node.names]
    return found


def _layer(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if parts[0] == "cosim" and len(parts) > 1 and parts[1] in LAYERS else None


def upward_imports(files) -> list[str]:
    """Each import of ``files`` (modules of ``cosim``) that reaches a layer above or beside its own."""
    wrong = []
    for file in files:
        mine = _layer(_module_name(file))
        if mine is None:
            continue
        for line, target in imports(file):
            theirs = _layer(target)
            if theirs is not None and theirs != mine and LAYERS[theirs] >= LAYERS[mine]:
                wrong.append(f"{file.relative_to(ROOT)}:{line}: {mine} imports {target} ({theirs})")
    return wrong


def cycles(files) -> list[list[str]]:
    """The import cycles among ``files``' modules (every import, in functions too), each as a list."""
    modules = {_module_name(f): f for f in files}
    # a module importing its own package's other modules (``from cosim.cli import commands``) names the
    # package too: that edge to an enclosing package is no cycle
    graph = {m: sorted({t for _, t in imports(f) if t in modules and t != m and not m.startswith(t + ".")})
             for m, f in modules.items()}
    found, state = [], {}

    def visit(node: str, stack: list[str]) -> None:
        state[node] = "open"
        for nxt in graph[node]:
            if state.get(nxt) == "open":
                found.append(stack[stack.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt, stack + [nxt])
        state[node] = "done"

    for module in graph:
        if module not in state:
            visit(module, [module])
    return found


def framework_files() -> list[Path]:
    return sorted((ROOT / "cosim").rglob("*.py"))


def test_no_layer_imports_one_above_or_beside_it():
    assert upward_imports(framework_files()) == []


def test_the_check_finds_an_upward_import(tmp_path):
    bad = ROOT / "cosim" / "scenario" / "_upward_probe.py"
    try:
        bad.write_text("def f():\n    from cosim.runtime.runner import run_one\n")
        assert upward_imports([bad]) == ["cosim/scenario/_upward_probe.py:2: scenario imports "
                                         "cosim.runtime.runner (runtime)",
                                         "cosim/scenario/_upward_probe.py:2: scenario imports "
                                         "cosim.runtime.runner.run_one (runtime)"]
    finally:
        bad.unlink()


def test_no_import_cycle():
    assert cycles(framework_files()) == []


def test_the_check_finds_a_cycle(tmp_path):
    a, b = ROOT / "cosim" / "record" / "_cycle_a.py", ROOT / "cosim" / "record" / "_cycle_b.py"
    try:
        a.write_text("from cosim.record import _cycle_b\n")
        b.write_text("def f():\n    import cosim.record._cycle_a\n")
        assert cycles([a, b]) == [["cosim.record._cycle_a", "cosim.record._cycle_b", "cosim.record._cycle_a"]]
    finally:
        a.unlink()
        b.unlink()


@pytest.mark.parametrize("folder", ["cosim_plugins", "examples"])
def test_the_domain_imports_only_the_public_api(folder):
    wrong = [f"{file.relative_to(ROOT)}:{line}: {target}"
             for file in sorted((ROOT / folder).rglob("*.py"))
             for line, target in imports(file)
             if target.split(".")[0] == "cosim" and not (
                 target in PUBLIC or target.startswith("cosim.contract.")
                 or (target.count(".") == 1 and target.split(".")[0] == "cosim" and _layer(target) is None)
                 or (target.startswith("cosim.api.")))]
    assert wrong == []


def test_loading_a_scenario_through_the_api_does_not_load_the_bus():
    code = ("import sys; from cosim import api; "
            f"api.load_scenario({str(ROOT / 'tests' / 'core' / 'data' / 'toy.yaml')!r}); "
            "print(sorted(m for m in ('zenoh', 'cosim.runtime.bus', 'cosim.runtime.runner') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert out.stdout.strip() == "[]"
