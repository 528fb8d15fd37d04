"""The main job's summary (results/<preset>.json, docs/results.md) against closed forms that do not
come from the FMU's code: the crank-slider's stroke 2r and its acceleration extremes
rω²(1 ± λ) at the dead centres (docs/model.md §3.1, λ = r/l < 1/4 so the minimum is at 180°); the
beam unit's closed-form stroke S = A·|ψ(P+R) − ψ(P−R)| (§3.2) and its acceleration extremes found
by an independent search in extended precision (mpmath on the exact four-bar position); the
elastic rod's piston law s = r(1 − cosθ) (§6), whose extremes are ±rω² at 0° and 180°. Every
preset's run writes its JSON and PNG through the script run.sh calls.

Tolerances: the summary refines sampled extremes by a parabola (error ~ step³ · third derivative):
with 900 samples per revolution that is below 1e-7 of a peak and 0.01° of its angle.
"""

from __future__ import annotations

import json
import math
import re

import mpmath as mp
import pytest
from conftest import ROOT
from reciprocating_drive.commands import simulate


def angle_close(a_deg, b_deg, tol=0.01):
    d = (a_deg - b_deg + 180.0) % 360.0 - 180.0
    return abs(d) <= tol


@pytest.fixture(scope="module")
def summaries(fmu_path, tmp_path_factory):
    out = tmp_path_factory.mktemp("results")
    got = {}
    for preset in (
        "default",
        "unb600a",
        "unb600a-simplex",
        "triplex-1600",
        "sk8-3.5-4000",
        "kvo630",
    ):
        assert simulate.main([preset, "--fmu", fmu_path, "--out-dir", str(out)]) == 0
        got[preset] = json.loads((out / f"{preset}.json").read_text())
        png = (out / f"{preset}.png").read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000
    return got


@pytest.mark.parametrize("preset", ["default", "unb600a"])
def test_crank_slider_summary(summaries, preset):
    s = summaries[preset]
    r, l, m = 0.2, 1.19, 300.0
    w = 2 * math.pi * 65 / 60
    lam = r / l
    assert s["mechanism"] == "crank-slider" and s["rod"] == "rigid rod"
    assert s["stroke"] == pytest.approx(2 * r, rel=1e-7)
    acc = s["extremes"]["suspension.acceleration"]
    assert acc["max"] == pytest.approx(r * w * w * (1 + lam), rel=1e-7)
    assert acc["min"] == pytest.approx(-r * w * w * (1 - lam), rel=1e-7)
    assert angle_close(acc["max_angle_deg"], 0.0) and angle_close(acc["min_angle_deg"], 180.0)
    phi = s["extremes"]["inertia.force"]
    assert phi["max"] == pytest.approx(-m * acc["min"], rel=1e-12)
    assert phi["min"] == pytest.approx(-m * acc["max"], rel=1e-12)
    # Guide friction is on in both (default supports): friction takes energy out every revolution.
    assert s["friction_work_per_revolution"] < 0
    assert s["extremes"]["guide.friction"]["max"] > 0 > s["extremes"]["guide.friction"]["min"]
    assert "rod_angle_amplitude" not in s


def beam_position(theta):
    """Polished-rod position A·b(θ) of the sk8-3.5-4000 unit (class I, rotation −1), written from
    the geometry of docs/model.md §3.2 in mpmath: intersection of the pitman circle about the crank
    pin with the equalizer circle about the centre bearing."""
    A, C, I, HG, P, R = map(mp.mpf, ("3.5", "2.5", "2.195", "3.0", "3.0", "1.01"))
    q = -theta
    cx, cy = R * mp.sin(q), R * mp.cos(q)
    # E = B − C(cos b, sin b); |E − crank pin| = P  →  solve for b near 0.
    f = lambda b: (I - C * mp.cos(b) - cx) ** 2 + (HG - C * mp.sin(b) - cy) ** 2 - P**2  # noqa: E731
    return A * mp.findroot(f, mp.mpf(0))


def test_beam_unit_summary(summaries):
    mp.mp.dps = 30
    s = summaries["sk8-3.5-4000"]
    A, C, I, HG, P, R = 3.5, 2.5, 2.195, 3.0, 3.0, 1.01
    K = math.hypot(I, HG)
    psi = lambda d: math.acos((C * C + K * K - d * d) / (2 * C * K))  # noqa: E731
    assert s["mechanism"] == "beam pumping unit, API class I"
    assert s["stroke"] == pytest.approx(A * abs(psi(P + R) - psi(P - R)), rel=1e-7)
    # Acceleration a = ω²·d²s/dθ² at constant speed: extremes by an independent search.
    w = 2 * math.pi * 10.9 / 60
    acc = lambda th: w * w * mp.diff(beam_position, th, 2)  # noqa: E731
    for key in ("max", "min"):
        e = s["extremes"]["suspension.acceleration"]
        th0 = mp.radians(e[f"{key}_angle_deg"])
        th = mp.findroot(lambda x: mp.diff(lambda y: acc(y), x), th0)
        assert e[key] == pytest.approx(float(acc(th)), rel=1e-6)
        assert angle_close(e[f"{key}_angle_deg"], float(mp.degrees(th)) % 360.0, tol=0.01)
    # The values a published analysis of this unit did not find (docs/model.md §9).
    assert s["extremes"]["suspension.acceleration"]["max"] == pytest.approx(2.8506428, rel=1e-6)
    assert s["friction_work_per_revolution"] == 0.0  # a single clamp: no redundant supports


