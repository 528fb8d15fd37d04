"""ReciprocatingDrive from Python: load the FMU, apply a preset, drive it with crank data and
summarise revolutions. Shared by the main job (scripts/simulate.py), the digital twin, the design
sweeps and the closed-loop system, and importable from users' own scripts.

    from reciprocating_drive import Fmu, preset_values, summarize_revolutions

The package lives in python/ of the repository; scripts/lib/venv.sh makes it importable in the
project's .venv (a .pth file), and the project's scripts put python/ first on sys.path.

Layer: the package's public names (from the FMU access and shared layers) (docs/architecture.md).
"""

from ._version import __version__
from .fmu import DEFAULT_FMU, Fmu, FmuError
from .presets import available_presets, preset_values, preset_values_from_fmu, read_ssv
from .revolution import RevolutionSummary, summarize_revolutions

__all__ = [
    "__version__",
    "DEFAULT_FMU",
    "Fmu",
    "FmuError",
    "available_presets",
    "preset_values",
    "preset_values_from_fmu",
    "read_ssv",
    "RevolutionSummary",
    "summarize_revolutions",
]
