"""The main job for a pump (docs/results.md "Pump presets") against closed forms independent of the
FMU's code.

* Flow pulsation (Q_max − Q_min)/Q_mean in the textbook limit r/l → 0, no piston rod: a duplex
  double-acting pump delivers Q ∝ |sin θ| + |cos θ|, so (√2 − 1)·π/4; a triplex single-acting
  one Q ∝ Σ max(0, sin(θ + 2πk/3)), so (1 − √3/2)·π/3; a single-acting simplex π.
  Here r/l = 1e-6 (the error of the harmonic law is O(r/l)) and v_ε = 1e-9 m/s against
  r·ω ≈ 7 mm/s (the rounding of the dead centres changes Q by at most 0.14·A·v_ε).
  The dead centres fall on samples (pump_presets.pump), so the extremes at the kinks are
  sampled exactly; the smooth ones are refined by a parabola (error ~ step³). Tolerance 1e-5.
* Mean flow = displaced volume per revolution × revolutions per second, Σ (A_h + A_c)·2r·ω/(2π)
  for a real rod ratio and piston rod (the stroke of a centred crank-slider is 2r for any l);
  the tanh rounding of the dead centres takes ~ v_ε²/a per dead centre, negligible; the means
  are trapezoidal sums, whose error at the kinks of Q at the dead centres is h²/12 times the
  jumps of dQ/dθ (Euler–Maclaurin), 4e-6 of the mean at the main job's 900 samples per
  revolution: these runs take 9000 (step 0.1 ms), 4e-8, and compare to 1e-6.
* Without friction at constant speed the crank's mean power equals the fluid's mean power
  Δp·Q_mean (the suction pressure's work on the two chamber areas integrates to zero over a
  revolution): 1e-6 (the trapezoidal rule at the kinks of the torque, as above).
* Every cylinder's torque extremes are those of the single-cylinder torque shifted by its phase,
  and the plot and CSV carry the pump's columns.
"""

from __future__ import annotations

import csv
import json
import math

import pytest
from pump_presets import pump, write_ssv
from reciprocating_drive.commands import simulate

TEXTBOOK = [
    ("duplex_double", 2, 2, [0.0, math.pi / 2], (math.sqrt(2) - 1) * math.pi / 4),
    (
        "triplex_single",
        3,
        1,
        [0.0, 2 * math.pi / 3, 4 * math.pi / 3],
        (1 - math.sqrt(3) / 2) * math.pi / 3,
    ),
    ("simplex_single", 1, 1, [0.0], math.pi),
]


def run(fmu_path, tmp_path, name, values):
    ssv = write_ssv(tmp_path / f"{name}.ssv", values)
    args = [str(ssv), "--fmu", fmu_path, "--out-dir", str(tmp_path), "--step", "1e-4"]
    assert simulate.main(args) == 0
    return json.loads((tmp_path / f"{name}.json").read_text())


@pytest.mark.parametrize("name, n, acting, phases, expected", TEXTBOOK)
def test_flow_pulsation_textbook_limit(fmu_path, tmp_path, name, n, acting, phases, expected):
    s = run(
        fmu_path,
        tmp_path,
        name,
        pump(n, acting, phases, **{"geometry.crank_radius": 1e-3, "geometry.rod_length": 1e3}),
    )
    assert s["pump"]["cylinders"] == n
    assert s["pump"]["flow_pulsation"] == pytest.approx(expected, rel=1e-5)


def test_mean_flow_is_the_displacement_times_the_speed(fmu_path, tmp_path):
    r, d_piston, d_rod = 0.2, 0.13, 0.07
    v = pump(2, 2, [0.0, math.pi / 2], **{"geometry.crank_radius": r, "geometry.rod_length": 1.19})
    for k in (1, 2):
        v[f"cylinder_{k}.rod_diameter"] = d_rod
    s = run(fmu_path, tmp_path, "duplex", v)
    area = math.pi / 4 * (2 * d_piston**2 - d_rod**2)  # head end + crank end
    w = v["crank.speed"]
    q_mean = 2 * area * 2 * r * w / (2 * math.pi)
    p = s["pump"]
    assert p["flow_mean"] == pytest.approx(q_mean, rel=1e-6)
    dp = v["fluid_end.discharge_pressure"] - v["fluid_end.suction_pressure"]
    assert p["hydraulic_power_mean"] == pytest.approx(dp * q_mean, rel=1e-6)
    assert p["mechanical_power_mean"] == pytest.approx(dp * q_mean, rel=1e-6)
    # The summary's text and the plot/CSV of a pump.
    text = simulate.format_summary(s)
    for words in (
        "2 cylinders",
        "mean flow",
        "flow pulsation",
        "mean hydraulic power",
        "cylinder_1.crank_torque",
        "cylinder_2.crank_torque",
    ):
        assert words in text
    with open(tmp_path / "duplex.csv") as f:
        head = next(csv.reader(f))
    for col in (
        "fluid_end.flow [m3/s]",
        "crank.mechanical_power [W]",
        "cylinder_2.crank_torque [N.m]",
    ):
        assert col in head
    assert "cylinder_3.crank_torque [N.m]" not in head
    # Cylinder 2 is cylinder 1 a quarter revolution later: the same torque extremes, 90° earlier.
    e1 = p["extremes"]["cylinder_1.crank_torque"]
    e2 = p["extremes"]["cylinder_2.crank_torque"]
    assert e2["max"] == pytest.approx(e1["max"], rel=1e-9)
    assert (e1["max_angle_deg"] - e2["max_angle_deg"]) % 360 == pytest.approx(90.0, abs=0.01)


def test_a_machine_without_pressures_has_no_pump_section(fmu_path, tmp_path):
    s = run(fmu_path, tmp_path, "plain", {"load.profile": 1})
    assert "pump" not in s
    assert "mean flow" not in simulate.format_summary(s)


def test_mechanical_power_is_the_fluids_plus_every_cylinders_friction(fmu_path, tmp_path):
    """With guide friction, the crank's mean power exceeds the fluid's by the friction of all
    cylinders. The summary's friction work is cylinder 1's (link.friction_total along
    suspension.position); the two equal cylinders a quarter turn apart dissipate the same per
    revolution, so mean mechanical − mean hydraulic = −2·W_fr·ω/(2π). Tolerance 1e-4 of the
    friction power (the trapezoidal means at 9000 samples per revolution, 4e-8 of 200 kW)."""
    v = pump(2, 2, [0.0, math.pi / 2], **{"geometry.crank_radius": 0.2})
    v.update({"guide.friction_coefficient": 0.1, "guide.velocity_scale": 0.02})
    s = run(fmu_path, tmp_path, "friction", v)
    p = s["pump"]
    loss = -2 * s["friction_work_per_revolution"] * v["crank.speed"] / (2 * math.pi)
    assert loss > 1e3
    got = p["mechanical_power_mean"] - p["hydraulic_power_mean"]
    assert got == pytest.approx(loss, rel=1e-4)
