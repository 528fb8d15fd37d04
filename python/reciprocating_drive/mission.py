"""The main job (scripts/run.sh): simulate one machine at constant crank speed and reduce the run to
what the FMU exists for, per revolution (docs/results.md documents the summary's keys).

The master (fmpy.simulate_fmu with input signals) supplies crank.angle = ω·t, crank.speed = ω,
crank.acceleration = 0; the angle the outputs belong to is read back from crank.model_angle
(docs/model.md §2), so a preset's crank.angle_offset is accounted for by the FMU itself.

A rigid mechanism is algebraic: every revolution is the same, and two are simulated. An elastic rod
starts with a transient of its cage oscillation (docs/model.md §6): the run is long enough for it to
decay, the transient revolutions are the ones before the per-revolution ϑ amplitude settles (to
`SETTLED` of its final value), and the summary describes the last complete revolution.

Layer: the main job, below the workflows (docs/architecture.md).
"""

from __future__ import annotations

import json
import math
import pathlib
from dataclasses import dataclass, field

import numpy as np

from .presets import preset_values
from .revolution import TWO_PI, summarize_revolutions

#: Outputs recorded by the main job.
OUTPUTS = (
    "crank.model_angle",
    "crank.model_speed",
    "suspension.position",
    "suspension.velocity",
    "suspension.acceleration",
    "kinematics.torque_factor",
    "inertia.force",
    "guide.friction",
    "link.friction_total",
    "rod.force",
    "crank.torque",
    "rod.angle",
    "rod.angular_velocity",
    "rod.stress_max",
)

#: Quantities whose extremes the summary reports, with their units.
EXTREMES = {
    "suspension.acceleration": "m/s2",
    "inertia.force": "N",
    "guide.friction": "N",
    "rod.force": "N",
    "crank.torque": "N.m",
}

#: A pump's outputs, recorded besides OUTPUTS for a pump preset (`is_pump`): the flow, the powers
#: and the torque of every cylinder (the plots and the summary's pump section, docs/results.md).
PUMP_OUTPUTS = (
    "fluid_end.flow",
    "fluid_end.hydraulic_power",
    "crank.mechanical_power",
    "cylinder_1.crank_torque",
    "cylinder_2.crank_torque",
    "cylinder_3.crank_torque",
)
PUMP_UNITS = {
    "fluid_end.flow": "m3/s",
    "fluid_end.hydraulic_power": "W",
    "crank.mechanical_power": "W",
    "cylinder_1.crank_torque": "N.m",
    "cylinder_2.crank_torque": "N.m",
    "cylinder_3.crank_torque": "N.m",
}

MECHANISMS = {
    1: "crank-slider",
    2: "beam pumping unit, API class I",
    3: "beam pumping unit, API class III",
}
ROD_KINDS = {0: "rigid rod", 1: "elastic thin rod", 2: "helical-spring rod"}

#: Relative change of the per-revolution ϑ amplitude below which the cage oscillation counts as settled.
SETTLED = 1e-3


def is_pump(params: dict) -> bool:
    """A pump preset: pressures in (load.profile 3) or more than one cylinder on the crankshaft."""
    return int(params.get("load.profile", 0)) == 3 or int(params.get("fluid_end.cylinders", 1)) > 1


def pump_outputs(params: dict) -> tuple:
    """The pump outputs of a pump preset (only the active cylinders' torques), else none."""
    if not is_pump(params):
        return ()
    n = int(params.get("fluid_end.cylinders", 1))
    return tuple(o for o in PUMP_OUTPUTS if not o.startswith("cylinder_") or int(o[9]) <= n)


@dataclass
class Mission:
    preset: str
    parameters: dict  # every parameter value in use (start values overridden by the preset)
    omega: float  # crank speed [rad/s]
    step: float  # communication step [s]
    data: dict  # output name -> samples (numpy), plus "time"
    revolutions: list  # RevolutionSummary of every complete revolution
    transient_revolutions: int  # complete revolutions before the steady state (0 for rigid rods)
    summary: dict = field(default_factory=dict)

    @property
    def mechanism(self) -> int:
        return int(self.parameters["mechanism"])

    @property
    def pump(self) -> bool:
        return is_pump(self.parameters)

    @property
    def cylinders(self) -> int:
        return int(self.parameters.get("fluid_end.cylinders", 1))

    @property
    def elastic(self) -> bool:
        return int(self.parameters["rod.kind"]) != 0

    @property
    def title(self) -> str:
        kind = MECHANISMS.get(self.mechanism, f"mechanism {self.mechanism}")
        if self.elastic:
            kind += f" with {ROD_KINDS[int(self.parameters['rod.kind'])]}"
        name = "default machine" if self.preset == "default" else f"preset {self.preset}"
        spm = self.omega * 60.0 / TWO_PI
        return f"{kind}, {name}: ω = {self.omega:.4g} rad/s ({spm:.4g} strokes/min)"

    def steady_slice(self, last: int | None = None) -> slice:
        """Samples of the steady revolutions (every complete revolution after the transient, or
        only the `last` ones)."""
        t = self.data["time"]
        revs = self.revolutions[self.transient_revolutions :]
        if last is not None:
            revs = revs[-last:]
        a = np.searchsorted(t, revs[0].start_time)
        b = np.searchsorted(t, revs[-1].start_time + revs[-1].duration, side="right")
        return slice(int(a), int(b))


