"""The digital twin (workflow layer, docs/twin.md, docs/architecture.md): measured crank data in,
the FMU's loads out, per sample and per revolution.

`core` (the twin: segments, FMU channel, revolutions, checkpoints), `samples` (the input as
numbers), `line_input` (input lines read in chunks, and the CSV reader), `conditioning` (angle to
speed and acceleration), `plots`, `sample` (the known truth behind the sample data) and `replay`
(the distributed replay on Dask). The core's
public names are importable from here too (`reciprocating_drive.twin.column_name`).
"""

from .core import (
    INPUTS,
    REV_SAMPLES_MAX,
    SUMMARY_FIELDS,
    CheckpointError,
    DataError,
    Options,
    Twin,
    column_name,
    detect_separator,
    load_checkpoint,
    save_checkpoint,
    summary_header,
    with_unit,
)

__all__ = [
    "INPUTS",
    "REV_SAMPLES_MAX",
    "SUMMARY_FIELDS",
    "CheckpointError",
    "DataError",
    "Options",
    "Twin",
    "column_name",
    "detect_separator",
    "load_checkpoint",
    "save_checkpoint",
    "summary_header",
    "with_unit",
]
