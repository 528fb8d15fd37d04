"""The plot of a sweep (docs/sweeps.md): each metric against the varied parameter (one varied
parameter), or as a heat map over a grid of two; for more parameters, each metric against each
parameter as a scatter plot. Rejected cases are marked. Axes are in display units (mm, mrad, MPa,
kN/m, ...), never with an offset; a metric that is 0 in every case gets no panel but a line saying
so and why; a varied parameter that cannot act is named under the title.

Layer: workflows, the sweeps (docs/architecture.md).
"""

from __future__ import annotations

import math
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..plots import MIN_SPAN, y_range  # noqa: E402
from .study import Study  # noqa: E402

#: SI unit -> (display unit, factor) for parameters (docs/fmi-interface.md "Units").
DISPLAY = {
    "m": ("mm", 1e3),
    "rad": ("mrad", 1e3),
    "Pa": ("MPa", 1e-6),
    "N/m": ("kN/m", 1e-3),
    "N": ("kN", 1e-3),
    "N.m": ("N·m", 1.0),
    "kg.m2": ("kg·m²", 1.0),
    "m/s": ("m/s", 1.0),
    "rad/s": ("rad/s", 1.0),
    "kg": ("kg", 1.0),
}
SPEEDS = {"strokes_per_minute": ("strokes/min", 1.0), "crank.speed": ("rad/s", 1.0)}
#: metric -> (label, display unit, factor from SI).
METRIC_AXES = {
    "friction_work": ("friction work per revolution", "J", 1.0),
    "torque_peak": ("largest |crank torque|", "N·m", 1.0),
    "torque_max": ("maximum crank torque", "N·m", 1.0),
    "torque_min": ("minimum crank torque", "N·m", 1.0),
    "acceleration_max": ("maximum acceleration", "m/s²", 1.0),
    "acceleration_max_angle": ("crank angle of the maximum acceleration", "deg", 1.0),
    "acceleration_min": ("minimum acceleration", "m/s²", 1.0),
    "inertia_force_max": ("maximum inertia force", "kN", 1e-3),
    "inertia_force_min": ("minimum inertia force", "kN", 1e-3),
    "guide_friction_max": ("maximum guide friction", "N", 1.0),
    "guide_friction_min": ("minimum guide friction", "N", 1.0),
    "rod_force_max": ("maximum rod force", "kN", 1e-3),
    "rod_force_max_angle": ("crank angle of the maximum rod force", "deg", 1.0),
    "rod_force_min": ("minimum rod force", "kN", 1e-3),
    "rod_angle_amplitude": ("largest cage angle |ϑ|", "mrad", 1e3),
    "stress_max": ("largest rod stress", "MPa", 1e-6),
    "flow_mean": ("mean flow", "L/s", 1e3),
    "flow_pulsation": ("flow pulsation (Q_max − Q_min)/Q_mean", "", 1.0),
}


def param_axis(study: Study, name: str) -> tuple[str, float]:
    """Axis label with its display unit, and the factor from the parameter's SI value."""
    if name in SPEEDS:
        unit, f = SPEEDS[name]
    else:
        var = study.variables.get(name)
        si = var.unit if var is not None else ""
        unit, f = DISPLAY.get(si, (si, 1.0))
    return (f"{name} [{unit}]" if unit else name), f


def metric_axis(m: str) -> tuple[str, float]:
    label, unit, f = METRIC_AXES.get(m, (m, "", 1.0))
    return (f"{label} [{unit}]" if unit else label), f


def zero_reason(study: Study, m: str) -> str:
    """Why a metric is 0 in every case, where the machine says it."""
    v = {k: x.start for k, x in study.variables.items()}
    v.update(study.base_values)
    present = [x for x in "ABC" if v.get(f"support_{x}.kind", 0) != 0]
    if m.startswith("guide_friction") or m == "friction_work":
        if not present:
            return "no support: the friction model is off"
        if len(present) == 1 and v.get(f"support_{present[0]}.kind") == 2:
            return f"no guide friction: a single clamp (support {present[0]}) holds the link"
        if "B" not in present and m.startswith("guide_friction"):
            return "no guide (support_B.kind = 0)"
        if m.startswith("guide_friction") and v.get("guide.friction_coefficient", 1) == 0:
            return "guide.friction_coefficient = 0"
    if m in ("rod_angle_amplitude", "stress_max") and v.get("rod.kind", 0) == 0:
        return "a rigid connecting rod (rod.kind = 0)"
    return "0 in every case"


