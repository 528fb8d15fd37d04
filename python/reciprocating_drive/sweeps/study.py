"""Study files of the design sweeps (docs/sweeps.md): which machine, which parameters vary and how,
how the FMU is driven, and which metrics are kept. A study is TOML (Python's tomllib):

    name = "unb600a_friction"
    machine = "unb600a-simplex"         # a preset, "default", or a path to an .ssv (relative to the file)
    strokes_per_minute = 65             # constant crank speed (or crank_speed = ... rad/s)
    skip_revolutions = 1                # transient, not evaluated
    revolutions = 1                     # evaluated
    steps_per_revolution = 360
    metrics = ["friction_work", "torque_peak"]

    [design]
    kind = "grid"                       # grid | random | lhs (scipy.stats.qmc.LatinHypercube)
    # samples = 64; seed = 1            # for random and lhs

    [fixed]                             # optional: values set in every case
    "balancer.enabled" = true

    [parameters]
    "support_A.offset" = { start = -1e-3, stop = 1e-3, num = 5 }   # a range (grid)
    "support_C.tilt" = { values = [0.0, 1e-4, 2e-4] }              # a list (grid)
    # random / lhs: { min = ..., max = ... }

The crank speed itself can be a parameter: `strokes_per_minute` or `crank.speed` [rad/s].

A study is validated before anything runs (docs/sweeps.md "The study file"): the file's structure
against a JSON schema (jsonschema, the library pinned in requirements.txt, rather than hand-written
checks of every key), then every parameter name, type and range against the FMU's model
description. An error is a `StudyError` of one line naming the file, the key, the value and what is
allowed.

Cases are planned lazily: the number of cases is counted from the design (a product of axis
lengths), and case i is computed when it is asked for (`Study.case`), so a study of 10¹⁵ cases
costs no more memory than one of ten. A case's number is its index in the design, stable for a given
study file, which is what lets a sweep resume.

Layer: workflows, the sweeps (docs/architecture.md).
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import pathlib
import re
import tomllib
from dataclasses import dataclass, field
from functools import cache

import numpy as np

from .. import artifacts
from ..cli_errors import UserError, show
from ..presets import preset_values

#: The model description of this repository (equal to the built FMU's), or of the FMU an installed
#: package carries; studies are validated against the FMU they run on when it is given.
MODEL_DESCRIPTION = (
    artifacts.fmu()
    if artifacts.installed()
    else artifacts.ROOT / "modelDescription" / "modelDescription.xml"
)

#: Metrics a study may ask for (docs/sweeps.md): (meaning, SI unit). Per evaluated revolution, then
#: over them: the mean for friction work, the extreme otherwise.
METRICS = {
    "friction_work": "friction work per revolution ∫F_fr ds [J] (mean over the evaluated revolutions)",
    "torque_peak": "largest |crank.torque| [N.m]",
    "torque_max": "maximum crank.torque (signed) [N.m]",
    "torque_min": "minimum crank.torque (signed) [N.m]",
    "acceleration_max": "maximum suspension.acceleration (signed) [m/s2]",
    "acceleration_max_angle": "crank angle of the maximum acceleration [deg] (last revolution)",
    "acceleration_min": "minimum suspension.acceleration (signed) [m/s2]",
    "inertia_force_max": "maximum inertia.force (signed) [N]",
    "inertia_force_min": "minimum inertia.force (signed) [N]",
    "guide_friction_max": "maximum guide.friction (signed) [N]",
    "guide_friction_min": "minimum guide.friction (signed) [N]",
    "rod_force_max": "maximum rod.force (signed) [N]",
    "rod_force_max_angle": "crank angle of the maximum rod force [deg] (last revolution)",
    "rod_force_min": "minimum rod.force (signed) [N]",
    "rod_angle_amplitude": "largest |rod.angle| (ϑ) [rad]",
    "stress_max": "largest rod.stress_max [Pa]",
    "flow_mean": "mean fluid_end.flow [m3/s] (mean over the evaluated revolutions)",
    "flow_pulsation": "flow pulsation (Q_max - Q_min)/Q_mean of fluid_end.flow (mean over the evaluated revolutions)",
}
#: The metrics of a pump's flow (docs/sweeps.md "Metrics"): computed by the reference summary of
#: each case (revolution.revolution_table), not by the batched arithmetic of sweep_cases.
PUMP_METRICS = ("flow_mean", "flow_pulsation")

#: The FMU's inputs a study (and the closed loop's --set) may set like parameters: held constant.
PRESSURE_INPUTS = ("fluid_end.discharge_pressure", "fluid_end.suction_pressure")

#: Study parameters that set the crank speed instead of an FMU parameter.
SPEED_PARAMETERS = ("strokes_per_minute", "crank.speed")

#: A study of more cases than this is refused unless the user raises the limit (--max-cases):
#: docs/sweeps.md "Size of a study". A million cases is a day of one worker at 10 cases/s.
DEFAULT_MAX_CASES = 1_000_000
#: Latin hypercube samples are drawn all at once (one float per sample and parameter).
MAX_LHS_SAMPLES = 10_000_000
#: Communication steps of one case: its samples are held in memory (10 outputs × 8 bytes each).
MAX_STEPS_PER_CASE = 1_000_000

NAME_PATTERN = r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}$"


class StudyError(UserError):
    """A study file that cannot run: one line naming the file, the key, the value, what is allowed."""


# The structure of a study file (JSON Schema, draft 2020-12). Parameter names, types and ranges come
# from the FMU's model description and are checked after this.
_INT = {"type": "integer"}
SCHEMA = {
    "type": "object",
    "additionalProperties": False,
    "required": ["parameters"],
    "properties": {
        "name": {"type": "string", "pattern": NAME_PATTERN},
        "machine": {"type": "string", "minLength": 1},
        "strokes_per_minute": {"type": "number", "exclusiveMinimum": 0},
        "crank_speed": {"type": "number", "exclusiveMinimum": 0},
        "skip_revolutions": {**_INT, "minimum": 0, "maximum": 100_000},
        "revolutions": {**_INT, "minimum": 1, "maximum": 100_000},
        "steps_per_revolution": {**_INT, "minimum": 8, "maximum": MAX_STEPS_PER_CASE},
        "metrics": {
            "type": "array",
            "minItems": 1,
            "uniqueItems": True,
            "items": {"enum": list(METRICS)},
        },
        "design": {
            "type": "object",
            "additionalProperties": False,
            "properties": {
                "kind": {"enum": ["grid", "random", "lhs"]},
                "samples": {**_INT, "minimum": 1},
                "seed": {**_INT, "minimum": 0, "maximum": 2**63 - 1},
            },
        },
        "fixed": {"type": "object"},
        "parameters": {"type": "object", "minProperties": 1},
    },
}
_GRID_VALUES = {
    "type": "object",
    "additionalProperties": False,
    "required": ["values"],
    "properties": {"values": {"type": "array", "minItems": 1}},
}
_GRID_RANGE = {
    "type": "object",
    "additionalProperties": False,
    "required": ["start", "stop", "num"],
    "properties": {
        "start": {"type": "number"},
        "stop": {"type": "number"},
        "num": {**_INT, "minimum": 1},
    },
}
_BOUNDS = {
    "type": "object",
    "additionalProperties": False,
    "required": ["min", "max"],
    "properties": {"min": {"type": "number"}, "max": {"type": "number"}},
}

_TYPE_WORDS = {
    "integer": "an integer",
    "number": "a number",
    "string": "a string",
    "object": "a table",
    "array": "a list",
    "boolean": "true or false",
}


def _validator(schema):
    """A draft 2020-12 validator in which an integer is a TOML integer (not 2.0, not a bool)."""
    import jsonschema

    base = jsonschema.Draft202012Validator
    checker = base.TYPE_CHECKER.redefine(
        "integer", lambda _c, x: isinstance(x, int) and not isinstance(x, bool)
    )
    return jsonschema.validators.extend(base, type_checker=checker)(schema)


def _key(prefix: str, path) -> str:
    parts = [prefix] if prefix else []
    for p in path:
        parts.append(f"[{p}]" if isinstance(p, int) else str(p))
    return ".".join(parts).replace(".[", "[")


def _schema_check(doc, schema, where: str, prefix: str = "") -> None:
    """Raises StudyError for the first violation of `schema`, in words."""
    errors = sorted(_validator(schema).iter_errors(doc), key=lambda e: (len(e.path), list(e.path)))
    if not errors:
        return
    e = errors[0]
    key = _key(prefix, e.absolute_path)
    v, s = e.validator, e.validator_value
    if v == "additionalProperties":
        allowed = sorted(e.schema.get("properties", {}))
        extra = sorted(k for k in e.instance if k not in e.schema.get("properties", {}))
        name = _key(prefix, [*e.absolute_path, extra[0]])
        raise StudyError(f"{where}: unknown key {name!r}; allowed here: {', '.join(allowed)}")
    if v == "required":
        missing = [k for k in s if k not in e.instance]
        raise StudyError(f"{where}: {key or 'the file'}: {missing[0]!r} is missing")
    what = {
        "type": lambda: f"allowed: {_TYPE_WORDS.get(s, s)}",
        "enum": lambda: f"allowed: {', '.join(map(str, s))}",
        "minimum": lambda: f"allowed: >= {s}",
        "maximum": lambda: f"allowed: <= {s}",
        "exclusiveMinimum": lambda: f"allowed: > {s}",
        "minItems": lambda: "allowed: a list of at least one item",
        "minProperties": lambda: "allowed: at least one entry",
        "uniqueItems": lambda: "allowed: each item once",
        "pattern": lambda: "allowed: letters, digits, '_', '.', '-' (a file name, no path)",
        "minLength": lambda: "allowed: a non-empty string",
    }.get(v, lambda: e.message)()
    raise StudyError(f"{where}: {key} = {show(e.instance)}; {what}")


def _finite_numbers(doc, where: str, path=()) -> None:
    """TOML allows nan and inf; no key of a study does."""
    if isinstance(doc, float) and not math.isfinite(doc):
        raise StudyError(f"{where}: {_key('', path)} = {doc}; allowed: a finite number")
    if isinstance(doc, dict):
        for k, v in doc.items():
            _finite_numbers(v, where, (*path, k))
    elif isinstance(doc, list):
        for k, v in enumerate(doc):
            _finite_numbers(v, where, (*path, k))


@dataclass(frozen=True)
class Variable:
    """What a study may set of an FMU parameter: its type, range and unit."""

    name: str
    type: str  # Real, Integer, Boolean, Enumeration
    min: float | None
    max: float | None
    unit: str
    start: object = None


@cache
def model_parameters(
    model: str = str(MODEL_DESCRIPTION), require_pump: bool = True
) -> tuple[dict, str, str]:
    """The parameters of a model description (an FMU or its modelDescription.xml): name ->
    Variable, and the model's GUID and version. `require_pump`: refuse another FMU."""
    from fmpy import read_model_description

    md = read_model_description(model, validate=False)
    units = {}
    out = {}
    for v in md.modelVariables:
        # A pump's pressures are inputs, but a study or a closed loop holds them constant like a
        # parameter (their start values): docs/sweeps.md "The study file".
        held = v.causality == "input" and v.name in PRESSURE_INPUTS
        if not held and (v.causality != "parameter" or v.variability not in ("fixed", "tunable")):
            continue
        dt = v.declaredType
        lo = v.min if v.min is not None else (dt.min if dt is not None else None)
        hi = v.max if v.max is not None else (dt.max if dt is not None else None)
        units[v.name] = v.unit or (dt.unit if dt is not None else None) or ""
        start = v.start
        if start is not None:
            if v.type == "Boolean":
                start = str(start).lower() in ("true", "1")
            elif v.type in ("Integer", "Enumeration"):
                start = int(start)
            else:
                start = float(start)
        out[v.name] = Variable(
            v.name,
            v.type,
            None if lo is None else float(lo),
            None if hi is None else float(hi),
            units[v.name],
            start,
        )
    names = {v.name for v in md.modelVariables}
    if require_pump and not {"crank.angle", "crank.model_angle", "crank.torque"} <= names:
        raise UserError(
            f"{model}: not a ReciprocatingDrive FMU ({md.modelName}: it has no crank.model_angle "
            "and crank.torque); allowed: target/fmu/ReciprocatingDrive.fmu"
        )
    return out, md.guid, md.version or ""


