"""The closed loop of docs/closed-loop.md solved exactly: the pump and the drive train as FMI 3.0
Model Exchange FMUs (target/fmu/<id>-fmi3.fmu) in ONE ordinary differential equation, integrated
by scipy (DOP853), instead of two co-simulation FMUs with a one-step delay between them.

The ODE's state is the drive train's (θ, ω) and the pump's two cage states (ϑ, ϑ̇ of an elastic
rod, docs/model.md §6; a rigid mechanism keeps them at 0 with derivative 0). At every evaluation
the algebraic loop between the pump's crank torque and the drive's crank acceleration is solved
exactly (docs/closed-loop.md "The algebraic loop"): the pump's torque is affine in the crank acceleration ε,
T(ε) = T₀ + k·ε (k = m·TF², the reciprocating mass seen at the crank), and the drive's
acceleration is affine in the load torque, ε(T) = a + b·T (b = −1/J). Each line is read from its
FMU with one evaluation and one exact directional derivative (fmi3GetDirectionalDerivative,
docs/fmi-interface.md "Directional derivatives"), and the loop's solution, one Newton step
ε ← ε − r/(1 − b·k) on r(ε) = ε − (a + b·T(ε)), is set into both FMUs (guide friction makes T(ε)
piecewise affine: further Newton steps end on the right piece). There is no stability condition:
ρ_eff ≥ 1, which makes the co-simulation diverge, is just another machine here.

Layer: workflows, the closed loop (docs/architecture.md).
"""

from __future__ import annotations

import contextlib
import pathlib
import tempfile

import numpy as np

from .system import FMU_DIR


class _Me:
    """One Model Exchange instance (FMI 3.0, or FMI 2.0 as in the Model Exchange SSP) through
    fmpy, with its parameters set and initialized, in continuous-time mode."""

    def __init__(self, path: pathlib.Path, values: dict, workdir: str, name: str):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Model
        from fmpy.fmi3 import FMU3Model

        self.md = read_model_description(str(path))
        if self.md.modelExchange is None:
            raise ValueError(f"{path}: no Model Exchange (an FMU of this project needed)")
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        types = {v.name: v.type for v in self.md.modelVariables}
        d = extract(str(path), unzipdir=str(pathlib.Path(workdir) / name))
        fmi2 = self.md.fmiVersion == "2.0"
        self.fmu = (FMU2Model if fmi2 else FMU3Model)(
            guid=self.md.guid,
            unzipDirectory=d,
            modelIdentifier=self.md.modelExchange.modelIdentifier,
            instanceName=name,
        )
        f = self.fmu
        # The two standards' names of the same calls.
        self._set = f.setReal if fmi2 else f.setFloat64
        self._get = f.getReal if fmi2 else f.getFloat64
        self.get_derivatives = f.getDerivatives if fmi2 else f.getContinuousStateDerivatives
        set_int = f.setInteger if fmi2 else f.setInt32
        if fmi2:
            # The project's own FMI 2.0 logger (fmu._Log), not fmpy's default: fmpy's native
            # proxy forwards every instance's messages to one process-wide callback, and once
            # the instance that registered it is freed, the next message (an error this FMU
            # reports) calls freed memory and the process dies.
            from ..fmu.instance import _Log

            self._log = _Log(echo=False)
            f.instantiate(callbacks=self._log.callbacks)
        else:
            f.instantiate()
        if fmi2:
            f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
        for k, v in values.items():
            if k not in self.vr:
                raise KeyError(f"{path.name}: no variable {k!r}")
            if types[k] in ("Float64", "Real"):
                self._set([self.vr[k]], [float(v)])
            elif types[k] in ("Int32", "Integer"):
                set_int([self.vr[k]], [int(v)])
            else:
                f.setBoolean([self.vr[k]], [bool(v)])
        f.exitInitializationMode()
        if fmi2:
            f.newDiscreteStates()
        else:
            f.updateDiscreteStates()
        f.enterContinuousTimeMode()
        self.nx = self.md.numberOfContinuousStates

    def set(self, names, values):
        self._set([self.vr[n] for n in names], [float(v) for v in values])

    def get(self, names):
        return self._get([self.vr[n] for n in names])

    def close(self):
        with contextlib.suppress(Exception):
            self.fmu.terminate()
        self.fmu.freeInstance()


