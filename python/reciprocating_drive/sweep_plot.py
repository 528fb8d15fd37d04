"""The plot of a sweep (docs/sweeps.md): each metric against the varied parameter (one varied
parameter), or as a heat map over a grid of two; for more parameters, each metric against each
parameter as a scatter plot. Rejected cases are marked."""

from __future__ import annotations

import math
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .study import METRICS, Study  # noqa: E402


def _label(m: str) -> str:
    return METRICS.get(m, m)


def plot_sweep(study: Study, rows: list[dict], path: str | pathlib.Path) -> None:
    ok = [r for r in rows if r["status"] == "ok"]
    bad = [r for r in rows if r["status"] != "ok"]
    params, metrics = study.varied, study.metrics
    fig, axes = plt.subplots(len(metrics), 1, figsize=(8, 3.4 * len(metrics)), squeeze=False)
    for ax, m in zip(axes[:, 0], metrics):
        if len(params) == 2 and study.design == "grid":
            px, py = params
            xs = sorted({r[px] for r in rows})
            ys = sorted({r[py] for r in rows})
            z = np.full((len(ys), len(xs)), np.nan)
            for r in ok:
                z[ys.index(r[py]), xs.index(r[px])] = r[m]
            im = ax.pcolormesh(xs, ys, z, shading="nearest", cmap="viridis")
            fig.colorbar(im, ax=ax, label=m)
            ax.set_title(_label(m), fontsize=9)
            for r in bad:
                ax.plot(r[px], r[py], "rx")
            ax.set_xlabel(px)
            ax.set_ylabel(py)
        else:
            for p in params[:1] if len(params) == 1 else params:
                x = np.array([r[p] for r in ok])
                y = np.array([r[m] for r in ok])
                order = np.argsort(x)
                style = "o-" if len(params) == 1 else "o"
                ax.plot(x[order], y[order], style, ms=3, label=p)
                for r in bad:
                    ax.axvline(r[p], color="r", lw=0.5, alpha=0.5)
            ax.set_xlabel(params[0] if len(params) == 1 else "parameter value")
            ax.set_ylabel(m)
            ax.set_title(_label(m), fontsize=9)
            if len(params) > 1:
                ax.legend(fontsize=8)
        ax.grid(True, alpha=0.3)
    n_bad = len(bad)
    fig.suptitle(
        f"{study.name}: {study.machine if len(study.machine) < 40 else pathlib.Path(study.machine).name}"
        f", {len(ok)} cases" + (f", {n_bad} rejected (red)" if n_bad else "")
    )
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    fig.savefig(path, dpi=90)
    plt.close(fig)


def finite(x) -> bool:
    return isinstance(x, float) and math.isfinite(x)