def _start_values(fmu: str) -> dict:
    from fmpy import read_model_description

    out = {}
    for v in read_model_description(fmu).modelVariables:
        if v.causality in ("parameter", "input") and v.start is not None:
            out[v.name] = {
                "Real": float,
                "Integer": int,
                "Boolean": lambda s: str(s).lower() in ("true", "1"),
            }[v.type](v.start)
    return out


def run_mission(
    fmu: str,
    preset: str = "default",
    step: float | None = None,
    revolutions: int | None = None,
    preset_dir: str | pathlib.Path | None = None,
) -> Mission:
    """Simulates the machine of `preset` (a name in resources/presets, a path to an .ssv, or
    "default") and summarises it. `step` defaults to 1/900 of a revolution, rounded to 10 µs,
    `revolutions` to 2 for a rigid rod and 30 for an elastic one (its transient)."""
    from fmpy import simulate_fmu

    values = preset_values(preset) if preset_dir is None else preset_values(preset, preset_dir)
    params = {**_start_values(fmu), **values}
    omega = float(params["crank.speed"])
    if not omega > 0:
        raise ValueError(f"the main job needs a positive crank.speed; the preset gives {omega}")
    elastic = int(params["rod.kind"]) != 0
    period = TWO_PI / omega
    if step is None:
        step = max(1e-5, round(period / 900 / 1e-5) * 1e-5)
    if revolutions is None:
        revolutions = 30 if elastic else 2
    # Revolutions count from the first θ = 2πk at or after the start (θ(0) = the angle offset),
    # and the run goes a little past the last one, so that it is complete despite the sampling.
    theta0 = float(params.get("crank.angle_offset", 0.0))
    wait = (TWO_PI * math.ceil(theta0 / TWO_PI) - theta0) / omega
    n = int(math.ceil((wait + revolutions * period) / step)) + 2
    stop = n * step
    inputs = ("crank.angle", "crank.speed", "crank.acceleration", "link.external_force")
    # A pump's pressures are inputs too, held at the preset's (or the FMU's start) values.
    pressures = tuple(
        p for p in ("fluid_end.discharge_pressure", "fluid_end.suction_pressure") if p in params
    )
    start = {k: v for k, v in values.items() if k not in inputs + pressures}
    outputs = OUTPUTS + pump_outputs(params)
    t = np.arange(n + 1) * step
    sig = np.zeros(
        n + 1,
        dtype=[
            ("time", float),
            ("crank.angle", float),
            ("crank.speed", float),
            ("crank.acceleration", float),
            ("link.external_force", float),
            *[(p, float) for p in pressures],
        ],
    )
    sig["time"], sig["crank.angle"], sig["crank.speed"] = t, omega * t, omega
    sig["link.external_force"] = float(params.get("link.external_force", 0.0))
    for p in pressures:
        sig[p] = float(params.get(p, 0.0))
    res = simulate_fmu(
        fmu,
        start_time=0.0,
        stop_time=stop,
        output_interval=step,
        start_values=start,
        input=sig,
        output=list(outputs),
    )
    data = {"time": np.asarray(res["time"], dtype=float)}
    for name in outputs:
        data[name] = np.asarray(res[name], dtype=float)
    # Revolutions of the model angle counted from the first outer dead centre at or after t = 0.
    revs = summarize_revolutions(
        data["time"],
        data["crank.model_angle"],
        data,
        speed=data["crank.model_speed"],
        quantities=tuple(EXTREMES) + ("suspension.position",) + pump_outputs(params)[1:],
    )
    if not revs:
        raise RuntimeError("the run holds no complete revolution")
    transient = 0
    if elastic:
        amp = np.array([r.rod_angle_amplitude for r in revs])
        settled = np.abs(amp - amp[-1]) <= SETTLED * abs(amp[-1])
        # The first revolution from which every later one is settled.
        transient = int(len(amp) - np.argmin(settled[::-1]) if not settled.all() else 0)
        transient = min(transient, len(revs) - 1)
    m = Mission(
        preset=preset,
        parameters=params,
        omega=omega,
        step=step,
        data=data,
        revolutions=revs,
        transient_revolutions=transient,
    )
    m.summary = summarize(m)
    return m


def _extreme(e, unit: str) -> dict:
    # An output zero over the whole revolution (a single clamp's guide friction) has no angle of
    # its extremes: null rather than the angle of the first sample.
    zero = e.max == 0.0 and e.min == 0.0
    return {
        "unit": unit,
        "max": e.max,
        "max_angle_deg": None if zero else e.max_angle_deg,
        "min": e.min,
        "min_angle_deg": None if zero else e.min_angle_deg,
    }


