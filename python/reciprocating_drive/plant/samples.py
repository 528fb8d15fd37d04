"""Timestamped samples between a source and the twin's core (docs/plant.md, "Pipeline").

A source hands out `Chunk`s: input lines for `Twin.feed` (a CSV source passes the file's own lines,
so its messages name the file's line numbers), or samples as numbers for `Twin.feed_samples` (a
source of numbers, OPC UA: the values it received, with no text in between), and data-health
events. `sample_lines` writes samples as the CSV lines of the same input (each number with `repr`,
which reads back to the same double): the form the twin computes the same numbers from, which the
benchmark (scripts/bench_samples.py) and the tests compare the numbers' path with.

Layer: workflows, the plant (docs/architecture.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..twin.samples import Samples


def sample_header(speed: bool, force: bool, discharge: bool = False, suction: bool = False) -> str:
    """The header of `sample_lines` for a source that measures speed, force and/or a pump's
    pressures. A column the source does not have is left out, not written empty: the twin
    refuses an empty field."""
    return ",".join(
        ["time", "crank_angle"]
        + ["crank_speed"] * bool(speed)
        + ["process_force"] * bool(force)
        + ["discharge_pressure"] * bool(discharge)
        + ["suction_pressure"] * bool(suction)
    )


@dataclass
class Event:
    """A data-health event: kind (gap, reconnect, dropped, history, fmu_error, data_error, ...),
    the twin time it concerns (s, None when unknown), a count and a one-line message."""

    kind: str
    message: str
    t: float | None = None
    count: int = 1
    reason: str | None = None  # a `dropped` event's reason (the run's summary counts by it)


@dataclass
class Chunk:
    lines: list[str] = field(default_factory=list)
    events: list[Event] = field(default_factory=list)
    #: Samples as numbers (a source of numbers), instead of lines.
    samples: Samples | None = None


def _num(v) -> str:
    return "" if v is None or (isinstance(v, float) and math.isnan(v)) else repr(float(v))


def sample_lines(t, angle, speed=None, force=None, discharge=None, suction=None) -> list[str]:
    """CSV lines (the columns of `sample_header(speed is not None, force is not None, ...)`) of
    samples given as sequences; a column is None when not measured. A None or NaN inside a
    measured column is written empty, which the twin refuses as bad data."""
    cols = [t, angle] + [c for c in (speed, force, discharge, suction) if c is not None]
    return [
        ",".join([repr(float(t[i])), repr(float(angle[i]))] + [_num(c[i]) for c in cols[2:]])
        for i in range(len(t))
    ]


def input_lines(samples: Samples, header: bool) -> list[str]:
    """The CSV form of `samples` as `sample_lines` writes it (the columns `samples.names()`, with
    their header first when `header`): how the stored input (docs/plant.md "Storage") keeps the
    samples of a source of numbers, read back by the twin to the same doubles."""
    names = samples.names()
    cols = [samples.columns[n] for n in names]
    out = [",".join(names)] if header else []
    out += [
        ",".join(
            [repr(float(cols[0][i])), repr(float(cols[1][i]))] + [_num(c[i]) for c in cols[2:]]
        )
        for i in range(len(samples))
    ]
    return out
