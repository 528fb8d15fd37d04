"""Generates what docs/ shows that comes from the code: the figures (sketches of each mechanism with
its coordinates and supports, plots of typical results computed by the FMU) and the variable table
of docs/fmi-interface.md (from the FMU's model description).

    .venv/bin/python scripts/make_docs.py                 # docs/figures/*.png + the table
    .venv/bin/python scripts/make_docs.py --out DIR       # figures into DIR, docs/ untouched
    .venv/bin/python scripts/make_docs.py --table-only    # only the variable table

The FMU is target/fmu/ReciprocatingDrive.fmu (RD_FMU overrides it); scripts/build-fmu.sh builds it.
"""

from __future__ import annotations

import argparse
import math
import os
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Circle, FancyArrowPatch, Rectangle  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))

FMU = pathlib.Path(os.environ.get("RD_FMU", ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu"))
FIGURES = ROOT / "docs" / "figures"
INTERFACE = ROOT / "docs" / "fmi-interface.md"

# Every figure this script writes; docs/*.md refer to them as figures/<name>.png.
SKETCHES = ("crank_slider", "beam_units", "supports", "elastic_rod")
RESULTS = ("results_default", "results_sk8-3.5-4000", "results_kvo630")
# Drawn by scripts/closed_loop.py (docs/closed-loop.md).
CLOSED_LOOP = "closed_loop"


def _arrow(ax, p, q, text=None, color="k", **kw):
    ax.add_patch(
        FancyArrowPatch(p, q, arrowstyle="-|>", mutation_scale=12, color=color, lw=1.2, **kw)
    )
    if text:
        ax.annotate(text, q, textcoords="offset points", xytext=(4, 4), color=color)


def _finish(ax, title):
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title(title, fontsize=11)


def sketch_crank_slider(path):
    """Crank-slider at θ = 50° (docs/model.md §3.1): crank, rod, crosshead, s from the ODC."""
    r, l, th = 0.2, 0.75, math.radians(50)
    pin = np.array([r * math.cos(th), r * math.sin(th)])
    beta = math.asin(r * math.sin(th) / l)
    x = r * math.cos(th) + l * math.cos(beta)
    fig, ax = plt.subplots(figsize=(7, 3))
    ax.plot([-0.3, 1.25], [0, 0], "k-.", lw=0.6)
    ax.add_patch(Circle((0, 0), r, fill=False, ls=":", lw=0.8))
    ax.plot([0, pin[0]], [0, pin[1]], "C0-", lw=3)
    ax.plot([pin[0], x], [pin[1], 0], "C1-", lw=3)
    ax.add_patch(Rectangle((x - 0.05, -0.04), 0.1, 0.08, fc="0.85", ec="k"))
    ax.plot([x + 0.05, 1.2], [0, 0], "k-", lw=4)  # piston rod
    ax.plot([0], [0], "ko")
    ax.annotate("θ", (0.07, 0.03))
    ax.annotate("β", (x - 0.2, 0.015), color="C1")
    ax.annotate("crank r", (pin[0] / 2 - 0.1, pin[1] / 2 + 0.03), color="C0")
    ax.annotate("rod l", ((pin[0] + x) / 2, pin[1] / 2 + 0.03), color="C1")
    xodc = r + l
    ax.plot([xodc, xodc], [-0.12, 0.12], "k:", lw=0.8)
    ax.annotate("ODC (s = 0)", (xodc - 0.05, -0.17))
    _arrow(ax, (xodc, -0.09), (x, -0.09), "s", color="C3")
    _arrow(ax, (0, 0), (0.3, 0), None)
    ax.annotate("x", (0.3, -0.05))
    _arrow(ax, (0, 0), (0, 0.28), "y")
    _finish(
        ax, "Crank-slider: θ from the stroke axis, s from the outer dead centre toward the crank"
    )
    fig.savefig(path, dpi=90, bbox_inches="tight")
    plt.close(fig)


def sketch_beam_units(path):
    """API class I and class III geometry (docs/model.md §3.2), well on the right."""
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6))
    for ax, cls in zip(axes, ("I", "III")):
        R, C, A, I, HG = (0.5, 1.2, 1.8, 1.2, 1.6) if cls == "I" else (0.5, 1.0, 2.6, 0.9, 1.6)
        bx = I if cls == "I" else -I
        b = 0.1
        u = np.array([math.cos(b), math.sin(b)])
        B = np.array([bx, HG])
        E = B - C * u if cls == "I" else B + C * u
        head = B + A * u if cls == "I" else B + A * u
        q = math.radians(30)
        pin = np.array([R * math.sin(q), R * math.cos(q)])
        ax.add_patch(Circle((0, 0), R, fill=False, ls=":", lw=0.8))
        ax.plot([0, pin[0]], [0, pin[1]], "C0-", lw=3)
        ax.plot([pin[0], E[0]], [pin[1], E[1]], "C1-", lw=3)
        ax.plot([E[0], head[0]], [E[1], head[1]], "C2-", lw=4)
        ax.plot([head[0], head[0]], [head[1], 0.0], "k-", lw=1.5)
        ax.plot(*B, "k^", ms=10)
        ax.plot(0, 0, "ko")
        ax.annotate("centre bearing", B + (0.05, 0.12), fontsize=8)
        ax.annotate("equalizer", E + (-0.3, -0.25), fontsize=8)
        ax.annotate("horsehead", head + (-0.2, 0.12), fontsize=8)
        ax.annotate("R", pin / 2 + (0.05, 0), color="C0")
        ax.annotate("P", (pin + E) / 2 + (0.05, 0), color="C1")
        ax.annotate("θ (from 12 o'clock)", (0.05, R + 0.08), fontsize=8)
        _arrow(ax, (head[0] + 0.15, 0.3), (head[0] + 0.15, 0.9), "s", color="C3")
        ax.annotate("well →", (head[0] + 0.1, -0.25), fontsize=8)
        ax.set_xlim(-2.3, 3.6)
        ax.set_ylim(-0.8, 2.4)
        _finish(
            ax,
            f"Class {cls}: "
            + (
                "bearing between\nequalizer and horsehead"
                if cls == "I"
                else "equalizer between\nbearing and horsehead"
            ),
        )
    fig.savefig(path, dpi=90, bbox_inches="tight")
    plt.close(fig)


