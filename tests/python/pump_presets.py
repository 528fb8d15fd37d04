"""Pump machines for the workflows' tests, written as .ssv files from parameters given here (not
from the shipped presets, so that the tests do not move when a preset's data sheet changes)."""

from __future__ import annotations

import math
import pathlib

_TYPES = {int: "Integer", float: "Real", bool: "Boolean"}


def write_ssv(path: pathlib.Path, values: dict) -> pathlib.Path:
    """An SSP 1.0 parameter-value file holding `values` (name -> int, float or bool)."""
    rows = []
    for name, v in values.items():
        kind = _TYPES[type(v)]
        text = str(v).lower() if isinstance(v, bool) else repr(v)
        rows.append(
            f'    <ssv:Parameter name="{name}"><ssv:{kind} value="{text}"/></ssv:Parameter>'
        )
    path.write_text(
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"'
        f' version="1.0" name="{path.stem}">\n  <ssv:Parameters>\n'
        + "\n".join(rows)
        + "\n  </ssv:Parameters>\n</ssv:ParameterSet>\n"
    )
    return path


def pump(cylinders: int, acting: int, phases, **extra) -> dict:
    """A frictionless crank-slider pump with pressures in (load.profile 3): `cylinders` equal
    cylinders at the crank phases `phases` [rad] (cylinder 1's is 0), piston 0.13 m, no piston
    rod, 10 MPa discharge, 0.2 MPa suction, one revolution in 0.9 s (900 samples of 1 ms
    at the main job's step: the dead centres of 90° and 120° phases fall on samples)."""
    v = {
        "load.profile": 3,
        "fluid_end.cylinders": cylinders,
        "fluid_end.discharge_pressure": 10e6,
        "fluid_end.suction_pressure": 0.2e6,
        "guide.friction_coefficient": 0.0,
        "guide.velocity_scale": 1e-9,
        "crank.speed": 2 * math.pi / 0.9,
    }
    for k in range(1, cylinders + 1):
        v[f"cylinder_{k}.acting"] = acting
        v[f"cylinder_{k}.piston_diameter"] = 0.13
        v[f"cylinder_{k}.rod_diameter"] = 0.0
        if k > 1:
            v[f"cylinder_{k}.phase"] = float(phases[k - 1])
    v.update(extra)
    return v
