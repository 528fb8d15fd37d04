"""The y-range rule of every plot (plots.y_range, docs/twin.md "Output"): a span of at least 2 %
of the value's size, so that rounding noise is drawn flat; and "largest" means the largest
magnitude in every label."""

from __future__ import annotations

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.figure  # noqa: E402


@pytest.fixture
def drawn(monkeypatch):
    """The y-ranges and tick labels of every axis of every figure saved (the real savefig runs)."""
    got = []
    save = matplotlib.figure.Figure.savefig

    def spy(fig, path, *a, **kw):
        fig.canvas.draw()
        for ax in fig.axes:
            labels = [t.get_text() for t in ax.get_yticklabels() if t.get_visible()]
            lo, hi = ax.get_ylim()
            got.append((str(path), ax.get_ylabel(), lo, hi, labels))
        return save(fig, path, *a, **kw)

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", spy)
    return got


def test_y_range_rule_by_hand():
    from reciprocating_drive.plots import y_range

    # Spread far below 2 %: centred, 2 % of 0.4 m wide, plus 5 % each side.
    lo, hi = y_range([0.399996, 0.4, 0.399998])
    mid, span = 0.399998, 0.02 * 0.4
    assert lo == pytest.approx(mid - 0.55 * span) and hi == pytest.approx(mid + 0.55 * span)
    # A real change (10 %) is drawn as it is, padded by 5 %.
    assert y_range([1.0, 1.1]) == pytest.approx((0.995, 1.105))
    # A limit within half the value's size is in view; one 20 times the value is not.
    assert y_range([374.0, 375.0], [500.0])[1] > 500.0
    assert y_range([374.0, 375.0], [8000.0])[1] < 400.0
    # Nothing finite: a unit range.
    assert y_range([np.nan]) == (0.0, 1.0)


def test_twin_revolutions_plot_does_not_stretch_a_4_um_stroke_change(tmp_path, drawn):
    """The finding: a twin's revolutions.png drew a stroke of 0.399996 to 0.400000 m and a
    friction work changing in its sixth digit at full height."""
    from reciprocating_drive.twin.plots import plot_twin

    n = 12
    t = np.linspace(0.0, 11.0, 1101)
    cols = {
        "time [s]": t,
        "crank.model_speed [rad/s]": 6.8 + 0.2 * np.sin(t),
        "suspension.acceleration [m/s²]": 9.0 * np.cos(6.8 * t),
        "guide.friction [N]": np.full_like(t, -45.0),
        "rod.force [N]": 3000.0 * np.cos(6.8 * t),
        "crank.torque [N·m]": 370.0 * np.sin(6.8 * t),
        "rod.angle [rad]": 0.16887 * np.sin(6.8 * t),
        "suspension.position [m]": 0.2 - 0.2 * np.cos(6.8 * t),
    }
    out = tmp_path / "o.csv"
    out.write_text(
        ",".join(cols)
        + "\n"
        + "".join(",".join(repr(float(c[i])) for c in cols.values()) + "\n" for i in range(len(t)))
    )
    rev = np.arange(n)
    summary = {
        "revolution [-]": rev,
        "start_time [s]": rev * 0.923,
        "mean_speed [rad/s]": 6.806 + 1e-3 * (rev % 3),
        "speed_fluctuation [-]": 0.0611 + 1e-4 * (rev % 2),
        "stroke [m]": 0.4 - 4e-6 * (rev % 2),
        "crank_torque_max [N·m]": 374.0 + (rev % 4),
        "friction_work [J]": -179.706 - 1e-4 * (rev % 2),
    }
    srv = tmp_path / "o-revolutions.csv"
    srv.write_text(
        ",".join(summary)
        + "\n"
        + "".join(",".join(repr(float(c[i])) for c in summary.values()) + "\n" for i in range(n))
    )
    plot_twin(out, srv, tmp_path / "plots")
    by_label = {
        label: (lo, hi, ticks)
        for path, label, lo, hi, ticks in drawn
        if path.endswith("revolutions.png")
    }
    lo, hi, ticks = by_label["stroke [m]"]
    assert hi - lo >= 0.02 * 0.4 and lo < 0.399996 and 0.4 < hi
    assert len(set(ticks)) == len(ticks) >= 2
    lo, hi, ticks = by_label["friction work [J]"]
    assert hi - lo >= 0.02 * 179.706 and len(set(ticks)) == len(ticks) >= 2
    # Every axis of the three figures follows the rule.
    for path, label, lo, hi, ticks in drawn:
        assert hi > lo and len(set(ticks)) == len(ticks), (path, label, ticks)


def test_largest_means_the_largest_magnitude_in_every_label():
    """Signed maxima are "maximum", never "largest" (the page's "largest rod force" is the largest
    magnitude, max(|max|, |min|))."""
    from reciprocating_drive.sweeps.plots import METRIC_AXES
    from reciprocating_drive.sweeps.study import METRICS

    signed = [k for k in METRICS if k.endswith(("_max", "_min")) and k != "stress_max"]
    assert signed
    for k in signed:
        assert "largest" not in METRICS[k] and "smallest" not in METRICS[k], METRICS[k]
        assert "largest" not in METRIC_AXES[k][0] and "smallest" not in METRIC_AXES[k][0]
    assert METRIC_AXES["rod_force_max"][0] == "maximum rod force"
