"""Exact directional derivatives (docs/fmi-interface.md "Directional derivatives"):
fmi2GetDirectionalDerivative (co-simulation) and fmi3GetDirectionalDerivative (co-simulation and
Model Exchange) of both FMUs against independent references.

References, none of which shares code with the FMU's derivatives:
* the crank-slider without friction: tests/python/reference.py (the vector loop at 30 digits),
  differentiated by mpmath.diff at 30 digits, so its own error is ~1e-25 relative;
* everything else (guide friction, the beam units, the balancer, the load profiles, DriveTrain):
  an 8th-order central difference of the FMU's own f64 outputs, its sums evaluated in mpmath
  (30 digits) so that only the f64 outputs' rounding and the stencil's truncation remain. With
  step h the rounding contributes about 1e-16·|f|/h and the truncation about (h/ℓ)^8 (ℓ the
  length over which the output bends: ~1e-2 rad in θ where tanh(v/v_ε) switches, ~1 elsewhere).
  The steps below (h = 2e-4 in the scaled input) keep both below 1e-11 of the derivative's
  scale, far under the 1e-8 asked of the FMU; a stencil that straddles a kink of the piecewise-
  linear friction law (a support reaction through zero) shows as a disagreement between the
  difference at h and at h/2, and that point is skipped for that input (counted, and bounded).

Tolerance: |FMU − reference| ≤ 1e-8 · (the largest |∂y/∂u| of that pair over the sampled points),
the issue's "1e-8 relative of the derivative's scale", plus the difference's own rounding bound
(16 ulps of |y| over h/2) where a partial is small beside its output (a support reaction of a few
hundred newtons changing by 5e-4 N per rad/s²); a pair whose reference is 0 everywhere must be
exactly 0.
"""

from __future__ import annotations

import ctypes
import math
import pathlib
import random

import mpmath
import pytest
from reciprocating_drive.presets import preset_values
from reference import OUTPUTS as REFERENCE_OUTPUTS
from reference import Machine
from test_lowlevel import Log

INPUTS = [
    "crank.angle",
    "crank.speed",
    "crank.acceleration",
    "link.external_force",
    "fluid_end.discharge_pressure",
    "fluid_end.suction_pressure",
]
# Scales of the random pressures [Pa] and the differences' steps in them.
DISCHARGE, SUCTION = 3.0e7, 1.0e6
PRESSURE_STEPS = [2e-4 * DISCHARGE, 2e-4 * SUCTION]
# Outputs formed as a level times a chamber weight (1 ± tanh(v/v_ε))/2 (docs/model.md §4.1).
WEIGHTED = (".fluid_force", ".flow", ".hydraulic_power")
TOL = 1e-8
# 8th-order central difference: f'(x) ≈ Σ c_k (f(x + k h) − f(x − k h)) / h.
STENCIL = [
    mpmath.mpf(4) / 5,
    mpmath.mpf(-1) / 5,
    mpmath.mpf(4) / 105,
    mpmath.mpf(-1) / 280,
]

# Machines: every mechanism, friction on and off, the balancer, each load profile.
FRICTIONLESS = {"support_A.kind": 0, "support_B.kind": 0, "support_C.kind": 0}
MACHINES = {
    "crank-slider, guide friction (default machine)": {},
    "offset crank-slider, friction, cosine load": {
        "geometry.slider_offset": 0.06,
        "load.amplitude": 4.0e4,
        "load.phase": 0.4,
    },
    "crank-slider, no friction, balancer": {
        **FRICTIONLESS,
        "balancer.enabled": True,
        "balancer.tuning": 2,
        "balancer.design_speed": 6.0,
    },
    "crank-slider, friction, balancer, single-acting load": {
        "balancer.enabled": True,
        "balancer.tuning": 1,
        "balancer.design_speed": 6.0,
        "load.profile": 2,
        "load.mean": 5.0e4,
    },
    "unb600a (crank-slider, gland, double-acting load)": "unb600a-simplex",
    "sk8-3.5-4000 (beam unit class I, clamp friction)": "sk8-3.5-4000",
    # The pump of docs/model.md §4.1: the chambers' pressures, several cylinders.
    "duplex double-acting, pressures, guide friction": {
        "fluid_end.cylinders": 2,
        "cylinder_2.phase": math.pi / 2,
        "load.profile": 3,
    },
    "triplex single-acting, pressures, no friction, balancer": {
        **FRICTIONLESS,
        "fluid_end.cylinders": 3,
        "cylinder_1.acting": 1,
        "cylinder_2.acting": 1,
        "cylinder_3.acting": 1,
        "cylinder_2.phase": 2 * math.pi / 3,
        "cylinder_3.phase": 4 * math.pi / 3,
        "load.profile": 3,
        "balancer.enabled": True,
        "balancer.tuning": 1,
        "balancer.design_speed": 6.0,
    },
    "sk8-3.5-4000 without friction": ("sk8-3.5-4000", FRICTIONLESS),
    "sk8-3.5-4000 counter-clockwise": ("sk8-3.5-4000", {"rotation": -1}),
    # A Mark II-like class III unit (the geometry of beam_unit.rs's tests), clamp friction.
    "beam unit class III": (
        "sk8-3.5-4000",
        {
            "mechanism": 3,
            "geometry.beam_front_arm": 3.8,
            "geometry.beam_rear_arm": 2.4,
            "geometry.pivot_dx": 1.4,
            "geometry.pivot_dy": 3.2,
            "geometry.rod_length": 3.4,
            "geometry.crank_radius": 0.9,
        },
    ),
}


# Elastic connecting rods (docs/model.md §6), with the process force each can take far below its
# buckling load (kvo630: ~33 N; the thin rod: ~230 N): (machine, force scale of the random points).
THIN_ROD = {
    "rod.kind": 1,
    "rod.flex_length": 0.12,
    "rod.rigid_length": 0.03,
    "rod.wire_diameter": 2.0e-3,
    "rod.E": 2.1e11,
    "rod.poisson": 0.3,
}
# load.profile 3 on a 0.2 mm piston: the random pressures (up to DISCHARGE) give about 1 N, far
# below the elastic rods' buckling loads.
SMALL_PISTON = {
    "load.profile": 3,
    "cylinder_1.piston_diameter": 2e-4,
    "cylinder_1.rod_diameter": 5e-5,
}
ROD_MACHINES = {
    "kvo630 (helical spring, clamp friction)": ("kvo630", 5.0),
    "kvo630 without friction": (("kvo630", {"support_B.kind": 0}), 5.0),
    "kvo630, cage at rest, rigid part with mass": (
        ("kvo630", {"rod.initial_state": 0, "rod.rigid_mass": 2e-3, "rod.rigid_lever": 0.01}),
        5.0,
    ),
    "thin rod (clamp friction)": (("kvo630", THIN_ROD), 40.0),
    "kvo630 loaded by the pressures": (("kvo630", SMALL_PISTON), 5.0),
}


def machine_values(spec) -> dict:
    if isinstance(spec, str):
        return preset_values(spec)
    if isinstance(spec, tuple):
        return {**preset_values(spec[0]), **spec[1]}
    return dict(spec)


def sibling(fmu_path, name: str) -> str:
    p = pathlib.Path(fmu_path).parent / name
    assert p.is_file(), f"scripts/build-fmu.sh builds {p.name}"
    return str(p)