def sketch_supports(path):
    """The default pump's link as a stepped beam with supports A, B, C (docs/model.md §5)."""
    fig, ax = plt.subplots(figsize=(9, 2.6))
    sections = [(0.55, 0.070), (0.15, 0.130), (1.00, 0.100), (0.40, 0.300)]
    z = 0.0
    for length, d in sections:
        ax.add_patch(Rectangle((z, -d / 2), length, d, fc="0.9", ec="k"))
        z += length
    L = z
    ax.annotate("A: clamp (piston in liner)\nmoves with the link", (0.0, 0.19), fontsize=8)
    ax.add_patch(Rectangle((0.0, -0.06), 0.25, 0.12, fc="none", ec="C0", lw=2))
    ax.add_patch(Rectangle((1.70, -0.17), 0.40, 0.34, fc="none", ec="C1", lw=2))
    ax.annotate(
        "B: two-edge guide (crosshead)\noffset δ, tilt α", (1.55, 0.21), fontsize=8, color="C1"
    )
    ax.plot([1.60, 1.60], [-0.2, 0.2], "C2-", lw=2)
    ax.annotate("C: pin fixed in the frame\n(gland, spring)", (1.05, -0.33), fontsize=8, color="C2")
    _arrow(ax, (0, -0.22), (0.4, -0.22), "z", color="k")
    ax.annotate("z = 0 (piston end)", (0, -0.3), fontsize=8)
    ax.annotate(f"z = L = {L:.2f} m (crank side)", (L - 0.5, -0.3), fontsize=8)
    _arrow(ax, (L + 0.05, 0), (L + 0.05, 0.2), "y", color="k")
    ax.set_xlim(-0.1, L + 0.3)
    ax.set_ylim(-0.4, 0.4)
    ax.set_aspect("auto")
    ax.axis("off")
    ax.set_title("The link of the default pump: sections l1..l4, supports A, B, C", fontsize=11)
    fig.savefig(path, dpi=90, bbox_inches="tight")
    plt.close(fig)


