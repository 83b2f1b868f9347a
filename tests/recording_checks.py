"""Reading back what a run recorded: the events (faults and stops) and the entities of its rerun recording."""

from __future__ import annotations

import warnings
from pathlib import Path


def _chunks(rrd: Path):
    """The chunks of ``rrd`` in order (a run's files have no footer, see :data:`cosim.record.rerun_log.WRITE_FOOTER`,
    so rerun's reader scans the file, which it warns about)."""
    from rerun.chunk import RrdReader

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="RRD file has no footer")
        reader = RrdReader(rrd)
    return reader.stream()


def recorded_events(rrd: Path) -> list[str]:
    """The texts logged at ``events`` (faults and stops) in the rerun recording ``rrd``, in order."""
    texts = []
    for chunk in _chunks(rrd):
        if chunk.entity_path == "/events":
            for row in chunk.to_record_batch().column("TextLog:text").to_pylist():
                texts.extend(row)
    return texts


def recorded_entities(rrd: Path) -> set[str]:
    """The entity paths with data in the rerun recording ``rrd``."""
    return {chunk.entity_path for chunk in _chunks(rrd)}