class Probe:
    """One instance of an FMU, co-simulation 2.0 ("cs2"), co-simulation 3.0 ("cs3"), Model
    Exchange 2.0 ("me2") or Model Exchange 3.0 ("me3"), initialized with `start` and ready to
    evaluate (Model Exchange: in continuous-time mode)."""

    def __init__(self, path: str, kind: str, start: dict, tmp_path, tag: str):
        from fmpy import extract, read_model_description

        self.kind = kind
        self.md = read_model_description(path)
        self.var = {v.name: v for v in self.md.modelVariables}
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        d = extract(path, unzipdir=str(tmp_path / f"{kind}-{tag}"))
        ident = (self.md.coSimulation or self.md.modelExchange).modelIdentifier
        self._messages: list[str] = []
        self.fmi2 = kind in ("cs2", "me2")
        if self.fmi2:
            from fmpy.fmi2 import FMU2Model, FMU2Slave

            self.f = (FMU2Slave if kind == "cs2" else FMU2Model)(
                guid=self.md.guid, unzipDirectory=d, modelIdentifier=ident, instanceName="p"
            )
            self.log = Log()
            self.f.instantiate(callbacks=self.log.callbacks, loggingOn=True)
            self.f.setupExperiment(startTime=0.0)
        else:
            from fmpy.fmi3 import FMU3Model, FMU3Slave

            cls = FMU3Slave if kind == "cs3" else FMU3Model
            self.f = cls(
                guid=self.md.guid, unzipDirectory=d, modelIdentifier=ident, instanceName="p"
            )
            self.f.instantiate(
                loggingOn=True,
                logMessage=lambda e, st, cat, msg: self._messages.append(msg.decode()),
            )
        self.f.enterInitializationMode()
        for k, v in start.items():
            self.set_any(k, v)
        self.f.exitInitializationMode()
        if kind == "me3":
            self.f.updateDiscreteStates()
            self.f.enterContinuousTimeMode()
        elif kind == "me2":
            self.f.newDiscreteStates()
            self.f.enterContinuousTimeMode()

    @property
    def messages(self) -> list[str]:
        return self.log.messages() if self.fmi2 else self._messages

    def clear(self):
        if self.fmi2:
            self.log.lines.clear()
        else:
            self._messages.clear()

    def set_any(self, name, value):
        t = self.var[name].type
        vr = [self.vr[name]]
        if t in ("Real", "Float64"):
            self.set([name], [float(value)])
        elif t in ("Integer", "Int32"):
            (self.f.setInteger if self.fmi2 else self.f.setInt32)(vr, [int(value)])
        else:
            self.f.setBoolean(vr, [bool(value)])

    def set(self, names, values):
        vrs = [self.vr[n] for n in names]
        (self.f.setReal if self.fmi2 else self.f.setFloat64)(vrs, list(values))

    def get(self, names):
        vrs = [self.vr[n] for n in names]
        return (self.f.getReal if self.fmi2 else self.f.getFloat64)(vrs)

    def dd(self, unknowns, knowns, seed):
        u = [self.vr[n] for n in unknowns]
        k = [self.vr[n] for n in knowns]
        return list(self.f.getDirectionalDerivative(u, k, list(seed)))

    def states(self, x):
        n = len(x)
        self.f.setContinuousStates((ctypes.c_double * n)(*x), n)

    def derivatives(self, n=2):
        dx = (ctypes.c_double * n)()
        if self.fmi2:
            self.f.getDerivatives(dx, n)
        else:
            self.f.getContinuousStateDerivatives(dx, n)
        return list(dx)

    def close(self):
        self.f.terminate()
        self.f.freeInstance()


def central_difference(f, x: float, h: float):
    """8th-order central difference of the vector function f at x with step h, summed in mpmath
    (the differences of f64 values are exact there)."""
    acc = None
    for k, c in enumerate(STENCIL, start=1):
        fp, fm = f(x + k * h), f(x - k * h)
        term = [c * (mpmath.mpf(a) - mpmath.mpf(b)) for a, b in zip(fp, fm)]
        acc = term if acc is None else [s + t for s, t in zip(acc, term)]
    return [s / h for s in acc]


def random_points(rng, nominal_speed: float, force_scale: float, n: int):
    pts = []
    for _ in range(n):
        w = nominal_speed * rng.uniform(0.3, 1.5) * rng.choice([1.0, 1.0, -1.0])
        pts.append(
            [
                rng.uniform(0.0, 2.0 * math.pi),
                w,
                rng.uniform(-3.0, 3.0) * abs(w),
                rng.uniform(-1.0, 1.0) * force_scale,
                rng.uniform(0.0, 1.0) * DISCHARGE,
                rng.uniform(0.0, 1.0) * SUCTION,
            ]
        )
    return pts


def pump_outputs(md) -> list[str]:
    return [v.name for v in md.modelVariables if v.causality == "output"]


def check_against_differences(probe: Probe, outputs, points, steps, knowns=tuple(range(6))):
    """The FMU's partials of `outputs` wrt each input at `points` against the central difference;
    returns (worst error / scale, number of (point, input) pairs skipped at a kink)."""
    fmu, ref, noise, level, half_step = {}, {}, {}, {}, {}
    skipped = 0
    for p, x0 in enumerate(points):
        for j in knowns:

            def f(x, j=j, x0=x0):
                x1 = list(x0)
                x1[j] = x
                probe.set(INPUTS, x1)
                return probe.get(outputs)

            h = steps[j]
            d1 = central_difference(f, x0[j], h)
            d2 = central_difference(f, x0[j], h / 2)
            probe.set(INPUTS, x0)
            at_x0 = probe.get(outputs)
            seed = [0.0] * len(INPUTS)
            seed[j] = 1.0
            got = probe.dd(outputs, INPUTS, seed)
            scale = max(abs(float(v)) for v in d1) or 1.0
            # A kink shows as d1 ≠ d2 beyond both differences' rounding (the bound below at h/2,
            # half of it at h): a large output with a small partial (an elastic rod's stress,
            # ~1e8 Pa) is not mistaken for one.
            if any(
                abs(float(a - b)) > 1e-10 * scale + 1.5 * 16 * 2.3e-16 * abs(y) / (h / 2)
                for a, b, y in zip(d1, d2, at_x0)
            ):
                skipped += 1
                continue
            for i, o in enumerate(outputs):
                fmu[(p, j, o)] = got[i]
                ref[(p, j, o)] = float(d2[i])
                # The difference's own rounding: each f64 output is off by a few ulps, and the
                # stencil's weights sum to < 2.1 in absolute value, divided by h/2.
                noise[(p, j, o)] = 16 * 2.3e-16 * abs(at_x0[i]) / (h / 2)
                level[o] = max(level.get(o, 0.0), abs(at_x0[i]))
                half_step[(p, j, o)] = h / 2
    # A fluid force, a flow and the hydraulic power are a level times a chamber weight
    # (1 ± tanh(v/v_ε))/2 (docs/model.md §4, §4.1): where the weight is nearly 0 their rounding
    # is that of the level, not of their value.
    for (p, j, o), hh in half_step.items():
        if o.endswith(WEIGHTED):
            noise[(p, j, o)] = max(noise[(p, j, o)], 16 * 2.3e-16 * level[o] / hh)
    worst = 0.0
    for (p, j, o), r in ref.items():
        scale = max(abs(v) for (q, k, u), v in ref.items() if k == j and u == o)
        err = abs(fmu[(p, j, o)] - r)
        if scale == 0.0:
            # (A weighted output's partial may be below what its f64 difference resolves.)
            bound = noise[(p, j, o)] if o.endswith(WEIGHTED) else 0.0
            assert abs(fmu[(p, j, o)]) <= bound, (o, INPUTS[j], fmu[(p, j, o)])
            continue
        rel = max(err - noise[(p, j, o)], 0.0) / scale
        assert rel <= TOL, (
            f"∂{o}/∂{INPUTS[j]} at {points[p]}: FMU {fmu[(p, j, o)]!r}, reference {r!r}, "
            f"error {rel:.2e} of the scale {scale:.3e}"
        )
        worst = max(worst, rel)
    return worst, skipped