def test_elastic_rod_summary(summaries):
    s = summaries["kvo630"]
    r, w = 1e-3, 2 * math.pi * 1500 / 60
    assert s["rod"] == "helical-spring rod"
    assert s["stroke"] == pytest.approx(2 * r, rel=1e-9)
    acc = s["extremes"]["suspension.acceleration"]
    assert acc["max"] == pytest.approx(r * w * w, rel=1e-9) and angle_close(
        acc["max_angle_deg"], 0.0
    )
    assert acc["min"] == pytest.approx(-r * w * w, rel=1e-9) and angle_close(
        acc["min_angle_deg"], 180.0
    )
    # The cage oscillates within the validity limit of the linear theory, and the transient is
    # over before the summarised revolution.
    assert 0 < s["rod_angle_amplitude"] < 0.2
    assert s["stress_max"] > 0
    assert s["transient_revolutions"] < s["summarized_revolution"]


def test_results_page_shows_what_a_fresh_run_prints(summaries):
    """docs/results.md gives the summary of every preset as the main job prints it; a fresh run
    prints the same, to the last printed digit (regenerate: scripts/make_docs.py --results-only)."""
    from reciprocating_drive.mission import format_summary
    from reciprocating_drive.presets import available_presets

    page = (ROOT / "docs" / "results.md").read_text()
    section = page.split("<!-- results:begin -->")[1].split("<!-- results:end -->")[0]
    shown = dict(re.findall(r"`scripts/run\.sh (\S+)`:\s*```text\n(.*?)\n```", section, re.S))
    assert set(shown) == set(available_presets()) == set(summaries)
    for preset, s in summaries.items():
        assert shown[preset] == format_summary(s), (
            f"docs/results.md: the summary of {preset} differs from a fresh run; "
            "regenerate it with scripts/make_docs.py --results-only"
        )


def _summary(max_deg=10.0, min_deg=190.0, vmax=1.0, vmin=-1.0, transient=None):
    s = {
        "preset": "p",
        "mechanism": "crank-slider",
        "rod": "rigid rod",
        "strokes_per_minute": 65.0,
        "stroke": 0.4,
        "extremes": {
            "guide.friction": {
                "unit": "N",
                "max": vmax,
                "max_angle_deg": max_deg,
                "min": vmin,
                "min_angle_deg": min_deg,
            }
        },
        "friction_work_per_revolution": -1.0,
    }
    if transient is not None:
        s.update(rod_angle_amplitude=0.04, stress_max=2.7e8, transient_revolutions=transient)
    return s


@pytest.mark.parametrize(
    "deg, shown",
    [
        (359.996, "0.00°"),
        (359.994, "359.99°"),
        (360.0, "0.00°"),
        (-0.001, "0.00°"),
        (0.004, "0.00°"),
    ],
)
def test_printed_angles_are_modulo_360(deg, shown):
    """An extreme at the end of a revolution prints as 0.00°, never 360.00° (or -0.00°)."""
    from reciprocating_drive.mission import format_summary

    line = format_summary(_summary(max_deg=deg)).splitlines()[2]
    assert f"max 1 N at {shown}," in line, line


def test_printed_angles_of_every_preset_are_below_360(summaries):
    from reciprocating_drive.mission import format_summary

    for s in summaries.values():
        angles = [float(a) for a in re.findall(r"at (-?[\d.]+)°", format_summary(s))]
        assert angles and all(0.0 <= a < 360.0 for a in angles), format_summary(s)


def test_a_zero_signal_reads_zero_throughout(summaries):
    """sk8-3.5-4000 is held by a single clamp: its guide friction is zero over the revolution, which
    the summary says in words (no "max 0 N at 0.22°"), and the JSON gives no angle for it."""
    from reciprocating_drive.mission import format_summary

    s = summaries["sk8-3.5-4000"]
    e = s["extremes"]["guide.friction"]
    assert e["max"] == e["min"] == 0.0 and e["max_angle_deg"] is None is e["min_angle_deg"]
    assert re.search(r"guide\.friction +zero throughout$", format_summary(s), re.M)
    # A signal that is not zero keeps its extremes and their angles.
    assert "zero throughout" not in format_summary(_summary(vmax=0.0, vmin=-1.0))
    assert "zero throughout" not in format_summary(summaries["default"])


@pytest.mark.parametrize(
    "n, words", [(0, "0 revolutions"), (1, "1 revolution)"), (2, "2 revolutions")]
)
def test_revolutions_singular_and_plural(n, words):
    from reciprocating_drive.mission import format_summary

    assert f"steady after {words}" in format_summary(_summary(transient=n))
