#!/usr/bin/env python3
"""A design sweep on Dask (docs/sweeps.md).

The same command as `rdrive sweep` of the installed package: python/reciprocating_drive/commands/sweep.py
(`--help` describes it).
"""

import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "python"))
from reciprocating_drive.commands import run_script  # noqa: E402

if __name__ == "__main__":
    run_script("sweep")