@pytest.mark.parametrize("kind", ["cs2", "cs3", "me2", "me3"])
@pytest.mark.parametrize("machine", list(MACHINES))
def test_partials_match_high_order_differences(fmu_path, tmp_path, machine, kind):
    """Every output wrt every input, every mechanism, friction on and off, FMI 2.0 CS and ME,
    FMI 3.0 CS and ME, at 6 random points, against the 8th-order central difference (module
    doc)."""
    values = machine_values(MACHINES[machine])
    path = fmu_path if kind in ("cs2", "me2") else sibling(fmu_path, "ReciprocatingDrive-fmi3.fmu")
    probe = Probe(path, kind, values, tmp_path, "m")
    try:
        nominal = float(values.get("crank.speed", probe.var["crank.speed"].start))
        outputs = pump_outputs(probe.md)
        rng = random.Random(hash(machine) % 1000 + 27)
        points = random_points(rng, nominal, 2.0e4, 6)
        steps = [2e-4, 2e-4 * abs(nominal), 2e-4 * (1 + nominal**2), 2e-4 * 2.0e4, *PRESSURE_STEPS]
        worst, skipped = check_against_differences(probe, outputs, points, steps)
        # Kinks are rare: at most a quarter of the (point, input) pairs sit next to one.
        assert skipped <= len(points) * len(INPUTS) // 4, skipped
        assert worst <= TOL
    finally:
        probe.close()


@pytest.mark.parametrize("kind", ["cs2", "cs3", "me2", "me3"])
@pytest.mark.parametrize("machine", list(ROD_MACHINES))
def test_elastic_rod_partials_match_high_order_differences(fmu_path, tmp_path, machine, kind):
    """The elastic rod (the cage state held at its value after initialization; in Model Exchange
    the states the solver would set, here the initial ones):
    every output wrt every input at 6 random points against the 8th-order central difference of
    the FMU's own outputs (module doc); the outputs that are the cage state itself (rod.angle,
    rod.angular_velocity) have partials exactly 0."""
    spec, force_scale = ROD_MACHINES[machine]
    values = machine_values(spec)
    path = fmu_path if kind in ("cs2", "me2") else sibling(fmu_path, "ReciprocatingDrive-fmi3.fmu")
    probe = Probe(path, kind, values, tmp_path, "rod")
    try:
        nominal = float(values.get("crank.speed", probe.var["crank.speed"].start))
        outputs = pump_outputs(probe.md)
        rng = random.Random(hash(machine) % 1000 + 31)
        points = random_points(rng, nominal, force_scale, 6)
        steps = [
            2e-4,
            2e-4 * abs(nominal),
            2e-4 * (1 + nominal**2),
            2e-4 * force_scale,
            *PRESSURE_STEPS,
        ]
        worst, skipped = check_against_differences(probe, outputs, points, steps)
        assert skipped <= len(points) * len(INPUTS) // 4, skipped
        assert worst <= TOL
        for x0 in points:
            probe.set(INPUTS, x0)
            for j in range(len(INPUTS)):
                seed = [0.0] * len(INPUTS)
                seed[j] = 1.0
                assert probe.dd(["rod.angle", "rod.angular_velocity"], INPUTS, seed) == [0.0, 0.0]
    finally:
        probe.close()


def test_elastic_rod_with_a_frame_fixed_support(fmu_path, tmp_path):
    """kvo630 with a frame-fixed pin A (the link slides through it: its clamp reactions come from a
    solve at each position, with no exact rate in s): a seed on crank.angle is refused in one line
    naming it; the partials wrt the three other inputs match the central difference."""
    values = {
        **preset_values("kvo630"),
        "support_A.kind": 1,
        "support_A.attached": 1,
        "support_A.z": 0.009,
        "support_A.friction": 0.1,
    }
    probe = Probe(fmu_path, "cs2", values, tmp_path, "gland")
    try:
        probe.set(INPUTS, [1.0, 150.0, 0.0, 0.0, 0.0, 0.0])
        probe.f.dll.fmi2GetDirectionalDerivative.restype = ctypes.c_int
        vr = probe.vr
        probe.clear()
        st, _ = call_dd(probe, [vr["crank.torque"]], [vr["crank.angle"]], [1.0])
        lines = [m for m in probe.messages if "fmi2GetDirectionalDerivative" in m]
        assert st == 3 and len(lines) == 1 and "crank.angle" in lines[0], lines
        nominal = float(values["crank.speed"])
        points = random_points(random.Random(5), nominal, 5.0, 4)
        steps = [2e-4, 2e-4 * nominal, 2e-4 * (1 + nominal**2), 2e-4 * 5.0, *PRESSURE_STEPS]
        worst, skipped = check_against_differences(
            probe, pump_outputs(probe.md), points, steps, knowns=(1, 2, 3, 4, 5)
        )
        assert skipped <= len(points) * 3 // 4, skipped
        assert worst <= TOL
    finally:
        probe.close()


@pytest.mark.parametrize(
    "machine",
    [
        Machine(),
        Machine(e=0.08, m=420.0, angle_offset=0.3, load_mean=-2.0e4),
        Machine(r=0.15, l=0.7, e=-0.05, load_mean=3.0e4, load_amplitude=1.5e4, load_phase=1.1),
    ],
)
def test_crank_slider_partials_match_the_mpmath_reference(fmu_path, tmp_path, machine):
    """The crank-slider without friction: the FMU's partials of the reference's outputs wrt the
    four inputs equal mpmath.diff of the independent 30-digit vector-loop reference, to 1e-10 of
    each partial's scale (the f64 evaluation's rounding is ~1e-15 of it)."""
    probe = Probe(fmu_path, "cs2", machine.start_values(), tmp_path, "ref")
    try:
        rng = random.Random(11)
        points = random_points(rng, 6.0, 2.0e4, 5)
        got_all, ref_all = [], []
        for x0 in points:
            probe.set(INPUTS, x0)
            for j in range(4):
                seed = [0.0] * len(INPUTS)
                seed[j] = 1.0
                got = probe.dd(list(REFERENCE_OUTPUTS), INPUTS, seed)

                def g(x, o, j=j, x0=x0):
                    args = [mpmath.mpf(v) for v in x0[:4]]
                    args[j] = x
                    return machine.outputs_mp(*args)[o]

                with mpmath.workdps(30):
                    ref = [
                        mpmath.diff(lambda x, o=o: g(x, o), mpmath.mpf(x0[j]))
                        for o in REFERENCE_OUTPUTS
                    ]
                got_all.append(got)
                ref_all.append([float(r) for r in ref])
        for i, o in enumerate(REFERENCE_OUTPUTS):
            for j in range(4):
                pairs = [
                    (g[i], r[i]) for k, (g, r) in enumerate(zip(got_all, ref_all)) if k % 4 == j
                ]
                scale = max(abs(r) for _, r in pairs)
                for gv, rv in pairs:
                    if scale == 0.0:
                        assert gv == 0.0, (o, INPUTS[j], gv)
                    else:
                        assert abs(gv - rv) <= 1e-10 * scale, (o, INPUTS[j], gv, rv, scale)
    finally:
        probe.close()


