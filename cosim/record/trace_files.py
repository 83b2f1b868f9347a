"""The trace on disk: written in chunks as the run goes, one ``trace.npz`` when it ends.

While a run goes its trace is the folder ``trace.chunks/``:

* ``index.json``: ``{"dtype": "<f8", "dt_s", "columns": [[name, shape], ...], "chunks":
  [{"file", "start", "ticks"}, ...], "ticks"}`` (the ticks in the chunks), rewritten
  (write, then rename) after each chunk, so a reader always finds a whole one;
* ``NNNNNN.npz``: one per chunk (uncompressed; ``t_s`` and one array per
  ``component.port``, shape (chunk ticks, *port shape), SI units);
* ``current.part``: the rows of the chunk under way, float64, ``t_s`` then the columns
  laid end to end, appended about once a second (so a killed run loses at most that).

When the run ends the chunks are joined into ``trace.npz`` (compressed, the layout
:func:`load_trace` returns) column by column, each chunk's column read once, never the
whole trace in memory, and the folder is removed. :func:`load_trace` reads a
``trace.npz``, a ``trace.chunks/`` (a run going, or one that was killed) and the single
``trace.part`` of runs recorded before chunks, and the parts of a run recorded in parts
(``part-000/``, ... of ``cosim run --rotate``) one after another; :func:`iter_trace` reads a
trace chunk by chunk.
"""

from __future__ import annotations

import json
import os
import shutil
import zipfile
from pathlib import Path
from typing import Iterator

import numpy as np

from cosim.contract.errors import UserError

CHUNKS_DIR = "trace.chunks"
INDEX = "index.json"
CURRENT = "current.part"
#: the folders of a run recorded in parts (``cosim run --rotate``), in order
PARTS_GLOB = "part-[0-9][0-9][0-9]"


class ChunkedTrace:
    """Writer of ``trace.chunks/`` (see the module doc). ``columns``: ``[(name, shape), ...]``
    after ``t_s``; ``dt_s``: the tick [s]."""

    def __init__(self, out_dir: Path, columns: list[tuple[str, tuple]], dt_s: float):
        self.out_dir, self.dir = Path(out_dir), Path(out_dir) / CHUNKS_DIR
        self.columns = [("t_s", ()), *[(name, tuple(shape)) for name, shape in columns]]
        self.dt_s = dt_s
        self.chunks: list[dict] = []
        self.ticks = 0  # ticks in sealed chunks
        self._part = None

    def open(self) -> None:
        if self.dir.exists():
            shutil.rmtree(self.dir)
        self.dir.mkdir(parents=True)
        self._write_index()
        self._part = open(self.dir / CURRENT, "wb")

    def append(self, table: np.ndarray) -> None:
        """Rows of the chunk under way, (rows, 1 + every column's width) float64."""
        self._part.write(np.ascontiguousarray(table, dtype="<f8").tobytes())
        self._part.flush()

    def seal(self, arrays: dict[str, np.ndarray]) -> None:
        """The chunk under way is complete: ``arrays`` holds its rows, ``{name: (ticks, *shape)}``
        (every column, ``t_s`` included); written as the next ``NNNNNN.npz``."""
        ticks = len(arrays["t_s"])
        if not ticks:
            return
        name = f"{len(self.chunks):06d}.npz"
        tmp = self.dir / (name + ".tmp")
        with open(tmp, "wb") as f:
            np.savez(f, **{k: arrays[k] for k, _ in self.columns})
        os.replace(tmp, self.dir / name)
        self.chunks.append({"file": name, "start": self.ticks, "ticks": ticks})
        self.ticks += ticks
        self._write_index()
        self._part.close()
        self._part = open(self.dir / CURRENT, "wb")

    def _write_index(self) -> None:
        tmp = self.dir / (INDEX + ".tmp")
        tmp.write_text(json.dumps({"dtype": "<f8", "dt_s": self.dt_s,
                                   "columns": [[n, list(s)] for n, s in self.columns],
                                   "chunks": self.chunks, "ticks": self.ticks}))
        os.replace(tmp, self.dir / INDEX)

    def finish(self, rest: dict[str, np.ndarray], path: Path) -> Path:
        """Join the sealed chunks and ``rest`` (the rows not sealed, ``{name: (ticks, *shape)}``)
        into ``path`` (a compressed ``.npz``) and remove the folder; returns ``path``."""
        self._part.close()
        files = [self.dir / c["file"] for c in self.chunks]
        total = self.ticks + len(rest["t_s"])
        tmp = path.with_name(path.name + ".tmp")
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED, allowZip64=True) as zf:
            for name, shape in self.columns:
                with zf.open(f"{name}.npy", "w", force_zip64=True) as member:
                    np.lib.format.write_array_header_1_0(member, {"descr": "<f8", "fortran_order": False,
                                                                  "shape": (total, *shape)})
                    for file in files:  # one chunk's column at a time, written from its own buffer
                        with np.load(file) as chunk:
                            member.write(_raw(chunk[name]))
                    member.write(_raw(rest[name]))
        os.replace(tmp, path)
        shutil.rmtree(self.dir)
        return path


