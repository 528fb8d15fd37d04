"""The main job's figure (scripts/run.sh, docs/figures/results_*.png): what the FMU exists for,
against the crank angle over whole steady revolutions (ticks every 90°). An elastic rod adds its
cage angle ϑ and largest stress, with the start transient in its own panel; a beam unit adds its
card (rod force against position)."""

from __future__ import annotations

import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .mission import Mission, plural  # noqa: E402

# (output, axis label, SI unit); forces and torques switch to kN, kN·m from 1 kN, 1 kN·m.
PANELS = [
    ("suspension.acceleration", "acceleration a", "m/s²"),
    ("inertia.force", "inertia force Φ", "N"),
    ("guide.friction", "guide friction", "N"),
    ("rod.force", "rod force P", "N"),
    ("crank.torque", "crank torque T", "N·m"),
]
ROD_PANELS = [
    ("rod.angle", "rod angle ϑ", "rad"),
    ("rod.stress_max", "largest stress", "MPa"),
]
#: Steady revolutions drawn against the crank angle.
PLOT_REVOLUTIONS = 2


def _scale(y: np.ndarray, unit: str) -> tuple[float, str]:
    if unit == "MPa":
        return 1e-6, unit
    if unit in ("N", "N·m") and np.max(np.abs(y)) >= 1e3:
        return 1e-3, "k" + unit
    return 1.0, unit


def plot_mission(m: Mission, path: str | pathlib.Path, dpi: int = 100) -> None:
    d = m.data
    revs = m.revolutions[m.transient_revolutions :][-PLOT_REVOLUTIONS:]
    sl = m.steady_slice(last=len(revs))
    first = revs[0].index
    # Crank angle from the start of the first steady revolution, in degrees.
    deg = np.degrees(d["crank.model_angle"][sl]) - 360.0 * first
    panels = PANELS + (ROD_PANELS if m.elastic else [])
    card = m.mechanism in (2, 3)
    rows = len(panels) + (1 if m.elastic else 0)
    fig = plt.figure(figsize=(13 if card else 10, 1.9 * rows + 1.2))
    gs = fig.add_gridspec(rows, 2 if card else 1, width_ratios=[2.2, 1] if card else None)
    axes = []
    r0 = 0
    if m.elastic:
        ax = fig.add_subplot(gs[0, 0])
        ax.plot(d["time"], d["rod.angle"], lw=0.6, color="C3")
        t_steady = m.revolutions[m.transient_revolutions].start_time
        ax.axvspan(d["time"][0], t_steady, color="0.9")
        ax.set_xlabel(
            "time [s]  (shaded: start transient, "
            f"{plural(m.transient_revolutions, 'revolution')} until the ϑ amplitude settles)"
        )
        ax.set_ylabel("ϑ, whole run\n[rad]")
        ax.grid(True, alpha=0.4)
        r0 = 1
    for i, (name, label, unit) in enumerate(panels):
        ax = fig.add_subplot(gs[r0 + i, 0], sharex=axes[0] if axes else None)
        k, unit = _scale(d[name][sl], unit)
        ax.plot(deg, d[name][sl] * k, lw=1.2)
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_ylabel(f"{label}\n[{unit}]")
        ax.grid(True, alpha=0.4)
        axes.append(ax)
    span = 360.0 * len(revs)
    ticks = np.arange(0.0, span + 1e-6, 90.0)
    for ax in axes:
        ax.set_xticks(ticks)
        ax.tick_params(labelbottom=False)
        ax.set_xlim(0.0, span)
    axes[-1].tick_params(labelbottom=True)
    axes[-1].set_xticklabels([f"{x:.0f}" for x in ticks], rotation=0, fontsize=8)
    zero = "outer dead centre" if m.mechanism == 1 else "crank at 12 o'clock"
    axes[-1].set_xlabel(
        f"crank angle θ [deg] over {plural(len(revs), 'steady revolution')}, "
        f"revolutions {revs[0].index}–{revs[-1].index} of the run (0 = {zero})"
    )
    if card:
        ax = fig.add_subplot(gs[:, 1])
        k, unit = _scale(d["rod.force"][sl], "N")
        ax.plot(d["suspension.position"][sl], d["rod.force"][sl] * k, lw=1.2, color="C2")
        ax.set_xlabel("polished-rod position s [m]")
        ax.set_ylabel(f"rod force P [{unit}] (compression positive)")
        ax.set_title("card: rod force against position")
        ax.grid(True, alpha=0.4)
    fig.suptitle(m.title)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