def sketch_elastic_rod(path):
    """Elastic rod clamped in the piston, rigid end, cage on the pin, ϑ (docs/model.md §6)."""
    fig, ax = plt.subplots(figsize=(7, 3))
    lf, f, delta, th = 2.3, 1.5, 0.45, 0.18
    zz = np.linspace(0, lf, 60)
    # a clamped bent shape ending at slope th
    v = (
        delta * (3 * (zz / lf) ** 2 - 2 * (zz / lf) ** 3) * 0.8
        + th * lf * ((zz / lf) ** 3 - (zz / lf) ** 2) * 0.5
    )
    ax.add_patch(Rectangle((-0.8, -0.35), 0.8, 0.7, fc="0.85", ec="k"))
    ax.annotate("piston\n(clamp)", (-0.75, -0.15), fontsize=8)
    ax.plot(zz, v, "C1-", lw=2.5)
    end = np.array([lf, v[-1]])
    tip = end + f * np.array([math.cos(th), math.sin(th)])
    ax.plot([end[0], tip[0]], [end[1], tip[1]], "C0-", lw=4)
    ax.add_patch(Circle(tip, 0.18, fill=False, ec="C0", lw=2))
    ax.annotate("cage on the crank pin (J_m)", tip + (-0.6, 0.3), fontsize=8, color="C0")
    ax.plot([end[0], end[0] + 1.2], [end[1], end[1]], "k:", lw=0.8)
    ax.annotate("ϑ", end + (0.6, 0.05), fontsize=12, color="C3")
    ax.annotate("elastic part l_f", (0.6, -0.35), fontsize=8, color="C1")
    ax.annotate("rigid part f", ((end + tip) / 2 + (0, -0.35)), fontsize=8, color="C0")
    ax.plot([-0.8, lf + f + 0.5], [0, 0], "k-.", lw=0.6)
    _arrow(ax, (tip[0] + 0.5, 0), (tip[0] + 0.5, tip[1]), None, color="C3")
    ax.annotate(
        "Δ = r sinθ − e\n(pin's lateral offset)", (tip[0] + 0.6, 0.2), fontsize=8, color="C3"
    )
    ax.set_xlim(-1, lf + f + 2.6)
    ax.set_ylim(-0.6, 1.0)
    _finish(ax, "Elastic connecting rod clamped in the piston: cage rotation ϑ")
    fig.savefig(path, dpi=90, bbox_inches="tight")
    plt.close(fig)


def result_figures(out: pathlib.Path) -> None:
    """Typical results of the default machine, the beam unit and kvo630, drawn by the main job's
    plotting code (python/reciprocating_drive/plots.py) from a run of the FMU."""
    from reciprocating_drive.mission import run_mission
    from reciprocating_drive.plots import plot_mission

    for name in RESULTS:
        preset = name.removeprefix("results_")
        mission = run_mission(str(FMU), preset)
        plot_mission(mission, out / f"{name}.png", dpi=70)