def check_fmu(path: str | pathlib.Path) -> tuple[dict, str, str]:
    """model_parameters of an FMU file, with a one-line UserError for anything but a readable
    ReciprocatingDrive FMU."""
    p = pathlib.Path(path)
    if not p.is_file():
        raise UserError(f"--fmu {p}: not found; build it with scripts/build-fmu.sh")
    try:
        return model_parameters(str(p.resolve()))
    except UserError:
        raise
    except Exception as e:
        raise UserError(
            f"--fmu {p}: not a readable FMU ({type(e).__name__}: {e}); allowed: an FMI 2.0 .fmu"
        ) from None


def _check_value(where: str, key: str, name: str, x, var: Variable | None) -> float | int | bool:
    """One value of a parameter against its type and range. Returns it as the FMU takes it."""
    if var is None:  # a speed parameter
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not x > 0:
            raise StudyError(f"{where}: {key} = {show(x)}; allowed: a number > 0 ({name})")
        return float(x)
    if var.type == "Boolean":
        if not isinstance(x, bool):
            raise StudyError(f"{where}: {key} = {show(x)}; allowed: true or false ({name})")
        return x
    if var.type in ("Integer", "Enumeration"):
        if isinstance(x, bool) or not isinstance(x, int):
            raise StudyError(f"{where}: {key} = {show(x)}; allowed: an integer ({name})")
    elif isinstance(x, bool) or not isinstance(x, (int, float)):
        raise StudyError(
            f"{where}: {key} = {show(x)}; allowed: a number ({name}, {var.unit or '-'})"
        )
    if (var.min is not None and x < var.min) or (var.max is not None and x > var.max):
        lo = "-inf" if var.min is None else f"{var.min:g}"
        hi = "inf" if var.max is None else f"{var.max:g}"
        unit = f" {var.unit}" if var.unit else ""
        raise StudyError(f"{where}: {key} = {show(x)}; allowed: {lo} .. {hi}{unit} ({name})")
    return x if var.type != "Real" else float(x)