def test_three_interfaces_give_the_same_derivatives(fmu_path, tmp_path):
    """FMI 2.0 CS, FMI 3.0 CS and FMI 3.0 ME share the model's derivative code: equal to the bit,
    including a seed along several inputs at once (J·seed, linear in the seed)."""
    values = machine_values(MACHINES["unb600a (crank-slider, gland, double-acting load)"])
    fmi3 = sibling(fmu_path, "ReciprocatingDrive-fmi3.fmu")
    probes = [
        Probe(fmu_path, "cs2", values, tmp_path, "a"),
        Probe(fmi3, "cs3", values, tmp_path, "b"),
        Probe(fmi3, "me3", values, tmp_path, "c"),
    ]
    try:
        outputs = pump_outputs(probes[0].md)
        x0 = [1.3, 5.5, -2.0, 3.0e4, 2.0e7, 3.0e5]
        seed = [0.3, -1.2, 2.5, 1.0e3, 1.0e6, -2.0e4]
        results = []
        for pr in probes:
            pr.set(INPUTS, x0)
            results.append(pr.dd(outputs, INPUTS, seed))
        assert results[0] == results[1] == results[2]
        singles = []
        for j in range(len(INPUTS)):
            e = [0.0] * len(INPUTS)
            e[j] = 1.0
            singles.append(probes[0].dd(outputs, INPUTS, e))
        for i in range(len(outputs)):
            combo = sum(seed[j] * singles[j][i] for j in range(len(INPUTS)))
            scale = sum(abs(seed[j] * singles[j][i]) for j in range(len(INPUTS)))
            assert abs(results[0][i] - combo) <= 1e-14 * scale + 1e-300, outputs[i]
    finally:
        for pr in probes:
            pr.close()


def test_drive_train_partials(fmu_path, tmp_path):
    """DriveTrain: the outputs wrt load.torque in co-simulation (the state held), and in Model
    Exchange the outputs and the state derivatives wrt load.torque and both states, against the
    8th-order central difference; der(crank.angle) = crank.speed exactly."""
    cs = Probe(sibling(fmu_path, "DriveTrain.fmu"), "cs2", {}, tmp_path, "dcs")
    me = Probe(sibling(fmu_path, "DriveTrain-fmi3.fmu"), "me3", {}, tmp_path, "dme")
    try:
        outputs = [v.name for v in cs.md.modelVariables if v.causality == "output"]
        for load in [0.0, 350.0, -800.0, 2500.0]:
            cs.set(["load.torque"], [load])
            got = cs.dd(outputs, ["load.torque"], [1.0])

            def f(x):
                cs.set(["load.torque"], [x])
                return cs.get(outputs)

            ref = central_difference(f, load, 1.0)
            cs.set(["load.torque"], [load])
            for o, g, r in zip(outputs, got, ref):
                assert abs(g - float(r)) <= TOL * max(abs(float(v)) for v in ref), (o, g, r)
        unknowns = outputs + ["der(crank.angle)", "der(crank.speed)"]
        rng = random.Random(5)
        for _ in range(5):
            x0 = [rng.uniform(-3.0, 3.0), rng.uniform(5.0, 16.0), rng.uniform(-500.0, 3000.0)]
            for j, known in enumerate(["crank.angle", "crank.speed", "load.torque"]):

                def f(x, j=j, x0=x0):
                    x1 = list(x0)
                    x1[j] = x
                    me.states(x1[:2])
                    me.set(["load.torque"], [x1[2]])
                    return me.get(outputs) + me.derivatives()

                h = [1e-3, 1e-3, 1.0][j]
                ref = central_difference(f, x0[j], h)
                me.states(x0[:2])
                me.set(["load.torque"], [x0[2]])
                got = me.dd(unknowns, [known], [1.0])
                scale = max(abs(float(v)) for v in ref)
                for o, g, r in zip(unknowns, got, ref):
                    assert abs(g - float(r)) <= TOL * scale, (o, known, g, r)
                if known == "crank.speed":
                    assert got[unknowns.index("der(crank.angle)")] == 1.0
    finally:
        cs.close()
        me.close()


def dependencies_2(md) -> dict:
    """Output name → the names of the inputs the 2.0 ModelStructure lists."""
    out = {}
    for u in md.outputs:
        out[u.variable.name] = {d.name for d in (u.dependencies or [])}
    return out


@pytest.mark.parametrize("machine", list(MACHINES) + list(ROD_MACHINES))
def test_model_structure_matches_the_derivatives(fmu_path, tmp_path, machine):
    """Every partial the model description says is absent is exactly 0 at random points, and every
    listed one is non-zero at some point (the ModelStructure is consistent with the derivative
    code), for every mechanism and the elastic rods (whose rod.angle and rod.angular_velocity
    are the held cage state: listed for the rigid rod's angle, 0 here)."""
    elastic = machine in ROD_MACHINES
    spec, force_scale = ROD_MACHINES[machine] if elastic else (MACHINES[machine], 2.0e4)
    values = machine_values(spec)
    probe = Probe(fmu_path, "cs2", values, tmp_path, "ms")
    try:
        deps = dependencies_2(probe.md)
        outputs = list(deps)
        nominal = float(values.get("crank.speed", probe.var["crank.speed"].start))
        seen_nonzero = {(o, i): False for o in outputs for i in INPUTS}
        for x0 in random_points(random.Random(3), nominal, force_scale, 8):
            probe.set(INPUTS, x0)
            for j, name in enumerate(INPUTS):
                seed = [0.0] * len(INPUTS)
                seed[j] = 1.0
                for o, v in zip(outputs, probe.dd(outputs, INPUTS, seed)):
                    if name not in deps[o]:
                        assert v == 0.0, f"∂{o}/∂{name} = {v!r}, but the ModelStructure omits it"
                    elif v != 0.0:
                        seen_nonzero[(o, name)] = True
        # Listed dependencies that are identically 0 for this machine (e.g. the friction outputs
        # without friction) are allowed; but each output must depend on something it lists.
        for o in outputs:
            if deps[o]:
                held = elastic and o in ("rod.angle", "rod.angular_velocity")
                # (Cylinders beyond fluid_end.cylinders are 0, and a friction or fluid force may be.)
                may_vanish = (
                    o.startswith(
                        (
                            "guide.",
                            "support_",
                            "link.friction",
                            "rod.stress",
                            "rod.axial",
                            "balancer.",
                        )
                    )
                    or o.startswith(("cylinder_2.", "cylinder_3."))
                    or o.endswith((".friction", ".fluid_force"))
                )
                # (The cage states listed are not seeded here: co-simulation holds them.)
                seen = any(seen_nonzero.get((o, i), False) for i in deps[o])
                assert held or may_vanish or seen, o
    finally:
        probe.close()


