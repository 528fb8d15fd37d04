#!/usr/bin/env python3
"""The pump and its drive train in a closed loop (docs/closed-loop.md): builds the SSP system
ClosedLoop.ssp (and its Model Exchange variant ClosedLoopME.ssp) from the shipped system and both
FMUs, simulates it in libcosim (default) or fmpy, or solves the loop exactly as one Model Exchange
ODE (--importer model-exchange), prints the mean crank speed over the last whole revolutions and
the per-revolution speed fluctuation δ = (ω_max − ω_min)/ω_mean, and writes into --out-dir
(default results/): the two SSPs, closed_loop.csv (time and the recorded variables, the same
columns for every importer), closed_loop.json (the summary) and closed_loop.png (crank speed, motor
torque and power, δ per revolution).

    rdrive closed-loop [--importer libcosim|fmpy|model-exchange] [--step 1e-3] [--time 10]
    rdrive closed-loop --set drivetrain.crank.inertia=80 --set pump.load.mean=2e4
    rdrive closed-loop --pump unb600a --set pump.fluid_end.discharge_pressure=1e6

Exit codes: 0 done, 1 the loop failed or diverged (the message names docs/closed-loop.md's
stability condition ρ_eff < 1), 2 a user error, 70 an internal error, 130 stopped.
"""

# Layer: commands (docs/architecture.md); a comment, as --help prints the docstring.

from __future__ import annotations

import argparse
import json
import math
import pathlib
import sys
import time

import numpy as np

from .. import artifacts
from ..cli_errors import (
    ArgumentParser,
    RunFailed,
    UserError,
    one_line,
    positive_float,
    run_cli,
    show,
)

PROG = "closed_loop.py"
#: At least this many steps per revolution: δ is a per-revolution extreme (docs/closed-loop.md).
MIN_STEPS_PER_REVOLUTION = 36
#: Samples of a run are held in memory (7 series): 10⁷ steps are about 0.6 GB.
MAX_STEPS = 10_000_000
COMPONENTS = {"pump": "ReciprocatingDrive.fmu", "drivetrain": "DriveTrain.fmu"}


def parser(prog: str = PROG) -> ArgumentParser:
    ap = ArgumentParser(
        prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "--importer",
        choices=("libcosim", "fmpy", "model-exchange"),
        default="libcosim",
        help="libcosim or fmpy: co-simulation of the SSP system (one-step delay in the loop); "
        "model-exchange: both FMI 3.0 FMUs as Model Exchange in one ODE, the loop solved exactly "
        "(reciprocating_drive/closed_loop/me_loop.py, docs/closed-loop.md)",
    )
    ap.add_argument("--step", default="1e-3", help="communication step [s] (default 1e-3)")
    ap.add_argument("--time", default="10", help="simulated time [s] (default 10)")
    ap.add_argument(
        "--out-dir",
        type=pathlib.Path,
        default=artifacts.results_dir(),
        help="where the SSPs, closed_loop.csv, .json and .png go (default: results/)",
    )
    ap.add_argument(
        "--fmu-dir",
        type=pathlib.Path,
        default=artifacts.fmu_dir(),
        help="where ReciprocatingDrive.fmu and DriveTrain.fmu are",
    )
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="COMPONENT.PARAMETER=VALUE",
        help="a parameter of the pump or the drivetrain over the shipped sets (ssp/ClosedLoop/*.ssv); "
        "for the pump also its input fluid_end.discharge_pressure or fluid_end.suction_pressure [Pa]",
    )
    ap.add_argument(
        "--pump",
        default=None,
        metavar="PRESET",
        help="the pump's parameter set: a preset (resources/presets/PRESET.ssv, or a path to an "
        ".ssv) instead of ssp/ClosedLoop/pump.ssv, e.g. the duplex pump unb600a; --set applies "
        "over it",
    )
    return ap


#: The inputs the drive train drives: a preset's values of them are not applied.
CONNECTED = ("crank.angle", "crank.speed", "crank.acceleration")


def overrides(items: list[str], fmu_dir: pathlib.Path) -> dict:
    """--set pump.mass.reciprocating=350 → {"pump": {"mass.reciprocating": 350.0}}, each value
    checked against the FMU's type and range."""
    from ..sweeps.study import model_parameters

    out = {"pump": {}, "drivetrain": {}}
    for item in items:
        key, eq, text = item.partition("=")
        comp, _, name = key.partition(".")
        if not eq or comp not in COMPONENTS or not name:
            raise UserError(
                f"--set {show(item)}: allowed: pump.PARAMETER=VALUE or drivetrain.PARAMETER=VALUE"
            )
        params, _, _ = model_parameters(str(fmu_dir / COMPONENTS[comp]), require_pump=False)
        var = params.get(name)
        if var is None:
            raise UserError(
                f"--set {show(item)}: {name!r} is not a parameter of the {comp} "
                f"({COMPONENTS[comp]}); see docs/closed-loop.md"
            )
        t = text.strip().lower()
        if var.type == "Boolean":
            if t not in ("true", "false", "1", "0"):
                raise UserError(f"--set {show(item)}: allowed: true or false")
            value = t in ("true", "1")
        else:
            try:
                value = int(t) if var.type in ("Integer", "Enumeration") else float(t)
            except ValueError:
                kind = "an integer" if var.type != "Real" else "a number"
                raise UserError(f"--set {show(item)}: allowed: {kind}") from None
            if (
                not math.isfinite(value)
                or (var.min is not None and value < var.min)
                or (var.max is not None and value > var.max)
            ):
                lo = "-inf" if var.min is None else f"{var.min:g}"
                hi = "inf" if var.max is None else f"{var.max:g}"
                raise UserError(f"--set {show(item)}: allowed: {lo} .. {hi} {var.unit}".rstrip())
        out[comp][name] = value
    return out


