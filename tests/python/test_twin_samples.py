"""The twin's core fed numbers (`Twin.feed_samples`, what the OPC UA source hands over) against the
same samples written as CSV lines with `repr` and read by the twin's CSV reader (`Twin.feed`, the
path every file and standard input takes, tested against closed forms in test_twin.py): the same
output rows and summaries bit for bit, the same messages and the same checkpoint, in chunks of
any size, through a gap, after a restart from a checkpoint, and for every kind of bad value a
source of numbers can hand over (missing, not finite, time going backwards), each named by the
same line with the same words (docs/twin.md "Input").
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from reciprocating_drive.fmu import Fmu
from reciprocating_drive.plant.samples import sample_header, sample_lines
from reciprocating_drive.twin import DataError, Options, Twin
from reciprocating_drive.twin.sample import truth
from reciprocating_drive.twin.samples import OPTIONAL, Samples


@pytest.fixture(scope="module")
def fmu(fmu_path):
    return Fmu(fmu_path)


def data(seconds=4.0, gap=(2.0, 2.3)):
    """1 kHz samples of the default machine's crank (wrapped angle, measured speed, a force
    step), with a gap that re-initializes the FMU."""
    t = np.arange(int(seconds * 1000) + 1) / 1000.0
    t = t[(t < gap[0]) | (t > gap[1])]
    theta, omega, _ = truth(t)
    force = np.where((t > 1.0) & (t < 3.0), 20e3, 0.0)
    return t, np.mod(theta, 2 * math.pi), omega, force


def by_text(twin, cols, sizes, header=True):
    """Feeds the columns as CSV lines (a header first when `header`) in chunks of `sizes`."""
    out, sums, err, lineno = [], [], None, twin.lines_read
    names = [n for n in ("time", "crank_angle", "crank_speed", "process_force") if n in cols]
    first = True
    for lo, hi in sizes:
        lines = sample_lines(
            cols["time"][lo:hi],
            cols["crank_angle"][lo:hi],
            cols["crank_speed"][lo:hi] if "crank_speed" in names else None,
            cols["process_force"][lo:hi] if "process_force" in names else None,
        )
        if first and header:
            lines = [sample_header("crank_speed" in names, "process_force" in names), *lines]
        first = False
        try:
            r, s = twin.feed(lines, lineno + 1)
        except DataError as e:
            err = str(e)
            break
        lineno += len(lines)
        out.append(r)
        sums += s
    if err is None:
        r, s = twin.finish()
        out.append(r)
        sums += s
    return np.concatenate(out) if out else None, sums, err


def by_numbers(twin, cols, sizes):
    out, sums, err = [], [], None
    for lo, hi in sizes:
        s = Samples.of(**{k: v[lo:hi] for k, v in cols.items()})
        try:
            r, su = twin.feed_samples(s, twin.lines_read + 1)
        except DataError as e:
            err = str(e)
            break
        out.append(r)
        sums += su
    if err is None:
        r, su = twin.finish()
        out.append(r)
        sums += su
    return np.concatenate(out) if out else None, sums, err


def chunked(n, sizes=(1, 7, 50, 333)):
    out, lo, k = [], 0, 0
    while lo < n:
        hi = min(n, lo + sizes[k % len(sizes)])
        out.append((lo, hi))
        lo, k = hi, k + 1
    return out


def same(a, b):
    return a is None and b is None or (a.shape == b.shape and a.tobytes() == b.tobytes())


def comparable(cp):
    """A checkpoint's content, its FMU state's bytes included."""
    return repr(sorted(cp.items()))


@pytest.mark.parametrize("columns", [("speed", "force"), ("speed",), ("force",), ()])
def test_numbers_give_the_rows_summaries_messages_and_checkpoint_of_the_csv_lines(fmu, columns):
    t, a, w, f = data()
    cols = {"time": t, "crank_angle": a}
    if "speed" in columns:
        cols["crank_speed"] = w
    if "force" in columns:
        cols["process_force"] = f
    sizes = chunked(len(t))
    opts = Options(angle_unit="rad")
    text, numbers = Twin(fmu, options=opts), Twin(fmu, options=opts)
    r1, s1, e1 = by_text(text, cols, sizes)
    r2, s2, e2 = by_numbers(numbers, cols, sizes)
    assert e1 is None and e2 is None
    assert len(r1) == len(t) and same(r1, r2)
    assert repr(s1) == repr(s2) and len(s1) >= 3
    assert text.messages == numbers.messages and any("gap" in m for m in text.messages)
    assert text.lines_read == numbers.lines_read == len(t) + 1
    assert comparable(text.checkpoint()) == comparable(numbers.checkpoint())


def test_a_restarted_twin_numbers_on_without_a_header(fmu):
    """Restored from a checkpoint mid-run, the numbers go on from its input line, as the lines do
    (no header line then), and the rest of the run is the same bit for bit."""
    t, a, w, _ = data()
    cols = {"time": t, "crank_angle": a, "crank_speed": w}
    half = len(t) // 2
    first = Twin(fmu)
    by_text(first, {k: v[:half] for k, v in cols.items()}, chunked(half)[:-1])
    cp = first.checkpoint()
    done = first.lines_read - 1
    rest = chunked(len(t) - done)
    tail = {k: v[done:] for k, v in cols.items()}
    # One after the other: both restore the FMU state into the one loaded FMU.
    text = Twin.from_checkpoint(fmu, cp)
    r1, s1, e1 = by_text(text, tail, rest, header=False)
    numbers = Twin.from_checkpoint(fmu, cp)
    r2, s2, e2 = by_numbers(numbers, tail, rest)
    assert e1 is None and e2 is None and same(r1, r2) and repr(s1) == repr(s2)
    assert text.lines_read == numbers.lines_read == len(t) + 1


@pytest.mark.parametrize(
    "column, value, words",
    [
        ("crank_speed", math.nan, "crank_speed is empty (a number is needed)"),
        ("process_force", math.nan, "process_force is empty (a number is needed)"),
        ("crank_speed", math.inf, "crank_speed = 'inf' is not a finite number"),
        ("process_force", -math.inf, "process_force = '-inf' is not a finite number"),
        ("crank_angle", math.nan, "crank_angle = 'nan' is not a finite number"),
        ("time", math.inf, "time = 'inf' is not a finite number"),
        ("time", 0.5, "time 0.5 s goes backwards"),
    ],
)
def test_a_bad_value_stops_both_paths_at_the_same_line_with_the_same_words(
    fmu, column, value, words
):
    t, a, w, f = data(seconds=2.0, gap=(9.0, 9.0))
    cols = {"time": t, "crank_angle": a, "crank_speed": w, "process_force": f}
    k = 1234  # sample 1234 is input line 1236 (the header is line 1)
    cols[column] = cols[column].copy()
    cols[column][k] = value
    sizes = chunked(len(t))
    text, numbers = Twin(fmu), Twin(fmu)
    r1, s1, e1 = by_text(text, cols, sizes)
    r2, s2, e2 = by_numbers(numbers, cols, sizes)
    assert e1 == e2 and e1.startswith(f"line {k + 2}: {words}"), (e1, e2)
    assert same(r1, r2) and repr(s1) == repr(s2)
    assert text.lines_read == numbers.lines_read


def test_an_optional_column_is_one_entry():
    """Samples of an input without an optional column take its default; a name that is not an
    input column is refused."""
    s = Samples.of(time=[0.0, 0.001], crank_angle=[0.0, 0.01])
    assert s.names() == ["time", "crank_angle"]
    assert np.isnan(s.value("crank_speed")).all() and OPTIONAL["process_force"] == 0.0
    assert (s.value("process_force") == 0.0).all()
    assert len(s + s) == 4
    with pytest.raises(ValueError, match="no input column 'pressure'"):
        Samples.of(time=[0.0], crank_angle=[0.0], pressure=[1.0])
