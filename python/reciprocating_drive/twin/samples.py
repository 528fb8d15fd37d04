"""The twin's input as numbers (docs/twin.md "Input"): what the core computes from, whichever source
the samples come from. A CSV file or standard input is parsed into `Samples` (`line_input.parse_lines`);
a source that receives numbers (OPC UA) hands them over as they are, with no text in between.

Each sample carries its origin for messages (`line`): the input line it was read from, or, for a
source of numbers, the line it would have in the input's CSV form (header = line 1), so that a
message names the same place whichever way the samples came.

An optional column is one entry of `OPTIONAL`: its name in the input's header and the value a
sample takes when the input has no such column.

Layer: workflows, the twin (docs/architecture.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


class DataError(ValueError):
    """Bad measured data, with the input line number. `rows` and `summaries` are what the twin
    computed from the samples before it (to be written before the run stops)."""

    rows = None
    summaries: list = []


#: The columns every input has, in the order of a CSV header.
REQUIRED = ("time", "crank_angle")
#: The optional columns and the value a sample takes when its input has no such column: the
#: crank speed is then estimated from the angle (NaN), the process force is 0, a pump's pressure
#: is the machine's (NaN: the preset's, else the FMU's start value; docs/twin.md "Input").
OPTIONAL = {
    "crank_speed": math.nan,
    "process_force": 0.0,
    "discharge_pressure": math.nan,
    "suction_pressure": math.nan,
}


@dataclass
class Samples:
    """Consecutive samples: `columns` maps a column name (REQUIRED, then those of OPTIONAL the
    input has) to its values (float64), all of one length; `line` is each sample's origin (int64),
    or None for samples numbered on from the line `Twin.feed_samples` is given."""

    columns: dict
    line: np.ndarray | None = None

    @classmethod
    def of(cls, line=None, **columns) -> Samples:
        """Samples from sequences of numbers, by column name; a column that is None is left out
        (not measured). A None inside a column is NaN."""
        cols = {name: np.asarray(v, dtype=float) for name, v in columns.items() if v is not None}
        for name in cols:
            if name not in REQUIRED and name not in OPTIONAL:
                raise ValueError(f"no input column {name!r}")
        return cls(cols, None if line is None else np.asarray(line, dtype=np.int64))

    def __len__(self) -> int:
        return len(self.columns["time"])

    def names(self) -> list[str]:
        """The columns of these samples in the order of a CSV header."""
        return [*REQUIRED, *(n for n in OPTIONAL if n in self.columns)]

    def value(self, name: str) -> np.ndarray:
        """The column `name`, or its default for every sample when the input has no such column."""
        if name in self.columns:
            return self.columns[name]
        return np.full(len(self), OPTIONAL[name])

    @staticmethod
    def concat(parts: list[Samples]) -> Samples:
        """The samples of `parts` one after the other (parts of the same columns, all numbered
        by `line` or none)."""
        if len(parts) == 1:
            return parts[0]
        lines = None if parts[0].line is None else np.concatenate([p.line for p in parts])
        return Samples(
            {n: np.concatenate([p.columns[n] for p in parts]) for n in parts[0].columns}, lines
        )

    def __add__(self, other: Samples) -> Samples:
        """These samples followed by `other`'s."""
        return Samples.concat([self, other])
