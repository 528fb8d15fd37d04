"""The closed loop of docs/closed-loop.md as an SSP system: the pump (ReciprocatingDrive FMU) and
its drive train (DriveTrain FMU), connected

    pump.crank.torque             -> drivetrain.load.torque
    drivetrain.crank.angle        -> pump.crank.angle
    drivetrain.crank.speed        -> pump.crank.speed
    drivetrain.crank.acceleration -> pump.crank.acceleration

`build_ssp` writes the system (ssp/ClosedLoop/SystemStructure.ssd of the repository, both FMUs
and parameter sets for each component) as a .ssp archive; `run_libcosim` and `run_fmpy` simulate
it with the two importers. Both masters are Jacobi schemes: every FMU steps with the inputs the
other produced at the previous communication point, which breaks the algebraic loop
(crank.torque depends directly on crank.acceleration) with a delay of one step.
"""

from __future__ import annotations

import math
import pathlib
import shutil
import tempfile
import zipfile
from xml.sax.saxutils import escape

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
SSD = ROOT / "ssp" / "ClosedLoop" / "SystemStructure.ssd"
FMU_DIR = ROOT / "target" / "fmu"

#: What the scripts and tests record: (component, variable).
RECORD = (
    ("drivetrain", "crank.speed"),
    ("drivetrain", "crank.angle"),
    ("drivetrain", "crank.acceleration"),
    ("drivetrain", "motor.torque"),
    ("drivetrain", "motor.power"),
    ("drivetrain", "motor.slip"),
    ("pump", "crank.torque"),
)


def write_ssv(path: pathlib.Path, values: dict, name: str) -> None:
    """An SSP 1.0 parameter-value file with `values` (float → Real, bool → Boolean, int → Integer)."""
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" '
        f'version="1.0" name="{escape(name)}">',
        "  <ssv:Parameters>",
    ]
    for k, v in values.items():
        if isinstance(v, bool):
            val = f'<ssv:Boolean value="{str(v).lower()}"/>'
        elif isinstance(v, int):
            val = f'<ssv:Integer value="{v}"/>'
        else:
            val = f'<ssv:Real value="{float(v)!r}"/>'
        lines.append(f'    <ssv:Parameter name="{escape(k)}">{val}</ssv:Parameter>')
    lines += ["  </ssv:Parameters>", "</ssv:ParameterSet>", ""]
    path.write_text("\n".join(lines))


def build_ssp(
    out: pathlib.Path,
    pump: dict | None = None,
    drive: dict | None = None,
    fmu_dir: pathlib.Path = FMU_DIR,
) -> pathlib.Path:
    """Writes the system as `out` (.ssp, a zip): SystemStructure.ssd, resources/ with both FMUs
    and the two components' parameter sets (pump.ssv, drivetrain.ssv; the repository's
    ssp/ClosedLoop/*.ssv unless `pump`/`drive` values are given)."""
    out = pathlib.Path(out)
    with tempfile.TemporaryDirectory() as d:
        d = pathlib.Path(d)
        (d / "resources").mkdir()
        shutil.copy(SSD, d / "SystemStructure.ssd")
        for fmu in ("ReciprocatingDrive.fmu", "DriveTrain.fmu"):
            src = pathlib.Path(fmu_dir) / fmu
            if not src.is_file():
                raise FileNotFoundError(f"{src} not found: build it with scripts/build-fmu.sh")
            shutil.copy(src, d / "resources" / fmu)
        for comp, values in (("pump", pump), ("drivetrain", drive)):
            if values is None:
                shutil.copy(SSD.parent / f"{comp}.ssv", d / "resources" / f"{comp}.ssv")
            else:
                write_ssv(d / "resources" / f"{comp}.ssv", values, comp)
        out.parent.mkdir(parents=True, exist_ok=True)
        with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
            for p in sorted(d.rglob("*")):
                if p.is_file():
                    z.write(p, p.relative_to(d).as_posix())
    return out


