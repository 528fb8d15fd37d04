#!/usr/bin/env python3
"""The twin in a plant: a configuration file names the source, the sinks and the page (docs/plant.md).

The same command as `rdrive plant` of the installed package: python/reciprocating_drive/commands/twin_plant.py
(`--help` describes it).
"""

import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "python"))
from reciprocating_drive.commands import run_script  # noqa: E402

if __name__ == "__main__":
    run_script("twin_plant")
