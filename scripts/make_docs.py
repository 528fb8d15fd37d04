"""Generates what docs/ shows that comes from the code: the figures (sketches of each mechanism with
its coordinates and supports, plots of typical results computed by the FMU), the variable table
of docs/fmi-interface.md (from the FMU's model description) and the presets' expected summaries in
docs/results.md (from a run of the main job).

    .venv/bin/python scripts/make_docs.py                 # docs/figures/*.png, the table, results
    .venv/bin/python scripts/make_docs.py --out DIR       # figures into DIR, docs/ untouched
    .venv/bin/python scripts/make_docs.py --table-only    # only the variable table
    .venv/bin/python scripts/make_docs.py --results-only  # only the summaries in docs/results.md

The FMU is target/fmu/ReciprocatingDrive.fmu (RD_FMU overrides it); scripts/build-fmu.sh builds it.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import os
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Arc, Circle, FancyArrowPatch, Rectangle  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))

FMU = pathlib.Path(os.environ.get("RD_FMU", ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu"))
FIGURES = ROOT / "docs" / "figures"
INTERFACE = ROOT / "docs" / "fmi-interface.md"
RESULTS_PAGE = ROOT / "docs" / "results.md"

# Every figure this script writes; docs/*.md refer to them as figures/<name>.png.
SKETCHES = ("crank_slider", "beam_units", "supports", "elastic_rod")
# The main job's presets: the FMU's start values and every preset of resources/presets.
PRESETS = ("default", "unb600a", "unb600a-simplex", "triplex-1600", "sk8-3.5-4000", "kvo630")
RESULTS = tuple(f"results_{p}" for p in PRESETS)
# Drawn by the closed loop's command (rdrive closed-loop, docs/closed-loop.md).
CLOSED_LOOP = "closed_loop"
# The cage integrator's work-precision diagram, drawn from the study's committed table
# (scripts/work_precision.py measures it: cargo, minutes).
WORK_PRECISION = "work_precision"


# Sketches are drawn for a screen: 11 inches wide at 200 dpi, about 2 000 pixels after cropping.
SKETCH_WIDTH, SKETCH_DPI = 11.0, 200


def _arrow(ax, p, q, text=None, color="k", **kw):
    ax.add_patch(
        FancyArrowPatch(p, q, arrowstyle="-|>", mutation_scale=14, color=color, lw=1.2, **kw)
    )
    if text:
        ax.annotate(text, q, textcoords="offset points", xytext=(4, 4), color=color)


def _dimension(ax, z0, z1, y, text, color="0.3"):
    """A dimension line from z0 to z1 at height y, its text centred below it."""
    ax.add_patch(
        FancyArrowPatch((z0, y), (z1, y), arrowstyle="<|-|>", mutation_scale=9, color=color, lw=0.8)
    )
    for z in (z0, z1):
        ax.plot([z, z], [y - 0.02, y + 0.02], "-", color=color, lw=0.8)
    ax.annotate(
        text,
        ((z0 + z1) / 2, y),
        textcoords="offset points",
        xytext=(0, -11),
        ha="center",
        fontsize=9,
        color=color,
    )


def _finish(ax, title):
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title(title, fontsize=11)


def _save(fig, path) -> None:
    fig.savefig(path, dpi=SKETCH_DPI, bbox_inches="tight", pad_inches=0.1)
    plt.close(fig)


def text_overlaps(fig) -> list[tuple[str, str]]:
    """Pairs of texts of the figure whose boxes overlap on the canvas (tests/python/test_sketches.py
    requires none)."""
    from matplotlib.text import Text

    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    boxes = [
        (t.get_text(), t.get_window_extent(renderer))
        for t in fig.findobj(Text)
        if t.get_visible() and t.get_text().strip()
    ]
    return [
        (ta, tb) for i, (ta, a) in enumerate(boxes) for tb, b in boxes[i + 1 :] if a.overlaps(b)
    ]


def draw_crank_slider():
    """Crank-slider at θ = 50° (docs/model.md §3.1): crank, rod, crosshead, s from the ODC."""
    r, l, th = 0.2, 0.75, math.radians(50)
    pin = np.array([r * math.cos(th), r * math.sin(th)])
    beta = math.asin(r * math.sin(th) / l)
    x = r * math.cos(th) + l * math.cos(beta)
    fig, ax = plt.subplots(figsize=(SKETCH_WIDTH, 3.6))
    ax.plot([-0.3, 1.25], [0, 0], "k-.", lw=0.6)
    ax.add_patch(Circle((0, 0), r, fill=False, ls=":", lw=0.8))
    ax.plot([0, pin[0]], [0, pin[1]], "C0-", lw=3)
    ax.plot([pin[0], x], [pin[1], 0], "C1-", lw=3)
    ax.add_patch(Rectangle((x - 0.05, -0.04), 0.1, 0.08, fc="0.85", ec="k"))
    ax.plot([x + 0.05, 1.2], [0, 0], "k-", lw=4)  # piston rod
    ax.plot([0], [0], "ko")
    ax.add_patch(Arc((0, 0), 0.16, 0.16, theta1=0, theta2=50, lw=0.8))
    ax.annotate("θ", (0.09, 0.035))
    ax.add_patch(
        Arc((x, 0), 0.3, 0.3, theta1=180 - math.degrees(beta), theta2=180, lw=0.8, color="C1")
    )
    ax.annotate("β", (x - 0.2, 0.012), color="C1")
    ax.annotate("crank r", (-0.02, 0.1), ha="right", color="C0")
    ax.annotate("rod l", ((pin[0] + x) / 2, pin[1] / 2 + 0.04), color="C1")
    ax.annotate("crosshead", (x - 0.06, 0.06), fontsize=9)
    xodc = r + l
    ax.plot([xodc, xodc], [-0.12, 0.12], "k:", lw=0.8)
    ax.annotate("ODC (s = 0)", (xodc + 0.01, -0.17), fontsize=9)
    _arrow(ax, (xodc, -0.09), (x, -0.09), None, color="C3")
    ax.annotate(
        "s",
        ((xodc + x) / 2, -0.085),
        textcoords="offset points",
        xytext=(0, 3),
        ha="center",
        color="C3",
    )
    _arrow(ax, (0, 0), (0.3, 0), None)
    ax.annotate("x", (0.3, -0.05))
    _arrow(ax, (0, 0), (0, 0.26), "y")
    ax.set_ylim(-0.22, 0.36)
    _finish(
        ax, "Crank-slider: θ from the stroke axis, s from the outer dead centre toward the crank"
    )
    return fig


def sketch_crank_slider(path):
    _save(draw_crank_slider(), path)


def draw_beam_units():
    """API class I and class III geometry (docs/model.md §3.2), well on the right, θ = 30°."""
    fig, axes = plt.subplots(1, 2, figsize=(SKETCH_WIDTH, 4.4))
    for ax, cls in zip(axes, ("I", "III")):
        R, C, A, I, HG = (0.5, 1.2, 1.8, 1.2, 1.6) if cls == "I" else (0.5, 1.0, 2.6, 0.9, 1.6)
        bx = I if cls == "I" else -I
        b = 0.1
        u = np.array([math.cos(b), math.sin(b)])
        B = np.array([bx, HG])
        E = B - C * u if cls == "I" else B + C * u
        head = B + A * u
        q = math.radians(30)
        pin = np.array([R * math.sin(q), R * math.cos(q)])
        ax.plot([-2.4, 3.2], [-0.55, -0.55], "k-", lw=0.8)  # ground
        ax.plot([B[0], B[0]], [B[1], -0.55], "0.6", lw=2)  # samson post
        ax.add_patch(Circle((0, 0), R, fill=False, ls=":", lw=0.8))
        ax.plot([0, 0], [0, R + 0.15], "k:", lw=0.8)  # 12 o'clock
        ax.add_patch(Arc((0, 0), 0.5, 0.5, theta1=60, theta2=90, lw=0.8))
        ax.plot([0, pin[0]], [0, pin[1]], "C0-", lw=3)
        ax.plot([pin[0], E[0]], [pin[1], E[1]], "C1-", lw=3)
        ax.plot([E[0], head[0]], [E[1], head[1]], "C2-", lw=4)
        ax.plot([head[0], head[0]], [head[1], -0.55], "k-", lw=1.5)  # polished rod
        ax.plot(*B, "k^", ms=10)
        ax.plot(*E, "ko", ms=4)
        ax.plot(0, 0, "ko")
        ax.annotate(
            "centre bearing", B, textcoords="offset points", xytext=(0, 12), ha="center", fontsize=9
        )
        if cls == "I":
            ax.annotate(
                "equalizer", E, textcoords="offset points", xytext=(-8, 8), ha="right", fontsize=9
            )
        else:
            ax.annotate(
                "equalizer", E, textcoords="offset points", xytext=(10, -14), ha="left", fontsize=9
            )
        ax.annotate(
            "horsehead", head, textcoords="offset points", xytext=(0, 12), ha="center", fontsize=9
        )
        ax.annotate("R", pin / 2, textcoords="offset points", xytext=(6, -6), color="C0")
        ax.annotate("P", (pin + E) / 2, textcoords="offset points", xytext=(6, 0), color="C1")
        ax.annotate("θ", (0.05, R + 0.12), fontsize=10)
        ax.annotate("θ = 0 at 12 o'clock", (-2.3, 2.45), fontsize=9)
        _arrow(ax, (head[0] + 0.2, 0.1), (head[0] + 0.2, 0.8), None, color="C3")
        ax.annotate("s", (head[0] + 0.28, 0.4), color="C3")
        ax.annotate(
            "well", (head[0], -0.55), textcoords="offset points", xytext=(4, -12), fontsize=9
        )
        ax.set_xlim(-2.4, 3.3)
        ax.set_ylim(-0.9, 2.7)
        _finish(
            ax,
            f"Class {cls}: "
            + (
                "the centre bearing between\nequalizer and horsehead"
                if cls == "I"
                else "the equalizer between\ncentre bearing and horsehead"
            ),
        )
    return fig


def sketch_beam_units(path):
    _save(draw_beam_units(), path)


#: The default pump's link (docs/model.md §8): (l_i, d_i) of sections 1..4 [m].
LINK_SECTIONS = [(0.55, 0.070), (0.15, 0.130), (1.00, 0.100), (0.40, 0.300)]


def draw_supports():
    """The default pump's link as a stepped beam with sections l1..l4 and supports A, B, C
    (docs/model.md §5, §8), at s = 0."""
    fig, ax = plt.subplots(figsize=(SKETCH_WIDTH, 4.0))
    z = 0.0
    bounds = [0.0]
    for length, d in LINK_SECTIONS:
        ax.add_patch(Rectangle((z, -d / 2), length, d, fc="0.9", ec="k"))
        z += length
        bounds.append(z)
    L = z
    for i in range(4):
        _dimension(ax, bounds[i], bounds[i + 1], -0.24, f"l{i + 1}")
    ax.plot([L, L], [-0.27, -0.15], "-", color="0.3", lw=0.8)
    sizes = ", ".join(f"{length:.2f}" for length, _ in LINK_SECTIONS)
    diams = ", ".join(f"{d * 1e3:.0f}" for _, d in LINK_SECTIONS)
    ax.annotate(
        f"l1..l4 = {sizes} m;  diameters d1..d4 = {diams} mm", (0.0, -0.37), fontsize=9, color="0.3"
    )
    # A: clamp over [0, 0.25], moves with the link.
    ax.add_patch(Rectangle((0.0, -0.06), 0.25, 0.12, fc="none", ec="C0", lw=2))
    ax.annotate(
        "A: clamp (piston in its liner),\nmoves with the link",
        (0.0, 0.1),
        textcoords="offset points",
        xytext=(0, 8),
        fontsize=9,
        color="C0",
    )
    # C: pin fixed in the frame at z = 1.60 m (s = 0).
    ax.plot([1.60, 1.60], [-0.17, 0.17], "C2-", lw=2)
    ax.annotate(
        "C: pin fixed in the frame\n(gland, spring)",
        (1.60, 0.17),
        textcoords="offset points",
        xytext=(-6, 4),
        ha="right",
        fontsize=9,
        color="C2",
    )
    # B: two-edge guide, centre 1.90 m, length 0.40 m, moves with the link.
    ax.add_patch(Rectangle((1.70, -0.17), 0.40, 0.34, fc="none", ec="C1", lw=2))
    ax.annotate(
        "B: two-edge guide (crosshead),\noffset δ, tilt α",
        (1.70, 0.17),
        textcoords="offset points",
        xytext=(0, 4),
        fontsize=9,
        color="C1",
    )
    # The axes: z along the link from the piston end, y lateral (docs/model.md §5.1).
    _arrow(ax, (0, -0.56), (0.4, -0.56), None, color="k")
    _arrow(ax, (0, -0.56), (0, -0.46), None, color="k")
    ax.annotate("z", (0.42, -0.58), fontsize=10)
    ax.annotate("y", (0.02, -0.47), fontsize=10)
    ax.annotate(
        "z = 0: piston end", (0.0, -0.56), textcoords="offset points", xytext=(0, -13), fontsize=9
    )
    ax.annotate(
        f"z = L = {L:.2f} m: crank side",
        (L, -0.56),
        textcoords="offset points",
        xytext=(0, -13),
        ha="right",
        fontsize=9,
    )
    ax.set_xlim(-0.05, L + 0.25)
    ax.set_ylim(-0.68, 0.42)
    ax.set_aspect("auto")
    ax.axis("off")
    ax.set_title("The link of the default pump: sections l1..l4, supports A, B, C", fontsize=11)
    return fig


def sketch_supports(path):
    _save(draw_supports(), path)


def draw_elastic_rod():
    """Elastic rod clamped in the piston, rigid end, cage on the pin, ϑ (docs/model.md §6)."""
    fig, ax = plt.subplots(figsize=(SKETCH_WIDTH, 3.8))
    lf, f, delta, th = 2.3, 1.5, 0.45, 0.18
    zz = np.linspace(0, lf, 60)
    # a clamped bent shape ending at slope th
    v = (
        delta * (3 * (zz / lf) ** 2 - 2 * (zz / lf) ** 3) * 0.8
        + th * lf * ((zz / lf) ** 3 - (zz / lf) ** 2) * 0.5
    )
    ax.add_patch(Rectangle((-0.8, -0.35), 0.8, 0.7, fc="0.85", ec="k"))
    ax.annotate("piston\n(clamp)", (-0.4, 0.0), ha="center", va="center", fontsize=9)
    ax.plot(zz, v, "C1-", lw=2.5)
    end = np.array([lf, v[-1]])
    tip = end + f * np.array([math.cos(th), math.sin(th)])
    ax.plot([end[0], tip[0]], [end[1], tip[1]], "C0-", lw=4)
    ax.add_patch(Circle(tip, 0.18, fill=False, ec="C0", lw=2))
    ax.annotate(
        "cage on the crank pin (J_m)",
        tip,
        textcoords="offset points",
        xytext=(-20, 18),
        ha="center",
        fontsize=9,
        color="C0",
    )
    ax.plot([end[0], end[0] + 1.2], [end[1], end[1]], "k:", lw=0.8)
    ax.add_patch(Arc(end, 1.6, 1.6, theta1=0, theta2=math.degrees(th), color="C3", lw=1))
    ax.annotate("ϑ", end + (0.85, 0.03), fontsize=12, color="C3")
    ax.annotate("elastic part l_f", (lf / 2, -0.2), ha="center", fontsize=9, color="C1")
    ax.annotate(
        "rigid part f",
        (end + tip) / 2,
        textcoords="offset points",
        xytext=(0, -26),
        ha="center",
        fontsize=9,
        color="C0",
    )
    ax.plot([0, lf + f + 0.5], [0, 0], "k-.", lw=0.6)  # the stroke axis
    _arrow(ax, (tip[0] + 0.5, 0), (tip[0] + 0.5, tip[1]), None, color="C3")
    ax.annotate(
        "Δ = r sinθ − e\n(pin's lateral offset)", (tip[0] + 0.6, 0.2), fontsize=9, color="C3"
    )
    ax.set_xlim(-1, lf + f + 2.6)
    ax.set_ylim(-0.6, 1.1)
    _finish(ax, "Elastic connecting rod clamped in the piston: cage rotation ϑ")
    return fig


def sketch_elastic_rod(path):
    _save(draw_elastic_rod(), path)


def missions() -> dict:
    """The main job's run of every preset (python/reciprocating_drive/mission.py)."""
    from reciprocating_drive.mission import run_mission

    return {p: run_mission(str(FMU), p) for p in PRESETS}