def _raw(values: np.ndarray) -> memoryview:
    """``values`` as little-endian float64 bytes in C order, without a copy when they already are."""
    return memoryview(np.ascontiguousarray(values, dtype="<f8").reshape(-1))


def _layout_error(run_dir: Path):

    return UserError(f"run {run_dir}: no trace.npz (nor a trace.chunks/ or trace.part of a run going or cut short)")


def _split(table: np.ndarray, columns: list) -> dict[str, np.ndarray]:
    widths = [int(np.prod(shape)) for _, shape in columns]
    edges = np.cumsum([0, *widths])
    rows = len(table)
    return {name: table[:, a:b].reshape(rows, *shape) for (name, shape), a, b in zip(columns, edges, edges[1:])}


def _read_part(part: Path, columns: list) -> dict[str, np.ndarray]:
    """A raw part file's whole rows (a row cut by a kill is dropped)."""
    width = sum(int(np.prod(shape)) for _, shape in columns)
    data = part.read_bytes() if part.is_file() else b""
    rows = len(data) // (8 * width)
    return _split(np.frombuffer(data[: rows * width * 8], dtype="<f8").reshape(rows, width), columns)


def iter_trace(run_dir: str | Path, names: list[str] | None = None) -> Iterator[dict[str, np.ndarray]]:
    """A run's trace piece by piece, ``{"t_s": (k,), "component.port": (k, *shape)}`` in tick order
    (``names``: only these columns, plus ``t_s``). A ``trace.chunks/`` gives one piece per chunk
    (memory: one chunk); a ``trace.npz`` or an old ``trace.part`` gives one piece."""
    run_dir = Path(run_dir)
    def keep(piece: dict) -> dict:
        return {k: v for k, v in piece.items() if names is None or k == "t_s" or k in names}

    chunks = run_dir / CHUNKS_DIR
    if (run_dir / "trace.npz").is_file():
        with np.load(run_dir / "trace.npz") as data:
            yield {k: data[k] for k in data.files if names is None or k == "t_s" or k in names}
        return
    if (chunks / INDEX).is_file():
        index = json.loads((chunks / INDEX).read_text())
        columns = [(n, tuple(s)) for n, s in index["columns"]]
        for chunk in index["chunks"]:
            with np.load(chunks / chunk["file"]) as data:
                yield keep({n: data[n] for n, _ in columns})
        rest = _read_part(chunks / CURRENT, columns)
        # the part may still hold a sealed chunk's rows (a kill between sealing and truncating it)
        first = np.rint(rest["t_s"] / index["dt_s"]).astype(np.int64) >= index["ticks"]
        yield keep({k: v[first] for k, v in rest.items()})
        return
    part, layout = run_dir / "trace.part", run_dir / "trace.part.json"
    if part.is_file() and layout.is_file():
        columns = [(n, tuple(s)) for n, s in json.loads(layout.read_text())["columns"]]
        yield keep(_read_part(part, columns))
        return
    parts = sorted(run_dir.glob(PARTS_GLOB))
    if parts:  # a run recorded in parts (cosim run --rotate): each in turn
        for folder in parts:
            yield from iter_trace(folder, names)
        return
    raise _layout_error(run_dir)


def load_trace(run_dir: str | Path) -> dict[str, np.ndarray]:
    """A run's trace: ``trace.npz``; or, of a run going or killed, ``trace.chunks/`` (every whole
    row written) or the ``trace.part`` of the layout before chunks; or a run's parts joined.

    Returns ``{"t_s": (n,), "component.port": (n, *shape), ...}``.
    """
    run_dir = Path(run_dir)
    if (run_dir / "trace.npz").is_file():
        with np.load(run_dir / "trace.npz") as data:
            return {k: data[k] for k in data.files}
    pieces = [p for p in iter_trace(run_dir) if len(p["t_s"])] or list(iter_trace(run_dir))[:1]
    return {k: np.concatenate([p[k] for p in pieces]) for k in pieces[0]}