def call_dd(probe: Probe, unknowns, knowns, seed):
    """fmi2GetDirectionalDerivative through ctypes (raw value references): (status, values)."""
    nu, nk = len(unknowns), len(knowns)
    out = (ctypes.c_double * max(nu, 1))()
    st = probe.f.dll.fmi2GetDirectionalDerivative(
        probe.f.component,
        (ctypes.c_uint32 * max(nu, 1))(*unknowns),
        ctypes.c_size_t(nu),
        (ctypes.c_uint32 * max(nk, 1))(*knowns),
        ctypes.c_size_t(nk),
        (ctypes.c_double * max(nk, 1))(*seed),
        out,
    )
    return st, list(out)[:nu]


def test_bad_arguments_are_refused_in_one_line(fmu_path, tmp_path):
    """Unknown value references, a known that is not an input, an unknown that is not an output,
    a non-finite seed, NULL arrays: fmi2Error with one line naming the reference."""
    probe = Probe(fmu_path, "cs2", {}, tmp_path, "bad")
    vr = probe.vr
    torque, acc = vr["crank.torque"], vr["crank.acceleration"]
    try:
        probe.f.dll.fmi2GetDirectionalDerivative.restype = ctypes.c_int
        cases = [
            (
                [torque],
                [vr["crank.torque"]],
                [1.0],
                f'value reference {torque} ("crank.torque") is not an input',
            ),
            ([torque], [vr["mass.reciprocating"]], [1.0], '("mass.reciprocating") is not an input'),
            ([torque], [99999], [1.0], "value reference 99999 is not an input"),
            ([vr["mass.reciprocating"]], [acc], [1.0], "is not an output"),
            ([99999], [acc], [1.0], "unknown[0] = value reference 99999 is not an output"),
            ([torque], [acc], [math.nan], "seed[0] = NaN"),
        ]
        for unknowns, knowns, seed, text in cases:
            probe.clear()
            st, _ = call_dd(probe, unknowns, knowns, seed)
            assert st == 3, (text, st)
            lines = [m for m in probe.messages if "fmi2GetDirectionalDerivative" in m]
            assert len(lines) == 1 and "\n" not in lines[0] and text in lines[0], (text, lines)
        probe.clear()
        st = probe.f.dll.fmi2GetDirectionalDerivative(
            probe.f.component, None, ctypes.c_size_t(1), None, ctypes.c_size_t(0), None, None
        )
        assert st == 3 and any("vUnknown_ref is NULL" in m for m in probe.messages)
        # The call still works after the refusals (off the dead centre, where TF = 0).
        probe.set(["crank.angle"], [1.0])
        st, v = call_dd(probe, [torque], [acc], [1.0])
        assert st == 0 and v[0] != 0.0
    finally:
        probe.close()


@pytest.mark.parametrize("kind", ["me2", "me3"])
def test_drive_train_model_structure_matches_the_derivatives(fmu_path, tmp_path, kind):
    """DriveTrain in Model Exchange, FMI 2.0 and 3.0: each output and state derivative lists
    exactly the knowns (load.torque and the states) whose partial is non-zero: the omitted ones
    are exactly 0 and the listed ones non-zero at random states."""
    name = "DriveTrain.fmu" if kind == "me2" else "DriveTrain-fmi3.fmu"
    me = Probe(sibling(fmu_path, name), kind, {}, tmp_path, "dms")
    try:
        deps = {o.variable.name: {d.name for d in o.dependencies} for o in me.md.outputs}
        for d in me.md.derivatives:
            deps[d.variable.name] = {x.name for x in d.dependencies}
        knowns = ["load.torque", "crank.angle", "crank.speed"]
        assert len(deps) == 9  # 7 outputs, 2 state derivatives
        rng = random.Random(9)
        for _ in range(5):
            me.states([rng.uniform(-3.0, 3.0), rng.uniform(5.0, 16.0)])
            me.set(["load.torque"], [rng.uniform(-500.0, 3000.0)])
            for k in knowns:
                for u, v in zip(deps, me.dd(list(deps), [k], [1.0])):
                    assert (v != 0.0) == (k in deps[u]), (u, k, v, sorted(deps[u]))
    finally:
        me.close()


def test_fmi3_argument_counts_and_mode_are_checked(fmu_path, tmp_path):
    """fmi3GetDirectionalDerivative: nSeed ≠ nKnowns and nSensitivity ≠ nUnknowns are refused in
    one line; so is a call in initialization mode (the machine is built at its end); a valid call
    afterwards works."""
    from fmpy import extract, read_model_description
    from fmpy.fmi3 import FMU3Slave

    path = sibling(fmu_path, "ReciprocatingDrive-fmi3.fmu")
    md = read_model_description(path)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    d = extract(path, unzipdir=str(tmp_path / "args"))
    messages = []
    s = FMU3Slave(
        guid=md.guid, unzipDirectory=d, modelIdentifier="ReciprocatingDrive", instanceName="a"
    )
    s.instantiate(loggingOn=True, logMessage=lambda e, st, c, m: messages.append(m.decode()))
    dll, c = s.dll, s.component
    u = (ctypes.c_uint32 * 1)(vr["crank.torque"])
    k = (ctypes.c_uint32 * 1)(vr["crank.acceleration"])
    seed = (ctypes.c_double * 2)(1.0, 0.0)
    out = (ctypes.c_double * 2)()

    def call(nu, nk, ns, nsens):
        n = ctypes.c_size_t
        return dll.fmi3GetDirectionalDerivative(c, u, n(nu), k, n(nk), seed, n(ns), out, n(nsens))

    try:
        s.enterInitializationMode()
        assert call(1, 1, 1, 1) == 3
        assert any("only after the end of initialization" in m for m in messages), messages
        s.exitInitializationMode()
        s.setFloat64([vr["crank.angle"]], [1.0])
        messages.clear()
        assert call(1, 1, 2, 1) == 3
        assert call(1, 1, 1, 2) == 3
        lines = [m for m in messages if "fmi3GetDirectionalDerivative" in m]
        assert len(lines) == 2 and all("must equal" in m and "\n" not in m for m in lines), lines
        assert call(1, 1, 1, 1) == 0 and out[0] != 0.0
    finally:
        s.terminate()
        s.freeInstance()


def test_layout_without_closed_form_reactions(fmu_path, tmp_path):
    """Two supports fixed in the frame (A and C) with the guide B on the link: the reactions come
    from a linear solve at each stroke position, so the partials with respect to crank.speed,
    crank.acceleration and link.external_force (which do not move the link) are exact and match
    the central difference, while one with respect to crank.angle is refused in one line."""
    values = {"support_A.kind": 1, "support_A.attached": 1, "support_A.z": 0.9}
    probe = Probe(fmu_path, "cs2", values, tmp_path, "lin")
    try:
        outputs = pump_outputs(probe.md)
        points = random_points(random.Random(21), 6.0, 2.0e4, 6)
        steps = [2e-4, 2e-4 * 6.0, 2e-4 * 37.0, 2e-4 * 2.0e4, *PRESSURE_STEPS]
        worst, skipped = check_against_differences(probe, outputs, points, steps, (1, 2, 3, 4, 5))
        assert worst <= TOL and skipped <= len(points) * 3 // 4
        probe.clear()
        probe.set(INPUTS, points[0])
        st, _ = call_dd(probe, [probe.vr["crank.torque"]], [probe.vr["crank.angle"]], [1.0])
        assert st == 3
        lines = [m for m in probe.messages if "fmi2GetDirectionalDerivative" in m]
        assert len(lines) == 1 and "no exact rate with respect to crank.angle" in lines[0], lines
    finally:
        probe.close()


