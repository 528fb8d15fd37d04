"""Stop/start cycles for the simulated PLC (docs/plant.md "Simulated PLC", `--stop-cycle N`).

N cycles of the default machine (twin_sample.cycle_truth, docs/twin.md "Machine states"): 6 s at
65 strokes/min, a 2 s ramp down, the crank rocking back 2° under the discharge pressure, a
standstill in which a 4096-count encoder dithers by one count (a flip every 20 ms on average), a
2 s ramp up and 6 s running; 22 s a cycle, read at 1 kHz. The same N always gives the same file
(a fixed seed), so a test replays it from the file and compares.

Layer: workflows, the plant (docs/architecture.md).
"""

from __future__ import annotations

import math
import pathlib

import numpy as np

from ..twin.sample import CYCLE, cycle_truth

RATE = 1000.0
COUNTS = 4096


def samples(cycles: int) -> tuple[np.ndarray, np.ndarray]:
    """(time [s], encoder counts, wrapped at COUNTS) of `cycles` stop/start cycles."""
    t = np.arange(int(round(cycles * sum(CYCLE) * RATE)) + 1) / RATE
    th, w, _, _ = cycle_truth(t, cycles=cycles)
    rng = np.random.default_rng(40)
    flips = np.cumsum((w == 0) & (rng.random(len(t)) < 0.05)) % 2
    counts = np.floor(th / (2 * math.pi) * COUNTS) + np.where(w == 0, flips, 0)
    return t, (counts % COUNTS).astype(np.int64)


def write(path, cycles: int, force: bool = False) -> pathlib.Path:
    """The cycles as a CSV file the PLC plays (time, crank_angle in counts; with `force`, a
    process_force column of zeros, for a twin that subscribes to the force node too)."""
    t, c = samples(cycles)
    p = pathlib.Path(path)
    tail = ",0.0\n" if force else "\n"
    p.write_text(
        ("time,crank_angle,process_force\n" if force else "time,crank_angle\n")
        + "".join(f"{a!r},{b}{tail}" for a, b in zip(t.tolist(), c.tolist()))
    )
    return p
