"""The digest of the code a generated page depends on, so a test can tell that page is stale.

:func:`code_digest` hashes modules by their syntax trees without docstrings and imports (a
reworded docstring or a reordered import changes no output, so it leaves the digest alone)
and data files (scenarios, the FMU's C sources, its model description) by their bytes.
``cosim reproduce --docs`` writes :func:`results_digest` into the page's results block;
``tests/docs/test_doc_outputs.py`` recomputes it and fails when the code changed since.
"""

from __future__ import annotations

import ast
import hashlib
from pathlib import Path

#: Where the names below are found: the folder holding ``cosim`` and ``cosim_plugins`` (a checkout
#: or site-packages).
ROOT = Path(__file__).resolve().parents[2]

#: What the paper's results depend on: the reproduction itself, the model fitting and comparison,
#: the models, every component the scenarios run (camera, estimators, controllers, coil driver,
#: plant with its C sources), the paths, the profiles, the effects the fitting code imports, the
#: scenario schema (profiles, numbers) and the scenarios run. Left out: the framework's loop
#: (``cosim/runtime``), whose stepping semantics ``tests/core`` pins exactly (delays, ordering),
#: so its refactors do not mark the results stale; and the diagnosis, which the results never run.
RESULTS_CODE = (
    "cosim_plugins/paper", "cosim_plugins/identify", "cosim_plugins/models", "cosim_plugins/estimators",
    "cosim_plugins/controllers", "cosim_plugins/camera", "cosim_plugins/coil_driver", "cosim_plugins/plant",
    "cosim_plugins/paths", "cosim_plugins/profiles", "cosim_plugins/effects", "cosim_plugins/vec3.py",
    "cosim_plugins/raw_log.py", "cosim/scenario",
    "cosim_plugins/scenarios/paper", "cosim_plugins/scenarios/feedback_sweep.yaml",
    "cosim_plugins/scenarios/realtime_prediction.yaml", "cosim_plugins/scenarios/controllers_racetrack.yaml",
    "cosim_plugins/scenarios/controllers_helix.yaml",
)

#: The file kinds hashed by their bytes (anything else in a folder, e.g. a README, is left out).
DATA_SUFFIXES = (".yaml", ".c", ".h", ".xml")


def update(h: "hashlib._Hash", names: tuple[str, ...], root: Path = ROOT) -> None:
    """Feed ``h`` with the code ``names`` (module paths with dots, or files and folders with ``/``,
    relative to ``root``), each file under its relative path, in a fixed order.

    Raises ``FileNotFoundError`` naming the entry when one no longer exists.
    """
    for name in names:
        path = root / name if "/" in name else root / name.replace(".", "/")
        if not path.exists():
            raise FileNotFoundError(f"the digest's code list names {name}, which is no more ({path})")
        files = sorted(path.rglob("*")) if path.is_dir() else [path]
        for file in files:
            if "__pycache__" in file.parts:
                continue
            if file.suffix == ".py":
                h.update(file.relative_to(root).as_posix().encode() + code_shape(file.read_text()).encode())
            elif file.suffix in DATA_SUFFIXES:
                h.update(file.relative_to(root).as_posix().encode() + file.read_bytes())


def code_shape(source: str) -> str:
    """A module's syntax tree as text, without its docstrings and imports."""
    tree = ast.parse(source)
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if isinstance(body, list):
            body[:] = [n for n in body if not isinstance(n, (ast.Import, ast.ImportFrom))
                       and not (isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant)
                                and isinstance(n.value.value, str))]
    return ast.dump(tree)


def code_digest(names: tuple[str, ...], seed: bytes = b"", root: Path = ROOT) -> str:
    """12 hex digits of the code ``names`` (see :func:`update`), after ``seed`` (e.g. the commands run)."""
    h = hashlib.sha256(seed)
    update(h, names, root)
    return h.hexdigest()[:12]


def results_digest(root: Path = ROOT) -> str:
    """The digest of the code the paper's results (``cosim reproduce``) depend on: :data:`RESULTS_CODE`."""
    return code_digest(RESULTS_CODE, b"cosim reproduce", root)
