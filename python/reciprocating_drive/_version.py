"""The package's version: that of the installed distribution, or, in a checkout, the Rust crate's
(Cargo.toml), which is also the FMUs' version (pyproject.toml takes it from there too).

Layer: shared, below the FMU access (docs/architecture.md).
"""

from __future__ import annotations

import pathlib
import re
from importlib import metadata


def _version() -> str:
    here = pathlib.Path(__file__).resolve()
    cargo = here.parents[2] / "Cargo.toml"
    # A checkout: python/reciprocating_drive beside the crate's Cargo.toml.
    if here.parent.parent.name == "python" and cargo.is_file():
        m = re.search(r'(?m)^version = "([^"]+)"', cargo.read_text(encoding="utf-8"))
        if m:
            return m.group(1)
    try:
        return metadata.version("reciprocating-drive")
    except metadata.PackageNotFoundError:
        return "0+unknown"


__version__ = _version()
