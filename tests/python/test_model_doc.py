"""docs/model.md against the FMU: §10 names every variable, the unit list of the introduction holds
every unit of the model description, the table of §5.2 says which support parameters act (checked
by varying each one in the FMU and comparing the outputs), and the figures of §6 "Communication
step" (kvo630's natural period from the closed form of §6, re-derived here; the free oscillation's
period, decay and the steady oscillation's harmonics measured in the FMU)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from conftest import ROOT

MODEL = (ROOT / "docs" / "model.md").read_text()
GUIDE = (ROOT / "docs" / "user-guide.md").read_text()


def section(title_start: str) -> str:
    return MODEL.split(f"\n## {title_start}")[1].split("\n## ")[0]


def test_units_list_holds_every_unit(model_description):
    intro = MODEL.split("Symbols used throughout")[0]
    listed = set(
        re.findall(r"\w[\w./]*\w|\w", intro.split("the variables use")[1].split("\n\n")[0])
    )
    units = {u.name for u in model_description.unitDefinitions}
    for v in model_description.modelVariables:
        if v.unit:
            units.add(v.unit)
    assert units and units <= listed, f"units missing from docs/model.md: {units - listed}"


def test_section_10_names_every_variable(model_description):
    sec = section("10.")
    names = set(re.findall(r"`([\w.*()]+)`", sec))
    patterns = [
        re.compile(
            "^"
            + re.escape(n)
            .replace(r"\*", r"\w+")
            .replace("support_X", "support_[ABC]")
            .replace("cylinder_k", "cylinder_[123]")
            + "$"
        )
        for n in names
    ]
    missing = [
        v.name
        for v in model_description.modelVariables
        if not any(p.match(v.name) for p in patterns)
    ]
    assert not missing, f"docs/model.md §10 does not name {missing}"
    assert "`crank.angle_offset`" in sec


# --- §5.2: which support parameters act -------------------------------------------------------

OUTPUTS = [
    "guide.friction",
    "guide.reaction",
    "guide.moment",
    "guide.edge_force_1",
    "guide.edge_force_2",
    "support_A.reaction",
    "support_C.reaction",
    "link.friction_total",
    "rod.force",
    "crank.torque",
]
PARAMS = ("attached", "z", "length", "offset", "tilt", "stiffness", "friction")


def support_table() -> dict:
    """kind -> (parameters that act, parameters without effect), the table of docs/model.md §5.2."""
    out = {}
    for m in re.finditer(r"^\| (\d) [a-z -]+ \| (.*?) \| (.*?) \|$", section("5."), re.M):
        acts = set(re.findall(r"`(\w+)`", m.group(2))) & set(PARAMS)
        none = set(re.findall(r"`(\w+)`", m.group(3))) & set(PARAMS)
        out[int(m.group(1))] = (acts, none)
    return out


def test_support_table_lists_every_parameter_of_every_kind():
    table = support_table()
    assert set(table) == {0, 1, 2, 3}
    for kind in (1, 2, 3):
        acts, none = table[kind]
        # A parameter that acts only under a condition is in both cells; none is in neither.
        assert acts | none == set(PARAMS), (kind, acts, none)
    assert table[1][1] == {"length", "tilt"} and table[2][1] == {"length"} and not table[3][1]


@pytest.fixture(scope="module")
def outputs_of(fmu_path):
    from fmpy import simulate_fmu

    w = 2 * math.pi * 65 / 60
    period = 2 * math.pi / w

    def run(values: dict) -> np.ndarray:
        r = simulate_fmu(
            fmu_path,
            start_values=values,
            stop_time=period,
            output_interval=period / 180,
            output=OUTPUTS,
        )
        return np.column_stack([r[n] for n in OUTPUTS])

    return run


def acts(run, base: dict, name: str, value) -> bool:
    return bool(np.any(run(base) != run({**base, name: value})))


# (support, kind, attached, friction, parameter, new value, acts) on the default machine: the
# cases the table of §5.2 states, with both outcomes for each conditional entry.
CASES = [
    ("C", 1, 1, 0.05, "tilt", 2e-4, False),  # a frame-fixed pin (the default gland)
    ("C", 1, 1, 0.05, "length", 0.2, False),
    ("C", 1, 0, 0.05, "tilt", 2e-4, True),  # a pin moving with the link
    ("C", 1, 1, 0.05, "offset", 2e-4, True),
    ("C", 1, 1, 0.05, "stiffness", 4e6, True),
    ("C", 1, 1, 0.05, "friction", 0.1, True),
    ("C", 2, 1, 0.0, "length", 0.2, False),  # a clamp without friction
    ("C", 2, 1, 0.05, "length", 0.2, True),
    ("C", 2, 1, 0.05, "tilt", 2e-4, True),
    ("C", 3, 1, 0.05, "tilt", 2e-4, True),
    ("C", 3, 1, 0.05, "length", 0.2, True),
    ("C", 0, 1, 0.05, "offset", 2e-4, False),
    ("C", 0, 1, 0.05, "friction", 0.1, False),
    ("C", 1, 1, 0.05, "attached", 0, True),
    ("C", 2, 1, 0.05, "attached", 0, True),
    ("C", 3, 1, 0.05, "attached", 0, True),
    ("C", 2, 1, 0.05, "z", 1.55, True),
    ("C", 2, 1, 0.05, "stiffness", 4e6, True),
    ("B", 1, 1, None, "tilt", 3e-4, False),
    ("B", 1, 0, None, "tilt", 3e-4, True),
    ("B", 3, 0, None, "length", 0.3, True),
]


@pytest.mark.parametrize("support, kind, attached, friction, name, value, expected", CASES)
def test_support_parameters_act_as_section_5_2_says(
    outputs_of, support, kind, attached, friction, name, value, expected
):
    acts_, none = support_table()[kind]
    # The page says so: an unconditional entry is in one cell only.
    assert name in (acts_ if expected else none) or kind == 0, (kind, name)
    base = {
        f"support_{support}.kind": kind,
        f"support_{support}.attached": attached,
        f"support_{support}.length": 0.1,
    }
    if friction is not None:
        base[f"support_{support}.friction"] = friction
    assert acts(outputs_of, base, f"support_{support}.{name}", value) == expected


def test_a_single_clamp_has_no_reaction_from_misalignment_or_friction(fmu_path):
    """§5.2: misalignments act only where the supports are redundant (sk8-3.5-4000: one clamp)."""
    from fmpy import simulate_fmu
    from reciprocating_drive import preset_values

    v = preset_values("sk8-3.5-4000")
    period = 2 * math.pi / v["crank.speed"]

    def run(extra):
        r = simulate_fmu(
            fmu_path,
            start_values={**v, **extra},
            stop_time=period,
            output_interval=period / 90,
            output=OUTPUTS,
        )
        return np.column_stack([r[n] for n in OUTPUTS])

    base = run({})
    for name, value in (("offset", 1e-3), ("tilt", 1e-3), ("friction", 0.1)):
        assert np.array_equal(run({f"support_A.{name}": value}), base), name


# --- §6 "Communication step": kvo630's time scales ---------------------------------------------


def k_theta(P: float) -> float:
    """K_ϑ of the kvo630 spring (docs/model.md §6 and §8), written out here from the page."""
    E, nu, d, D, i, lf, f = 2.06e11, 0.304, 1e-3, 5e-3, 8, 23e-3, 15e-3
    G = E / (2 * (1 + nu))
    h = lf / i
    Bt, Bb = G * math.pi * d**4 / 32, E * math.pi * d**4 / 64
    A1 = 8 * h * Bb / (math.pi * D**3)
    A2 = (2 * h / (math.pi * D)) * Bt * Bb / (Bt + Bb)
    N = -P
    sN = 1 - N / A1
    x = N * sN / A2
    z = lf
    if x == 0:
        C, S, V3, V4 = 1.0, z, z * z / 2, z**3 / 6
    elif x > 0:
        k = math.sqrt(x)
        C, S = math.cosh(k * z), math.sinh(k * z) / k
        V3, V4 = (C - 1) / x, (S - z) / x
    else:
        k = math.sqrt(-x)
        C, S = math.cos(k * z), math.sin(k * z) / k
        V3, V4 = (C - 1) / x, (S - z) / x
    eta, f1 = A2 / (A1 * sN**2), f / sN
    e_, d_ = V3 + f1 * S, V4 + f1 * V3 - eta * lf
    l3, l4 = C + f1 * x * S, S + f1 * C
    Ws = V3 * V3 - S * V4 + eta * lf * S
    return A2 * (e_ * l4 - d_ * l3) / Ws


def test_natural_period_in_the_pages():
    Jm = 5e-7
    om0 = math.sqrt(k_theta(0.0) / Jm)
    assert f"Ω0 = {om0:.0f} rad/s" in MODEL and f"Ω0 = {om0:.0f} rad/s" in GUIDE
    period_ms = 2e3 * math.pi / om0
    assert f"period of {period_ms:.1f} ms" in MODEL and f"{period_ms:.1f} ms" in GUIDE
    # Under the process force the spring is softer (the period the FMU shows, below).
    loaded_ms = 2e3 * math.pi / math.sqrt(k_theta(14.7) / Jm)
    assert f"period of {loaded_ms:.1f} ms" in MODEL
    assert f"ζ·Ω0 = {0.05 * om0:.0f} 1/s" in MODEL and f"{1e3 / (0.05 * om0):.0f} ms" in MODEL


def test_kvo630_time_scales_in_the_fmu(fmu_path):
    """The free oscillation (difference of the runs from the two initial states of §6) has the
    loaded natural period and decays at ζ·Ω0; the steady oscillation has the crank's period and a
    second harmonic of about 0.5 % of the first."""
    from fmpy import simulate_fmu
    from reciprocating_drive import preset_values

    v = preset_values("kvo630")
    h = 2e-5
    runs = [
        simulate_fmu(
            fmu_path,
            start_values={**v, "rod.initial_state": s},
            stop_time=0.4,
            output_interval=h,
            output=["rod.angle"],
        )
        for s in (0, 1)
    ]
    t = runs[0]["time"]
    free = runs[0]["rod.angle"] - runs[1]["rod.angle"]
    early = t < 0.06
    crossings = t[1:][early[1:] & (np.sign(free[1:]) != np.sign(free[:-1]))]
    period_ms = 2e3 * np.mean(np.diff(crossings))
    assert f"period of {period_ms:.1f} ms" in MODEL, period_ms
    # Decay rate from the envelope over 40 ms: ζ·Ω0 = 75 1/s within 5 %.
    a0 = np.abs(free[t < 0.01]).max()
    a1 = np.abs(free[(t >= 0.04) & (t < 0.05)]).max()
    assert math.log(a0 / a1) / 0.04 == pytest.approx(75, rel=0.05)
    # Steady: 5 crank periods (40 ms each, as the pages say) after 0.2 s.
    assert "crank's period 2π/ω, 40 ms for kvo630" in MODEL
    assert 2 * math.pi / v["crank.speed"] == pytest.approx(0.040, rel=1e-12)
    steady = runs[1]["rod.angle"][(t >= 0.2 - h / 2)][:10000]
    spectrum = np.abs(np.fft.rfft(steady))
    ratio = spectrum[10] / spectrum[5]
    assert 0.004 < ratio < 0.006 and "about 0.5 % of the first" in MODEL, ratio
    assert spectrum[15:].max() < 1e-3 * spectrum[5]
