"""FMU access (the layer below the workflows, docs/architecture.md): `instance` loads an FMU once
and drives it (start/reset, step, the fast Real channel, FMU state), `batch` is the native batch
library (tools/fmi2-batch) through ctypes. `Fmu`, `FmuError` and `DEFAULT_FMU` are importable from
here and from `reciprocating_drive`.
"""

from .instance import DEFAULT_FMU, Fmu, FmuError

__all__ = ["DEFAULT_FMU", "Fmu", "FmuError"]