def run_libcosim(ssp: pathlib.Path, h: float, t_end: float, timing: dict | None = None) -> dict:
    """The system in libcosim (its SSP loader, fixed step h). Returns time and RECORD series at
    the communication points t_1 .. t_n. `timing` receives the seconds of loading the system
    ("load") and of simulate_until ("simulate")."""
    import time

    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.WARNING)
    with tempfile.TemporaryDirectory() as d:
        with zipfile.ZipFile(ssp) as z:
            z.extractall(d)
        step_ns = int(round(h * 1e9))
        t0 = time.perf_counter()
        ex = CosimExecution.from_ssp_file(d, step_size=step_ns)
        n = int(round(t_end / h))
        obs = CosimObserver.create_time_series(buffer_size=n + 10)
        assert ex.add_observer(obs)
        idx = {s.name.decode(): s.index for s in ex.slave_infos()}
        refs = {}
        for comp, var in RECORD:
            vr = {v.name.decode(): v.reference for v in ex.slave_variables(idx[comp])}[var]
            refs[(comp, var)] = vr
            obs.start_time_series(
                idx[comp], value_reference=vr, variable_type=CosimVariableType.REAL
            )
        t1 = time.perf_counter()
        ok = ex.simulate_until(target_time=int(round(t_end * 1e9)))
        if timing is not None:
            timing.update(load=t1 - t0, simulate=time.perf_counter() - t1)
        if not ok:
            raise RuntimeError("libcosim: the simulation failed")
        out = {}
        for (comp, var), vr in refs.items():
            times, _steps, values = obs.time_series_real_samples(idx[comp], vr, 1, n)
            out[f"{comp}.{var}"] = np.asarray(values, dtype=float)
            out["time"] = np.asarray(times, dtype=float) * 1e-9
    return out


def run_fmpy(ssp: pathlib.Path, h: float, t_end: float) -> dict:
    """The system in fmpy's SSP simulation (fmpy.ssp.simulation.simulate_ssp). fmpy applies only
    a parameter set given to it, with names prefixed by the component: the components' .ssv files
    are read from the archive and passed that way. Returns the series at t_1 .. t_n (fmpy records
    each row before advancing its clock: row k holds the outputs at t_{k+1})."""
    from fmpy.ssp.simulation import simulate_ssp
    from fmpy.ssp.ssd import ParameterSet, read_ssv

    params = []
    with tempfile.TemporaryDirectory() as d:
        with zipfile.ZipFile(ssp) as z:
            z.extractall(d)
        for comp in ("pump", "drivetrain"):
            for p in read_ssv(str(pathlib.Path(d) / "resources" / f"{comp}.ssv")).parameters:
                p.name = f"{comp}.{p.name}"
                params.append(p)
    ps = ParameterSet(parameters=params)
    n = int(round(t_end / h))
    res = simulate_ssp(str(ssp), stop_time=n * h - 0.5 * h, step_size=h, parameter_set=ps)
    out = {"time": (np.arange(len(res)) + 1) * h}
    names = res.dtype.names
    for comp, var in RECORD:
        key = next(k for k in names if k.endswith(f"{comp}.{var}"))
        out[f"{comp}.{var}"] = np.asarray(res[key], dtype=float)
    return out


def speed_fluctuation(time: np.ndarray, angle: np.ndarray, speed: np.ndarray) -> list[float]:
    """δ = (ω_max − ω_min)/ω_mean of every complete revolution of the crank angle."""
    out = []
    k = math.ceil(angle[0] / (2 * math.pi))
    while True:
        sel = (angle >= 2 * math.pi * k) & (angle < 2 * math.pi * (k + 1))
        if not sel.any() or angle[-1] < 2 * math.pi * (k + 1):
            break
        w = speed[sel]
        out.append(float((w.max() - w.min()) / w.mean()))
        k += 1
    return out
