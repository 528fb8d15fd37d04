"""Display units in the model description (docs/fmi-interface.md "Units"): importers with a GUI
show deg, rpm, kN, kN.m, MPa. The factors are checked against definitions independent of the
generator (1 rev = 2π rad = 360°, 1 min = 60 s, SI prefixes), the XML is checked against the FMI
2.0 schema by fmpy's validator, and a value converted with the declared factor reads as an engineer
expects (the default crank speed, 65 strokes/min, is 65 rpm)."""

from __future__ import annotations

import math

import pytest

EXPECTED = {  # (unit, display unit) -> display value of one SI unit
    ("rad", "deg"): 360.0 / (2 * math.pi),
    ("rad/s", "rpm"): 60.0 / (2 * math.pi),
    ("rad/s", "deg/s"): 360.0 / (2 * math.pi),
    ("rad/s2", "deg/s2"): 360.0 / (2 * math.pi),
    ("N", "kN"): 1e-3,
    ("N.m", "kN.m"): 1e-3,
    ("Pa", "MPa"): 1e-6,
    ("m", "mm"): 1e3,
    ("N/m", "N/mm"): 1e-3,
}


def test_factors(model_description):
    got = {}
    for u in model_description.unitDefinitions:
        for d in u.displayUnits:
            got[(u.name, d.name)] = (float(d.factor), float(d.offset or 0.0))
    assert set(got) == set(EXPECTED)
    for key, factor in EXPECTED.items():
        f, off = got[key]
        assert f == pytest.approx(factor, rel=1e-15), key
        assert off == 0.0, key


@pytest.mark.parametrize(
    "name,display",
    [
        ("crank.angle", "deg"),
        ("crank.model_angle", "deg"),
        ("rod.angle", "deg"),
        ("crank.speed", "rpm"),
        ("crank.model_speed", "rpm"),
        ("rod.force", "kN"),
        ("inertia.force", "kN"),
        ("guide.friction", "kN"),
        ("crank.torque", "kN.m"),
        ("rod.stress_max", "MPa"),
    ],
)
def test_variables_carry_their_display_unit(model_description, name, display):
    v = {v.name: v for v in model_description.modelVariables}[name]
    assert v.displayUnit == display


def test_default_speed_reads_65_rpm(model_description):
    v = {v.name: v for v in model_description.modelVariables}["crank.speed"]
    rpm = next(
        d
        for u in model_description.unitDefinitions
        if u.name == "rad/s"
        for d in u.displayUnits
        if d.name == "rpm"
    )
    assert float(v.start) * float(rpm.factor) == pytest.approx(65.0, rel=1e-14)


def test_schema_valid(fmu_path):
    from fmpy.validation import validate_fmu

    assert validate_fmu(fmu_path) == []
