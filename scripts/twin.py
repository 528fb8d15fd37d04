#!/usr/bin/env python3
"""The drilling-pump digital twin: measured crank data in, the FMU's loads out (docs/twin.md).

The same command as `rdrive twin` of the installed package: python/reciprocating_drive/commands/twin.py
(`--help` describes it).
"""

import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "python"))
from reciprocating_drive.commands import run_script  # noqa: E402

if __name__ == "__main__":
    run_script("twin")