def main(argv=None, prog: str = PROG) -> int:
    """The command: its exit code, with every error as one line (cli_errors.run_cli)."""
    return run_cli(
        prog, lambda: _main(argv, prog), on_interrupt=lambda: "stopped; nothing was written"
    )


def require_libcosim() -> None:
    """libcosim is an optional importer (the extra `libcosim` of pyproject.toml): when it is not
    installed, or its native library does not load, say so, not "check the parameters"."""
    try:
        import libcosimpy.CosimExecution  # noqa: F401
    except ModuleNotFoundError as e:
        if e.name is None or e.name.split(".")[0] != "libcosimpy":
            raise
        raise UserError(
            "--importer libcosim (the default) needs libcosimpy, which is not installed: "
            "pip install 'reciprocating-drive[libcosim]', or use --importer fmpy"
        ) from None
    except (ImportError, OSError) as e:
        raise UserError(
            f"--importer libcosim: libcosimpy is installed but does not load ({one_line(e)}); "
            "use --importer fmpy"
        ) from None


def _main(argv, prog: str = PROG) -> int:
    a = parser(prog).parse_args(argv)
    h = positive_float("--step", a.step)
    t_end = positive_float("--time", a.time)
    needed = list(COMPONENTS.values())
    if a.importer == "model-exchange":
        needed += ["ReciprocatingDrive-fmi3.fmu", "DriveTrain-fmi3.fmu"]
    for fmu in needed:
        if not (a.fmu_dir / fmu).is_file():
            raise UserError(f"--fmu-dir {a.fmu_dir}: no {fmu}; build it with scripts/build-fmu.sh")
    if a.importer == "libcosim":
        require_libcosim()
    from ..closed_loop.system import (
        SSD,
        LoopFailed,
        build_ssp,
        loop_gain,
        mean_speed_last,
        plot_closed_loop,
        record_units,
        run_fmpy,
        run_libcosim,
        speed_fluctuation,
        start_values,
        write_series,
    )
    from ..presets import read_ssv

    extra = overrides(a.set, a.fmu_dir)
    if a.pump is None:
        base = read_ssv(SSD.parent / "pump.ssv")
    else:
        from ..presets import PRESET_DIR, available_presets, preset_values

        try:
            base = preset_values(a.pump)
        except KeyError:
            raise UserError(
                f"--pump {show(a.pump)}: no such preset; allowed: "
                f"{', '.join(available_presets(PRESET_DIR))} or a path to an .ssv file"
            ) from None
        except Exception as e:  # an .ssv that is no valid SSP parameter set
            raise UserError(f"--pump {show(a.pump)}: {one_line(e)}") from None
        base = {k: v for k, v in base.items() if k not in CONNECTED}
    pump = {**base, **extra["pump"]}
    custom = bool(a.set) or a.pump is not None
    drive = {**read_ssv(SSD.parent / "drivetrain.ssv"), **extra["drivetrain"]}
    d = {**start_values(a.fmu_dir / "DriveTrain.fmu"), **drive}
    omega = max(d["crank.speed_start"], d["motor.synchronous_speed"] / d["drive.gear_ratio"])
    h_max = 2 * math.pi / omega / MIN_STEPS_PER_REVOLUTION
    if h > h_max:
        raise UserError(
            f"--step {a.step}: a revolution takes {2 * math.pi / omega:.4g} s at "
            f"{omega:.4g} rad/s; allowed: <= {h_max:.4g} s ({MIN_STEPS_PER_REVOLUTION} steps per "
            "revolution, so that δ per revolution is resolved)"
        )
    n = round(t_end / h)
    if n < 1:
        raise UserError(f"--time {a.time}: shorter than one step (--step {a.step}); allowed: >= h")
    if n > MAX_STEPS:
        raise UserError(
            f"--time {a.time} / --step {a.step} = {n} steps; allowed: <= {MAX_STEPS:,} "
            "(every sample is kept in memory)"
        )

    # With the run's other results: the system that was simulated, as it was simulated.
    a.out_dir.mkdir(parents=True, exist_ok=True)
    ssp_path = a.out_dir / "ClosedLoop.ssp"
    ssp = build_ssp(
        ssp_path,
        pump=pump if custom else None,
        drive=drive if custom else None,
        fmu_dir=a.fmu_dir,
    )
    # The Model Exchange variant of the same system beside it (docs/closed-loop.md "Model
    # Exchange system"), for importers that integrate both FMUs in one ODE.
    ssp_me = build_ssp(
        ssp_path.with_name("ClosedLoopME.ssp"),
        pump=pump if custom else None,
        drive=drive if custom else None,
        fmu_dir=a.fmu_dir,
        model_exchange=True,
    )
    t0 = time.perf_counter()
    failure = None
    try:
        if a.importer == "model-exchange":
            from ..closed_loop.me_loop import run_model_exchange

            r = run_model_exchange(np.arange(1, n + 1) * h, pump, drive, a.fmu_dir)
        else:
            r = (run_libcosim if a.importer == "libcosim" else run_fmpy)(ssp, h, t_end)
    except LoopFailed as e:
        failure = (e.time, str(e))
    except Exception as e:  # fmpy raises a plain Exception when an FMU refuses a step
        failure = (None, f"{a.importer}: {e}")
    else:
        w = r["drivetrain.crank.speed"]
        bad = ~np.isfinite(w) | (w <= 0) | (w > 2 * omega)
        bad |= ~np.isfinite(r["pump.crank.torque"])
        if bad.any():
            k = int(np.argmax(bad))
            failure = (float(r["time"][k]), f"crank speed {w[k]:.4g} rad/s")
    wall = time.perf_counter() - t0
    if failure is not None:
        g = loop_gain(pump, drive, h, a.fmu_dir)
        at = f" at t = {failure[0]:.4g} s" if failure[0] is not None else ""
        cond = (
            f"ρ_eff = (m·TF²/J)·exp(−h/τ) = {g['rho']:.3g} (m·TF² = {g['m'] * g['tf'] ** 2:.4g} "
            f"kg·m², J = {g['J']:.4g} kg·m², τ = {g['tau']:.3g} s)"
        )
        if g["rho"] >= 1:
            raise RunFailed(
                f"the closed loop diverged{at} ({failure[1]}): {cond} >= 1 breaks the stability "
                'condition ρ_eff < 1 of docs/closed-loop.md "The algebraic loop"; give the drive '
                "more inertia or the motor a stiffer curve, or a smaller --step"
            )
        raise RunFailed(
            f"the closed loop failed{at} ({failure[1]}); {cond} < 1, so not the algebraic loop "
            "of docs/closed-loop.md: check the parameters"
        )
    dfl = speed_fluctuation(r["time"], r["drivetrain.crank.angle"], r["drivetrain.crank.speed"])
    w = r["drivetrain.crank.speed"]
    if a.importer == "model-exchange":
        # Not a fixed step: DOP853 chooses its own; the series are sampled every h.
        system, stepping = ssp_me, f"one ODE, DOP853 with variable steps, sampled every {h:g} s"
        title = f"model exchange, {ssp_me.name}: DOP853 variable step, sampled every {h * 1e3:g} ms"
    else:
        system, stepping = ssp, f"h = {h:g} s"
        title = f"{a.importer}, {ssp.name}, h = {h * 1e3:g} ms"
    print(f"{a.importer}: {system.name}, {t_end:g} s ({stepping}) in {wall:.2f} s wall")
    mean = mean_speed_last(r["time"], r["drivetrain.crank.angle"])
    if mean is not None:
        print(
            f"mean crank speed over the last {mean[1]} revolution(s): {mean[0]:.5g} rad/s "
            f"({mean[0] * 60 / (2 * math.pi):.4g} strokes/min)"
        )
    else:
        print(f"mean crank speed: no complete revolution in {t_end:g} s")
    if dfl:
        print("speed fluctuation δ per revolution: " + ", ".join(f"{x:.4%}" for x in dfl))
    else:
        print(f"speed fluctuation δ: no complete revolution in {t_end:g} s")
    csv_path, json_path = a.out_dir / "closed_loop.csv", a.out_dir / "closed_loop.json"
    write_series(csv_path, r, record_units(a.fmu_dir))
    summary = {
        "importer": a.importer,
        "system": system.name,
        "step": h,
        "variable_step": a.importer == "model-exchange",
        "time": t_end,
        "wall_time": wall,
        "revolutions": len(dfl),
        "mean_speed": None if mean is None else mean[0],
        "strokes_per_minute": None if mean is None else mean[0] * 60 / (2 * math.pi),
        "mean_over_revolutions": None if mean is None else mean[1],
        "speed_at_end": float(w[-1]),
        "speed_fluctuation": dfl,
        "parameters": {"pump": pump, "drivetrain": drive} if custom else None,
    }
    json_path.write_text(json.dumps(summary, indent=1) + "\n")
    png = a.out_dir / "closed_loop.png"
    plot_closed_loop(r, dfl, f"Pump and drive train in a closed loop ({title})", png)
    print(f"wrote {ssp}, {ssp_me.name}, {csv_path.name}, {json_path.name}, {png.name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
