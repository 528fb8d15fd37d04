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
    return {h: np.array([float(r[i]) if r[i] != "" else np.nan for r in rows[1:]]) for i, h in enumerate(head)}


def plot_twin(outputs: pathlib.Path, summary: pathlib.Path, folder: pathlib.Path) -> None:
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    o = _read(outputs)
    panels = [("crank.model_speed", "crank speed [rad/s]"), ("suspension.acceleration", "acceleration [m/s²]"),
              ("guide.friction", "guide friction [N]"), ("rod.force", "rod force [N]"),
              ("crank.torque", "crank torque [N·m]"), ("rod.angle", "rod angle [rad]")]
    fig, ax = plt.subplots(len(panels), 1, figsize=(10, 12), sharex=True)
    for a, (n, label) in zip(ax, panels):
        a.plot(o["time"], o[n], lw=0.7)
        a.set_ylabel(label, fontsize=8)
        a.grid(True, alpha=0.3)
    ax[-1].set_xlabel("time [s]")
    fig.suptitle("Digital twin: loads from measured crank data")
    fig.tight_layout()
    fig.savefig(folder / "timeseries.png", dpi=80)
    plt.close(fig)

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
    trends = [("mean_speed", "mean speed [rad/s]"), ("speed_fluctuation", "speed fluctuation [-]"),
              ("crank_torque_max", "largest crank torque [N·m]"), ("friction_work", "friction work [J]")]
    fig, ax = plt.subplots(len(trends), 1, figsize=(8, 9), sharex=True)
    for a, (n, label) in zip(ax, trends):
        a.plot(s["revolution"], s[n], "o-", ms=3)
        a.set_ylabel(label, fontsize=8)
        a.grid(True, alpha=0.3)
    ax[-1].set_xlabel("revolution")
    fig.suptitle("Per-revolution trends")
    fig.tight_layout()
    fig.savefig(folder / "revolutions.png", dpi=80)
    plt.close(fig)
