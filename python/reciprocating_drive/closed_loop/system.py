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

Layer: workflows, the closed loop (docs/architecture.md).
"""

from __future__ import annotations

import math
import pathlib
import shutil
import tempfile
import zipfile
from xml.sax.saxutils import escape

import numpy as np

from .. import artifacts

SSD = artifacts.ssp_system() / "SystemStructure.ssd"
#: The Model Exchange variant (same components and connections, OMSimulator's variable-step
#: solver), packed as SystemStructure.ssd of ClosedLoopME.ssp.
SSD_ME = artifacts.ssp_system() / "SystemStructureME.ssd"
FMU_DIR = artifacts.fmu_dir()


class LoopFailed(RuntimeError):
    """The co-simulation of the loop failed (an importer's error or non-finite values); `time`:
    the last communication point reached, where known."""

    time: float | None = None


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
    model_exchange: bool = False,
) -> pathlib.Path:
    """Writes the system as `out` (.ssp, a zip): SystemStructure.ssd, resources/ with both FMUs
    and the two components' parameter sets (pump.ssv, drivetrain.ssv; the repository's
    ssp/ClosedLoop/*.ssv unless `pump`/`drive` values are given). `model_exchange`: the Model
    Exchange variant (SystemStructureME.ssd; the FMI 2.0 FMUs carry both interfaces)."""
    out = pathlib.Path(out)
    with tempfile.TemporaryDirectory() as d:
        d = pathlib.Path(d)
        (d / "resources").mkdir()
        shutil.copy(SSD_ME if model_exchange else SSD, d / "SystemStructure.ssd")
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
    ("load") and of simulate_until ("simulate"). A failed simulation raises LoopFailed with the
    time of the last communication point reached (libcosim's own log is silenced: the tools
    print one line)."""
    import time

    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.FATAL)
    with tempfile.TemporaryDirectory() as d:
        with zipfile.ZipFile(ssp) as z:
            z.extractall(d)
        step_ns = int(round(h * 1e9))
        t0 = time.perf_counter()
        ex = CosimExecution.from_ssp_file(d, step_size=step_ns)
        n = int(round(t_end / h))
        obs = CosimObserver.create_time_series(buffer_size=n + 10)
        if not ex.add_observer(obs):
            raise LoopFailed("libcosim: the time-series observer could not be added")
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
        out = {}
        for (comp, var), vr in refs.items():
            times, _steps, values = obs.time_series_real_samples(idx[comp], vr, 1, n)
            out[f"{comp}.{var}"] = np.asarray(values, dtype=float)
            out["time"] = np.asarray(times, dtype=float) * 1e-9
        if not ok:
            reached = float(out["time"][-1]) if len(out["time"]) else 0.0
            err = LoopFailed(f"libcosim: the simulation failed after t = {reached:.4g} s")
            err.time, err.series = reached, out
            raise err
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
    # fmpy instantiates the components with its default callbacks, whose logger prints every FMU
    # message: keep them instead, and put the last error into LoopFailed's one line.
    # The logger of fmu.py's _Log takes this project's FMUs' "%s" messages (its docstring).
    import fmpy.fmi2 as fmi2

    from ..fmu.instance import _Log

    log = _Log(echo=False)
    saved = fmi2.defaultCallbacks.logger
    fmi2.defaultCallbacks.logger = log.callbacks.logger
    try:
        res = simulate_ssp(str(ssp), stop_time=n * h - 0.5 * h, step_size=h, parameter_set=ps)
    except Exception as e:
        text = f"fmpy: {str(e).rstrip('.')}"
        errors = [m for (status, _, m) in log.lines if status >= 3 and m]  # fmi2Error, Fatal
        if errors:
            text += f"; the FMU: {' '.join(errors[-1].split())[:300]}"
        raise LoopFailed(text) from None
    finally:
        fmi2.defaultCallbacks.logger = saved
    out = {"time": (np.arange(len(res)) + 1) * h}
    names = res.dtype.names
    for comp, var in RECORD:
        key = next(k for k in names if k.endswith(f"{comp}.{var}"))
        out[f"{comp}.{var}"] = np.asarray(res[key], dtype=float)
    return out


def revolution_times(time: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """The times at which the crank angle passes whole multiples of 2π (linear interpolation
    between the samples on either side), from the first multiple after the start."""
    k0 = math.floor(angle[0] / (2 * math.pi)) + 1
    k1 = math.floor(angle[-1] / (2 * math.pi))
    targets = 2 * math.pi * np.arange(k0, k1 + 1)
    return np.interp(targets, angle, time)


def mean_speed_last(
    time: np.ndarray, angle: np.ndarray, revolutions: int = 3
) -> tuple[float, int] | None:
    """(mean crank speed [rad/s], revolutions) over the last whole revolutions, at most
    `revolutions` of them: k·2π over the time they took, which is the time average of ω exactly
    (∫ω dt = Δθ), unlike the speed at one instant, which swings with the load over a revolution.
    None without a complete revolution."""
    t = revolution_times(time, angle)
    k = min(revolutions, len(t) - 1)
    if k < 1:
        return None
    return 2 * math.pi * k / float(t[-1] - t[-1 - k]), k


def write_series(path: pathlib.Path, r: dict, units: dict) -> None:
    """The recorded series as CSV: `time [s]` then RECORD's variables as `component.variable
    [unit]`, one row per communication point (the same columns for every importer), numbers
    written with repr (round-trip exact)."""
    from ..twin.core import with_unit

    names = [f"{c}.{v}" for c, v in RECORD]
    cols = [np.asarray(r["time"], dtype=float)] + [np.asarray(r[n], dtype=float) for n in names]
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        f.write(",".join([with_unit("time", "s")] + [with_unit(n, units.get(n)) for n in names]))
        f.write("\n")
        for row in zip(*cols):
            f.write(",".join(repr(float(x)) for x in row) + "\n")


def record_units(fmu_dir: pathlib.Path) -> dict:
    """The unit of each RECORD variable, from the two FMUs' model descriptions."""
    from fmpy import read_model_description

    out = {}
    for comp, fmu in (("pump", "ReciprocatingDrive.fmu"), ("drivetrain", "DriveTrain.fmu")):
        md = read_model_description(str(pathlib.Path(fmu_dir) / fmu), validate=False)
        units = {
            v.name: v.unit or (v.declaredType.unit if v.declaredType else None)
            for v in md.modelVariables
        }
        for c, v in RECORD:
            if c == comp:
                out[f"{c}.{v}"] = units.get(v)
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


def start_values(fmu: pathlib.Path) -> dict:
    """Start values of an FMU's parameters, as Python numbers."""
    from fmpy import read_model_description

    out = {}
    for v in read_model_description(str(fmu), validate=False).modelVariables:
        if v.causality == "parameter" and v.start is not None:
            if v.type == "Boolean":
                out[v.name] = str(v.start).lower() in ("true", "1")
            elif v.type in ("Integer", "Enumeration"):
                out[v.name] = int(v.start)
            else:
                out[v.name] = float(v.start)
    return out


def torque_factor_max(pump_fmu: pathlib.Path, pump: dict, omega: float, n: int = 720) -> float:
    """max |kinematics.torque_factor| over one revolution of the pump FMU at constant speed
    (any mechanism: the FMU's own kinematics, docs/model.md §3)."""
    import numpy as np

    from ..fmu.instance import Fmu

    f = Fmu(str(pump_fmu))
    values = {k: v for k, v in pump.items() if k not in ("crank.angle", "crank.speed")}
    values["crank.speed"] = omega
    f.start(values)
    ch = f.channel(["crank.angle", "crank.speed"], ["kinematics.torque_factor"])
    row = np.empty(1)
    h = 2 * math.pi / omega / n
    ch.set_inputs([0.0, omega])
    ch.read(row)
    best = abs(row[0])
    for k in range(1, n + 1):
        ch.step(k * h, [omega * (k - 1) * h, omega], row)
        best = max(best, abs(row[0]))
    return float(best)


def loop_gain(pump: dict, drive: dict, h: float, fmu_dir: pathlib.Path = FMU_DIR) -> dict:
    """ρ_eff = (m·TF²/J)·exp(−h/τ) of docs/closed-loop.md "The algebraic loop", with
    J = J_c + i²·J_m, τ = J/(i²·k_m), k_m = 2·T_b/(s_b·ω_s); TF_max from the pump FMU. `pump`,
    `drive`: the components' parameter values (start values where not given)."""
    fmu_dir = pathlib.Path(fmu_dir)
    p = {**start_values(fmu_dir / "ReciprocatingDrive.fmu"), **pump}
    d = {**start_values(fmu_dir / "DriveTrain.fmu"), **drive}
    i = d["drive.gear_ratio"]
    J = d["crank.inertia"] + i * i * d["motor.inertia"]
    k_m = (
        2 * d["motor.breakdown_torque"] / (d["motor.breakdown_slip"] * d["motor.synchronous_speed"])
    )
    tau = J / (i * i * k_m)
    omega = max(d["crank.speed_start"], d["motor.synchronous_speed"] / i)
    tf = torque_factor_max(fmu_dir / "ReciprocatingDrive.fmu", p, omega)
    m = p["mass.reciprocating"]
    rho = m * tf * tf / J * math.exp(-h / tau)
    return {"rho": rho, "m": m, "tf": tf, "J": J, "tau": tau}


def plot_closed_loop(r: dict, d: list, title: str, path: pathlib.Path | None = None):
    """closed_loop.png: crank speed, motor torque and power against time, and δ per revolution.
    No axis uses an offset, and a constant (δ once the loop is periodic) is drawn as one. Without
    `path`, returns the figure (the tests read its axes)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    from ..sweeps.plots import plain_axis

    fig, ax = plt.subplots(4, 1, figsize=(10, 10))
    t, w = r["time"], r["drivetrain.crank.speed"]
    series = [
        (w * 60 / (2 * math.pi), "crank speed\n[strokes/min]"),
        (r["drivetrain.motor.torque"], "motor torque\n[N·m]"),
        (r["drivetrain.motor.power"] * 1e-3, "motor power\n[kW]"),
    ]
    for x, (y, label) in zip(ax[:3], series):
        x.plot(t, y)
        x.set_ylabel(label)
        x.set_xlabel("time [s]")
        x.grid(True, alpha=0.4)
        plain_axis(x, y)
    # δ to the digits printed (4 decimals of a per cent): differences below are rounding noise.
    dp = np.round(np.asarray(d, dtype=float) * 100, 4)
    ax[3].plot(range(1, len(dp) + 1), dp, "o-")
    ax[3].set_xlabel("revolution")
    ax[3].set_ylabel("δ = (ω_max − ω_min)/ω_mean\n[%]")
    ax[3].grid(True, alpha=0.4)
    ax[3].xaxis.set_major_locator(MaxNLocator(integer=True))
    plain_axis(ax[3], dp)
    # δ is read against its size: the axis spans at least ±5 % of the mean δ, so that a change in
    # its last printed digit (the 1 ms sampling of ω's extremes) does not fill the panel as if the
    # fluctuation itself changed.
    fin = dp[np.isfinite(dp)]
    if fin.size:
        mid = 0.5 * (float(fin.min()) + float(fin.max()))
        half = max(0.5 * float(fin.max() - fin.min()) * 1.1, 0.05 * abs(mid))
        if half > 0:
            ax[3].set_ylim(mid - half, mid + half)
    fig.suptitle(title)
    fig.tight_layout()
    if path is None:
        return fig
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return None
