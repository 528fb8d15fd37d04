"""Timestamped samples between a source and the twin's core (docs/plant.md, "Pipeline").

A source hands out `Chunk`s: input lines for `Twin.feed` (a CSV source passes the file's own lines,
so its messages name the file's line numbers) and data-health events. A source of samples (OPC UA)
formats them as CSV lines with `sample_lines`: each number written with `repr`, which reads back to
the same double, so the twin computes from exactly the values the source received.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

#: The header of the lines made from samples (the twin's CSV input, docs/twin.md "Input").
SAMPLE_HEADER = "time,crank_angle,crank_speed,process_force"


@dataclass
class Event:
    """A data-health event: kind (gap, reconnect, dropped, history, fmu_error, data_error, ...),
    the twin time it concerns (s, None when unknown), a count and a one-line message."""

    kind: str
    message: str
    t: float | None = None
    count: int = 1


@dataclass
class Chunk:
    lines: list[str] = field(default_factory=list)
    events: list[Event] = field(default_factory=list)


def _num(v) -> str:
    return "" if v is None or (isinstance(v, float) and math.isnan(v)) else repr(float(v))


def sample_lines(t, angle, speed=None, force=None) -> list[str]:
    """CSV lines (SAMPLE_HEADER's columns) of samples given as sequences; speed and force may be
    None (not measured) or hold None/NaN where a sample has none."""
    n = len(t)
    speed = speed if speed is not None else [None] * n
    force = force if force is not None else [None] * n
    return [
        f"{float(t[i])!r},{float(angle[i])!r},{_num(speed[i])},{_num(force[i])}" for i in range(n)
    ]