CAGE_STATES = ["rod.cage_angle", "rod.cage_rate"]
CAGE_DERIVATIVES = ["der(rod.cage_angle)", "der(rod.cage_rate)"]


@pytest.mark.parametrize("kind", ["me2", "me3"])
@pytest.mark.parametrize("machine", ["default", "sk8-3.5-4000", "unb600a"])
def test_rigid_pump_state_partials_are_exactly_zero(fmu_path, tmp_path, machine, kind):
    """A rigid mechanism has no cage: every output and both cage-state derivatives have partials
    exactly 0 with respect to rod.cage_angle and rod.cage_rate, the derivatives (identically 0)
    exactly 0 with respect to every input, and the outputs' partials with respect to the inputs
    are bit for bit those of co-simulation (the same states held), at random points."""
    values = machine_values(machine)
    path = fmu_path if kind == "me2" else sibling(fmu_path, "ReciprocatingDrive-fmi3.fmu")
    me = Probe(path, kind, values, tmp_path, "rz")
    cs = Probe(fmu_path, "cs2", values, tmp_path, "rzc")
    try:
        outputs = pump_outputs(me.md)
        nominal = float(values.get("crank.speed", me.var["crank.speed"].start))
        for x0 in random_points(random.Random(11), nominal, 2.0e4, 4):
            me.set(INPUTS, x0)
            cs.set(INPUTS, x0)
            for k in CAGE_STATES:
                got = me.dd(outputs + CAGE_DERIVATIVES, [k], [1.0])
                assert all(v == 0.0 for v in got), (k, got)
            for k in INPUTS:
                got = me.dd(outputs + CAGE_DERIVATIVES, [k], [1.0])
                assert got[-2:] == [0.0, 0.0], (k, got[-2:])
                assert got[:-2] == cs.dd(outputs, [k], [1.0]), k
    finally:
        me.close()
        cs.close()


@pytest.mark.parametrize("kind", ["me2", "me3"])
@pytest.mark.parametrize("machine", ["kvo630", "thin rod"])
def test_elastic_rod_state_partials_match_high_order_differences(fmu_path, tmp_path, machine, kind):
    """An elastic rod in Model Exchange: every output and both cage-state derivatives
    (der(rod.cage_angle) = ϑ̇, der(rod.cage_rate) = ϑ̈) with respect to rod.cage_angle,
    rod.cage_rate (set by fmi2/fmi3SetContinuousStates) and the four inputs, at 5 random inputs
    and states, against the 8th-order central difference of the FMU's own outputs and
    derivatives (module doc), to 1e-8 of each partial's scale; a (point, known) pair whose
    stencil straddles a kink of the friction law (the difference at h and at h/2 disagree) is
    skipped, at most a quarter of them."""
    spec, force_scale = ROD_MACHINES[
        "thin rod (clamp friction)"
        if machine == "thin rod"
        else "kvo630 (helical spring, clamp friction)"
    ]
    values = machine_values(spec)
    path = fmu_path if kind == "me2" else sibling(fmu_path, "ReciprocatingDrive-fmi3.fmu")
    me = Probe(path, kind, values, tmp_path, "rs")
    try:
        unknowns = pump_outputs(me.md) + CAGE_DERIVATIVES
        knowns = INPUTS + CAGE_STATES
        nominal = float(values.get("crank.speed", me.var["crank.speed"].start))
        rng = random.Random(41 if machine == "thin rod" else 43)
        # The cage angle stays within the linear theory's range (a few mrad), its rate within
        # what the cage reaches in a run (docs/model.md §6).
        points = [
            x + [rng.uniform(-2e-3, 2e-3), rng.uniform(-0.05, 0.05)]
            for x in random_points(rng, nominal, force_scale, 5)
        ]
        steps = [
            2e-4,
            2e-4 * abs(nominal),
            2e-4 * (1 + nominal**2),
            2e-4 * force_scale,
            *PRESSURE_STEPS,
        ]
        # ϑ enters linearly at fixed P (the clamp loads, the cage moment) and through P only by
        # the friction; ϑ̇ enters ϑ̈ linearly (damping) and rod.angular_velocity as itself.
        steps += [2e-6, 1e-4]

        def at(x):
            me.set(INPUTS, x[:6])
            me.states(x[6:])
            return me.get(unknowns[:-2]) + me.derivatives()

        fmu, ref, noise = {}, {}, {}
        skipped = 0
        for p, x0 in enumerate(points):
            for j, k in enumerate(knowns):

                def f(v, j=j, x0=x0):
                    x1 = list(x0)
                    x1[j] = v
                    return at(x1)

                d1 = central_difference(f, x0[j], steps[j])
                d2 = central_difference(f, x0[j], steps[j] / 2)
                y0 = at(x0)
                got = me.dd(unknowns, [k], [1.0])
                h = steps[j] / 2
                scale = max(abs(float(v)) for v in d1) or 1.0
                if any(
                    abs(float(a - b)) > 1e-10 * scale + 1.5 * 16 * 2.3e-16 * abs(y) / h
                    for a, b, y in zip(d1, d2, y0)
                ):
                    skipped += 1
                    continue
                for i, o in enumerate(unknowns):
                    fmu[(p, k, o)] = got[i]
                    ref[(p, k, o)] = float(d2[i])
                    noise[(p, k, o)] = 16 * 2.3e-16 * abs(y0[i]) / h
        assert skipped <= len(points) * len(knowns) // 4, skipped
        # Each partial against its own scale over the points (module doc).
        for (p, k, o), r in ref.items():
            scale = max(abs(v) for (q, kk, u), v in ref.items() if kk == k and u == o)
            if scale == 0.0:
                assert fmu[(p, k, o)] == 0.0, (o, k, fmu[(p, k, o)])
                continue
            rel = max(abs(fmu[(p, k, o)] - r) - noise[(p, k, o)], 0.0) / scale
            assert rel <= TOL, (
                f"∂{o}/∂{k} at {points[p]}: FMU {fmu[(p, k, o)]!r}, reference {r!r}, "
                f"error {rel:.2e} of the scale {scale:.3e}"
            )
        # The trivial ones exactly: der(ϑ) = ϑ̇, rod.angle = ϑ, rod.angular_velocity = ϑ̇.
        for x0 in points:
            at(x0)
            pairs = [
                ("der(rod.cage_angle)", "rod.cage_rate", 1.0),
                ("der(rod.cage_angle)", "rod.cage_angle", 0.0),
                ("rod.angle", "rod.cage_angle", 1.0),
                ("rod.angle", "rod.cage_rate", 0.0),
                ("rod.angular_velocity", "rod.cage_rate", 1.0),
                ("rod.angular_velocity", "rod.cage_angle", 0.0),
            ]
            for o, k, want in pairs:
                assert me.dd([o], [k], [1.0]) == [want], (o, k)
            for k in INPUTS:
                assert me.dd(["der(rod.cage_angle)"], [k], [1.0]) == [0.0], k
    finally:
        me.close()


