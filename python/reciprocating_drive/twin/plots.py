"""Plots of a twin run (docs/twin.md "Output"): time series, the card (rod force against position)
and the per-revolution trends. Lines break where the data do: at a gap between samples and at a
missing revolution. Every y-range spans at least 2 % of the value's size (plots.y_range), on an axis
without matplotlib's offset notation: rounding noise is drawn as the flat line it is.

Layer: workflows, the twin (docs/architecture.md).
"""

from __future__ import annotations

import csv
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..plots import span_axis  # noqa: E402
from .core import column_name  # noqa: E402


def read_columns(path) -> dict:
    """name -> values of a CSV written by the twin (headers `name [unit]`, docs/twin.md)."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    head = [column_name(h) for h in rows[0]]
    return {
        h: np.array([float(r[i]) if r[i] != "" else np.nan for r in rows[1:]])
        for i, h in enumerate(head)
    }


def broken(x: np.ndarray, y: np.ndarray, breaks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x and y with a NaN inserted after every index in `breaks`: matplotlib then draws no line
    across it."""
    idx = np.asarray(breaks, dtype=int) + 1
    return np.insert(x.astype(float), idx, np.nan), np.insert(y.astype(float), idx, np.nan)


def steady_axis(a, y: np.ndarray) -> None:
    """No offset notation, and the y-range rule of every plot (plots.y_range): a span of at
    least 2 % of the value's size, so that a steady signal's rounding is drawn flat."""
    span_axis(a, y)


def _stacked(x, data, panels, xlabel, title, path, breaks, style="-", size=(10, 12)):
    """One panel per (column, label) of `data` against x, sharing the x axis."""
    fig, ax = plt.subplots(len(panels), 1, figsize=size, sharex=True)
    for a, (n, label) in zip(ax, panels):
        a.plot(*broken(x, data[n], breaks), style, lw=0.7, ms=3)
        steady_axis(a, data[n])
        a.set_ylabel(label, fontsize=8)
        a.grid(True, alpha=0.3)
    ax[-1].set_xlabel(xlabel)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def plot_twin(
    outputs: pathlib.Path,
    summary: pathlib.Path,
    folder: pathlib.Path,
    machine: str = "default",
    source: str = "",
    gap_limit: float | None = None,
) -> dict:
    """The three plots of a run of `machine` on the input `source`; an interval longer than
    `gap_limit` (default: 5 median intervals) is a gap. Returns each file's title."""
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    o = read_columns(outputs)
    t = o["time"]
    dt = np.diff(t)
    limit = gap_limit if gap_limit is not None else 5 * float(np.median(dt)) if len(dt) else 0
    gaps = np.flatnonzero(dt > limit)
    what = f"{machine}, {pathlib.Path(source).name or source}" if source else machine
    titles = {
        "timeseries.png": f"Digital twin: loads from measured crank data ({what})",
        "card.png": f"card: rod force against position ({what})",
        "revolutions.png": f"Per-revolution trends ({what})",
    }
    _stacked(
        t,
        o,
        [
            ("crank.model_speed", "crank speed [rad/s]"),
            ("suspension.acceleration", "acceleration [m/s²]"),
            ("guide.friction", "guide friction [N]"),
            ("rod.force", "rod force [N]"),
            ("crank.torque", "crank torque [N·m]"),
            ("rod.angle", "rod angle [rad]"),
        ],
        "time [s]",
        titles["timeseries.png"],
        folder / "timeseries.png",
        gaps,
    )

    fig, a = plt.subplots(figsize=(6, 5))
    a.plot(*broken(o["suspension.position"], o["rod.force"] * 1e-3, gaps), lw=0.5)
    steady_axis(a, o["rod.force"] * 1e-3)
    a.ticklabel_format(axis="x", useOffset=False, style="plain")
    a.set_xlabel("position s [m]")
    a.set_ylabel("rod force P [kN]")
    a.set_title(titles["card.png"], fontsize=9)
    a.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(folder / "card.png", dpi=80)
    plt.close(fig)

    s = read_columns(summary)
    rev = s["revolution"]
    _stacked(
        rev,
        s,
        [
            ("mean_speed", "mean speed [rad/s]"),
            ("speed_fluctuation", "speed fluctuation [-]"),
            ("stroke", "stroke [m]"),
            ("crank_torque_max", "maximum crank torque [N·m]"),
            ("friction_work", "friction work [J]"),
        ],
        "revolution",
        titles["revolutions.png"],
        folder / "revolutions.png",
        np.flatnonzero(np.diff(rev) > 1),
        style="o-",
        size=(8, 10),
    )
    return titles
