"""Study files of the design sweeps (docs/sweeps.md): which machine, which parameters vary and how,
how the FMU is driven, and which metrics are kept. A study is TOML (Python's tomllib):

    name = "unb600a_friction"
    machine = "unb600a"                 # a preset, "default", or a path to an .ssv (relative to the file)
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
A case is one combination; its id is its index in the design, stable for a given study file,
which is what lets a sweep resume.
"""

from __future__ import annotations

import itertools
import math
import pathlib
import tomllib
from dataclasses import dataclass, field

import numpy as np

from .presets import preset_values

#: Metrics a study may ask for (docs/sweeps.md). Per evaluated revolution, then over them: the
#: mean for friction work, the extreme otherwise.
METRICS = {
    "friction_work": "friction work per revolution ∫F_fr ds [J] (mean over the evaluated revolutions)",
    "torque_peak": "largest |crank.torque| [N.m]",
    "torque_max": "largest crank.torque [N.m]",
    "torque_min": "smallest crank.torque [N.m]",
    "acceleration_max": "largest suspension.acceleration [m/s2]",
    "acceleration_max_angle": "crank angle of the largest acceleration [deg] (last revolution)",
    "acceleration_min": "smallest suspension.acceleration [m/s2]",
    "inertia_force_max": "largest inertia.force [N]",
    "inertia_force_min": "smallest inertia.force [N]",
    "guide_friction_max": "largest guide.friction [N]",
    "guide_friction_min": "smallest guide.friction [N]",
    "rod_force_max": "largest rod.force [N]",
    "rod_force_max_angle": "crank angle of the largest rod force [deg] (last revolution)",
    "rod_force_min": "smallest rod.force [N]",
    "rod_angle_amplitude": "largest |rod.angle| (ϑ) [rad]",
    "stress_max": "largest rod.stress_max [Pa]",
}

#: Study parameters that set the crank speed instead of an FMU parameter.
SPEED_PARAMETERS = ("strokes_per_minute", "crank.speed")


class StudyError(ValueError):
    pass


@dataclass
class Study:
    name: str
    machine: str
    base_values: dict  # the machine's parameter values (preset)
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
    case_values: list = field(default_factory=list)  # one dict per case

    @property
    def varied(self) -> list[str]:
        return list(self.parameters)

    def case(self, i: int) -> dict:
        return self.case_values[i]


def _grid_axis(name: str, spec: dict) -> list:
    if "values" in spec:
        vals = list(spec["values"])
        if not vals:
            raise StudyError(f"parameter {name}: 'values' is empty")
        return vals
    if {"start", "stop", "num"} <= spec.keys():
        n = int(spec["num"])
        if n < 1:
            raise StudyError(f"parameter {name}: num = {n}; allowed: an integer >= 1")
        return [float(x) for x in np.linspace(float(spec["start"]), float(spec["stop"]), n)]
    raise StudyError(
        f"parameter {name}: give 'values = [...]' or 'start', 'stop', 'num' for a grid"
    )


def _bounds(name: str, spec: dict) -> tuple[float, float]:
    try:
        lo, hi = float(spec["min"]), float(spec["max"])
    except KeyError:
        raise StudyError(f"parameter {name}: random and lhs designs need 'min' and 'max'") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
        raise StudyError(f"parameter {name}: min = {lo}, max = {hi}; allowed: finite, min <= max")
    return lo, hi


def build_cases(study: Study) -> list[dict]:
    names = study.varied
    if study.design == "grid":
        axes = [_grid_axis(n, study.parameters[n]) for n in names]
        return [dict(zip(names, combo)) for combo in itertools.product(*axes)]
    if study.samples is None or study.samples < 1:
        raise StudyError(f"design {study.design}: give samples = N (N >= 1)")
    bounds = np.array([_bounds(n, study.parameters[n]) for n in names])
    if study.design == "random":
        u = np.random.default_rng(study.seed).random((study.samples, len(names)))
    elif study.design == "lhs":
        from scipy.stats import qmc

        u = qmc.LatinHypercube(d=len(names), seed=study.seed).random(study.samples)
    else:
        raise StudyError(f"design.kind = {study.design!r}; allowed: grid, random, lhs")
    x = bounds[:, 0] + u * (bounds[:, 1] - bounds[:, 0])
    return [dict(zip(names, (float(v) for v in row))) for row in x]


def load_study(path: str | pathlib.Path) -> Study:
    path = pathlib.Path(path)
    try:
        doc = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as e:
        raise StudyError(f"{path}: {e}") from None
    return study_from_dict(doc, base_dir=path.parent, source=str(path))


def study_from_dict(doc: dict, base_dir: pathlib.Path | None = None, source: str = "") -> Study:
    base_dir = base_dir or pathlib.Path.cwd()
    machine = str(doc.get("machine", "default"))
    if machine.endswith(".ssv") and not pathlib.Path(machine).is_absolute():
        machine = str((base_dir / machine).resolve())
    try:
        base = preset_values(machine)
    except KeyError:
        raise StudyError(
            f"machine = {machine!r}: not a preset, 'default' or an .ssv file"
        ) from None
    base.update(doc.get("fixed", {}))
    if "strokes_per_minute" in doc:
        speed = float(doc["strokes_per_minute"]) * 2 * math.pi / 60
    elif "crank_speed" in doc:
        speed = float(doc["crank_speed"])
    else:
        speed = float(base.get("crank.speed", 2 * math.pi * 65 / 60))
    metrics = list(doc.get("metrics", ["friction_work", "torque_peak"]))
    unknown = [m for m in metrics if m not in METRICS]
    if unknown:
        raise StudyError(f"metrics {unknown}: unknown; available: {', '.join(METRICS)}")
    design = doc.get("design", {})
    st = Study(
        name=str(doc.get("name", pathlib.Path(source).stem or "study")),
        machine=machine,
        base_values=base,
        crank_speed=speed,
        skip_revolutions=int(doc.get("skip_revolutions", 1)),
        revolutions=int(doc.get("revolutions", 1)),
        steps_per_revolution=int(doc.get("steps_per_revolution", 360)),
        metrics=metrics,
        design=str(design.get("kind", "grid")),
        parameters=dict(doc.get("parameters", {})),
        samples=design.get("samples"),
        seed=int(design.get("seed", 0)),
        source=source,
    )
    if st.revolutions < 1 or st.skip_revolutions < 0 or st.steps_per_revolution < 8:
        raise StudyError(
            "revolutions >= 1, skip_revolutions >= 0 and steps_per_revolution >= 8 are required"
        )
    if not st.parameters:
        raise StudyError("[parameters] is empty: a study varies at least one parameter")
    st.case_values = build_cases(st)
    return st