def result_figures(out: pathlib.Path, runs: dict) -> None:
    """Typical results of every preset, drawn by the main job's plotting code
    (python/reciprocating_drive/plots.py) from a run of the FMU."""
    from reciprocating_drive.plots import plot_mission

    for p, mission in runs.items():
        plot_mission(mission, out / f"results_{p}.png", dpi=100)


def results_summaries(runs: dict) -> str:
    """The summary the main job prints for every preset, as docs/results.md shows it."""
    from reciprocating_drive.mission import format_summary

    blocks = [
        f"`scripts/run.sh {p}`:\n\n```text\n{format_summary(m.summary)}\n```"
        for p, m in runs.items()
    ]
    return "\n\n".join(blocks)


def write_results(runs: dict, doc: pathlib.Path = RESULTS_PAGE) -> None:
    text = doc.read_text()
    begin, end = "<!-- results:begin -->", "<!-- results:end -->"
    head, rest = text.split(begin)
    _, tail = rest.split(end)
    doc.write_text(f"{head}{begin}\n{results_summaries(runs)}\n{end}{tail}")


def closed_loop_figure(out: pathlib.Path) -> None:
    """The closed loop of the pump and its drive train in libcosim (`rdrive closed-loop`)."""
    from reciprocating_drive.commands import closed_loop

    rc = closed_loop.main(["--out-dir", str(out), "--fmu-dir", str(FMU.parent)])
    if rc != 0:
        raise SystemExit(f"make_docs.py: the closed loop's figure failed (exit {rc})")
    # The command writes the systems, the series and the summary beside its figure; the docs
    # show only the figure.
    for name in ("ClosedLoop.ssp", "ClosedLoopME.ssp", "closed_loop.csv", "closed_loop.json"):
        (out / name).unlink(missing_ok=True)


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
    (
        "Outputs: the pump (flow, powers) and its cylinders",
        lambda v: (
            v.causality == "output" and v.name.split(".")[0].startswith(("pump", "cylinder_"))
        ),
    ),
    ("Outputs", lambda v: v.causality == "output"),
    (
        "Model Exchange: the continuous states and their derivatives",
        lambda v: v.causality == "local",
    ),
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
        "Parameters: the pump's cylinders",
        lambda v: v.name.split(".")[0].startswith(("pump", "cylinder_")),
    ),
    (
        "Parameters: link, supports and guide friction",
        lambda v: v.name.split(".")[0] in ("link", "guide", "support_A", "support_B", "support_C"),
    ),
    ("Other variables", lambda v: True),
]


def work_precision_figure(path: pathlib.Path) -> None:
    """docs/figures/work_precision.png from docs/figures/work_precision.csv."""
    spec = importlib.util.spec_from_file_location("wp", ROOT / "scripts" / "work_precision.py")
    wp = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(wp)
    wp.draw(wp.read(wp.TABLE), path)


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
    ap.add_argument("--results-only", action="store_true")
    ap.add_argument("--sketches-only", action="store_true")
    a = ap.parse_args(argv)
    if a.out is None:
        if not a.results_only:
            write_table(FMU)
        if a.table_only:
            return
    runs = None
    if a.out is None and not a.sketches_only:
        runs = missions()
        write_results(runs)
        if a.results_only:
            return
    out = a.out or FIGURES
    out.mkdir(parents=True, exist_ok=True)
    for name in SKETCHES:
        globals()[f"sketch_{name}"](out / f"{name}.png")
    if not a.sketches_only:
        result_figures(out, runs or missions())
        closed_loop_figure(out)
    work_precision_figure(out / f"{WORK_PRECISION}.png")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