def closed_loop_figure(out: pathlib.Path) -> None:
    """The closed loop of the pump and its drive train in libcosim (scripts/closed_loop.py)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "closed_loop", ROOT / "scripts" / "closed_loop.py"
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    mod.main(["--out-dir", str(out), "--fmu-dir", str(FMU.parent)])


# Sections of the variable table, in order: (title, which variables). A variable goes to the
# first section that takes it; the connecting rod's outputs have their own section (rod.angle is a
# rigid rod's swing angle but an elastic rod's cage rotation, its angular oscillation).
TABLE_SECTIONS = [
    ("Inputs", lambda v: v.causality == "input"),
    (
        "Outputs: kinematics",
        lambda v: (
            v.causality == "output"
            and v.name.split(".")[0] in ("suspension", "kinematics")
            or v.name in ("crank.model_angle", "crank.model_speed")
        ),
    ),
    (
        "Outputs: connecting rod (rigid: its swing; elastic: the cage's angular oscillation)",
        lambda v: v.causality == "output" and v.name.startswith("rod.") and v.name != "rod.force",
    ),
    (
        "Outputs: loads",
        lambda v: (
            v.causality == "output"
            and (
                v.name.split(".")[0] in ("inertia", "balancer")
                or v.name in ("rod.force", "crank.torque")
            )
        ),
    ),
    (
        "Outputs: guide friction",
        lambda v: (
            v.causality == "output"
            and v.name.split(".")[0] in ("guide", "link", "support_A", "support_B", "support_C")
        ),
    ),
    ("Outputs", lambda v: v.causality == "output"),
    (
        "Parameters: mechanism, geometry, mass, process load",
        lambda v: (
            v.name.split(".")[0] in ("mechanism", "rotation", "crank", "geometry", "mass", "load")
        ),
    ),
    (
        "Parameters: elastic rod (rod.kind 1 or 2)",
        lambda v: v.name.startswith("rod.") or v.name == "solver.tolerance",
    ),
    ("Parameters: balancer", lambda v: v.name.startswith("balancer.")),
    (
        "Parameters: link, supports and guide friction",
        lambda v: v.name.split(".")[0] in ("link", "guide", "support_A", "support_B", "support_C"),
    ),
    ("Other variables", lambda v: True),
]


def variable_table(fmu: pathlib.Path) -> str:
    """The variables of the model description by section, each with its description (the one
    variable table, src/fmus/*/variables.rs, writes both)."""
    from fmpy import read_model_description

    md = read_model_description(str(fmu))
    sections: dict[str, list] = {title: [] for title, _ in TABLE_SECTIONS}
    for v in md.modelVariables:
        title = next(t for t, takes in TABLE_SECTIONS if takes(v))
        sections[title].append(v)
    out = []
    for title, members in sections.items():
        if not members:
            continue
        out += [
            f"**{title}**",
            "",
            "| name | causality | variability | type | unit | value reference | description |",
            "|---|---|---|---|---|---|---|",
        ]
        for v in members:
            unit = v.unit or (v.declaredType.unit if v.declaredType is not None else None) or ""
            desc = (v.description or "").replace("|", "\\|")
            out.append(
                f"| `{v.name}` | {v.causality} | {v.variability} | {v.type} | {unit} "
                f"| {v.valueReference} | {desc} |"
            )
        out.append("")
    return "\n".join(out).rstrip("\n")


def write_table(fmu: pathlib.Path, doc: pathlib.Path = INTERFACE) -> None:
    text = doc.read_text()
    begin, end = "<!-- variables:begin -->", "<!-- variables:end -->"
    head, rest = text.split(begin)
    _, tail = rest.split(end)
    doc.write_text(f"{head}{begin}\n{variable_table(fmu)}\n{end}{tail}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "--out",
        type=pathlib.Path,
        default=None,
        help="figure folder (default docs/figures; docs untouched when given)",
    )
    ap.add_argument("--table-only", action="store_true")
    ap.add_argument("--sketches-only", action="store_true")
    a = ap.parse_args(argv)
    if a.out is None:
        write_table(FMU)
        if a.table_only:
            return
    out = a.out or FIGURES
    out.mkdir(parents=True, exist_ok=True)
    for name in SKETCHES:
        globals()[f"sketch_{name}"](out / f"{name}.png")
    if not a.sketches_only:
        result_figures(out)
        closed_loop_figure(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
