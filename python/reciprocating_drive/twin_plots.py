"""Plots of a twin run (docs/twin.md): time series, the card (rod force against position) and the
per-revolution trends."""

from __future__ import annotations

import csv
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def _read(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    head = rows[0]
    return {
        h: np.array([float(r[i]) if r[i] != "" else np.nan for r in rows[1:]])
        for i, h in enumerate(head)
    }


def _stacked(x, data, panels, xlabel, title, path, style="-", size=(10, 12)):
    """One panel per (column, label) of `data` against x, sharing the x axis."""
    fig, ax = plt.subplots(len(panels), 1, figsize=size, sharex=True)
    for a, (n, label) in zip(ax, panels):
        a.plot(x, data[n], style, lw=0.7, ms=3)
        a.set_ylabel(label, fontsize=8)
        a.grid(True, alpha=0.3)
    ax[-1].set_xlabel(xlabel)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def plot_twin(outputs: pathlib.Path, summary: pathlib.Path, folder: pathlib.Path) -> None:
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    o = _read(outputs)
    _stacked(
        o["time"],
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
        "Digital twin: loads from measured crank data",
        folder / "timeseries.png",
    )

    fig, a = plt.subplots(figsize=(6, 5))
    a.plot(o["suspension.position"], o["rod.force"] * 1e-3, lw=0.5)
    a.set_xlabel("position s [m]")
    a.set_ylabel("rod force P [kN]")
    a.set_title("card: rod force against position")
    a.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(folder / "card.png", dpi=80)
    plt.close(fig)

    s = _read(summary)
    _stacked(
        s["revolution"],
        s,
        [
            ("mean_speed", "mean speed [rad/s]"),
            ("speed_fluctuation", "speed fluctuation [-]"),
            ("crank_torque_max", "largest crank torque [N·m]"),
            ("friction_work", "friction work [J]"),
        ],
        "revolution",
        "Per-revolution trends",
        folder / "revolutions.png",
        style="o-",
        size=(8, 9),
    )
