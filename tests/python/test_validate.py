"""Static checks of the archive: fmpy's validator, and the interface contract of docs/model.md §10."""

from fmpy.validation import validate_fmu

# docs/model.md §10, copied from the spec (not from the code): name -> unit.
SPEC_INPUTS = {
    "crank.angle": "rad",
    "crank.speed": "rad/s",
    "crank.acceleration": "rad/s2",
    "link.external_force": "N",
    # The pump's pressures (§4.1).
    "fluid_end.discharge_pressure": "Pa",
    "fluid_end.suction_pressure": "Pa",
}
SPEC_OUTPUTS = {
    "suspension.position": "m",
    "suspension.velocity": "m/s",
    "suspension.acceleration": "m/s2",
    "kinematics.torque_factor": "m",
    "inertia.force": "N",
    "rod.force": "N",
    "crank.torque": "N.m",
    "rod.angle": "rad",
    "rod.angular_velocity": "rad/s",
    "guide.friction": "N",
    "guide.reaction": "N",
    "guide.moment": "N.m",
    "guide.edge_force_1": "N",
    "guide.edge_force_2": "N",
    "support_A.reaction": "N",
    "support_C.reaction": "N",
    "link.friction_total": "N",
    "rod.stress_max": "Pa",
    "rod.axial_deflection": "m",
    "balancer.force": "N",
    "balancer.residual": "N",
    # Added to the contract: the crank state the outputs belong to (docs/model.md §2).
    "crank.model_angle": "rad",
    "crank.model_speed": "rad/s",
    # The whole pump (§4.1): the pump's flow and powers, and each cylinder's link and loads.
    "fluid_end.flow": "m3/s",
    "fluid_end.hydraulic_power": "W",
    "crank.mechanical_power": "W",
    **{
        f"cylinder_{k}.{name}": unit
        for k in (1, 2, 3)
        for name, unit in (
            ("position", "m"),
            ("velocity", "m/s"),
            ("acceleration", "m/s2"),
            ("fluid_force", "N"),
            ("inertia_force", "N"),
            ("friction", "N"),
            ("rod_force", "N"),
            ("crank_torque", "N.m"),
            ("flow", "m3/s"),
        )
    },
}
# The outputs the crank-slider kinematics and loads (§2, §3.1, §4) need; later features add more.
REQUIRED_OUTPUTS = list(SPEC_OUTPUTS)[:9]


def test_fmpy_validate_reports_no_problems(fmu_path):
    problems = validate_fmu(fmu_path)
    assert problems == [], "\n".join(problems)


def test_interface_matches_physics_md_section_10(model_description):
    md = model_description
    assert md.fmiVersion == "2.0"
    assert md.coSimulation is not None and md.coSimulation.modelIdentifier == "ReciprocatingDrive"
    assert md.variableNamingConvention == "structured"
    by_name = {v.name: v for v in md.modelVariables}
    inputs = {v.name: v for v in md.modelVariables if v.causality == "input"}
    outputs = {v.name: v for v in md.modelVariables if v.causality == "output"}
    # Exactly the inputs of §2 and the pump's pressures (§4.1), with their units.
    assert {n: v.unit for n, v in inputs.items()} == SPEC_INPUTS
    # Every output is one of §10 with the unit of §10, and the crank-slider set is complete.
    for n, v in outputs.items():
        assert n in SPEC_OUTPUTS, f"output {n} is not in docs/model.md §10"
        assert v.unit == SPEC_OUTPUTS[n], f"{n}: unit {v.unit}, spec {SPEC_OUTPUTS[n]}"
    for n in REQUIRED_OUTPUTS:
        assert n in outputs, f"missing output {n}"
    # Every variable has a description (docs/fmi-interface.md / §10).
    for v in md.modelVariables:
        assert v.description, f"{v.name} has no description"
    # Start values of the default machine (§8): 65 strokes/min, r = 0.2 m, l = 1.19 m, 300 kg.
    assert abs(float(by_name["crank.speed"].start) - 2 * 3.141592653589793 * 65 / 60) < 1e-12
    assert float(by_name["geometry.crank_radius"].start) == 0.2
    assert float(by_name["geometry.rod_length"].start) == 1.19
    assert float(by_name["geometry.slider_offset"].start) == 0.0
    assert float(by_name["mass.reciprocating"].start) == 300.0
    assert int(by_name["mechanism"].start) == 1


def test_output_dependencies_are_the_true_feedthrough(model_description):
    """<ModelStructure><Outputs>: each output depends on exactly the inputs its formula uses
    (§2-§4): s, TF, β on θ; v, β' on θ, ω; a, Φ on θ, ω, ε; P, T on all four and on the
    pump's two pressures (the fluid force of load.profile 3, §4.1); and, Model
    Exchange's other knowns, on the elastic rod's cage states (§6): ϑ (the rod angle, and P, T
    through the clamp loads) and ϑ̇ (the rod's angular velocity)."""
    md = model_description
    theta, omega, eps, f = "crank.angle", "crank.speed", "crank.acceleration", "link.external_force"
    pd, ps = "fluid_end.discharge_pressure", "fluid_end.suction_pressure"
    cage, rate = "rod.cage_angle", "rod.cage_rate"
    expected = {
        "suspension.position": {theta},
        "kinematics.torque_factor": {theta},
        "rod.angle": {theta, cage},
        "suspension.velocity": {theta, omega},
        "rod.angular_velocity": {theta, omega, rate},
        "suspension.acceleration": {theta, omega, eps},
        "inertia.force": {theta, omega, eps},
        "rod.force": {theta, omega, eps, f, pd, ps, cage},
        "crank.torque": {theta, omega, eps, f, pd, ps, cage},
        # The crank state itself: the angle as set (carried forward), the speed as set.
        "crank.model_angle": {theta},
        "crank.model_speed": {omega},
    }
    got = {u.variable.name: {d.name for d in (u.dependencies or [])} for u in md.outputs}
    for name, deps in expected.items():
        assert got.get(name) == deps, f"{name}: declared {got.get(name)}, expected {deps}"