def summarize(m: Mission) -> dict:
    """The summary written to results/<preset>.json (keys documented in docs/results.md)."""
    last = m.revolutions[-1]
    pos = last.extremes["suspension.position"]
    out = {
        "preset": m.preset,
        "mechanism": MECHANISMS.get(m.mechanism, str(m.mechanism)),
        "rod": ROD_KINDS.get(int(m.parameters["rod.kind"]), str(m.parameters["rod.kind"])),
        "crank_speed": m.omega,
        "strokes_per_minute": m.omega * 60.0 / TWO_PI,
        "communication_step": m.step,
        "revolutions_simulated": len(m.revolutions),
        "transient_revolutions": m.transient_revolutions,
        "summarized_revolution": last.index,
        "stroke": pos.max - pos.min,
        "extremes": {
            q: _extreme(e, unit)
            for q, unit in EXTREMES.items()
            if (e := last.extremes.get(q)) is not None
        },
        "friction_work_per_revolution": last.friction_work,
    }
    if m.elastic:
        out["rod_angle_amplitude"] = last.rod_angle_amplitude
        out["stress_max"] = last.stress_max
    if m.pump:
        p = m.parameters
        out["pump"] = {
            "cylinders": m.cylinders,
            "discharge_pressure": float(p.get("fluid_end.discharge_pressure", 0.0)),
            "suction_pressure": float(p.get("fluid_end.suction_pressure", 0.0)),
            "flow_mean": last.flow_mean,
            "flow_pulsation": last.flow_pulsation,
            "hydraulic_power_mean": last.hydraulic_power_mean,
            "mechanical_power_mean": last.mechanical_power_mean,
            "extremes": {
                q: _extreme(e, PUMP_UNITS[q])
                for q in pump_outputs(p)[1:]  # the flow: its mean and pulsation
                if (e := last.extremes.get(q)) is not None
            },
        }
    return out


def write_summary(m: Mission, path: pathlib.Path) -> None:
    path.write_text(json.dumps(m.summary, indent=2) + "\n")


def _angle(deg: float) -> str:
    """A crank angle as the summary prints it: modulo 360° after rounding to 0.01°, so that an
    extreme at 359.998° reads 0.00° (docs/results.md: angles are the model angle modulo 360°)."""
    return f"{round(deg, 2) % 360.0:.2f}°"


def plural(n: int, word: str) -> str:
    """ "1 revolution", "2 revolutions" (the summary and the plots' labels)."""
    return f"{n} {word}" if n == 1 else f"{n} {word}s"


def format_summary(s: dict) -> str:
    """The summary as scripts/simulate.py prints it (docs/results.md shows it for every preset)."""
    lines = [
        f"{s['preset']}: {s['mechanism']}, {s['rod']}, {s['strokes_per_minute']:.4g} strokes/min",
        f"  stroke                      {s['stroke']:.6g} m",
    ]
    for q, e in s["extremes"].items():
        if e["max"] == 0.0 and e["min"] == 0.0:
            # A signal that is zero over the whole revolution has no angle of its extremes.
            lines.append(f"  {q:<26}  zero throughout")
            continue
        lines.append(
            f"  {q:<26}  max {e['max']:.6g} {e['unit']} at {_angle(e['max_angle_deg'])}, "
            f"min {e['min']:.6g} {e['unit']} at {_angle(e['min_angle_deg'])}"
        )
    lines.append(f"  friction work / revolution  {s['friction_work_per_revolution']:.6g} J")
    if "rod_angle_amplitude" in s:
        lines.append(
            f"  rod angle ϑ amplitude       {s['rod_angle_amplitude']:.6g} rad "
            f"(steady after {plural(s['transient_revolutions'], 'revolution')})"
        )
        lines.append(f"  largest rod stress          {s['stress_max'] / 1e6:.6g} MPa")
    if "pump" in s:
        p = s["pump"]
        lines.append(
            f"  pump                        {plural(p['cylinders'], 'cylinder')}, discharge "
            f"{p['discharge_pressure'] / 1e6:.6g} MPa, suction {p['suction_pressure'] / 1e6:.6g} MPa"
        )
        lines.append(
            f"  mean flow                   {p['flow_mean']:.6g} m3/s "
            f"({p['flow_mean'] * 60e3:.6g} L/min)"
        )
        lines.append(
            f"  flow pulsation              {p['flow_pulsation']:.6g} (Q_max - Q_min)/Q_mean"
        )
        lines.append(f"  mean hydraulic power        {p['hydraulic_power_mean'] / 1e3:.6g} kW")
        lines.append(f"  mean mechanical power       {p['mechanical_power_mean'] / 1e3:.6g} kW")
        for q, e in p["extremes"].items():
            if q.startswith("cylinder_"):
                lines.append(
                    f"  {q:<26}  max {e['max']:.6g} {e['unit']} at {_angle(e['max_angle_deg'])}, "
                    f"min {e['min']:.6g} {e['unit']} at {_angle(e['min_angle_deg'])}"
                )
    return "\n".join(lines)
