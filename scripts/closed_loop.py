#!/usr/bin/env python3
"""The pump and its drive train in one SSP system (docs/closed-loop.md).

The same command as `rdrive closed-loop` of the installed package: python/reciprocating_drive/commands/closed_loop.py
(`--help` describes it).
"""

import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "python"))
from reciprocating_drive.commands import run_script  # noqa: E402

if __name__ == "__main__":
    run_script("closed_loop")
