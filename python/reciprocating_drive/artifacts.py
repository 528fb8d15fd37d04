"""Where the package finds what it did not write in Python: the FMUs, the native batch library of
the twin, the closed-loop SSP system, the example studies and the twin's sample data.

Two layouts, tried in this order:

* an installed wheel (`pip install reciprocating_drive-*.whl`, built by scripts/build-wheel.sh):
  everything under the package's own `_data/` folder (`fmu/`, `lib/`, `ssp/`, `studies/`, `twin/`);
* a checkout of the repository: `target/fmu/`, `target/release/`, `ssp/`, `studies/`, `data/twin/`
  as scripts/build-fmu.sh leaves them.

So the same code runs from a clone and from a wheel on a machine that has never seen the
repository (a Dask worker, an edge computer); nothing else in the package names these paths.

Layer: shared, below the FMU access (docs/architecture.md).
"""

from __future__ import annotations

import pathlib
import sys

PACKAGE = pathlib.Path(__file__).resolve().parent
DATA = PACKAGE / "_data"
#: The repository root when the package runs from a checkout (python/reciprocating_drive).
ROOT = PACKAGE.parents[1]

#: The FMUs the project builds, by modelIdentifier.
MODELS = ("ReciprocatingDrive", "DriveTrain")


def installed() -> bool:
    """True when the package carries its own binaries (an installed wheel)."""
    return (DATA / "fmu").is_dir()


def _pick(wheel: pathlib.Path, checkout: pathlib.Path) -> pathlib.Path:
    return wheel if installed() else checkout


def fmu(model: str = "ReciprocatingDrive") -> pathlib.Path:
    """The `.fmu` of a model (ReciprocatingDrive or DriveTrain)."""
    if model not in MODELS:
        raise ValueError(f"model {model!r} is not one of this package's FMUs ({', '.join(MODELS)})")
    return _pick(DATA / "fmu", ROOT / "target" / "fmu") / f"{model}.fmu"


def fmu_dir() -> pathlib.Path:
    return fmu().parent


def batch_library() -> pathlib.Path:
    """The native batch driver of the twin (tools/fmi2-batch)."""
    name = {"win32": "fmi2_batch.dll", "darwin": "libfmi2_batch.dylib"}.get(
        sys.platform, "libfmi2_batch.so"
    )
    return _pick(DATA / "lib", ROOT / "target" / "release") / name


def ssp_system() -> pathlib.Path:
    """The folder of the closed-loop SSP system (SystemStructure.ssd and its .ssv files)."""
    return _pick(DATA / "ssp", ROOT / "ssp") / "ClosedLoop"


def studies_dir() -> pathlib.Path:
    """The example design studies."""
    return _pick(DATA / "studies", ROOT / "studies")


def presets_dir() -> pathlib.Path:
    """The presets of docs/model.md §8 as SSP parameter-value files (also inside the FMU)."""
    return _pick(DATA / "presets", ROOT / "resources" / "presets")


def results_dir() -> pathlib.Path:
    """Where the commands write by default: `results/` of the checkout, or of the current folder
    when the package is installed."""
    return pathlib.Path.cwd() / "results" if installed() else ROOT / "results"


def examples_dir() -> pathlib.Path:
    """The example twin configurations and alarm limits (examples/twin/)."""
    return _pick(DATA / "examples", ROOT / "examples" / "twin")


def twin_sample() -> pathlib.Path:
    """The twin's sample data (a 4096-count encoder at 1 kHz, docs/twin.md)."""
    return _pick(DATA / "twin", ROOT / "data" / "twin") / "pump_encoder.csv"
