"""The drilling-pump digital twin (docs/twin.md): measured crank data in, the FMU's loads out, per
sample and per revolution, replayed from a file or live.

The pipeline works on chunks of input lines (`Twin.feed`): a whole block of a file in replay, the
lines available now in live mode; a source of numbers (OPC UA) hands over chunks of samples as
arrays (`Twin.feed_samples`, `samples.Samples`), checked as the reader checks a field, then the
same steps. Every sample's numbers are computed on their own, so the size of the chunks changes
when rows appear, never their values: replay, live and resumed runs give the same numbers bit for
bit.

1. **Reader** (`line_input.parse_lines`): a CSV with a header naming `time`, `crank_angle` and optionally
   `crank_speed` and `process_force`. A bad field, time going backwards, a duplicate timestamp
   (dropped and counted, or an error) or an angle step faster than `max_speed` stops the run with
   the line number (`DataError`), after the samples before it. The crank may stand still and
   turn either way (docs/twin.md "Machine states"): every sample is computed.
2. **Conditioning** (`conditioning.py`, vectorised over the chunk): angle to rad and unwrapped;
   ω and ε from a local cubic over the smoothing window where they are not measured (natively,
   `batch.local_cubic`, the algorithm of `conditioning.fit`). A gap longer
   than `gap_limit` ends a segment: the smoother does not bridge it, the gap is reported, and the
   FMU is re-initialized at the first sample after it (its dynamic state, an elastic rod's cage,
   starts quasi-statically again, docs/model.md §6), because the crank's motion inside the gap is
   unknown.
3. **FMU**: the sample times are the communication points (variable step); at each sample the
   crank inputs are set and every output is read, for a whole chunk in one call of the native
   batch driver (`fmu.Channel.run`, tools/fmi2-batch).
4. **Per revolution** (`revolution.py`): when the model angle completes a revolution its summary
   is emitted, flagged `interrupted` when a stop or a reversal fell inside it. The machine's state
   (running, stopped, reversing) is followed at every sample and its changes are `motion_events`.

Checkpoints (`Twin.checkpoint`/`Twin.from_checkpoint`) hold the FMU's serialized state and the
twin's own position and buffers; a run resumed from one continues exactly as if uninterrupted.

Layer: workflows, the twin (docs/architecture.md).
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import json
import math
from dataclasses import dataclass, field

import numpy as np

from ..fmu.batch import local_cubic
from ..fmu.instance import Fmu, FmuError
from ..presets import available_presets, preset_values
from ..revolution import PUMP_COLUMNS, TWO_PI, revolution_table
from ..timestamps import LOOKS_ISO, Clock, TimestampError
from ..timestamps import zone as time_zone
from . import conditioning as cond
from .line_input import (
    _EUROPEAN,
    _NUMBER,
    detect_separator,
    n_fields,
    parse_header,
    parse_lines,
)
from .samples import OPTIONAL, DataError, Samples

INPUTS = (
    "crank.angle",
    "crank.speed",
    "crank.acceleration",
    "link.external_force",
    "fluid_end.discharge_pressure",
    "fluid_end.suction_pressure",
)
#: The optional CSV columns of the process (docs/twin.md "Input") and the FMU inputs they drive:
#: a sample's `force` holds them in this order. A pressure column that is absent (NaN) leaves the
#: machine's value (the preset's, else the FMU's start value).
PROCESS_COLUMNS = ("process_force", "discharge_pressure", "suction_pressure")

#: Absolute part of the measured speed's tolerance [rad/s] (docs/twin.md "Measured speed"): a
#: crank at rest, whose estimated speed is rounding noise around 0.
SPEED_SLACK = 0.1

#: |time| and |angle| the twin reads (docs/twin.md "Input"): beyond 1e10 s a double resolves
#: 2 µs at best, beyond 1e9 revolutions 1 µrad.
TIME_LIMIT = 1e10
ANGLE_LIMIT = 1e9 * 2.0 * math.pi
#: Most samples a smoothing window may hold: more means a wrong time unit or --window (docs/twin.md
#: "Input"), and would cost memory and time for nothing.
MAX_WINDOW_SAMPLES = 200_001

#: Format of `Twin.checkpoint` (3: the smoothing window is a time; the buffer holds its
#: segment's start time and the sparse stretches).
CHECKPOINT_VERSION = 3

#: Samples conditioned and sent to the FMU per call at most (bounds the memory of the windows).
BLOCK = 4096

#: Samples of one revolution kept whole (docs/twin.md "Machine states"): a longer revolution (a
#: stop inside it) keeps only the samples that hold its extremes, so a standstill of hours holds
#: a bounded memory; its friction_work and speed_fluctuation, which need every sample, are empty.
REV_SAMPLES_MAX = 32768

#: The machine states (docs/twin.md "Machine states") and the event that enters each.
MOTION_STATES = {1: "running", 0: "stopped", -1: "reversing"}
MOTION_EVENTS = {1: "started", 0: "stopped", -1: "reversed"}
MOTION_KEEP = 64


#: The default machine's crank speed [rad/s] (the FMU's start value of crank.speed, 65 strokes/min)
#: and the options' defaults at that speed; for another machine `window` and `gap_limit` scale
#: with 1/ω and `max_speed` with ω of its design speed (docs/twin.md "Options follow the machine"),
#: so that each covers the same crank angle.
DEFAULT_DESIGN_SPEED = 2.0 * math.pi * 65.0 / 60.0
DEFAULT_WINDOW, DEFAULT_GAP_LIMIT, DEFAULT_MAX_SPEED = 0.1, 0.05, 100.0


@dataclass
class Options:
    angle_unit: str = "rad"  # rad | deg | counts
    counts_per_rev: float | None = None
    wrapped: bool = True  # angles wrap every revolution (else continuous)
    speed_unit: str = "rad/s"  # rad/s | rpm
    duplicates: str = "drop"  # drop | error
    window: float | None = None  # smoothing window [s]; None: from the machine's design speed
    gap_limit: float | None = None  # a longer interval between samples is a gap [s]; None: idem
    max_speed: float | None = None  # fastest physically possible crank speed [rad/s]; None: idem
    use_measured_speed: bool = True  # take crank_speed from the data when present
    separator: str = "auto"  # of the input's fields: auto | , | ; (';' reads decimal commas)
    speed_check: str = "refuse"  # a measured speed that contradicts the angle: refuse | warn
    speed_tolerance: float = 0.1  # relative, see docs/twin.md "Measured speed"
    # A segment between gaps too short for the local cubic (fewer than 4 samples): refuse stops
    # the run (a file); drop leaves its samples out and records them (a live source, where a
    # reconnect can leave a sample or two between two gaps; docs/plant.md "Faults").
    short_segments: str = "refuse"
    # The zone of ISO 8601 timestamps without a UTC offset (an IANA name, docs/twin.md
    # "Timestamps"); None: such timestamps are refused.
    timezone: str | None = None
    # Machine states (docs/twin.md "Machine states"): below stop_speed [rpm] in magnitude the
    # crank is stopped, at -stop_speed or less it reverses; a state holds from the sample where
    # it begins once it has lasted stop_duration [s].
    stop_speed: float = 1.0
    stop_duration: float = 0.5

    def to_dict(self) -> dict:
        return dict(self.__dict__)

    def resolved(self, design_speed: float) -> Options:
        """These options with the machine-dependent defaults filled in for a machine whose design
        crank speed is `design_speed` rad/s."""
        r = DEFAULT_DESIGN_SPEED / design_speed
        o = Options(**self.to_dict())
        o.window = DEFAULT_WINDOW * r if o.window is None else o.window
        o.gap_limit = DEFAULT_GAP_LIMIT * r if o.gap_limit is None else o.gap_limit
        o.max_speed = DEFAULT_MAX_SPEED / r if o.max_speed is None else o.max_speed
        return o

    def validate(self) -> None:
        """Raises ValueError naming the first illegal option (as its command-line flag)."""
        choices = {
            "angle_unit": ("rad", "deg", "counts"),
            "speed_unit": ("rad/s", "rpm"),
            "duplicates": ("drop", "error"),
            "separator": ("auto", ",", ";"),
            "speed_check": ("refuse", "warn"),
            "short_segments": ("refuse", "drop"),
        }
        for name, allowed in choices.items():
            v = getattr(self, name)
            if v not in allowed:
                flag = "--" + name.replace("_", "-")
                raise ValueError(f"{flag} {v!r}: allowed: {', '.join(allowed)}")
        time_zone(self.timezone)  # ValueError naming --timezone
        positive = [
            "window",
            "gap_limit",
            "max_speed",
            "speed_tolerance",
            "stop_speed",
            "stop_duration",
        ]
        if self.angle_unit == "counts" or self.counts_per_rev is not None:
            positive.append("counts_per_rev")
        for name in positive:
            v = getattr(self, name)
            flag = "--" + name.replace("_", "-")
            if v is None and name == "counts_per_rev":
                raise ValueError("--counts-per-rev must be given (> 0) with --angle-unit counts")
            if v is None:
                continue
            if not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"{flag} {v!r}: must be a finite number > 0")


SUMMARY_FIELDS = (
    "revolution",
    "start_time",
    "mean_speed",
    "speed_fluctuation",
    "acceleration_max",
    "acceleration_min",
    "inertia_force_max",
    "inertia_force_min",
    "guide_friction_max",
    "guide_friction_min",
    "rod_force_max",
    "rod_force_min",
    "crank_torque_max",
    "crank_torque_min",
    "friction_work",
    "stroke",
    "rod_angle_amplitude",
    "stress_max",
    "interrupted",
    # A pump's (docs/twin.md "Output"): the time means of fluid_end.flow, fluid_end.hydraulic_power and
    # crank.mechanical_power over the revolution and the flow pulsation (Q_max − Q_min)/Q_mean.
    "flow_mean",
    "flow_pulsation",
    "hydraulic_power_mean",
    "mechanical_power_mean",
)

#: The unit of each of SUMMARY_FIELDS ("-": a count or a ratio), written in the CSV header as
#: `name [unit]` (docs/twin.md "Output").
SUMMARY_UNITS = {
    "revolution": "-",
    "start_time": "s",
    "mean_speed": "rad/s",
    "speed_fluctuation": "-",
    "friction_work": "J",
    "stroke": "m",
    "rod_angle_amplitude": "rad",
    "stress_max": "Pa",
    "interrupted": "-",
    "flow_mean": "m3/s",
    "flow_pulsation": "-",
    "hydraulic_power_mean": "W",
    "mechanical_power_mean": "W",
    **{
        f"{k}_{m}": u
        for k, u in (
            ("acceleration", "m/s2"),
            ("inertia_force", "N"),
            ("guide_friction", "N"),
            ("rod_force", "N"),
            ("crank_torque", "N.m"),
        )
        for m in ("max", "min")
    },
}


def with_unit(name: str, unit: str | None) -> str:
    """A CSV column header: `name [unit]` (docs/twin.md "Output"); `[-]` without a unit."""
    return f"{name} [{unit or '-'}]"


def column_name(header: str) -> str:
    """The name of a column header written by `with_unit` (or a plain name)."""
    name, sep, rest = header.rpartition(" [")
    return name if sep and rest.endswith("]") else header


def summary_header() -> list[str]:
    return [with_unit(f, SUMMARY_UNITS[f]) for f in SUMMARY_FIELDS]


#: Outputs the twin itself reads (the revolutions and the summaries).
_NEEDED_OUTPUTS = (
    "crank.model_angle",
    "crank.model_speed",
    "suspension.position",
    "suspension.acceleration",
)

_EXTREMES = (
    ("suspension.acceleration", "acceleration"),
    ("inertia.force", "inertia_force"),
    ("guide.friction", "guide_friction"),
    ("rod.force", "rod_force"),
    ("crank.torque", "crank_torque"),
)
#: The column of revolution_table behind each of SUMMARY_FIELDS.
_EXTREME_KEYS = {f"{key}_{m}": f"{q}.{m}" for q, key in _EXTREMES for m in ("max", "min")}
_SUMMARY_KEYS = tuple(_EXTREME_KEYS.get(f, f) for f in SUMMARY_FIELDS)


#: A number as the twin reads it (docs/twin.md "Input"): ASCII decimal digits, an optional sign,
#: point and exponent, and the words inf/nan (refused as not finite). Python's float() alone also
#: takes `1_0` (as 10) and non-ASCII digits; Rust's parser (the native reader) takes neither.
def _process_rows(saved) -> np.ndarray:
    """A checkpoint's buffered process values as rows of PROCESS_COLUMNS: a checkpoint written
    before the pressure columns holds the process force alone (its pressures: the machine's)."""
    a = np.array(saved, dtype=float)
    if a.ndim == 1:
        return np.column_stack([a, np.full((len(a), len(PROCESS_COLUMNS) - 1), math.nan)])
    return a.reshape(-1, len(PROCESS_COLUMNS))


def remainder_2pi(x: np.ndarray) -> np.ndarray:
    """math.remainder(x, 2π) elementwise (IEEE remainder: exact, ties to an even quotient)."""
    r = np.fmod(x, TWO_PI)
    r = np.where(r > math.pi, r - TWO_PI, np.where(r < -math.pi, r + TWO_PI, r))
    for i in np.flatnonzero(np.abs(r) == math.pi):
        r[i] = math.remainder(float(x[i]), TWO_PI)
    return r


@dataclass
class _Segment:
    """Samples of the current segment whose outputs are not computed yet, with the window
    history before them."""

    t: np.ndarray = field(default_factory=lambda: np.empty(0))
    theta: np.ndarray = field(default_factory=lambda: np.empty(0))
    speed: np.ndarray = field(default_factory=lambda: np.empty(0))  # NaN: not measured
    # process_force and the pressures (PROCESS_COLUMNS), one row per sample
    force: np.ndarray = field(default_factory=lambda: np.empty((0, len(PROCESS_COLUMNS))))
    line: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    done: int = 0  # samples of the buffer already sent to the FMU
    segment_start: bool = True
    t0: float = math.nan  # time of the segment's first sample (the buffer may start later)

    NAMES = ("t", "theta", "speed", "force", "line")

    def append(self, **arrays) -> None:
        if math.isnan(self.t0) and len(arrays["t"]):
            self.t0 = float(arrays["t"][0])
        for name in self.NAMES:
            setattr(self, name, np.concatenate((getattr(self, name), arrays[name])))

    def drop(self, k: int) -> None:
        for name in self.NAMES:
            setattr(self, name, getattr(self, name)[k:])
        self.done -= k


class Twin:
    """One twin run. `feed(lines, first_lineno)` takes consecutive input lines; it returns the
    output rows now ready (a 2-D array: time then the FMU's outputs) and the revolution summaries
    now complete. `finish()` flushes the rest at the end of the input.

    With `defer_summaries` set, `feed` and `finish` return, instead of the summaries, the pieces
    they are made from, and `summaries(pieces)` makes them: on another thread, in order, while
    this one goes on with the next input (scripts/twin.py does so). The revolution state is then
    only touched by `summaries`, so the caller takes `checkpoint()` only once every piece handed
    out has been summarized (feed and finish hand out all they emitted)."""

    def __init__(
        self,
        fmu_path: str,
        machine: str = "default",
        options: Options | None = None,
        extra_values: dict | None = None,
    ):
        self.machine = machine
        try:
            preset = preset_values(machine)
        except KeyError:
            raise ValueError(
                f"--machine {machine!r}: no such machine; allowed: "
                f"{', '.join(available_presets())} or an .ssv file"
            ) from None
        except Exception as e:  # an .ssv file that fmpy cannot read
            raise ValueError(f"--machine {machine!r}: not a readable .ssv file ({e})") from None
        self.values = {k: v for k, v in preset.items() if k not in INPUTS}
        self.values.update(extra_values or {})
        # The pressures where the input has no column: the machine's (docs/twin.md "Input").
        self.pressures = np.array(
            [float({**preset, **(extra_values or {})}.get(n, 0.0)) for n in INPUTS[4:]],
            dtype=float,
        )
        try:
            # An Fmu already loaded is taken as it is: the distributed replay (replay.py) runs
            # many pieces in one worker process, and loading costs more than a small piece.
            self.fmu = fmu_path if isinstance(fmu_path, Fmu) else Fmu(fmu_path)
        except Exception as e:  # not a zip, not an FMU, no binary for this platform
            raise ValueError(f"--fmu {str(fmu_path)!r}: not a usable FMU ({e})") from None
        self.outputs = list(self.fmu.outputs)
        missing = [n for n in (*INPUTS, "crank.speed") if n not in self.fmu.vr]
        missing += [n for n in _NEEDED_OUTPUTS if n not in self.outputs]
        if missing:
            raise ValueError(
                f"--fmu {str(fmu_path)!r}: not the ReciprocatingDrive FMU (it has no "
                f"{', '.join(missing)})"
            )
        self.design_speed = float(
            preset.get("crank.speed", self.fmu.variables["crank.speed"].start)
        )
        if not (math.isfinite(self.design_speed) and self.design_speed > 0):
            raise ValueError(f"--machine {machine!r}: crank.speed {self.design_speed!r} is not > 0")
        self.o = (options or Options()).resolved(self.design_speed)
        self.o.validate()
        self.i_angle = 1 + self.outputs.index("crank.model_angle")
        self.i_speed = 1 + self.outputs.index("crank.model_speed")
        self.channel = None
        self.cols = None
        self.separator = ","  # of the input's fields: ',' or ';' (decimal comma), from the header
        # The time column's format, from the first sample: "number" (seconds) or "iso" (ISO 8601
        # timestamps, read by `clock`; docs/twin.md "Timestamps"); None before it.
        self.time_kind: str | None = None
        self.clock: Clock | None = None
        self.iso_line = None  # the line of the first timestamp
        self._slack_tables: dict = {}
        self.buf = _Segment()
        self.last_raw = None  # previous accepted raw angle (rad), unwrapped angle, time
        self.last_unwrapped = None
        self.last_t = None
        self.duplicates = 0
        self.speed_ignored = 0  # measured speeds ignored (--speed-check warn)
        self.gaps: list = []
        self.rev_parts: list = []  # rows of the revolution in progress (and the sample before it)
        self.rev_next = None  # index of the next revolution to complete
        self.rev_dropped = 0  # its samples left out to bound the memory (REV_SAMPLES_MAX)
        # Machine state (docs/twin.md "Machine states"): the state (1 running, 0 stopped, -1
        # reversing; None before the first sample), the candidate state, the time and line it
        # began; the last MOTION_KEEP events [kind, time, line] of the changes and their count
        # (a twin that runs for months keeps a bounded list).
        self.motion: list | None = None
        self.motion_events: list = []
        self.motion_count = 0
        self.defer_summaries = False
        self._pending: list = []  # rows for the summaries, None where a segment starts
        self.lines_read = 0  # input lines consumed (header included)
        self.rows_out = 0
        self.messages: list = []
        #: The message of each gap found in this process, by (t0, t1) (gaps holds them all).
        self.gap_notes: dict = {}
        #: (first line, samples) of each segment left out as too short (Options.short_segments).
        self.short_dropped: list = []
        #: Sparse stretches, consecutive samples whose smoothing window holds fewer than
        #: cond.MIN_SAMPLES samples: [first line, first time, last time, samples, fewest in a
        #: window], the last one still growing while `sparse_open`.
        self.sparse: list = []
        self.sparse_open = False

    @property
    def header(self) -> list[str]:
        return ["time", *self.outputs]

    @property
    def units(self) -> list[str]:
        """The unit of each column of `header` (the FMU's declared units)."""
        return ["s", *(self.fmu.variables[n].unit or "-" for n in self.outputs)]

    def header_with_units(self) -> list[str]:
        """`header` as the CSV writes it: `name [unit]` (docs/twin.md "Output")."""
        return [with_unit(n, u) for n, u in zip(self.header, self.units)]

    def _empty(self) -> np.ndarray:
        return np.empty((0, 1 + len(self.outputs)))

    # ---- reading -------------------------------------------------------------------------------

    def feed(self, lines: list[str], first_lineno: int) -> tuple[np.ndarray, list]:
        """Lines first_lineno, first_lineno + 1, ... of the input. On bad data the samples before
        it are processed and DataError carries their rows and summaries (pieces, when deferred)."""
        rows = [self._empty()]
        if lines and self.cols is None:
            sep = self.o.separator
            if sep == "auto":
                sep = detect_separator(lines[0])
            self.separator = sep
            self.cols = parse_header(lines[0], sep)
            if sep == ";":
                self.messages.append(
                    "the input is ';'-separated: a decimal comma is read as a decimal point"
                )
            lines, first_lineno = lines[1:], first_lineno + 1
        if self.separator == ";" and lines:
            lines = "\n".join(lines).translate(_EUROPEAN).split("\n")
        self.lines_read = first_lineno + len(lines) - 1
        lines, time_err = self._timestamps(lines, first_lineno)
        if not lines:
            return self._hand_out(rows, time_err)
        samples, err = parse_lines(lines, first_lineno, self.cols)
        err = err or time_err
        try:
            err = self._accept_samples(samples, rows) or err
        except (DataError, FmuError) as e:
            err = e
        return self._hand_out(rows, err)

    def _accept_samples(self, s: Samples, rows) -> DataError | None:
        """`_accept` of numbered samples (an optional column the input has not: its default)."""
        return self._accept(
            s.line,
            s.columns["time"],
            s.columns["crank_angle"],
            s.value("crank_speed"),
            np.column_stack([s.value(c) for c in PROCESS_COLUMNS]),
            rows,
        )

    def feed_samples(self, samples: Samples, first_lineno: int) -> tuple[np.ndarray, list]:
        """`feed` for samples given as numbers (a source of numbers: OPC UA), the first of them
        numbered `first_lineno` (after the header line the input's CSV form would start with,
        when these are the run's first samples) unless `samples.line` numbers them. The same
        checks and the same results as `feed` of the samples written as CSV lines with `repr`,
        bit for bit, with no text in between."""
        rows = [self._empty()]
        n = len(samples)
        if n and self.cols is None:
            # The columns the CSV form's header would name; the header is its line 1.
            self.separator = ","
            self.cols = parse_header(",".join(samples.names()))
            first_lineno += 1
        ln = (
            samples.line
            if samples.line is not None
            else np.arange(first_lineno, first_lineno + n, dtype=np.int64)
        )
        if n:
            self.lines_read = int(ln[-1])
        if n and self.time_kind is None:
            # Numbers, not ISO 8601 timestamps (the CSV path decides this at its first sample).
            self.time_kind = "number"
            if self.o.timezone is not None:
                self.messages.append(
                    f"--timezone {self.o.timezone} is not used: the input's times are "
                    "numbers (seconds), not timestamps"
                )
        # What the CSV reader refuses in a field (parse_line): a missing value, which the CSV form
        # writes empty, and a value that is not finite; the samples before it are computed.
        names = samples.names()
        values = [samples.columns[c] for c in names]
        bad = np.flatnonzero(~np.isfinite(np.stack(values)).all(axis=0)) if n else []
        err = None
        if len(bad):
            k = int(bad[0])
            name = next(c for c, v in zip(names, values) if not math.isfinite(v[k]))
            v = float(samples.columns[name][k])
            what = (
                f"{name} is empty (a number is needed)"
                if math.isnan(v) and name in OPTIONAL
                else f"{name} = {repr(v)!r} is not a finite number"
            )
            err = DataError(f"line {ln[k]}: {what}")
            n = k
        try:
            ok = Samples({c: v[:n] for c, v in samples.columns.items()}, ln[:n])
            err = self._accept_samples(ok, rows) or err
        except (DataError, FmuError) as e:
            err = e
        return self._hand_out(rows, err)

    @property
    def time_origin(self) -> float | None:
        """Unix seconds of the twin's time 0 when the input's times are timestamps, else None."""
        return self.clock.origin if self.clock is not None else None

    def _timestamps(
        self, lines: list[str], first_lineno: int
    ) -> tuple[list[str], DataError | None]:
        """The lines with ISO 8601 time fields replaced by seconds from the origin (the format is
        detected at the first sample, as the decimal comma is from the header). Returns the lines
        before the first bad timestamp and its DataError (or None). A line with the wrong number
        of fields is passed on as it is: the reader reports it."""
        if self.time_kind == "number" or not lines:
            return lines, None
        col, nf = self.cols["time"], n_fields(self.cols)
        out: list[str] = []
        for i, line in enumerate(lines):
            parts = line.split(",")
            if not line.strip() or len(parts) != nf:
                out.append(line)
                continue
            raw = parts[col]
            lineno = first_lineno + i
            if self.time_kind is None:
                if not LOOKS_ISO.match(raw):
                    self.time_kind = "number"
                    if self.o.timezone is not None:
                        self.messages.append(
                            f"--timezone {self.o.timezone} is not used: the input's times are "
                            "numbers (seconds), not timestamps"
                        )
                    return out + lines[i:], None
                self.time_kind, self.clock, self.iso_line = "iso", Clock(self.o.timezone), lineno
            repeated = self.clock.repeated_hour
            try:
                t = self.clock.seconds(raw)
            except TimestampError as e:
                what = (
                    f"time = {raw.strip()!r} is a number, but the input's times are ISO 8601 "
                    f"timestamps (from line {self.iso_line}): one format per input"
                    if _NUMBER.fullmatch(raw.strip())
                    else f"time = {e}"
                )
                return out, DataError(f"line {lineno}: {what}")
            if lineno == self.iso_line:
                zone_note = (
                    f"; timestamps without an offset are local times in {self.o.timezone}"
                    if self.o.timezone
                    else ""
                )
                self.messages.append(
                    f"the input's times are ISO 8601 timestamps: time is in seconds from "
                    f"{self.clock.origin_text()} (line {lineno}){zone_note}"
                )
            if self.clock.repeated_hour and not repeated:
                self.messages.append(
                    f"line {lineno}: {raw.strip()!r} is in the hour that {self.o.timezone} repeats "
                    "when daylight-saving time ends: read as the first time not before the sample "
                    "before it"
                )
            parts[col] = repr(t)
            out.append(",".join(parts))
        return out, None

    def _accept(self, ln, t, a, w, f, rows) -> DataError | None:
        """Validates, unwraps and conditions parsed samples; returns the first DataError of the
        checks that depend on the previous samples, after processing the samples before it."""
        o = self.o
        a = cond.to_radians(a, o.angle_unit, o.counts_per_rev)
        if not o.use_measured_speed:
            w = np.full(len(w), math.nan)
        elif o.speed_unit == "rpm":
            w = w * TWO_PI / 60.0
        n = len(t)
        err = None
        if n == 0:
            return err
        # Magnitudes beyond which a double no longer resolves a 1 kHz sample or a sample's step
        # of the angle (docs/twin.md "Input"): refused, not computed with lost digits.
        with np.errstate(invalid="ignore"):
            big = np.flatnonzero((np.abs(t) > TIME_LIMIT) | (np.abs(a) > ANGLE_LIMIT))
        if big.size:
            k = int(big[0])
            name, v, lim, unit = (
                ("time", t[k], TIME_LIMIT, "s")
                if abs(t[k]) > TIME_LIMIT
                else ("crank_angle", a[k], ANGLE_LIMIT, "rad")
            )
            err = DataError(
                f"line {ln[k]}: {name} = {float(v):.6g} {unit} is beyond ±{lim:.6g} {unit}, "
                "where a double no longer resolves the samples"
            )
            ln, t, a, w, f = (x[:k] for x in (ln, t, a, w, f))
            n = k
            if n == 0:
                return err
        # Intervals to the previous line (time never goes backwards up to the first error, so the
        # previous accepted sample of a line is the line before it, duplicates included).
        prev = (
            np.concatenate(([self.last_t], t[:-1]))
            if self.last_t is not None
            else np.concatenate(([math.nan], t[:-1]))
        )
        with np.errstate(invalid="ignore"):
            back = np.flatnonzero(t < prev)
            dup = np.flatnonzero(t == prev)
        stop = n
        if back.size:
            k = stop = int(back[0])
            err = DataError(
                f"line {ln[k]}: time {float(t[k])!r} s goes backwards (previous sample at {float(prev[k])!r} s)"
            )
        dup = dup[dup < stop]
        if dup.size and o.duplicates == "error":
            k = stop = int(dup[0])
            err = DataError(f"line {ln[k]}: duplicate timestamp {float(t[k])!r} s")
            dup = dup[:0]
        keep = np.ones(stop, dtype=bool)
        keep[dup] = False
        self.duplicates += int(dup.size)
        ln, t, a, w, f = (
            ln[:stop][keep],
            t[:stop][keep],
            a[:stop][keep],
            w[:stop][keep],
            f[:stop][keep],
        )
        if len(t) == 0:
            return err
        # Unwrap: each step is the smallest one modulo a revolution.
        first = self.last_t is None
        if o.wrapped:
            steps = remainder_2pi(np.diff(a, prepend=a[0] if first else self.last_raw))
            theta = np.cumsum(
                np.concatenate(
                    ([a[0] if first else self.last_unwrapped], steps[1:] if first else steps)
                )
            )
            theta = theta if first else theta[1:]
        else:
            theta = a
        tp = np.concatenate(([t[0] if first else self.last_t], t[:-1]))
        thp = np.concatenate(([theta[0] if first else self.last_unwrapped], theta[:-1]))
        dt, dth = t - tp, theta - thp
        near = dt <= o.gap_limit
        bad = np.flatnonzero(near & (np.abs(dth) > o.max_speed * dt + 1e-9))
        if bad.size and (err is None or bad[0] < len(t)):
            k = int(bad[0])
            err = DataError(
                f"line {ln[k]}: the crank angle moves {float(dth[k]):.6g} rad in {float(dt[k]):.6g} s "
                f"(more than the largest possible crank speed, --max-speed {o.max_speed:g} rad/s, allows)"
            )
            ln, t, theta, w, f, dt, near, dth = (x[:k] for x in (ln, t, theta, w, f, dt, near, dth))
            a = a[:k]
        # A step backwards is a state of the machine (a stop that rocks back, an encoder dithering
        # at standstill, a crank jogged backwards), not an error: docs/twin.md "Machine states".
        if len(t) == 0:
            return err
        # Segments: a gap (an interval longer than gap_limit) starts a new one.
        gaps = [k for k in np.flatnonzero(dt > o.gap_limit).tolist() if not (first and k == 0)]
        # A gap at the first sample of a chunk starts the first piece: reported once.
        starts = [0, *gaps] if not gaps or gaps[0] != 0 else gaps
        for lo, hi in zip(starts, [*starts[1:], len(t)]):
            if lo in gaps:
                t0, t1 = (self.last_t if lo == 0 else float(t[lo - 1])), float(t[lo])
                self.gaps.append((t0, t1))
                note = (
                    f"gap of {t1 - t0:.6g} s from t = {t0!r} s to {t1!r} s (line {ln[lo]}): "
                    "the FMU is re-initialized after it"
                )
                self.messages.append(note)
                self.gap_notes[(t0, t1)] = note
                self._drain(True, rows)
                self.buf = _Segment()
            if hi > lo:
                self.buf.append(
                    t=t[lo:hi], theta=theta[lo:hi], speed=w[lo:hi], force=f[lo:hi], line=ln[lo:hi]
                )
                self.last_raw, self.last_unwrapped, self.last_t = (
                    float(a[hi - 1]),
                    float(theta[hi - 1]),
                    float(t[hi - 1]),
                )
        self._drain(False, rows)
        return err

    def finish(self) -> tuple[np.ndarray, list]:
        """Flushes the samples still waiting for their window at the end of the input. An input
        without a header or without a single sample is an error (DataError)."""
        if self.cols is None:
            raise DataError("the input is empty (no header, no sample)")
        if self.last_t is None:
            raise DataError("the input has no sample (only the header)")
        rows, err = [self._empty()], None
        try:
            self._drain(True, rows)
        except (DataError, FmuError) as e:
            err = e
        return self._hand_out(rows, err)

    def _hand_out(self, rows: list, err: Exception | None) -> tuple[np.ndarray, list]:
        """The rows emitted and their summaries; with an error, raises it carrying them."""
        parts = [r for r in rows if len(r)] or rows[:1]
        # One block (the usual case) goes out as it is: nothing writes to it any more.
        out = (parts[0] if len(parts) == 1 else np.concatenate(parts)), self._take_summaries()
        if err is not None:
            err.rows, err.summaries = out
            raise err
        return out

    def _emit(self, r: np.ndarray, rows: list, lines: np.ndarray | None = None) -> None:
        rows.append(r)
        if len(r):
            self._pending.append(r)
            self._follow_motion(r[:, 0], r[:, self.i_speed], lines)

    @property
    def machine_state(self) -> str | None:
        """running, stopped or reversing (docs/twin.md "Machine states"); None before a sample."""
        return None if self.motion is None else MOTION_STATES[self.motion[0]]

    def _follow_motion(self, t: np.ndarray, w: np.ndarray, lines) -> None:
        """The machine state through these samples (time, the speed the FMU got): a class per
        sample (running at ω ≥ stop_speed, reversing at ω ≤ -stop_speed, else stopped); a class
        other than the state's becomes the state once it has held for stop_duration, from its
        first sample (the event's time). Loops over the runs of equal class only."""
        thr = self.o.stop_speed * TWO_PI / 60.0
        cls = np.where(w >= thr, 1, np.where(w <= -thr, -1, 0))
        if lines is None:
            lines = np.full(len(t), -1)
        if self.motion is None:
            # The first sample's class is the state the record starts in (no event).
            self.motion = [int(cls[0]), int(cls[0]), float(t[0]), int(lines[0])]
        state, cand, t0, l0 = self.motion
        change = (np.flatnonzero(np.diff(cls)) + 1).tolist()
        for a, b in zip([0, *change], [*change, len(cls)]):
            c = int(cls[a])
            if c != cand:
                cand, t0, l0 = c, float(t[a]), int(lines[a])
            if cand != state and float(t[b - 1]) - t0 >= self.o.stop_duration:
                state = cand
                self.motion_events.append([MOTION_EVENTS[state], t0, l0])
                self.motion_events = self.motion_events[-MOTION_KEEP:]
                self.motion_count += 1
        self.motion = [state, cand, t0, l0]

    def motion_message(self, ev) -> str:
        """The one-line report of a motion event [kind, time, line]."""
        kind, t0, line = ev
        rule = {
            "stopped": f"|crank speed| below {self.o.stop_speed:g} rpm",
            "started": f"crank speed at or above {self.o.stop_speed:g} rpm",
            "reversed": f"crank speed at or below -{self.o.stop_speed:g} rpm",
        }[kind]
        where = f" (line {line})" if line >= 0 else ""
        return f"t = {t0!r} s{where}: {kind} ({rule} for {self.o.stop_duration:g} s)"

    def _take_summaries(self) -> list:
        """The summaries of what was emitted since the last call (or its pieces, when deferred)."""
        pieces, self._pending = self._pending, []
        return pieces if self.defer_summaries else self.summaries(pieces)

    def summaries(self, pieces: list) -> list:
        """Summaries of the revolutions completed by these pieces (rows; None starts a segment)."""
        out = []
        for r in pieces:
            if r is None:
                self.rev_parts, self.rev_next, self.rev_dropped = [], None, 0
            else:
                out += self._revolutions(r)
        return out

    # ---- conditioning and the FMU ---------------------------------------------------------------

    def _ready(self, final: bool) -> int:
        """The number of leading samples of the buffer whose smoothing window is complete: all
        of them when the segment ends; else those whose window no later sample can change
        (cond.complete, docs/twin.md "Conditioning")."""
        b = self.buf
        n = len(b.t)
        if final or n == 0:
            return n
        return b.done + cond.complete(b.t, 0.5 * self.o.window, b.t0, b.done)

    def _keep_from(self) -> int:
        """The first sample of the buffer that a window not yet computed can reach
        (cond.window): the window of a sample to come starts half a window before it, or the
        longest interval (at most the gap limit) and the sample before further where a dropout
        left that side short, or a window before the last sample read (shifted inward at the
        segment's end), or SPARSE_REACH samples before it (sparse)."""
        b = self.buf
        n = len(b.t)
        if n == 0:
            return 0
        half = 0.5 * self.o.window
        ref = float(b.t[min(b.done, n - 1)])
        reach = min(ref - half - self.o.gap_limit, float(b.t[-1]) - 2.0 * half)
        k = int(np.searchsorted(b.t, reach, side="left")) - 1
        return max(0, min(k, b.done - cond.SPARSE_REACH))

    def _drain(self, final: bool, rows: list) -> None:
        """Emits into `rows` the outputs of the samples whose smoothing window is complete (all of
        them when the segment ends), in blocks of at most BLOCK. When the FMU fails, the samples
        before the failing one are emitted before the error goes on."""
        b = self.buf
        n = len(b.t)
        ready = self._ready(final)
        if ready <= b.done:
            if not final and n - b.done > MAX_WINDOW_SAMPLES:
                self._too_wide(int(b.line[b.done]), n - b.done)
            if final:
                self._close_sparse()
            return
        if n < cond.DEGREE + 1 and final and self.o.short_segments == "drop":
            self.short_dropped.append((int(b.line[0]), n))
            b.done = n
            return
        if n < cond.DEGREE + 1:
            raise DataError(
                f"line {b.line[0]}: a segment of {n} sample(s) between gaps is too short "
                f"(at least {cond.DEGREE + 1} are needed)"
            )
        half = 0.5 * self.o.window
        t_end = float(b.t[-1]) if final else math.inf
        for lo in range(b.done, ready, BLOCK):
            centres = np.arange(lo, min(ready, lo + BLOCK))
            # Refused before the fits, which cost the window's samples each.
            tc = b.t[centres]
            wide = np.searchsorted(b.t, tc + half, "right") - np.searchsorted(b.t, tc - half)
            if int(wide.max()) > MAX_WINDOW_SAMPLES:
                self._too_wide(int(b.line[lo]), int(wide.max()))
            w_est, e_est, inside = local_cubic(b.t, b.theta, half, lo, len(centres), b.t0, t_end)
            self._note_sparse(inside, b.line[centres], b.t[centres])
            w_meas = b.speed[centres]
            err = None
            # Samples too close in time for a double (1e-300 s apart: a wrong time unit) give
            # no finite estimate; refused, as a time a double cannot resolve is.
            nonfinite = np.flatnonzero(~(np.isfinite(w_est) & np.isfinite(e_est)))
            if nonfinite.size:
                k = int(nonfinite[0])
                err = DataError(
                    f"line {int(b.line[centres[k]])}: the speed and acceleration at "
                    f"t = {float(b.t[centres[k]])!r} s are not finite numbers: the samples of "
                    "its smoothing window lie too close in time (check the time unit)"
                )
                centres, w_est, e_est, w_meas = (x[:k] for x in (centres, w_est, e_est, w_meas))
                if k == 0:
                    raise err
            # A measured speed is checked against the angle's own rate (docs/twin.md "Measured
            # speed"): a wrong unit or sign would otherwise go straight into the loads.
            slack = SPEED_SLACK + self._resolution_slack(
                b.t[centres], inside[: len(centres)], float(b.t0), t_end
            )
            with np.errstate(invalid="ignore"):
                off = np.abs(w_meas - w_est) > self.o.speed_tolerance * np.abs(w_est) + slack
            bad = np.flatnonzero(off)
            if bad.size and self.o.speed_check == "warn":
                if not self.speed_ignored:
                    k = int(bad[0])
                    self.messages.append(
                        f"line {int(b.line[centres[k]])}: crank_speed {float(w_meas[k]):.6g} rad/s "
                        f"contradicts the angle's rate {float(w_est[k]):.6g} rad/s: ignored there "
                        "and wherever else it does (--speed-check warn)"
                    )
                self.speed_ignored += int(bad.size)
                w_meas = np.where(off, math.nan, w_meas)
            elif bad.size:
                k = int(bad[0])
                err = DataError(
                    f"line {int(b.line[centres[k]])}: crank_speed = {float(w_meas[k]):.6g} rad/s "
                    f"contradicts the crank angle, which turns at {float(w_est[k]):.6g} rad/s "
                    f"(allowed: within {self.o.speed_tolerance:.0%} of it + {SPEED_SLACK:g} rad/s; "
                    "check --speed-unit, or --speed-check warn, or --ignore-speed)"
                )
                centres, w_est, e_est, w_meas = (x[:k] for x in (centres, w_est, e_est, w_meas))
                if k == 0:
                    raise err
            w = np.where(np.isnan(w_meas), w_est, w_meas)
            fp = b.force[centres]
            fp = np.column_stack(
                [fp[:, 0], np.where(np.isnan(fp[:, 1:]), self.pressures, fp[:, 1:])]
            )
            inputs = np.column_stack([b.theta[centres], w, e_est, fp])
            block = np.empty((len(centres), 1 + len(self.outputs)))
            block[:, 0] = b.t[centres]
            try:
                self._fmu_rows(block, inputs, b.segment_start and lo == 0)
            except FmuError as e:
                k = getattr(e, "index", 0)
                self._emit(block[:k], rows, b.line[centres[:k]])
                if k < len(centres):
                    e.args = (
                        f"line {int(b.line[centres[k]])} (t = {float(b.t[centres[k]])!r} s): {e}",
                    )
                raise
            self._emit(block, rows, b.line[centres])
            b.done = int(centres[-1]) + 1
            if err is not None:
                raise err
        if final:
            self._close_sparse()
        # Keep only what later windows can still reach.
        keep_from = self._keep_from()
        if keep_from > 0:
            b.drop(keep_from)
            b.segment_start = False

    def _resolution_slack(self, tc: np.ndarray, inside: np.ndarray, t0: float, t_end: float):
        """What the angle's resolution can add to ω̂ at samples at times tc [rad/s] (docs/twin.md
        "Measured speed"): an encoder's angle is within half a count h of the truth, so the local
        cubic's ω̂ is within (h/2)·Σ|c_j| of the truth's, c_j the weights of ω̂ at the sample's
        place in its window: `inside` samples spread evenly over the window, which shifts inward
        near a segment's ends (from t0 to t_end), where the sum is largest. 0 for angles in rad or
        deg (no known resolution)."""
        if self.o.angle_unit != "counts":
            return np.zeros(len(tc))
        w = self.o.window
        start = np.maximum(t0, np.minimum(tc - 0.5 * w, t_end - w))
        m = np.maximum(inside, cond.MIN_SAMPLES).astype(np.int64)
        pos = np.clip(np.rint((tc - start) / w * (m - 1)), 0, m - 1).astype(np.int64)
        h = TWO_PI / self.o.counts_per_rev
        out = np.empty(len(tc))
        for key in set(zip(m.tolist(), pos.tolist())):
            if key not in self._slack_tables:
                mm, p = key
                # ω̂ = c1 of the cubic fitted on x = j - p (in sample spacings): its weights are
                # row 1 of (VᵀV)⁻¹Vᵀ, scaled by the spacing w/(m-1); x scaled to [-1, 1] first.
                x = np.arange(mm, dtype=float) - p
                sc = max(1.0, float(np.max(np.abs(x))))
                v = np.vander(x / sc, 4, True)
                c = np.linalg.solve(v.T @ v, v.T)[1] / sc
                if len(self._slack_tables) > 4096:
                    self._slack_tables.clear()
                self._slack_tables[key] = 0.5 * h * float(np.sum(np.abs(c)))
            sel = (m == key[0]) & (pos == key[1])
            out[sel] = self._slack_tables[key] * (m[sel] - 1) / w
        return out

    def _too_wide(self, line: int, samples: int) -> None:
        raise DataError(
            f"line {line}: the --window {self.o.window:g} s smoothing window holds {samples} "
            f"samples or more (at most {MAX_WINDOW_SAMPLES}): check the time unit or --window"
        )

    def _note_sparse(self, inside: np.ndarray, line: np.ndarray, t: np.ndarray) -> None:
        """Records the samples (in order) whose window holds fewer than cond.MIN_SAMPLES samples
        as sparse stretches (docs/twin.md "Conditioning"): consecutive ones, across calls, make
        one, reported in `messages` once it ends."""
        k = np.flatnonzero(inside < cond.MIN_SAMPLES)
        if k.size == 0 or k[0] > 0:
            self._close_sparse()
        for run in np.split(k, np.flatnonzero(np.diff(k) > 1) + 1) if k.size else []:
            i, j = int(run[0]), int(run[-1])
            fewest = int(inside[run].min())
            if self.sparse_open:  # continues the stretch of the previous call
                last = self.sparse[-1]
                last[2], last[3], last[4] = float(t[j]), last[3] + len(run), min(last[4], fewest)
            else:
                self.sparse.append([int(line[i]), float(t[i]), float(t[j]), len(run), fewest])
                self.sparse_open = True
            if j < len(inside) - 1:
                self._close_sparse()

    def _close_sparse(self) -> None:
        if self.sparse_open:
            self.sparse_open = False
            self.messages.append(self.sparse_message(self.sparse[-1]))

    def sparse_message(self, s: list) -> str:
        """The data-health message of a sparse stretch (an entry of `sparse`)."""
        line, t0, t1, n, fewest = s
        return (
            f"sparse data: the smoothing window (±{0.5 * self.o.window:g} s) of {n} sample(s) "
            f"from t = {t0!r} s to {t1!r} s (line {line}) holds as few as {fewest} sample(s), "
            f"fewer than {cond.MIN_SAMPLES}: their speed and acceleration come from the "
            f"{cond.MIN_SAMPLES} samples nearest to each"
        )

    def _fmu_rows(self, rows, inputs, new_segment) -> None:
        """Outputs into rows[:, 1:] for the inputs at the times rows[:, 0]."""
        first = 0
        if new_segment or self.channel is None:
            self.fmu.start(
                {**self.values, **dict(zip(INPUTS, map(float, inputs[0])))},
                start_time=float(rows[0, 0]),
            )
            self.channel = self.fmu.channel(list(INPUTS), self.outputs)
            self.channel.read(rows[0, 1:])
            self._pending.append(None)  # the summaries start again with this segment
            self.rows_out += 1
            first = 1
        try:
            self.channel.run(rows[first:, 0], inputs[first:], rows[first:, 1:])
        except FmuError as e:
            e.index = first + e.index
            self.rows_out += e.index - first
            raise
        self.rows_out += len(rows) - first

    def _revolutions(self, rows: np.ndarray) -> list:
        """Summaries of the revolutions of the model angle completed by these rows."""
        if len(rows) == 0:
            return []
        ang = rows[:, self.i_angle]
        if self.rev_next is None:
            self.rev_next = math.ceil(ang[0] / TWO_PI)  # the first revolution starts there
        self.rev_parts.append(rows)
        last = self.rev_next
        top = float(np.max(ang))
        while TWO_PI * (last + 1) <= top:
            last += 1
        if last == self.rev_next:
            # Once reduced, a revolution is reduced at every chunk: its rows stay few.
            if self.rev_dropped or sum(map(len, self.rev_parts)) > REV_SAMPLES_MAX + 3:
                self._reduce_revolution()
            return []
        arr = np.concatenate(self.rev_parts)
        series = {name: arr[:, 1 + i] for i, name in enumerate(self.outputs)}
        tab = revolution_table(
            arr[:, 0],
            arr[:, self.i_angle],
            series,
            speed=series["crank.model_speed"],
            stop_speed=self.o.stop_speed * TWO_PI / 60.0,
        )
        pick = (tab["revolution"] >= self.rev_next) & (tab["revolution"] < last)
        n = int(np.count_nonzero(pick))
        samples = tab["samples"][pick]
        if n and tab["revolution"][pick][0] == self.rev_next:
            samples[0] += self.rev_dropped
        columns = [tab[key][pick].tolist() if key in tab else [None] * n for key in _SUMMARY_KEYS]
        out = [dict(zip(SUMMARY_FIELDS, values)) for values in zip(*columns)]
        for sm, k in zip(out, samples.tolist()):
            if k > REV_SAMPLES_MAX:
                # Not every sample was kept: these two need them all (docs/twin.md).
                sm["friction_work"] = sm["speed_fluctuation"] = None
                for key in PUMP_COLUMNS:
                    sm[key] = None
        # Keep the samples from just before the next revolution's start (the first sample at
        # which the angle reaches it: the crank may have turned back before).
        reached = np.maximum.accumulate(arr[:, self.i_angle])
        start = int(np.searchsorted(reached, TWO_PI * last)) - 1
        self.rev_parts = [arr[max(0, start) :].copy()]
        self.rev_next = last
        self.rev_dropped = 0
        return out

    def _reduce_revolution(self) -> None:
        """Bounds the rows kept for the revolution in progress (REV_SAMPLES_MAX): the rows before
        it are not needed but the one before its start; of its own rows, the first three, the
        last two, and those holding each column's largest and smallest value with their
        neighbours (the summary's extremes, refined by the parabola through them) are kept."""
        # Part by part, without joining them: a join would double the memory at its peak.
        parts = self.rev_parts
        off = np.concatenate(([0], np.cumsum([len(p) for p in parts])))
        n = int(off[-1])
        ang = np.concatenate([p[:, self.i_angle] for p in parts])
        c = int(np.searchsorted(np.maximum.accumulate(ang), TWO_PI * self.rev_next))

        def gather(idx: np.ndarray) -> np.ndarray:
            """The rows at these (sorted) indices of the parts one after the other."""
            return np.concatenate(
                [p[idx[(idx >= lo) & (idx < hi)] - lo] for p, lo, hi in zip(parts, off, off[1:])]
            )

        if c >= n:  # not begun yet: the last samples before it are all it needs
            self.rev_parts = [gather(np.arange(n - 2, n))]
            return
        start = max(0, c - 1)
        if n - start <= REV_SAMPLES_MAX + 3 and not self.rev_dropped:
            self.rev_parts = [
                p[max(0, start - lo) :] for p, lo in zip(parts, off) if lo + len(p) > start
            ]
            return
        b0, b1 = start + 3, n - 2  # the body: all but the first three and the last two rows
        best = []  # per part: (max, index of the first max, min, index of the first min)
        for p, lo in zip(parts, off):
            a, b = max(b0, lo), min(b1, lo + len(p))
            if a < b:
                seg = p[a - lo : b - lo]
                best.append((seg.max(0), seg.argmax(0) + a, seg.min(0), seg.argmin(0) + a))
        mx, amx, mn, amn = (np.stack(x) for x in zip(*best))
        cols = np.arange(mx.shape[1])
        ext = np.concatenate((amx[np.argmax(mx, 0), cols], amn[np.argmin(mn, 0), cols]))
        idx = np.unique(np.clip(np.concatenate((ext - 1, ext, ext + 1)), b0, b1 - 1))
        self.rev_dropped += (b1 - b0) - len(idx)
        self.rev_parts = [gather(np.concatenate((np.arange(start, b0), idx, np.arange(b1, n))))]

    # ---- checkpoints ---------------------------------------------------------------------------

    def checkpoint(self) -> dict:
        """Everything needed to continue exactly: the FMU's serialized state and time, the
        position in the input, and the twin's buffers."""
        b = self.buf
        rev = np.concatenate(self.rev_parts) if self.rev_parts else self._empty()
        return {
            "version": CHECKPOINT_VERSION,
            "fmu_guid": self.fmu.model_description.guid,
            "machine": self.machine,
            "options": self.o.to_dict(),
            "fmu_state": base64.b64encode(self.fmu.serialize()).decode()
            if self.channel is not None
            else None,
            "fmu_time": self.fmu.time,
            "lines_read": self.lines_read,
            "rows_out": self.rows_out,
            "cols": self.cols,
            "buf": {
                "t": b.t.tolist(),
                "theta": b.theta.tolist(),
                "speed": [None if math.isnan(v) else v for v in b.speed.tolist()],
                "force": b.force.tolist(),
                "line": b.line.tolist(),
                "done": b.done,
                "segment_start": b.segment_start,
                "t0": None if math.isnan(b.t0) else b.t0,
            },
            "sparse": self.sparse,
            "sparse_open": self.sparse_open,
            "last": [self.last_raw, self.last_unwrapped, self.last_t],
            "duplicates": self.duplicates,
            "speed_ignored": self.speed_ignored,
            "separator": self.separator,
            "time_kind": self.time_kind,
            "time_clock": None
            if self.clock is None
            else [self.clock.origin_us, self.clock.prev_us, self.iso_line],
            "gaps": self.gaps,
            "rev_rows": rev.tolist(),
            "rev_next": self.rev_next,
            "rev_dropped": self.rev_dropped,
            "motion": self.motion,
            "motion_events": self.motion_events,
            "motion_count": self.motion_count,
        }

    @classmethod
    def from_checkpoint(cls, fmu_path: str, cp: dict, extra_values: dict | None = None) -> Twin:
        """The twin of a checkpoint (a dict as `checkpoint()` made it). A checkpoint that is not
        one (missing or mistyped entries, a damaged FMU state) raises CheckpointError naming what
        is wrong; a wrong machine or FMU raises ValueError."""
        if not isinstance(cp, dict):
            raise CheckpointError(f"not a twin checkpoint (a JSON {type(cp).__name__})")
        if "sha256" in cp and cp["sha256"] != _digest(cp):
            raise CheckpointError(
                "the checkpoint was damaged or edited (its checksum does not match)"
            )
        if cp.get("version") in (1, 2):
            # Version 2 kept the smoothing window as a number of samples, set by the first
            # interval of the run; its buffer may not hold what a window in time needs.
            raise CheckpointError(
                f"checkpoint version {cp['version']!r} was written by an earlier twin, whose "
                f"smoothing window was a number of samples; this twin reads version "
                f"{CHECKPOINT_VERSION}: run again from the start of the input"
            )
        if cp.get("version") != CHECKPOINT_VERSION:
            raise CheckpointError(
                f"checkpoint version {cp.get('version')!r}; this twin reads version "
                f"{CHECKPOINT_VERSION}"
            )
        try:
            options = Options(**cp["options"])
            machine = cp["machine"]
        except (KeyError, TypeError) as e:
            raise CheckpointError(f"not a twin checkpoint (options or machine: {e})") from None
        tw = cls(fmu_path, machine, options, extra_values)
        guid = tw.fmu.model_description.guid
        if cp.get("fmu_guid", guid) != guid:
            raise CheckpointError(
                f"made with the FMU {cp['fmu_guid']!r}; {str(fmu_path)!r} is {guid!r} (another "
                "build: its state cannot be restored into this one)"
            )
        try:
            tw._restore(cp)
        except FmuError as e:
            raise CheckpointError(f"the FMU refused the checkpoint's state ({e})") from None
        except (KeyError, TypeError, ValueError, IndexError, binascii.Error) as e:
            raise CheckpointError(f"not a twin checkpoint ({type(e).__name__}: {e})") from None
        return tw

    def _restore(self, cp: dict) -> None:
        tw = self
        tw.lines_read, tw.rows_out, tw.cols = (
            int(cp["lines_read"]),
            int(cp["rows_out"]),
            cp["cols"],
        )
        if tw.cols is not None and not isinstance(tw.cols, dict):
            raise TypeError("cols is not a mapping")
        tw.separator = cp.get("separator", ",")
        tw.time_kind = cp.get("time_kind")
        if cp.get("time_clock") is not None:
            origin_us, prev_us, tw.iso_line = cp["time_clock"]
            tw.clock = Clock(tw.o.timezone, int(origin_us))
            tw.clock.prev_us = None if prev_us is None else int(prev_us)
        bb = cp["buf"]
        tw.buf = _Segment(
            t=np.array(bb["t"], dtype=float),
            theta=np.array(bb["theta"], dtype=float),
            speed=np.array([math.nan if v is None else v for v in bb["speed"]], dtype=float),
            force=_process_rows(bb["force"]),
            line=np.array(bb["line"], dtype=np.int64),
            done=int(bb["done"]),
            segment_start=bool(bb["segment_start"]),
            t0=math.nan if bb["t0"] is None else float(bb["t0"]),
        )
        tw.sparse = [
            [int(s[0]), float(s[1]), float(s[2]), int(s[3]), int(s[4])] for s in cp["sparse"]
        ]
        tw.sparse_open = bool(cp["sparse_open"]) and bool(tw.sparse)
        if len({len(getattr(tw.buf, n)) for n in _Segment.NAMES}) != 1:
            raise ValueError("the buffered samples' columns differ in length")
        tw.last_raw, tw.last_unwrapped, tw.last_t = cp["last"]
        tw.duplicates, tw.gaps = int(cp["duplicates"]), [tuple(g) for g in cp["gaps"]]
        tw.speed_ignored = int(cp.get("speed_ignored", 0))
        rev = np.array(cp["rev_rows"], dtype=float).reshape(-1, 1 + len(tw.outputs))
        tw.rev_parts, tw.rev_next = ([rev] if len(rev) else []), cp["rev_next"]
        tw.rev_dropped = int(cp.get("rev_dropped", 0))
        tw.motion = cp.get("motion")
        tw.motion_events = [list(e) for e in cp.get("motion_events", [])]
        tw.motion_count = int(cp.get("motion_count", len(tw.motion_events)))
        if cp["fmu_state"] is not None:
            tw.fmu.start(tw.values)
            tw.fmu.restore(base64.b64decode(cp["fmu_state"], validate=True), float(cp["fmu_time"]))
            tw.channel = tw.fmu.channel(list(INPUTS), tw.outputs)


class CheckpointError(ValueError):
    """A checkpoint that cannot be used: damaged, edited, or not a twin's."""


def _digest(cp: dict) -> str:
    body = {k: v for k, v in cp.items() if k != "sha256"}
    return hashlib.sha256(json.dumps(body, sort_keys=True).encode()).hexdigest()


def load_checkpoint(path) -> dict:
    """A checkpoint file written by `save_checkpoint`, its checksum verified: a damaged or edited
    file raises CheckpointError naming the file (a changed number in a valid JSON would otherwise
    resume with wrong values)."""
    import pathlib

    p = pathlib.Path(path)
    try:
        cp = json.loads(p.read_bytes().decode("utf-8"))
    except OSError as e:
        raise CheckpointError(f"{p}: cannot be read ({e.strerror or e})") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise CheckpointError(f"{p}: not a twin checkpoint (not JSON: {e})") from None
    if not isinstance(cp, dict) or "sha256" not in cp:
        raise CheckpointError(f"{p}: not a twin checkpoint (no checksum)")
    if cp["sha256"] != _digest(cp):
        raise CheckpointError(
            f"{p}: the checkpoint was damaged or edited (its checksum does not match)"
        )
    return cp


def save_checkpoint(path, cp: dict) -> None:
    import os
    import pathlib

    p = pathlib.Path(path)
    tmp = p.with_suffix(p.suffix + ".tmp")
    cp = {**cp, "sha256": _digest(cp)}
    with open(tmp, "w") as f:
        f.write(json.dumps(cp))
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, p)
