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
    if hi - lo <= rel * size or hi == lo:
        mid = 0.5 * (lo + hi)
        half = 0.05 * abs(mid) if mid != 0 else 1.0
        (ax.set_ylim if axis == "y" else ax.set_xlim)(mid - half, mid + half)
