"""The wheel's build hook (hatchling, pyproject.toml): puts the binaries that scripts/build-fmu.sh
built, and the data the workflows ship with (presets, SSP system, studies, example twin
configurations, the twin's sample), into reciprocating_drive/_data/ (the layout
python/reciprocating_drive/artifacts.py reads), and tags the wheel for the platform of its native
code.

The native code is loaded with ctypes (the batch library) or by the FMU importer (the FMUs), not
imported as a CPython extension, so the tag is `py3-none-<platform>`: any Python 3.11+, one
platform. The FMUs carry their own linux64 and win64 binaries; the batch library is the host's.
"""

from __future__ import annotations

import pathlib
import sysconfig

from hatchling.builders.hooks.plugin.interface import BuildHookInterface

MODELS = ("ReciprocatingDrive", "DriveTrain")


class CustomBuildHook(BuildHookInterface):
    def initialize(self, version, build_data):
        if self.target_name != "wheel":
            return
        root = pathlib.Path(self.root)
        lib = root / "target" / "release" / "libfmi2_batch.so"
        # FMI 2.0 (<id>.fmu) and FMI 3.0 (<id>-fmi3.fmu) archives of each model.
        files = {root / "target" / "fmu" / f"{m}.fmu": f"fmu/{m}.fmu" for m in MODELS}
        for m in MODELS:
            files[root / "target" / "fmu" / f"{m}-fmi3.fmu"] = f"fmu/{m}-fmi3.fmu"
        files[lib] = f"lib/{lib.name}"
        files[root / "data" / "twin" / "pump_encoder.csv"] = "twin/pump_encoder.csv"
        for src in sorted((root / "ssp" / "ClosedLoop").iterdir()):
            files[src] = f"ssp/ClosedLoop/{src.name}"
        for src in sorted((root / "resources" / "presets").glob("*.ssv")):
            files[src] = f"presets/{src.name}"
        for src in sorted((root / "examples" / "twin").glob("*.toml")):
            files[src] = f"examples/{src.name}"
        for src in sorted((root / "studies").glob("*.toml")):
            files[src] = f"studies/{src.name}"
        missing = [str(p.relative_to(root)) for p in files if not p.is_file()]
        if missing:
            raise RuntimeError(
                f"the wheel needs {', '.join(missing)}: run scripts/build-fmu.sh first "
                "(scripts/build-wheel.sh does)"
            )
        for src, dest in files.items():
            build_data["force_include"][str(src)] = f"reciprocating_drive/_data/{dest}"
        build_data["pure_python"] = False
        platform = sysconfig.get_platform().replace("-", "_").replace(".", "_")
        build_data["tag"] = f"py3-none-{platform}"
