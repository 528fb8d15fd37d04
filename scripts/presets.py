#!/usr/bin/env python3
"""Presets of ReciprocatingDrive (physics.md §8) and how to apply one in fmpy.

A preset is an SSP 1.0 parameter-value file (.ssv) shipped in the FMU under
resources/presets/ (and in the repository under resources/presets/). It sets every parameter,
plus the start value of crank.speed.

    from presets import preset_values
    values = preset_values("sk8-3.5-4000")            # name -> value
    fmpy.simulate_fmu(fmu, start_values={k: v for k, v in values.items() if k != "crank.speed"}, ...)

or from the command line: `python scripts/presets.py FMU NAME` prints the values read from the
FMU's own copy of the preset.
"""

from __future__ import annotations

import pathlib
import sys
import xml.etree.ElementTree as ET
import zipfile

ROOT = pathlib.Path(__file__).resolve().parents[1]
PRESET_DIR = ROOT / "resources" / "presets"


def parse_ssv(text: str | bytes) -> dict:
    """name -> value of every parameter in an SSV document (namespace-agnostic)."""
    values = {}
    for el in ET.fromstring(text).iter():
        if el.tag.split("}")[-1] != "Parameter":
            continue
        name = el.get("name")
        for child in el:
            kind = child.tag.split("}")[-1]
            v = child.get("value")
            if v is None:
                continue
            if kind == "Real":
                values[name] = float(v)
            elif kind in ("Integer", "Enumeration"):
                values[name] = int(v)
            elif kind == "Boolean":
                values[name] = v.strip().lower() in ("true", "1")
    return values


def read_ssv(path: pathlib.Path) -> dict:
    return parse_ssv(pathlib.Path(path).read_bytes())


def available_presets(directory: pathlib.Path = PRESET_DIR) -> list[str]:
    return ["default"] + sorted(p.stem for p in pathlib.Path(directory).glob("*.ssv"))


def preset_values(name: str, directory: pathlib.Path = PRESET_DIR) -> dict:
    """The preset's values; "default" is the FMU's own start values (an empty dict)."""
    if name == "default":
        return {}
    if not name or name.startswith(".") or not all(c.isalnum() or c in "._-" for c in name):
        raise KeyError(name)
    path = pathlib.Path(directory) / f"{name}.ssv"
    if not path.is_file():
        raise KeyError(name)
    return read_ssv(path)


def preset_values_from_fmu(fmu: str, name: str) -> dict:
    """The preset as shipped inside the FMU (resources/presets/NAME.ssv)."""
    with zipfile.ZipFile(fmu) as z:
        return parse_ssv(z.read(f"resources/presets/{name}.ssv"))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        print(__doc__)
        sys.exit(2)
    for k, v in preset_values_from_fmu(sys.argv[1], sys.argv[2]).items():
        print(f"{k} = {v}")