@dataclass
class Axis:
    """One varied parameter of a grid: a list of values, or `num` evenly spaced values from
    `start` to `stop` computed on demand (np.linspace's formula: start + k·step, stop at the end)."""

    values: list | None = None
    start: float = 0.0
    stop: float = 0.0
    num: int = 0

    def __len__(self) -> int:
        return len(self.values) if self.values is not None else self.num

    def __getitem__(self, k: int):
        if self.values is not None:
            return self.values[k]
        if k == self.num - 1:
            return float(self.stop)
        step = (self.stop - self.start) / (self.num - 1) if self.num > 1 else 0.0
        return float(self.start + k * step)


@dataclass
class Study:
    name: str
    machine: str
    base_values: dict  # the machine's parameter values (preset) with [fixed]
    crank_speed: float  # rad/s, unless a parameter varies it
    skip_revolutions: int
    revolutions: int
    steps_per_revolution: int
    metrics: list
    design: str
    parameters: dict  # name -> spec (as in the file)
    samples: int | None = None
    seed: int = 0
    source: str = ""
    n_cases: int = 0
    axes: list = field(default_factory=list)  # grid: one Axis per varied parameter
    bounds: np.ndarray | None = None  # random, lhs: (min, max) per varied parameter
    lhs: np.ndarray | None = None  # lhs: the unit samples
    content_hash: str = ""  # of everything that determines the results (not the name)
    inert: dict = field(default_factory=dict)  # varied parameters that cannot act -> why
    variables: dict = field(default_factory=dict, repr=False)  # the FMU's parameters

    @property
    def varied(self) -> list[str]:
        return list(self.parameters)

    def case(self, i: int) -> dict:
        """The parameter values of case i (0 <= i < n_cases), computed on demand."""
        if not 0 <= i < self.n_cases:
            raise IndexError(f"case {i} of {self.n_cases}")
        names = self.varied
        if self.design == "grid":
            # Mixed radix, the last parameter fastest (itertools.product's order).
            out = {}
            for name, axis in zip(names[::-1], self.axes[::-1]):
                i, k = divmod(i, len(axis))
                out[name] = axis[k]
            return {n: out[n] for n in names}
        if self.design == "random":
            # Row i of default_rng(seed).random((samples, d)), without drawing rows 0..i-1:
            # PCG64 jumps ahead by the i·d doubles before it (one 64-bit draw per double).
            bg = np.random.PCG64(self.seed)
            bg.advance(i * len(names))
            u = np.random.Generator(bg).random(len(names))
        else:
            u = self.lhs[i]
        x = self.bounds[:, 0] + u * (self.bounds[:, 1] - self.bounds[:, 0])
        return dict(zip(names, (float(v) for v in x)))

    @property
    def floats_only(self) -> bool:
        """Whether every varied value is a float (not an Integer's or a Boolean's `values`): then
        `case_array` holds the values of `case` exactly, types included."""
        return self.design != "grid" or all(
            a.values is None or all(type(v) is float for v in a.values) for a in self.axes
        )

    def case_array(self, ids) -> np.ndarray:
        """The values of the cases `ids` as a float64 array, one row per case, one column per
        varied parameter: row k is `case(ids[k])`'s values (an integer or boolean as its float),
        computed with the same operations on the same numbers, bit for bit. For a batch of
        cases, where one `case` call per case would cost more than the arithmetic."""
        names = self.varied
        n = len(ids)
        out = np.empty((n, len(names)))
        if n == 0:
            return out
        if min(ids) < 0 or max(ids) >= self.n_cases:
            raise IndexError(f"cases {min(ids)}..{max(ids)} of {self.n_cases}")
        if self.design == "grid":
            if self.n_cases >= 2**62:  # beyond numpy's integers: case by case
                for k, i in enumerate(ids):
                    out[k] = [float(v) for v in self.case(i).values()]
                return out
            i = np.asarray(ids, dtype=np.int64)
            for j in range(len(names) - 1, -1, -1):  # mixed radix, as case()
                axis = self.axes[j]
                i, k = np.divmod(i, len(axis))
                if axis.values is not None:
                    out[:, j] = np.asarray([float(v) for v in axis.values])[k]
                    continue
                step = (axis.stop - axis.start) / (axis.num - 1) if axis.num > 1 else 0.0
                # Axis[k]: start + k·step (k as a float), the stop itself at the end.
                out[:, j] = axis.start + k.astype(np.float64) * step
                out[k == axis.num - 1, j] = axis.stop
            return out
        if self.design == "random":
            # Each run of consecutive cases continues one stream: row i of default_rng(seed)
            # .random((samples, d)) is the doubles i·d .. i·d + d − 1 of PCG64(seed), as in case().
            ids = np.asarray(ids, dtype=np.int64)
            cuts = np.flatnonzero(np.diff(ids) != 1) + 1
            u = np.empty_like(out)
            for a, b in zip([0, *cuts.tolist()], [*cuts.tolist(), n]):
                bg = np.random.PCG64(self.seed)
                bg.advance(int(ids[a]) * len(names))
                u[a:b] = np.random.Generator(bg).random((b - a, len(names)))
        else:
            u = self.lhs[np.asarray(ids, dtype=np.int64)]
        return self.bounds[:, 0] + u * (self.bounds[:, 1] - self.bounds[:, 0])

    @property
    def case_values(self) -> list[dict]:
        """Every case (for small studies and tests; a sweep asks for them one by one)."""
        return [self.case(i) for i in range(self.n_cases)]


