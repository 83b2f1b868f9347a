"""Reading back what a run recorded: the events (faults and stops) and the entities of its rerun recording."""

from __future__ import annotations

from pathlib import Path


def recorded_events(rrd: Path) -> list[str]:
    """The texts logged at ``events`` (faults and stops) in the rerun recording ``rrd``, in order."""
    from rerun.chunk import RrdReader

    texts = []
    for chunk in RrdReader(rrd).stream():
        if chunk.entity_path == "/events":
            for row in chunk.to_record_batch().column("TextLog:text").to_pylist():
                texts.extend(row)
    return texts


def recorded_entities(rrd: Path) -> set[str]:
    """The entity paths with data in the rerun recording ``rrd``."""
    from rerun.chunk import RrdReader

    return {chunk.entity_path for chunk in RrdReader(rrd).stream()}