def test_drive_train_model_exchange_2_and_3_are_bit_identical(fmu_path, tmp_path):
    """DriveTrain in Model Exchange: the partials of every output and state derivative with
    respect to load.torque and both states agree bit for bit between FMI 2.0 and FMI 3.0 (one
    tangent, two glues) at random states, and match the 8th-order difference (2.0's own)."""
    me2 = Probe(sibling(fmu_path, "DriveTrain.fmu"), "me2", {}, tmp_path, "d2")
    me3 = Probe(sibling(fmu_path, "DriveTrain-fmi3.fmu"), "me3", {}, tmp_path, "d3")
    try:
        outputs = [v.name for v in me2.md.modelVariables if v.causality == "output"]
        unknowns = outputs + ["der(crank.angle)", "der(crank.speed)"]
        knowns = ["crank.angle", "crank.speed", "load.torque"]
        rng = random.Random(17)
        for _ in range(5):
            x0 = [rng.uniform(-3.0, 3.0), rng.uniform(5.0, 16.0), rng.uniform(-500.0, 3000.0)]
            for p in (me2, me3):
                p.states(x0[:2])
                p.set(["load.torque"], [x0[2]])
            for j, k in enumerate(knowns):
                got2 = me2.dd(unknowns, [k], [1.0])
                assert got2 == me3.dd(unknowns, [k], [1.0]), k

                def f(x, j=j, x0=x0):
                    x1 = list(x0)
                    x1[j] = x
                    me2.states(x1[:2])
                    me2.set(["load.torque"], [x1[2]])
                    return me2.get(outputs) + me2.derivatives()

                ref = central_difference(f, x0[j], [1e-3, 1e-3, 1.0][j])
                me2.states(x0[:2])
                me2.set(["load.torque"], [x0[2]])
                scale = max(abs(float(v)) for v in ref)
                for o, g, r in zip(unknowns, got2, ref):
                    assert abs(g - float(r)) <= TOL * scale, (o, k, g, r)
    finally:
        me2.close()
        me3.close()


@pytest.mark.parametrize("kind", ["me2", "me3"])
@pytest.mark.parametrize("machine", ["kvo630", "thin rod"])
def test_pump_derivative_dependencies_omit_only_what_the_derivative_leaves_alone(
    fmu_path, tmp_path, machine, kind
):
    """The pump's <Derivatives> (2.0) and ContinuousStateDerivative (3.0) list their knowns: for
    an elastic rod, every known a derivative omits has a partial exactly 0 and leaves the
    derivative bit for bit unchanged when moved, and every listed one is non-zero at some
    random point (dϑ/dt = ϑ̇ only; ϑ̈ from the crank's inputs, the force, the pressures, ϑ and
    ϑ̇)."""
    rod = {**THIN_ROD, **SMALL_PISTON} if machine == "thin rod" else SMALL_PISTON
    values = machine_values(("kvo630", rod))
    path = fmu_path if kind == "me2" else sibling(fmu_path, "ReciprocatingDrive-fmi3.fmu")
    me = Probe(path, kind, values, tmp_path, "dd")
    try:
        deps = {d.variable.name: {x.name for x in d.dependencies} for d in me.md.derivatives}
        assert sorted(deps) == CAGE_DERIVATIVES
        assert deps["der(rod.cage_angle)"] == {"rod.cage_rate"}
        knowns = INPUTS + CAGE_STATES
        nominal = float(values.get("crank.speed", me.var["crank.speed"].start))
        rng = random.Random(31)
        seen = set()
        for x0 in random_points(rng, nominal, 5.0, 4):
            me.set(INPUTS, x0)
            x = [rng.uniform(-2e-3, 2e-3), rng.uniform(-0.05, 0.05)]
            me.states(x)
            base = me.derivatives()
            for k in knowns:
                for u, v in zip(CAGE_DERIVATIVES, me.dd(CAGE_DERIVATIVES, [k], [1.0])):
                    if k not in deps[u]:
                        assert v == 0.0, f"∂{u}/∂{k} = {v!r}, but the ModelStructure omits it"
                    elif v != 0.0:
                        seen.add((u, k))
            # Moving an input or a state: the derivatives that omit it stay bit for bit.
            for j, k in enumerate(knowns):
                if k in INPUTS:
                    y0 = list(x0)
                    y0[j] += 1e-3 * (1.0 + abs(y0[j]))
                    me.set(INPUTS, y0)
                else:
                    y = list(x)
                    y[j - len(INPUTS)] += 1e-4 * (1.0 + abs(y[j - len(INPUTS)]))
                    me.states(y)
                for u, a, b in zip(CAGE_DERIVATIVES, base, me.derivatives()):
                    if k not in deps[u]:
                        assert a == b, f"{u} moved with {k} ({a!r} -> {b!r}), not listed"
                me.set(INPUTS, x0)
                me.states(x)
        assert seen == {(u, k) for u in deps for k in deps[u]}, sorted(seen)
    finally:
        me.close()


@pytest.mark.parametrize("kind", ["me2", "me3"])
@pytest.mark.parametrize("machine", ["kvo630", "thin rod", "default"])
def test_pump_state_dependencies_omit_only_what_the_state_leaves_alone(
    fmu_path, tmp_path, machine, kind
):
    """The pump's ModelStructure (both standards) lists a cage state for an output only if the
    output may move with it: moving ϑ or ϑ̇ leaves every output that omits it bit for bit
    unchanged, and its partial with respect to that state is exactly 0, at random inputs and
    states; every listed state moves some output of an elastic rod (listed outputs may stay put
    at a point: friction saturated, ...)."""
    rod = machine != "default"
    values = machine_values(("kvo630", THIN_ROD) if machine == "thin rod" else machine)
    path = fmu_path if kind == "me2" else sibling(fmu_path, "ReciprocatingDrive-fmi3.fmu")
    me = Probe(path, kind, values, tmp_path, "sd")
    try:
        deps = {o.variable.name: {d.name for d in o.dependencies} for o in me.md.outputs}
        outputs = list(deps)
        assert {o for o in outputs if deps[o] & set(CAGE_STATES)} >= {"rod.angle", "rod.force"}
        nominal = float(values.get("crank.speed", me.var["crank.speed"].start))
        rng = random.Random(23)
        moved = set()
        for x0 in random_points(rng, nominal, 5.0 if rod else 2.0e4, 4):
            me.set(INPUTS, x0)
            x = [rng.uniform(-2e-3, 2e-3), rng.uniform(-0.05, 0.05)] if rod else [0.0, 0.0]
            me.states(x)
            base = me.get(outputs)
            for j, state in enumerate(CAGE_STATES):
                for o, v in zip(outputs, me.dd(outputs, [state], [1.0])):
                    if state not in deps[o]:
                        assert v == 0.0, f"∂{o}/∂{state} = {v!r}, but the ModelStructure omits it"
                y = list(x)
                y[j] += 1e-3 * (1.0 + abs(y[j]))
                me.states(y)
                for o, a, b in zip(outputs, base, me.get(outputs)):
                    if state not in deps[o]:
                        assert a == b, f"{o} moved with {state} ({a!r} -> {b!r}), not listed"
                    elif a != b:
                        moved.add(state)
                me.states(x)
        assert moved == (set(CAGE_STATES) if rod else set()), moved
    finally:
        me.close()


