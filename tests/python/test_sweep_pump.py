"""Sweeps of a pump (docs/sweeps.md, example (d) and the metrics flow_mean, flow_pulsation), against
closed forms independent of the FMU's and the sweep's code.

* The example study studies/unb600a_phase_error.toml runs (three of its cases) and its mean flow is
  the displaced volume per revolution times the revolutions per second, less what the tanh
  transition of docs/model.md §4.1 takes at the dead centres: near one, v ≈ a·t, and every chamber
  delivers A·|v|·(1 − tanh(|v|/v_ε))/2 less than the ideal valve on both sides of it, in all
  A·(v_ε²/a)·∫₀^∞ u(1 − tanh u) du = A·(v_ε²/a)·π²/24. With a = rω²(1 ± λ) at the two dead
  centres, the relative deficit is (π²/24)·v_ε²/(r²ω²(1 − λ²)) (9e-5 for the UNB-600A), left
  at O(v_ε⁴); tolerance 1e-6. The mean flow does not depend on the phase.
* The flow pulsation against the phase φ of cylinder 2 in the textbook limit (r/l = 1e-6, no piston
  rod, v_ε = 1e-9 m/s): Q ∝ |sin θ| + |sin(θ + φ)|, whose extremes the test finds on a grid of
  0.001° that holds every kink; the phases are whole multiples of the study's 0.1° step, so the
  sweep samples the kinks too. Tolerance 1e-5 (the O(r/l) of the harmonic law, the parabola-free
  sampled maximum 0.1° from a smooth peak: (0.1°)²/2·Q'' ≈ 2e-6 of Q).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROOT
from pump_presets import pump, write_ssv
from reciprocating_drive.sweeps.study import load_study
from reciprocating_drive.sweeps.sweep import run_batch


def test_example_study_mean_flow(fmu_path):
    study = load_study(ROOT / "studies" / "unb600a_phase_error.toml", fmu=fmu_path)
    v = {k: x.start for k, x in study.variables.items()}
    v.update(study.base_values)
    r, lam = v["geometry.crank_radius"], v["geometry.crank_radius"] / v["geometry.rod_length"]
    w, ve = study.crank_speed, v["guide.velocity_scale"]
    volume = 0.0
    for k in range(1, int(v["fluid_end.cylinders"]) + 1):
        d2 = v[f"cylinder_{k}.piston_diameter"] ** 2
        rod2 = v[f"cylinder_{k}.rod_diameter"] ** 2 if v[f"cylinder_{k}.acting"] == 2 else d2
        volume += math.pi / 4 * (2 * d2 - rod2) * 2 * r
    deficit = math.pi**2 / 24 * ve**2 / (r * r * w * w * (1 - lam * lam))
    expected = volume * w / (2 * math.pi) * (1 - deficit)
    rows = run_batch(fmu_path, study, [0, 10, 20])
    for row in rows:
        assert row["status"] == "ok", row["message"]
        assert row["flow_mean"] == pytest.approx(expected, rel=1e-6)
        assert row["flow_pulsation"] > 0 and row["torque_peak"] > 0
    # The peak torque and the pulsation do change with the phase.
    assert len({round(row["flow_pulsation"], 6) for row in rows}) == 3


def textbook_pulsation(phi: float) -> float:
    """(Q_max − Q_min)/Q_mean of |sin θ| + |sin(θ + φ)|, on a grid of 0.001° (holding the kinks
    at multiples of 180° and at −φ, which the phases below are multiples of 0.1° for)."""
    th = np.radians(np.arange(360_000) * 1e-3)
    q = np.abs(np.sin(th)) + np.abs(np.sin(th + phi))
    return float((q.max() - q.min()) / (4 / math.pi))


def test_phase_error_in_the_textbook_limit(fmu_path, tmp_path):
    machine = pump(2, 2, [0.0, math.pi / 2])
    machine.update({"geometry.crank_radius": 1e-3, "geometry.rod_length": 1e3})
    write_ssv(tmp_path / "duplex.ssv", machine)
    phases = [math.radians(d) for d in (80.0, 85.0, 90.0, 95.0, 100.0)]
    text = (ROOT / "studies" / "unb600a_phase_error.toml").read_text()
    head, _, _ = text.partition("[parameters]")
    head = head.replace('machine = "unb600a"', f'machine = "{tmp_path / "duplex.ssv"}"')
    head = head.replace("strokes_per_minute = 65", "strokes_per_minute = 66.66666666666667")
    body = f'[parameters]\n"cylinder_2.phase" = {{ values = {phases!r} }}\n'
    (tmp_path / "s.toml").write_text(head + body)
    study = load_study(tmp_path / "s.toml", fmu=fmu_path)
    rows = run_batch(fmu_path, study, list(range(len(phases))))
    for row, phi in zip(rows, phases):
        assert row["status"] == "ok", row["message"]
        assert row["flow_pulsation"] == pytest.approx(textbook_pulsation(phi), rel=1e-5), phi
    # The textbook optimum is the quarter turn: (√2 − 1)·π/4.
    assert rows[2]["flow_pulsation"] == pytest.approx((math.sqrt(2) - 1) * math.pi / 4, rel=1e-5)
