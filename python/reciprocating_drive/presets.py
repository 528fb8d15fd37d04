"""Presets: parameter sets shipped as SSP parameter-value files (.ssv) in resources/presets/ of
the repository and of the FMU (docs/model.md §8). fmpy reads and validates them against the SSP
schema; this module turns fmpy's parameter set into {name: value} with Python types
(float, int, bool) so that it can be handed to `Fmu.start` or fmpy.simulate_fmu.

Layer: shared, below the FMU access (docs/architecture.md).
"""

from __future__ import annotations

import os
import pathlib
import tempfile
import zipfile

from . import artifacts

PRESET_DIR = artifacts.presets_dir()

_CONVERT = {
    "Real": float,
    "Integer": int,
    "Enumeration": int,
    "Boolean": lambda v: v.strip().lower() in ("true", "1"),
}


def _values(parameter_set) -> dict:
    out = {}
    for p in parameter_set.parameters:
        conv = _CONVERT.get(p.type)
        if conv is None or p.value is None:
            raise ValueError(f"parameter {p.name!r}: unsupported SSV type {p.type!r}")
        out[p.name] = conv(p.value)
    return out


def read_ssv(path: str | os.PathLike) -> dict:
    """name -> value of every parameter of an .ssv file (validated against the SSP 1.0 schema)."""
    from fmpy.ssp.ssd import read_ssv as fmpy_read_ssv

    return _values(fmpy_read_ssv(str(path)))


def available_presets(directory: str | os.PathLike = PRESET_DIR) -> list[str]:
    """ "default" (the FMU's own start values) and the name of every .ssv in `directory`."""
    return ["default"] + sorted(p.stem for p in pathlib.Path(directory).glob("*.ssv"))


def preset_values(name: str, directory: str | os.PathLike = PRESET_DIR) -> dict:
    """The preset's values; "default" is the FMU's own start values (an empty dict). A path to an
    .ssv file is accepted as well. Raises KeyError for an unknown name."""
    if name == "default":
        return {}
    if name.endswith(".ssv") and pathlib.Path(name).is_file():
        return read_ssv(name)
    if not name or name.startswith(".") or not all(c.isalnum() or c in "._-" for c in name):
        raise KeyError(name)
    path = pathlib.Path(directory) / f"{name}.ssv"
    if not path.is_file():
        raise KeyError(name)
    return read_ssv(path)


def preset_values_from_fmu(fmu: str | os.PathLike, name: str) -> dict:
    """The preset as shipped inside the FMU (resources/presets/NAME.ssv)."""
    with zipfile.ZipFile(fmu) as z, tempfile.TemporaryDirectory() as d:
        target = pathlib.Path(d) / f"{name}.ssv"
        target.write_bytes(z.read(f"resources/presets/{name}.ssv"))
        return read_ssv(target)