def plot_sweep(study: Study, rows: list[dict], path: str | pathlib.Path | None = None):
    """Draws the sweep; without `path` returns the figure (the tests read its axes)."""
    ok = [r for r in rows if r["status"] == "ok"]
    bad = [r for r in rows if r["status"] != "ok"]
    params = study.varied
    zero = [m for m in study.metrics if ok and all(r[m] == 0 for r in ok)]
    metrics = [m for m in study.metrics if m not in zero]
    notes = [f"{metric_axis(m)[0]}: 0 in every case ({zero_reason(study, m)})" for m in zero]
    notes += [f"{k} cannot act: {why}" for k, why in study.inert.items()]
    n_panels = max(1, len(metrics))
    fig, axes = plt.subplots(n_panels, 1, figsize=(8, 3.4 * n_panels), squeeze=False)
    for ax, m in zip(axes[:, 0], metrics):
        ylabel, fy = metric_axis(m)
        if len(params) == 2 and study.design == "grid":
            (px, py), ((lx, fx), (ly, fy2)) = params, (param_axis(study, p) for p in params)
            xs = sorted({r[px] for r in rows})
            ys = sorted({r[py] for r in rows})
            z = np.full((len(ys), len(xs)), np.nan)
            for r in ok:
                z[ys.index(r[py]), xs.index(r[px])] = r[m] * fy
            im = ax.pcolormesh(
                np.array(xs) * fx, np.array(ys) * fy2, z, shading="nearest", cmap="viridis"
            )
            cb = fig.colorbar(im, ax=ax, label=ylabel)
            cb.formatter.set_useOffset(False)
            cb.update_ticks()
            for r in bad:
                ax.plot(r[px] * fx, r[py] * fy2, "rx")
            ax.set_xlabel(lx)
            ax.set_ylabel(ly)
            plain_axis(ax, np.array(ys) * fy2)
            plain_axis(ax, np.array(xs) * fx, axis="x")
        else:
            ys_all = []
            for p in params:
                label, fx = param_axis(study, p)
                x = np.array([r[p] for r in ok]) * fx
                y = np.array([r[m] for r in ok]) * fy
                ys_all.append(y)
                order = np.argsort(x)
                style = "o-" if len(params) == 1 else "o"
                ax.plot(x[order], y[order], style, ms=3, label=label)
                for r in bad:
                    ax.axvline(r[p] * fx, color="r", lw=0.5, alpha=0.5)
            ax.set_xlabel(
                param_axis(study, params[0])[0] if len(params) == 1 else "parameter value"
            )
            ax.set_ylabel(ylabel)
            plain_axis(ax, np.concatenate(ys_all) if ys_all else [])
            plain_axis(ax, [], axis="x")
            if len(params) > 1:
                ax.legend(fontsize=8)
        ax.set_title(ylabel, fontsize=9)
        ax.grid(True, alpha=0.3)
    if not metrics:
        axes[0, 0].set_axis_off()
    n_bad = len(bad)
    machine = study.machine if len(study.machine) < 40 else pathlib.Path(study.machine).name
    title = f"{study.name}: {machine}, {len(ok)} cases" + (
        f", {n_bad} rejected (red)" if n_bad else ""
    )
    fig.suptitle(title)
    bottom = 0.0
    if notes:
        h = 0.25 * len(notes) / fig.get_figheight()
        fig.text(0.01, 0.005, "\n".join(notes), fontsize=8, va="bottom", color="0.25", wrap=True)
        bottom = min(0.3, h + 0.01)
    fig.tight_layout(rect=(0, bottom, 1, 0.97))
    if path is None:
        return fig
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return None


def finite(x) -> bool:
    return isinstance(x, float) and math.isfinite(x)


def plain_axis(ax, values, axis: str = "y", rel: float = 1e-9) -> None:
    """No offset notation ("1e−5+3.203" for a constant 3.2037): tick labels are the values
    themselves. A series whose spread is rounding noise (below `rel` of its size) is drawn as the
    constant it is, in the middle of a range of ±5 % of its value."""
    fmt = (ax.yaxis if axis == "y" else ax.xaxis).get_major_formatter()
    if hasattr(fmt, "set_useOffset"):
        fmt.set_useOffset(False)
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return
    lo, hi = float(v.min()), float(v.max())
    size = max(abs(lo), abs(hi))
    if axis == "y" and hi - lo < MIN_SPAN * size:
        # The y-range rule of every plot (plots.y_range): at least 2 % of the value's size.
        ax.set_ylim(*y_range(v))
    elif hi - lo <= rel * size or hi == lo:
        mid = 0.5 * (lo + hi)
        half = 0.05 * abs(mid) if mid != 0 else 1.0
        (ax.set_ylim if axis == "y" else ax.set_xlim)(mid - half, mid + half)