def run_model_exchange(
    t_eval,
    pump: dict | None = None,
    drive: dict | None = None,
    fmu_dir: pathlib.Path = FMU_DIR,
    rtol: float = 1e-10,
    atol: float = 1e-10,
    fmus: tuple[pathlib.Path, pathlib.Path] | None = None,
) -> dict:
    """Integrates the closed loop over [0, t_eval[-1]] and returns time and the recorded series
    (the keys of `system.RECORD`: drivetrain.crank.speed, ..., pump.crank.torque) at `t_eval`.
    `pump` and `drive` are the two FMUs' parameter values (names as in their model descriptions).
    `fmus`: the pump's and the drive train's FMU (default: the FMI 3.0 ones in `fmu_dir`).
    Raises RuntimeError with scipy's message when the integration fails."""
    import ctypes

    from scipy.integrate import solve_ivp

    t_eval = np.asarray(t_eval, dtype=float)
    fmu_dir = pathlib.Path(fmu_dir)
    with tempfile.TemporaryDirectory() as d:
        pump_fmu, drive_fmu = fmus or (
            fmu_dir / "ReciprocatingDrive-fmi3.fmu",
            fmu_dir / "DriveTrain-fmi3.fmu",
        )
        p = _Me(pathlib.Path(pump_fmu), pump or {}, d, "pump")
        q = _Me(pathlib.Path(drive_fmu), drive or {}, d, "drivetrain")
        try:
            if p.nx != 2 or q.nx != 2:
                raise ValueError("expected the pump's two cage states and the drive train's θ, ω")
            x = (ctypes.c_double * 2)()
            dx = (ctypes.c_double * 2)()
            q.fmu.getContinuousStates(x, 2)
            y0 = [x[0], x[1]]
            p.fmu.getContinuousStates(x, 2)
            y0 += [x[0], x[1]]
            crank = ["crank.angle", "crank.speed", "crank.acceleration"]

            der_speed, load = q.vr["der(crank.speed)"], q.vr["load.torque"]
            torque_vr, acc_vr = p.vr["crank.torque"], p.vr["crank.acceleration"]
            last = [0.0]

            def solve(t, y):
                """Sets (θ, ω) and the loop's exact ε and T into both FMUs; returns ε."""
                for m in (p, q):
                    m.fmu.setTime(t)
                x[0], x[1] = y[2], y[3]
                p.fmu.setContinuousStates(x, 2)
                x[0], x[1] = y[0], y[1]
                q.fmu.setContinuousStates(x, 2)
                # The drive's line ε(T) = a + b·T: its value at T = 0 and its exact slope.
                q.set(["load.torque"], [0.0])
                q.get_derivatives(dx, 2)
                a = dx[1]
                b = q.fmu.getDirectionalDerivative([der_speed], [load], [1.0])[0]
                # Newton from the last solution: T(ε) and k = ∂T/∂ε exact on the affine piece
                # of T the iterate lies on, so one step solves it there; with guide friction a
                # further step moves to the right piece.
                eps = last[0]
                p.set(crank, [y[0], y[1], eps])
                for _ in range(50):
                    torque = p.get(["crank.torque"])[0]
                    r = eps - (a + b * torque)
                    # Solved to rounding (ε's own and that of the torque it passes through).
                    if abs(r) <= 1e-12 * (1.0 + abs(eps)):
                        break
                    k = p.fmu.getDirectionalDerivative([torque_vr], [acc_vr], [1.0])[0]
                    eps -= r / (1.0 - b * k)
                    p.set(["crank.acceleration"], [eps])
                else:
                    raise RuntimeError(f"Model Exchange loop: no ε solves the loop at t = {t}")
                last[0] = eps
                q.set(["load.torque"], [torque])
                return eps

            def rhs(t, y):
                eps = solve(t, y)
                # The cage's rates at the solved ε (the last value the loop set in the pump).
                p.get_derivatives(dx, 2)
                return [y[1], eps, dx[0], dx[1]]

            sol = solve_ivp(
                rhs,
                (0.0, float(t_eval[-1])),
                y0,
                method="DOP853",
                rtol=rtol,
                atol=atol,
                t_eval=t_eval,
            )
            if not sol.success:
                raise RuntimeError(f"Model Exchange loop: {sol.message}")
            from .system import RECORD

            out = {"time": sol.t, **{f"{c}.{v}": np.empty(len(sol.t)) for c, v in RECORD}}
            for j, t in enumerate(sol.t):
                solve(t, sol.y[:, j])
                for c, v in RECORD:
                    m = p if c == "pump" else q
                    out[f"{c}.{v}"][j] = m.get([v])[0]
            return out
        finally:
            p.close()
            q.close()


#: The connections the loop solved here has (system.py's docstring), as the SSD writes them:
#: (startElement, startConnector, endElement, endConnector).
CONNECTIONS = {
    ("pump", "crank.torque", "drivetrain", "load.torque"),
    ("drivetrain", "crank.angle", "pump", "crank.angle"),
    ("drivetrain", "crank.speed", "pump", "crank.speed"),
    ("drivetrain", "crank.acceleration", "pump", "crank.acceleration"),
}


def run_model_exchange_ssp(ssp: pathlib.Path, t_eval, rtol: float = 1e-10, atol: float = 1e-10):
    """`run_model_exchange` of the system in the Model Exchange SSP (target/fmu/ClosedLoopME.ssp):
    its two FMUs (FMI 2.0, both interfaces) with its parameter sets. Raises ValueError naming the
    file when the SSP is not this loop (other components or connections)."""
    import xml.etree.ElementTree as ET
    import zipfile

    from ..presets import read_ssv

    ns = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription"}
    with tempfile.TemporaryDirectory() as d:
        with zipfile.ZipFile(ssp) as z:
            z.extractall(d)
        root = ET.parse(pathlib.Path(d) / "SystemStructure.ssd").getroot()
        comps = {}
        for c in root.iterfind(".//ssd:Component", ns):
            binding = c.find(".//ssd:ParameterBinding", ns)
            values = (
                read_ssv(pathlib.Path(d) / binding.get("source")) if binding is not None else {}
            )
            comps[c.get("name")] = (pathlib.Path(d) / c.get("source"), values)
        conns = {
            (
                c.get("startElement"),
                c.get("startConnector"),
                c.get("endElement"),
                c.get("endConnector"),
            )
            for c in root.iterfind(".//ssd:Connection", ns)
        }
        if set(comps) != {"pump", "drivetrain"} or conns != CONNECTIONS:
            raise ValueError(
                f"{ssp}: not the closed loop of docs/closed-loop.md (components {sorted(comps)}, "
                f"{len(conns)} connections); allowed: pump and drivetrain connected as in "
                "ssp/ClosedLoop/SystemStructureME.ssd"
            )
        return run_model_exchange(
            t_eval,
            comps["pump"][1],
            comps["drivetrain"][1],
            rtol=rtol,
            atol=atol,
            fmus=(comps["pump"][0], comps["drivetrain"][0]),
        )
