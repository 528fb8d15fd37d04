"""The main job's figure (scripts/run.sh, docs/figures/results_*.png): what the FMU exists for,
against the crank angle over whole steady revolutions (ticks every 90°). An elastic rod adds its
cage angle ϑ and largest stress, with the start transient in its own panel; a beam unit adds its
card (rod force against position).

Layer: the main job, below the workflows (docs/architecture.md).
"""

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
#: A pump preset's panels (mission.is_pump): the crank torque panel also draws every cylinder's.
PUMP_PANELS = [
    ("fluid_end.flow", "flow Q", "L/s"),
    ("fluid_end.hydraulic_power", "hydraulic power", "kW"),
    ("crank.mechanical_power", "mechanical power", "kW"),
]
#: Steady revolutions drawn against the crank angle.
PLOT_REVOLUTIONS = 2
#: The y-range rule of every plot and of the live page's trends (docs/twin.md "Output",
#: docs/page.md "Trends"): a span of at least MIN_SPAN times the largest magnitude drawn, limits
#: within NEAR times the value's size of the data included.
MIN_SPAN, NEAR = 0.02, 0.5


def y_range(values, limits=()) -> tuple[float, float]:
    """The y-range of `values` (and of each limit near them): the data's range, widened to at
    least MIN_SPAN times the largest magnitude among them and padded by 5 % each side, so that
    rounding noise of a steady value (a 4 µm change of a 0.4 m stroke, the sixth digit of a
    friction work) is drawn as the flat line it is. The page's page.js `yRange` is the same."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    lims = [float(x) for x in limits if x is not None and np.isfinite(x)]
    if len(v) == 0:
        if not lims:
            return 0.0, 1.0
        v = np.asarray(lims)
    lo, hi = float(np.min(v)), float(np.max(v))
    size = max(abs(lo), abs(hi))
    shown = [x for x in lims if abs(x - min(max(x, lo), hi)) <= NEAR * size]
    for x in shown:
        lo, hi = min(lo, x), max(hi, x)
    span = MIN_SPAN * max([size, *map(abs, shown)]) or 1.0
    if hi - lo < span:
        mid = 0.5 * (lo + hi)
        lo, hi = mid - 0.5 * span, mid + 0.5 * span
    pad = 0.05 * (hi - lo)
    return lo - pad, hi + pad


def span_axis(ax, values, limits=()) -> None:
    """The y-range rule on a matplotlib axis, without offset notation (which would show rounding
    noise as variation)."""
    ax.ticklabel_format(axis="y", useOffset=False, style="plain")
    ax.set_ylim(*y_range(values, limits))


def _scale(y: np.ndarray, unit: str) -> tuple[float, str]:
    if unit == "MPa":
        return 1e-6, unit
    if unit == "L/s":
        return 1e3, unit
    if unit == "kW":
        return 1e-3, unit
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
    panels = PANELS + (ROD_PANELS if m.elastic else []) + (PUMP_PANELS if m.pump else [])
    card = m.mechanism in (2, 3)
    rows = len(panels) + (1 if m.elastic else 0)
    fig = plt.figure(figsize=(13 if card else 10, 1.9 * rows + 1.2))
    gs = fig.add_gridspec(rows, 2 if card else 1, width_ratios=[2.2, 1] if card else None)
    axes = []
    r0 = 0
    if m.elastic:
        ax = fig.add_subplot(gs[0, 0])
        ax.plot(d["time"], d["rod.angle"], lw=0.6, color="C3")
        span_axis(ax, d["rod.angle"])
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
        ax.plot(deg, d[name][sl] * k, lw=1.2, label="sum" if m.pump else None)
        shown = d[name][sl] * k
        if m.pump and name == "crank.torque" and m.cylinders > 1:
            # The pump's crankshaft torque is the sum of its cylinders' (docs/results.md).
            for c in range(1, m.cylinders + 1):
                y = d[f"cylinder_{c}.crank_torque"][sl] * k
                ax.plot(deg, y, lw=0.8, ls="--", label=f"cylinder {c}")
                shown = np.append(shown, y)
            ax.legend(loc="upper right", fontsize=7, ncol=m.cylinders + 1)
        ax.axhline(0.0, color="k", lw=0.5)
        # The zero line stays in view, as matplotlib's own range kept it.
        span_axis(ax, np.append(shown, 0.0))
        if m.pump and m.cylinders > 1 and (name, label, unit) in PANELS[:4]:
            label += ", cyl. 1"  # the link's outputs are cylinder 1's (docs/results.md)
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
        span_axis(ax, d["rod.force"][sl] * k)
        ax.set_xlabel("polished-rod position s [m]")
        ax.set_ylabel(f"rod force P [{unit}] (compression positive)")
        ax.set_title("card: rod force against position")
        ax.grid(True, alpha=0.4)
    fig.suptitle(m.title)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
