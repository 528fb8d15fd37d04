#!/usr/bin/env python3
"""Writes the twin's sample data data/twin/pump_encoder.csv (docs/twin.md): the default machine
at 65 strokes/min with a ±3 % speed fluctuation (python/reciprocating_drive/twin/sample.py is the
truth), a 4096-count encoder read at 1 kHz with 20 µs timestamp jitter, one 0.2 s gap at 6 s,
no speed channel.

    .venv/bin/python scripts/make_twin_sample.py [--out data/twin/pump_encoder.csv]
"""

from __future__ import annotations

import argparse
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
from reciprocating_drive.twin.sample import encoder_samples  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "data" / "twin" / "pump_encoder.csv")
    a = ap.parse_args(argv)
    t, c = encoder_samples()
    a.out.parent.mkdir(parents=True, exist_ok=True)
    with open(a.out, "w") as f:
        f.write("time,crank_angle\n")
        for ti, ci in zip(t, c):
            f.write(f"{ti:.6f},{ci}\n")
    print(f"wrote {a.out} ({len(t)} samples)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