def load_study(
    path: str | pathlib.Path, fmu: str | pathlib.Path | None = None, max_cases: int | None = None
) -> Study:
    """Reads and validates a study file. `fmu`: the FMU the study will run on (its model
    description is what the parameters are checked against; default this repository's)."""
    path = pathlib.Path(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except IsADirectoryError:
        raise StudyError(f"{path}: is a folder; allowed: a TOML study file") from None
    except FileNotFoundError:
        raise StudyError(f"{path}: no such file") from None
    except OSError as e:
        raise StudyError(f"{path}: cannot be read ({e.strerror})") from None
    except UnicodeDecodeError as e:
        raise StudyError(f"{path}: byte {e.start} is not UTF-8; allowed: a TOML file") from None
    deep = f"{path}: tables or arrays nested too deep to read; allowed: a study of a few levels"
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise StudyError(f"{path}: not valid TOML: {e}") from None
    except RecursionError:  # tomllib recurses once per level of nested arrays or tables
        raise StudyError(deep) from None
    try:
        return study_from_dict(
            doc, base_dir=path.parent, source=str(path), fmu=fmu, max_cases=max_cases
        )
    except RecursionError:  # dotted keys a.b.c... nest without recursing in the parser
        raise StudyError(deep) from None


def _speed_of(doc: dict, base: dict) -> float:
    if "strokes_per_minute" in doc:
        return float(doc["strokes_per_minute"]) * 2 * math.pi / 60
    if "crank_speed" in doc:
        return float(doc["crank_speed"])
    return float(base.get("crank.speed", 2 * math.pi * 65 / 60))


def study_from_dict(
    doc: dict,
    base_dir: pathlib.Path | None = None,
    source: str = "",
    fmu: str | pathlib.Path | None = None,
    max_cases: int | None = None,
) -> Study:
    """Validates a study (the parsed TOML) and plans its cases. Raises StudyError (one line)."""
    where = source or "study"
    base_dir = base_dir or pathlib.Path.cwd()
    max_cases = DEFAULT_MAX_CASES if max_cases is None else max_cases
    _schema_check(doc, SCHEMA, where)
    _finite_numbers(doc, where)
    if "strokes_per_minute" in doc and "crank_speed" in doc:
        raise StudyError(f"{where}: strokes_per_minute and crank_speed: allowed: one of them")
    variables, _, _ = check_fmu(fmu) if fmu is not None else model_parameters()

    machine = doc.get("machine", "default")
    if machine.endswith(".ssv"):
        p = pathlib.Path(machine)
        machine = str(p if p.is_absolute() else (base_dir / p).resolve())
        if not pathlib.Path(machine).is_file():
            raise StudyError(
                f"{where}: machine = {doc['machine']!r}: no such .ssv file ({machine})"
            )
    try:
        base = preset_values(machine)
    except KeyError:
        from ..presets import available_presets

        raise StudyError(
            f"{where}: machine = {show(doc.get('machine'))}; allowed: "
            f"{', '.join(available_presets())} or a path to an .ssv file"
        ) from None
    except Exception as e:
        raise StudyError(
            f"{where}: machine = {show(doc.get('machine'))}: not a readable SSP parameter set "
            f"({type(e).__name__}: {one_line_error(e)})"
        ) from None

    inputs = ("crank.angle", "crank.speed", "crank.acceleration", "link.external_force")
    for k in base:
        if k not in variables and k not in inputs:
            raise StudyError(
                f"{where}: machine = {doc.get('machine')!r}: sets {k!r}, not a parameter of the FMU"
            )
    fixed = doc.get("fixed", {})
    params = doc["parameters"]
    for k, v in fixed.items():
        if k in SPEED_PARAMETERS:
            raise StudyError(
                f"{where}: fixed.{k}: the crank speed is set by the top-level strokes_per_minute "
                "or crank_speed; allowed in [fixed]: FMU parameters"
            )
        if k not in variables:
            raise StudyError(_unknown(where, f"fixed.{k}", k, variables))
        base[k] = _check_value(where, f"fixed.{k!r}", k, v, variables[k])
    speed_keys = [k for k in params if k in SPEED_PARAMETERS]
    if len(speed_keys) > 1:
        raise StudyError(
            f"{where}: parameters {', '.join(speed_keys)} both set the crank speed; allowed: one"
        )
    design = doc.get("design", {})
    kind = design.get("kind", "grid")
    for k, spec in params.items():
        if k in fixed:
            raise StudyError(
                f"{where}: {k!r} is in both [fixed] and [parameters]; allowed: one of them"
            )
        if k not in SPEED_PARAMETERS and k not in variables:
            raise StudyError(_unknown(where, f"parameters.{k}", k, variables))
        if not isinstance(spec, dict):
            raise StudyError(
                f"{where}: parameters.{k!r} = {show(spec)}; allowed: a table such as "
                + (
                    "{ values = [...] } or { start = ..., stop = ..., num = ... }"
                    if kind == "grid"
                    else "{ min = ..., max = ... }"
                )
            )
    speed = _speed_of(doc, base)

    st = Study(
        name=doc.get("name", pathlib.Path(source).stem if source else "study"),
        machine=machine,
        base_values=base,
        crank_speed=speed,
        skip_revolutions=doc.get("skip_revolutions", 1),
        revolutions=doc.get("revolutions", 1),
        steps_per_revolution=doc.get("steps_per_revolution", 360),
        metrics=list(doc.get("metrics", ["friction_work", "torque_peak"])),
        design=kind,
        parameters=dict(params),
        samples=design.get("samples"),
        seed=design.get("seed", 0),
        source=source,
    )
    if not re.match(NAME_PATTERN, st.name):
        raise StudyError(
            f"{where}: name = {st.name!r} (from the file name); allowed: letters, digits, '_', '.', "
            "'-': give name = ..."
        )
    steps = (st.skip_revolutions + st.revolutions) * st.steps_per_revolution
    if steps > MAX_STEPS_PER_CASE:
        raise StudyError(
            f"{where}: (skip_revolutions + revolutions) × steps_per_revolution = {steps} steps per "
            f"case; allowed: <= {MAX_STEPS_PER_CASE}"
        )
    _plan(st, where, variables, max_cases)
    st.content_hash = _content_hash(st)
    st.variables = variables
    st.inert = inert_parameters(st, variables)
    return st


def one_line_error(e: BaseException) -> str:
    return " ".join(str(e).split())[:160]


def _unknown(where: str, key: str, name: str, variables: dict) -> str:
    import difflib

    close = difflib.get_close_matches(name, [*variables, *SPEED_PARAMETERS], n=3)
    hint = f"; did you mean {', '.join(close)}?" if close else ""
    return (
        f"{where}: {key}: unknown parameter {name!r}; allowed: the FMU's parameters "
        f"(docs/model.md §10) or {', '.join(SPEED_PARAMETERS)}{hint}"
    )


def _plan(st: Study, where: str, variables: dict, max_cases: int) -> None:
    """Checks every parameter's spec and counts the cases (without listing them)."""
    names = st.varied
    if st.design == "grid":
        n = 1
        for name in names:
            spec = st.parameters[name]
            key = f"parameters.{name!r}"
            schema = _GRID_VALUES if "values" in spec else _GRID_RANGE
            _schema_check(spec, schema, where, prefix=key)
            var = variables.get(name)
            if "values" in spec:
                vals = [
                    _check_value(where, f"{key}.values[{j}]", name, x, var)
                    for j, x in enumerate(spec["values"])
                ]
                axis = Axis(values=vals)
            else:
                for end in ("start", "stop"):
                    _check_value(where, f"{key}.{end}", name, spec[end], var)
                if var is not None and var.type != "Real":
                    vals = np.linspace(spec["start"], spec["stop"], spec["num"])
                    if spec["num"] > 1 and not np.all(vals == np.round(vals)):
                        raise StudyError(
                            f"{where}: {key}: start = {spec['start']}, stop = {spec['stop']}, "
                            f"num = {spec['num']} gives non-integer values; allowed for an "
                            f"{var.type} parameter: a range of integers or values = [...]"
                        )
                axis = Axis(start=float(spec["start"]), stop=float(spec["stop"]), num=spec["num"])
            st.axes.append(axis)
            n *= len(axis)  # a Python int: 10¹⁵ and beyond are counted exactly
        st.n_cases = n
    else:
        if st.samples is None:
            raise StudyError(
                f"{where}: design.samples is missing; allowed: an integer >= 1 for "
                f"design.kind = {st.design!r}"
            )
        bounds = []
        for name in names:
            spec = st.parameters[name]
            key = f"parameters.{name!r}"
            _schema_check(spec, _BOUNDS, where, prefix=key)
            var = variables.get(name)
            if var is not None and var.type != "Real":
                raise StudyError(
                    f"{where}: {key}: {name} is an {var.type} parameter; allowed for "
                    f"design.kind = {st.design!r}: Real parameters (or a grid)"
                )
            lo = _check_value(where, f"{key}.min", name, spec["min"], var)
            hi = _check_value(where, f"{key}.max", name, spec["max"], var)
            if not lo <= hi:
                raise StudyError(f"{where}: {key}: min = {lo}, max = {hi}; allowed: min <= max")
            bounds.append((lo, hi))
        st.bounds = np.array(bounds, dtype=float)
        st.n_cases = st.samples
    if st.n_cases > max_cases:
        raise StudyError(
            f"{where}: {st.n_cases:,} cases; allowed: at most {max_cases:,} (raise the limit with "
            '--max-cases N; docs/sweeps.md "Size of a study")'
        )
    if st.design == "lhs":
        if st.samples > MAX_LHS_SAMPLES:
            raise StudyError(
                f"{where}: design.samples = {st.samples}; allowed for lhs: <= {MAX_LHS_SAMPLES:,} "
                "(a Latin hypercube is drawn at once; use random for more)"
            )
        from scipy.stats import qmc

        st.lhs = qmc.LatinHypercube(d=len(names), seed=st.seed).random(st.samples)


def _content_hash(st: Study) -> str:
    """SHA-256 of everything that determines a case's result: the machine's values (preset and
    [fixed]), the speed, the revolutions and steps, the metrics and the design. Not the name."""
    content = {
        "base_values": st.base_values,
        "crank_speed": st.crank_speed,
        "skip_revolutions": st.skip_revolutions,
        "revolutions": st.revolutions,
        "steps_per_revolution": st.steps_per_revolution,
        "metrics": st.metrics,
        "design": st.design,
        "samples": st.samples,
        "seed": st.seed,
        "parameters": st.parameters,
    }
    text = json.dumps(content, sort_keys=True, separators=(",", ":"), default=repr)
    return hashlib.sha256(text.encode()).hexdigest()


# ---- parameters that cannot act (docs/sweeps.md "Parameters that cannot act") ----------------

_SUPPORT_KEYS = ("attached", "z", "offset", "tilt", "length", "stiffness")
_LINK_KEYS = (
    *(f"link.l{i}" for i in range(1, 5)),
    *(f"link.d{i}" for i in range(1, 5)),
    "link.E",
    "link.lateral_load",
    "guide.rod_side_force",
)
_ELASTIC_ROD = (
    "rod.flex_length",
    "rod.rigid_length",
    "rod.wire_diameter",
    "rod.coil_diameter",
    "rod.coils",
    "rod.E",
    "rod.poisson",
    "rod.cage_inertia",
    "rod.damping_ratio",
    "rod.damping",
    "rod.initial_state",
)
_BEAM_UNIT = (
    "geometry.beam_front_arm",
    "geometry.beam_rear_arm",
    "geometry.pivot_dx",
    "geometry.pivot_dy",
)
#: The switches the rules below depend on.
CONDITIONS = (
    "mechanism",
    "rod.kind",
    "balancer.enabled",
    "balancer.tuning",
    *(f"support_{x}.{k}" for x in "ABC" for k in ("kind", "attached")),
)


def _friction_key(x: str) -> str:
    return "guide.friction_coefficient" if x == "B" else f"support_{x}.friction"


def inert_in(values: dict) -> dict[str, str]:
    """Parameters that cannot change any output for these parameter values (all of them given),
    with the reason (docs/model.md §3, §5.2, §6, §7):

    * a support of kind 0 is absent: its other parameters do nothing;
    * every support absent: the friction model is off, no beam problem is solved (the link's
      sections, E, lateral load and the rod's side force; not guide.velocity_scale, which also
      sets the pump's chamber weights, docs/model.md §4.1);
    * a pin (kind 1) has no length; a frame-fixed pin (attached = 1) touches the link at the
      same frame point Z = Z_ref all the time, so its tilt α·(Z − Z_ref) is 0;
    * a rigid rod (rod.kind 0) has none of the elastic rod's parameters; a thin rod (1) no coils;
      an elastic rod does not use geometry.rod_length;
    * a crank-slider (mechanism 1) has no beam;
    * the balancer's parameters without the balancer; tuning 1 and 2 set the stiffness and s_0
      themselves, tuning 0 does not use the design speed."""
    out = {}
    kinds = {x: values[f"support_{x}.kind"] for x in "ABC"}
    for x, kind in kinds.items():
        if kind == 0:
            for k in (*(f"support_{x}.{k}" for k in _SUPPORT_KEYS), _friction_key(x)):
                out[k] = f"support {x} is absent (support_{x}.kind = 0)"
        elif kind == 1:
            out[f"support_{x}.length"] = f"support {x} is a pin (support_{x}.kind = 1): no length"
            if values[f"support_{x}.attached"] == 1:
                out[f"support_{x}.tilt"] = (
                    f"support {x} is a frame-fixed pin (support_{x}.kind = 1, attached = 1): it "
                    "touches the link at one frame point, where the tilt's term is 0"
                )
    if all(k == 0 for k in kinds.values()):
        for k in _LINK_KEYS:
            out[k] = "no support: the friction model is off (support_A/B/C.kind = 0)"
    rod = values["rod.kind"]
    if rod == 0:
        for k in _ELASTIC_ROD:
            out[k] = "the connecting rod is rigid (rod.kind = 0)"
    else:
        out["geometry.rod_length"] = f"an elastic rod (rod.kind = {rod}) does not use it"
        if rod == 1:
            for k in ("rod.coil_diameter", "rod.coils"):
                out[k] = "a thin straight rod (rod.kind = 1) has no coils"
    if values["mechanism"] == 1:
        for k in _BEAM_UNIT:
            out[k] = "a crank-slider (mechanism = 1) has no beam"
    if not values["balancer.enabled"]:
        for k in ("balancer.tuning", "balancer.stiffness", "balancer.design_speed",
                  "balancer.neutral_position"):  # fmt: skip
            out[k] = "the balancer is off (balancer.enabled = false)"
    elif values["balancer.tuning"] == 0:
        out["balancer.design_speed"] = "balancer.tuning = 0 uses balancer.stiffness as given"
        if values["balancer.stiffness"] == 0:
            out["balancer.neutral_position"] = "balancer.stiffness = 0: the bar exerts no force"
    else:
        for k in ("balancer.stiffness", "balancer.neutral_position"):
            out[k] = f"balancer.tuning = {values['balancer.tuning']} sets it itself"
    return out


def inert_parameters(study: Study, variables: dict | None = None) -> dict[str, str]:
    """The varied parameters of `study` that cannot act in any of its cases, with the reason
    (inert_in over every combination of the varied switches)."""
    variables = variables if variables is not None else model_parameters()[0]
    base = {k: v.start for k, v in variables.items()}
    base.update(study.base_values)
    switches = [k for k in study.varied if k in CONDITIONS]
    if study.design == "grid" and switches:
        axes = [study.axes[study.varied.index(k)] for k in switches]
        combos = itertools.product(*([a[i] for i in range(len(a))] for a in axes))
    else:
        combos = [()]
    common = None
    for combo in combos:
        found = inert_in({**base, **dict(zip(switches, combo))})
        found = {k: r for k, r in found.items() if k in study.parameters}
        common = found if common is None else {k: r for k, r in common.items() if k in found}
    return common or {}