def _listed_pairs(md) -> dict:
    """Unknown name → the names of the knowns its <ModelStructure> entry lists, for the outputs
    and the state derivatives (FMI 2.0 <Outputs>/<Derivatives>, FMI 3.0 <Output>/
    <ContinuousStateDerivative>)."""
    deps = {o.variable.name: [d.name for d in o.dependencies] for o in md.outputs}
    for d in md.derivatives:
        deps[d.variable.name] = [x.name for x in d.dependencies]
    return deps


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("case", ["DriveTrain", "default", "kvo630", "thin rod"])
def test_co_simulation_answers_every_pair_its_model_structure_lists(fmu_path, tmp_path, case, fmi):
    """A co-simulation instance is asked what a loop solver asks (OMSimulator: the unknown, every
    known its <ModelStructure> entry lists, the seed 1 on one of them and 0 on the others,
    docs/closed-loop.md "In OMSimulator"): every listed (unknown, known) pair, outputs and state
    derivatives, inputs and continuous states, is answered with OK, and equals the 8th-order
    central difference (module doc) of a Model Exchange instance of the same FMU put at the
    co-simulation instance's state and inputs (where it gives the same outputs bit for bit), to
    1e-8 of the pair's scale over three states of a co-simulated run; a pair the structure does
    not list is exactly 0, and for the drive train and the elastic rods every listed pair with
    a state is non-zero somewhere (but a support's or friction output's, which may be 0 in a
    machine without that support). DriveTrain and the pump (rigid, kvo630, thin rod), FMI 2.0 and
    3.0."""
    drive = case == "DriveTrain"
    name = ("DriveTrain" if drive else "ReciprocatingDrive") + ("-fmi3" if fmi == 3 else "")
    path = sibling(fmu_path, f"{name}.fmu")
    if drive:
        values, force_scale = {}, 0.0
        inputs, states = ["load.torque"], ["crank.angle", "crank.speed"]
        steps = [1.0, 1e-3, 1e-3]
    else:
        spec, force_scale = {
            "default": ("default", 2.0e4),
            "kvo630": ROD_MACHINES["kvo630 (helical spring, clamp friction)"],
            "thin rod": ROD_MACHINES["thin rod (clamp friction)"],
        }[case]
        values = machine_values(spec)
        inputs, states = INPUTS, CAGE_STATES
    cs = Probe(path, f"cs{fmi}", values, tmp_path, "pairs-cs")
    me = Probe(path, f"me{fmi}", values, tmp_path, "pairs-me")
    try:
        listed = _listed_pairs(cs.md)
        assert listed == _listed_pairs(me.md) and len(listed) >= 9
        unknowns, knowns = list(listed), inputs + states
        assert {k for ks in listed.values() for k in ks} <= set(knowns)
        if not drive:
            omega = float(values.get("crank.speed", cs.var["crank.speed"].start))
            steps = [2e-4, 2e-4 * abs(omega), 2e-4 * (1 + omega**2), 2e-4 * force_scale]
            steps += [*PRESSURE_STEPS, 2e-6, 1e-4]
        rng = random.Random(sum(map(ord, case)) + fmi)
        t, h = 0.0, 1e-4 if not drive else 1e-3
        fmu_pairs, ref_pairs, noise, nonzero = {}, {}, {}, set()
        skipped = 0
        for point in range(3):
            # Co-simulate a while (the cage swings, the drive runs up), then put the inputs at a
            # random point: the instance holds its state there.
            for _ in range(15):
                if drive:
                    cs.set(["load.torque"], [rng.uniform(-500.0, 3000.0)])
                else:
                    cs.set(inputs, [omega * t, omega, 0.0, 0.3 * force_scale, 0.0, 0.0])
                cs.f.doStep(t, h)
                t += h
            x = (
                random_points(rng, omega, force_scale, 1)[0]
                if not drive
                else [rng.uniform(-500.0, 3000.0)]
            )
            cs.set(inputs, x)
            xs = cs.get(states)
            me.set(inputs, x)
            me.states(xs)
            assert me.get(unknowns) == cs.get(unknowns), "ME and CS at the same point differ"
            x0 = x + xs

            def at(v, j, x0=x0):
                y = list(x0)
                y[j] = v
                me.set(inputs, y[: len(inputs)])
                me.states(y[len(inputs) :])
                return me.get(unknowns)

            y0 = at(x0[0], 0)
            for j, k in enumerate(knowns):
                d1 = central_difference(lambda v, j=j: at(v, j), x0[j], steps[j])
                d2 = central_difference(lambda v, j=j: at(v, j), x0[j], steps[j] / 2)
                at(x0[j], j)
                sc = max(abs(float(v)) for v in d1) or 1.0
                kink = any(
                    abs(float(a - b)) > 1e-10 * sc + 1.5 * 16 * 2.3e-16 * abs(y) / (steps[j] / 2)
                    for a, b, y in zip(d1, d2, y0)
                )
                for i, u in enumerate(unknowns):
                    if k in listed[u]:
                        # What the loop solver asks: every listed known, seed 1 on this one.
                        seed = [1.0 if n == k else 0.0 for n in listed[u]]
                        (got,) = cs.dd([u], listed[u], seed)
                        if got != 0.0:
                            nonzero.add((u, k))
                        if kink:
                            continue
                        fmu_pairs[(point, u, k)] = got
                        ref_pairs[(point, u, k)] = float(d2[i])
                        noise[(point, u, k)] = 16 * 2.3e-16 * abs(y0[i]) / (steps[j] / 2)
                    else:
                        (got,) = cs.dd([u], [k], [1.0])
                        assert got == 0.0, f"∂{u}/∂{k} = {got!r}, but the ModelStructure omits it"
                skipped += kink
        assert skipped <= 3 * len(knowns) // 4, skipped
        for (p, u, k), r in ref_pairs.items():
            scale = max(abs(v) for (q, uu, kk), v in ref_pairs.items() if (uu, kk) == (u, k))
            got = fmu_pairs[(p, u, k)]
            if scale == 0.0:
                assert got == 0.0, (u, k, got)
                continue
            rel = max(abs(got - r) - noise[(p, u, k)], 0.0) / scale
            assert rel <= TOL, f"∂{u}/∂{k}: CS {got!r}, reference {r!r}, {rel:.2e} of {scale:.3e}"
        if drive or case != "default":
            # Listed for every machine, a support's or friction output's pair may be 0 in this one
            # (no such support, friction saturated), as in test_model_structure_matches_...
            may_vanish = ("guide.", "support_", "link.friction", "rod.stress", "rod.axial")
            state_pairs = {
                (u, k)
                for u in unknowns
                for k in listed[u]
                if k in states and not u.startswith(may_vanish)
            }
            assert state_pairs and state_pairs <= nonzero, sorted(state_pairs - nonzero)
    finally:
        cs.close()
        me.close()
