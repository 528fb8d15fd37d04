//! The variable table of the ReciprocatingDrive FMU: the one source of truth for its names,
//! value references, types, causality, variability, units, start values, ranges, descriptions and
//! output dependencies (the shape is `crate::fmi::variables`). Names are the contract of
//! docs/model.md §10.
//!
//! The value reference of a variable is its index in [`VARIABLES`].

use crate::fmi::variables::{
    input, output, param, param_at, param_bool, Binding, Range, Table, Var,
};
use crate::fmus::reciprocating_drive::ReciprocatingDrive;
use crate::model::drive::groups::{CYLINDERS, FLOW, FORCES, KINEMATICS, LOADS, TORQUE};
use crate::model::params::DEFAULT_CRANK_SPEED;

/// Where an input's value goes in the model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputSlot {
    CrankAngle,
    CrankSpeed,
    CrankAcceleration,
    ExternalForce,
    DischargePressure,
    SuctionPressure,
}

use InputSlot::*;

/// An output read through a closure (an element of an array field, `cylinders[k]`).
macro_rules! cyl_output {
    ($group:path => $name:literal, $get:expr, $unit:literal, [$($dep:ident),*], $desc:literal) => {
        output!(@var Output, Continuous, $name,
            crate::fmi::model::GroupedOutput { group: $group, get: $get }, $unit, [$($dep),*], $desc)
    };
}

/// Every variable, in value-reference order. Names are the contract of docs/model.md §10.
pub static VARIABLES: &[Var<ReciprocatingDrive>] = &[
    // ---- inputs (docs/model.md §2, §4)
    input!("crank.angle", CrankAngle, 0.0, "rad",
        "Crank angle theta_in, authoritative at the communication point where it is set; between sets the FMU carries it forward itself (theta_in += omega*h + epsilon*h^2/2 per step), so the angle the outputs belong to is crank.model_angle, not necessarily this value. Crank-slider: 0 = crank along the stroke axis toward the crosshead (outer dead centre for zero offset). Increases in the direction of rotation."),
    input!("crank.speed", CrankSpeed, DEFAULT_CRANK_SPEED, "rad/s",
        "Crank angular speed omega = d(theta)/dt, authoritative where set; between sets carried forward with crank.acceleration (omega += epsilon*h per step): see crank.model_speed"),
    input!("crank.acceleration", CrankAcceleration, 0.0, "rad/s2",
        "Crank angular acceleration epsilon; used for a = TF*epsilon + TF'*omega^2 and to carry the crank angle and speed forward inside and between steps (held until set again). Supply it when the speed varies."),
    input!("link.external_force", ExternalForce, 0.0, "N",
        "Process force on the link (cylinder 1's), positive along +s (toward the crank for the crank-slider); added to the load.profile force"),
    // ---- outputs (docs/model.md §2, §3, §4)
    output!(KINEMATICS => "suspension.position", position, "m", [CrankAngle],
        "Stroke coordinate s of the link: 0 at the outer end of the stroke, increasing toward the crank"),
    output!(KINEMATICS => "suspension.velocity", velocity, "m/s", [CrankAngle, CrankSpeed],
        "Link velocity v = ds/dt = TF*omega"),
    output!(KINEMATICS => "suspension.acceleration", acceleration, "m/s2", [CrankAngle, CrankSpeed, CrankAcceleration],
        "Link acceleration a = TF*epsilon + TF'*omega^2 (exact kinematics)"),
    output!(KINEMATICS => "kinematics.torque_factor", torque_factor, "m", [CrankAngle],
        "Torque factor TF = ds/d(theta), per radian"),
    output!(LOADS => "inertia.force", inertia_force, "N", [CrankAngle, CrankSpeed, CrankAcceleration],
        "d'Alembert inertia force of the reciprocating mass, Phi = -m*a, positive along +s"),
    output!(FORCES => "rod.force", rod_force, "N", [CrankAngle, CrankSpeed, CrankAcceleration, ExternalForce, DischargePressure, SuctionPressure],
        "Along-stroke force transmitted by the connecting rod, compression positive: P = F_ext + Phi + F_fr + F_bal (solved exactly although the friction depends on P)"),
    output!(TORQUE => "crank.torque", crank_torque, "N.m", [CrankAngle, CrankSpeed, CrankAcceleration, ExternalForce, DischargePressure, SuctionPressure],
        "Torque the drive supplies to the crankshaft, the sum over the active cylinders (fluid_end.cylinders) of T_k = -P_k*TF_k (+ V*dDelta/dtheta for an elastic rod); positive when the drive does work"),
    output!(KINEMATICS => "rod.angle", rod_angle, "rad", [CrankAngle],
        "Connecting-rod swing: crank-slider rod angle beta from the stroke axis (l*sin(beta) = r*sin(theta) - e); beam units: pitman inclination from the vertical, positive when its crank-pin end is nearer the well; elastic rod: rotation theta of its lower cage, integrated in time"),
    output!(KINEMATICS => "rod.angular_velocity", rod_angular_velocity, "rad/s", [CrankAngle, CrankSpeed],
        "Rate of rod.angle"),
    output!(LOADS => "balancer.force", balancer_force, "N", [CrankAngle],
        "Torsion-bar balancer force on the link, F_bal = -k_b*(s - s_0); 0 when balancer.enabled is false"),
    output!(LOADS => "balancer.residual", balancer_residual, "N", [CrankAngle, CrankSpeed, CrankAcceleration],
        "Inertia force left after balancing, Phi + F_bal"),
    output!(FORCES => "guide.friction", guide.friction_b, "N", [CrankAngle, CrankSpeed, CrankAcceleration, ExternalForce, DischargePressure, SuctionPressure],
        "Signed friction force of support B (the guide) on the link along +s, -|F|*tanh(v/v_eps), |F| = f*(|N1| + |N2|)"),
    output!(FORCES => "guide.reaction", guide.reaction_b, "N", [CrankAngle, CrankSpeed, CrankAcceleration, ExternalForce, DischargePressure, SuctionPressure],
        "Net lateral reaction R_B of support B on the link, along +y"),
    output!(FORCES => "guide.moment", guide.moment_b, "N.m", [CrankAngle, CrankSpeed, CrankAcceleration, ExternalForce, DischargePressure, SuctionPressure],
        "Net moment M_B of support B on the link about B's centre (positive turning +z toward +y)"),
    output!(FORCES => "guide.edge_force_1", guide.edge_force_1, "N", [CrankAngle, CrankSpeed, CrankAcceleration, ExternalForce, DischargePressure, SuctionPressure],
        "Force of B's crank-side edge on the link, N1 = R_B/2 + M_B/l_n"),
    output!(FORCES => "guide.edge_force_2", guide.edge_force_2, "N", [CrankAngle, CrankSpeed, CrankAcceleration, ExternalForce, DischargePressure, SuctionPressure],
        "Force of B's piston-side edge on the link, N2 = R_B/2 - M_B/l_n"),
    output!(FORCES => "support_A.reaction", guide.reaction_a, "N", [CrankAngle, CrankSpeed, CrankAcceleration, ExternalForce, DischargePressure, SuctionPressure],
        "Net lateral reaction of support A on the link, along +y"),
    output!(FORCES => "support_C.reaction", guide.reaction_c, "N", [CrankAngle, CrankSpeed, CrankAcceleration, ExternalForce, DischargePressure, SuctionPressure],
        "Net lateral reaction of support C on the link, along +y"),
    output!(FORCES => "link.friction_total", guide.friction_total, "N", [CrankAngle, CrankSpeed, CrankAcceleration, ExternalForce, DischargePressure, SuctionPressure],
        "Friction F_fr of supports A, B and C on the link along +s; part of rod.force and crank.torque"),
    output!(FORCES => "rod.stress_max", rod_stress_max, "Pa", [CrankAngle, CrankSpeed, CrankAcceleration, ExternalForce, DischargePressure, SuctionPressure],
        "Elastic rod: largest wire shear stress of the spring (Wahl factor) or largest fibre stress of a thin rod; 0 for a rigid rod"),
    output!(FORCES => "rod.axial_deflection", rod_axial_deflection, "m", [CrankAngle, CrankSpeed, CrankAcceleration, ExternalForce, DischargePressure, SuctionPressure],
        "Elastic rod: static axial shortening P*l_f/A3; 0 for a rigid rod"),
    // ---- parameters (docs/model.md §3, §4, §7, §8)
    param!("mechanism", Integer, mechanism, Fixed, "", Range::closed(1.0, 3.0),
        "Mechanism kind: 1 = crank-slider (optionally offset); 2 = beam pumping unit, conventional (API class I); 3 = beam pumping unit, class III (Mark II / air balanced)"),
    param!("rotation", Integer, rotation, Fixed, "", Range::closed(-1.0, 1.0),
        "Beam units: +1 clockwise, -1 counter-clockwise, viewed with the well on the right (API 11E); 0 is not allowed. Ignored by the crank-slider."),
    param!("crank.angle_offset", Real, crank_angle_offset, Fixed, "rad", Range::within(1e6),
        "Added to crank.angle to form the model angle (to match a sensor's zero)"),
    param!("geometry.crank_radius", Real, crank_radius, Fixed, "m", Range::positive_to(1e3),
        "Crank radius r"),
    param!("geometry.rod_length", Real, rod_length, Fixed, "m", Range::positive_to(1e3),
        "Connecting rod length l, centre to centre (crank-slider: must exceed r + |e|); beam units: pitman length P"),
    param!("geometry.slider_offset", Real, slider_offset, Fixed, "m", Range::within(1e3),
        "Crank-slider only: guide offset e; the stroke axis is the line y = e (y positive on the side of the crank pin at theta = 90 deg)"),
    param!("geometry.beam_front_arm", Real, beam_front_arm, Fixed, "m", Range::positive_to(1e3),
        "Beam units: A, centre bearing to horsehead arc (polished rod)"),
    param!("geometry.beam_rear_arm", Real, beam_rear_arm, Fixed, "m", Range::positive_to(1e3),
        "Beam units: C, centre bearing to equalizer bearing"),
    param!("geometry.pivot_dx", Real, pivot_dx, Fixed, "m", Range::positive_to(1e3),
        "Beam units: I, horizontal distance crankshaft to centre bearing"),
    param!("geometry.pivot_dy", Real, pivot_dy, Fixed, "m", Range::positive_to(1e3),
        "Beam units: H-G, vertical distance crankshaft to centre bearing"),
    param!("mass.reciprocating", Real, mass, Fixed, "kg", Range::closed(0.0, 1e9),
        "Reciprocating mass m reduced to the link"),
    param!("load.profile", Integer, load_profile, Tunable, "", Range::closed(0.0, 3.0),
        "Process-force profile: 0 = load.mean + load.amplitude*cos(theta + load.phase); 1 = double-acting pump -load.mean*tanh(v/v_eps); 2 = single-acting pump load.mean*(1 - tanh(v/v_eps))/2; 3 = pressures: each chamber at fluid_end.discharge_pressure while its volume shrinks and at fluid_end.suction_pressure while it grows, weights (1 -+ tanh(v/v_eps))/2 (docs/model.md 4.1). Profiles 0-2 act on every cylinder at its own angle and velocity"),
    param!("load.mean", Real, load_mean, Tunable, "N", Range::within(1e10),
        "Mean process force (profile 0) or pump force level (profiles 1, 2)"),
    param!("load.amplitude", Real, load_amplitude, Tunable, "N", Range::within(1e10),
        "Amplitude of the cosine process force (profile 0)"),
    param!("load.phase", Real, load_phase, Tunable, "rad", Range::within(1e6),
        "Phase of the cosine process force (profile 0)"),
    param!("guide.velocity_scale", Real, velocity_scale, Fixed, "m/s", Range::positive_to(1e3),
        "Velocity scale v_eps of the regularised sign tanh(v/v_eps) of the friction and of the pump load profiles"),
    // ---- elastic connecting rod clamped in the piston (docs/model.md §6)
    param!("rod.kind", Integer, rod_kind, Fixed, "", Range::closed(0.0, 2.0),
        "Connecting rod: 0 rigid (crank-slider kinematics of geometry.rod_length); 1 thin elastic rod, 2 helical spring, clamped in the piston (crank-slider only; its cage rotation is integrated in time)"),
    param!("rod.flex_length", Real, rod_flex_length, Fixed, "m", Range::positive_to(1e3),
        "Elastic length l_f of the rod, from the clamp in the piston"),
    param!("rod.rigid_length", Real, rod_rigid_length, Fixed, "m", Range::closed(0.0, 1e3),
        "Rigid length f from the end of the elastic part to the crank-pin centre"),
    param!("rod.wire_diameter", Real, rod_wire_diameter, Fixed, "m", Range::positive_to(10.0),
        "Wire diameter d of the spring (diameter of a thin rod)"),
    param!("rod.coil_diameter", Real, rod_coil_diameter, Fixed, "m", Range::positive_to(100.0),
        "Helical spring (rod.kind 2) only: mean coil diameter D of the spring (> d)"),
    param!("rod.coils", Real, rod_coils, Fixed, "", Range::closed(1.0, f64::INFINITY),
        "Helical spring (rod.kind 2) only: number of active coils i of the spring (pitch h = l_f/i)"),
    param!("rod.E", Real, rod_e_modulus, Fixed, "Pa", Range::positive_to(1e13), "Young's modulus of the rod"),
    param!("rod.poisson", Real, rod_poisson, Fixed, "", Range { min: -1.0, max: 0.5, min_open: true, max_open: false },
        "Poisson's ratio of the rod, G = E/(2(1 + nu))"),
    param!("rod.cage_inertia", Real, rod_cage_inertia, Fixed, "kg.m2", Range::positive_to(1e6),
        "Moment of inertia J_m of the rod's lower cage about the crank-pin axis"),
    param!("rod.damping_ratio", Real, rod_damping_ratio, Fixed, "", Range::closed(0.0, 100.0),
        "Damping ratio zeta of the cage oscillation, B_d = 2*zeta*sqrt(K_theta(0)*J_m) (used when rod.damping = 0)"),
    param!("rod.damping", Real, rod_damping, Fixed, "N.m.s/rad", Range::closed(0.0, 1e9),
        "Damping coefficient B_d of the cage; 0 = from rod.damping_ratio"),
    param!("rod.load_eccentricity", Real, rod_load_eccentricity, Fixed, "m", Range::within(1e3),
        "Lever e_P of the axial rod force on the cage (0 for a centred spring end)"),
    param!("rod.rigid_mass", Real, rod_rigid_mass, Fixed, "kg", Range::closed(0.0, 1e9),
        "Mass m_f of the rigid part of the rod"),
    param!("rod.rigid_lever", Real, rod_rigid_lever, Fixed, "m", Range::within(1e3),
        "Lever f_m of the rigid part's inertia force on the cage"),
    param!("rod.initial_state", Integer, rod_initial_state, Fixed, "", Range::closed(0.0, 1.0),
        "Initial cage state: 1 quasi-static (equilibrium at the initial inputs), 0 at rest"),
    param!("solver.tolerance", Real, solver_tolerance, Fixed, "", Range::TOLERANCE,
        "Elastic rod (rod.kind 1 or 2) only: tolerance of the cage-equation integrator (relative, and absolute on rod.angle and on rod.angular_velocity/Omega0) when fmi2SetupExperiment gives none"),
    param_bool!("balancer.enabled", balancer_enabled, Fixed,
        "Torsion-bar balancer on the link: F_bal = -k_b*(s - s_0)"),
    param!("balancer.tuning", Integer, balancer_tuning, Fixed, "", Range::closed(0.0, 2.0),
        "Balancer stiffness: 0 = balancer.stiffness as given; 1 = energy rule k_b = m*B^2*omega_d^2, B = v_max/(r*omega), s_0 at mid-stroke; 2 = exact cancellation at both dead centres of a central crank-slider, k_b = m*omega_d^2, s_0 = r*(1 + r/l)"),
    param!("balancer.stiffness", Real, balancer_stiffness, Fixed, "N/m", Range::closed(0.0, 1e15),
        "Balancer stiffness k_b for balancer.tuning = 0"),
    param!("balancer.design_speed", Real, balancer_design_speed, Fixed, "rad/s", Range::closed(0.0, 1e4),
        "Design crank speed omega_d of balancer tunings 1 and 2"),
    param!("balancer.neutral_position", Real, balancer_neutral_position, Fixed, "m", Range::within(1e3),
        "Stroke position s_0 where the balancer force is zero (tuning 0); a negative value means mid-stroke"),
    // ---- guide friction from the link's redundant supports (docs/model.md §5)
    param_at!("link.l1", link_lengths[0], "m", Range::closed(0.0, 1e3), "Length of link section 1 (from the piston end, z = 0); 0 = absent"),
    param_at!("link.l2", link_lengths[1], "m", Range::closed(0.0, 1e3), "Length of link section 2; 0 = absent"),
    param_at!("link.l3", link_lengths[2], "m", Range::closed(0.0, 1e3), "Length of link section 3; 0 = absent"),
    param_at!("link.l4", link_lengths[3], "m", Range::closed(0.0, 1e3), "Length of link section 4 (crank end); 0 = absent"),
    param_at!("link.d1", link_diameters[0], "m", Range::closed(0.0, 1e3), "(Equivalent) diameter of link section 1, J = pi*d^4/64"),
    param_at!("link.d2", link_diameters[1], "m", Range::closed(0.0, 1e3), "(Equivalent) diameter of link section 2"),
    param_at!("link.d3", link_diameters[2], "m", Range::closed(0.0, 1e3), "(Equivalent) diameter of link section 3"),
    param_at!("link.d4", link_diameters[3], "m", Range::closed(0.0, 1e3), "(Equivalent) diameter of link section 4"),
    param!("link.E", Real, link_e_modulus, Fixed, "Pa", Range::positive_to(1e13), "Young's modulus of the link"),
    param!("link.lateral_load", Real, link_lateral_load, Fixed, "N", Range::within(1e10),
        "Constant lateral force on the link along +y at support B's centre (z = L without B), e.g. the weight of crosshead and link of a horizontal machine"),
    param!("support_A.kind", Integer, supports[0].kind, Fixed, "", Range::closed(0.0, 3.0), "Support A: 0 none, 1 pin (lateral force), 2 clamp (lateral force + moment), 3 two-edge guide of length support_A.length"),
    param!("support_A.attached", Integer, supports[0].attached, Fixed, "", Range::closed(0.0, 1.0), "Support A: 0 moves with the link (fixed link coordinate support_A.z), 1 fixed in the frame (the link slides through it; support_A.z is its link coordinate at s = 0)"),
    param!("support_A.z", Real, supports[0].z, Fixed, "m", Range::within(1e3), "Support A: link coordinate of its centre (at s = 0 when fixed in the frame); z = 0 at the piston end"),
    param!("support_A.offset", Real, supports[0].offset, Fixed, "m", Range::within(1.0), "Support A: lateral offset delta of its axis from the reference axis (support A's)"),
    param!("support_A.tilt", Real, supports[0].tilt, Fixed, "rad", Range::within(1.0), "Support A: tilt alpha of its axis, y = delta + alpha*(Z - Z_ref), Z_ref its frame position at mid-stroke. Acts for a clamp (kind 2: slope alpha), a two-edge guide (kind 3) and a pin moving with the link (kind 1, attached 0); no effect on a frame-fixed pin (a gland: its contact stays at Z_ref) or when kind is 0"),
    param!("support_A.length", Real, supports[0].length, Fixed, "m", Range::closed(0.0, 1e3), "Support A: length l_n: edge distance of a two-edge guide (kind 3); for a clamp (kind 2) only its friction f*max(|R|, 2|M|/l_n) uses it; no effect on a pin"),
    param!("support_A.stiffness", Real, supports[0].stiffness, Fixed, "N/m", Range::closed(0.0, 1e15), "Support A: stiffness of each lateral contact; 0 = rigid"),
    param!("support_A.friction", Real, supports[0].friction, Fixed, "", Range::closed(0.0, 10.0), "Support A: friction coefficient"),
    param!("support_B.kind", Integer, supports[1].kind, Fixed, "", Range::closed(0.0, 3.0), "Support B: 0 none, 1 pin (lateral force), 2 clamp (lateral force + moment), 3 two-edge guide of length support_B.length"),
    param!("support_B.attached", Integer, supports[1].attached, Fixed, "", Range::closed(0.0, 1.0), "Support B: 0 moves with the link (fixed link coordinate support_B.z), 1 fixed in the frame (the link slides through it; support_B.z is its link coordinate at s = 0)"),
    param!("support_B.z", Real, supports[1].z, Fixed, "m", Range::within(1e3), "Support B: link coordinate of its centre (at s = 0 when fixed in the frame); z = 0 at the piston end"),
    param!("support_B.offset", Real, supports[1].offset, Fixed, "m", Range::within(1.0), "Support B: lateral offset delta of its axis from the reference axis (support A's)"),
    param!("support_B.tilt", Real, supports[1].tilt, Fixed, "rad", Range::within(1.0), "Support B: tilt alpha of its axis, y = delta + alpha*(Z - Z_ref), Z_ref its frame position at mid-stroke. Acts for a clamp (kind 2: slope alpha), a two-edge guide (kind 3) and a pin moving with the link (kind 1, attached 0); no effect on a frame-fixed pin (a gland: its contact stays at Z_ref) or when kind is 0"),
    param!("support_B.length", Real, supports[1].length, Fixed, "m", Range::closed(0.0, 1e3), "Support B: length l_n: edge distance of a two-edge guide (kind 3); for a clamp (kind 2) only its friction f*max(|R|, 2|M|/l_n) uses it; no effect on a pin"),
    param!("support_B.stiffness", Real, supports[1].stiffness, Fixed, "N/m", Range::closed(0.0, 1e15), "Support B: stiffness of each lateral contact; 0 = rigid"),
    param!("support_C.kind", Integer, supports[2].kind, Fixed, "", Range::closed(0.0, 3.0), "Support C: 0 none, 1 pin (lateral force), 2 clamp (lateral force + moment), 3 two-edge guide of length support_C.length"),
    param!("support_C.attached", Integer, supports[2].attached, Fixed, "", Range::closed(0.0, 1.0), "Support C: 0 moves with the link (fixed link coordinate support_C.z), 1 fixed in the frame (the link slides through it; support_C.z is its link coordinate at s = 0)"),
    param!("support_C.z", Real, supports[2].z, Fixed, "m", Range::within(1e3), "Support C: link coordinate of its centre (at s = 0 when fixed in the frame); z = 0 at the piston end"),
    param!("support_C.offset", Real, supports[2].offset, Fixed, "m", Range::within(1.0), "Support C: lateral offset delta of its axis from the reference axis (support A's)"),
    param!("support_C.tilt", Real, supports[2].tilt, Fixed, "rad", Range::within(1.0), "Support C: tilt alpha of its axis, y = delta + alpha*(Z - Z_ref), Z_ref its frame position at mid-stroke. Acts for a clamp (kind 2: slope alpha), a two-edge guide (kind 3) and a pin moving with the link (kind 1, attached 0); no effect on a frame-fixed pin (a gland: its contact stays at Z_ref) or when kind is 0"),
    param!("support_C.length", Real, supports[2].length, Fixed, "m", Range::closed(0.0, 1e3), "Support C: length l_n: edge distance of a two-edge guide (kind 3); for a clamp (kind 2) only its friction f*max(|R|, 2|M|/l_n) uses it; no effect on a pin"),
    param!("support_C.stiffness", Real, supports[2].stiffness, Fixed, "N/m", Range::closed(0.0, 1e15), "Support C: stiffness of each lateral contact; 0 = rigid"),
    param!("support_C.friction", Real, supports[2].friction, Fixed, "", Range::closed(0.0, 10.0), "Support C: friction coefficient"),
    param!("guide.friction_coefficient", Real, supports[1].friction, Fixed, "", Range::closed(0.0, 10.0),
        "Friction coefficient f of support B (the guide)"),
    param_bool!("guide.rod_side_force", rod_side_force, Fixed,
        "Rigid rod: its side load -P*tan(beta) acts on the link at B's centre (docs/model.md 5.4)"),
    output!(LOADS => CalculatedParameter, Fixed, "balancer.stiffness_used", balancer_stiffness_used, "N/m", [],
        "Balancer stiffness k_b in use (from balancer.tuning); 0 when the balancer is off"),
    // ---- the crank state the outputs belong to (§2); appended, so that earlier value
    // references stay what they were.
    output!(KINEMATICS => "crank.model_angle", model_angle, "rad", [CrankAngle],
        "Model angle theta the outputs belong to: crank.angle as last set plus crank.angle_offset, carried forward by every step since (theta += omega*h + epsilon*h^2/2); restored with the FMU state"),
    output!(KINEMATICS => "crank.model_speed", model_speed, "rad/s", [CrankSpeed],
        "Crank speed omega the outputs belong to: crank.speed as last set, carried forward by every step since (omega += epsilon*h); restored with the FMU state"),
    // ---- the whole pump: pressures in, cylinders on one crankshaft (docs/model.md §4.1);
    // appended, so that earlier value references stay what they were.
    input!("fluid_end.discharge_pressure", DischargePressure, 0.0, "Pa",
        "Discharge (standpipe) pressure p_d, gauge: the pressure of every chamber whose volume shrinks (load.profile 3)"),
    input!("fluid_end.suction_pressure", SuctionPressure, 0.0, "Pa",
        "Suction pressure p_s, gauge: the pressure of every chamber whose volume grows (load.profile 3)"),
    param!("fluid_end.cylinders", Integer, cylinders, Fixed, "", Range::closed(1.0, 3.0),
        "Number of active cylinders on the crankshaft (1 to 3), each with its own crosshead, guide and link (the parameters of the mechanism, mass, link and supports are shared); 2 or 3 need the rigid crank-slider (mechanism 1, rod.kind 0)"),
    param!("cylinder_1.acting", Integer, cylinder[0].acting, Fixed, "", Range::closed(1.0, 2.0),
        "Cylinder 1: 1 single-acting (head-end chamber only, area pi*D^2/4), 2 double-acting (also the crank-end chamber, area pi*(D^2 - d^2)/4)"),
    param!("cylinder_1.piston_diameter", Real, cylinder[0].piston_diameter, Fixed, "m", Range::positive_to(10.0),
        "Piston (liner) diameter D of cylinder 1"),
    param!("cylinder_1.rod_diameter", Real, cylinder[0].rod_diameter, Fixed, "m", Range::closed(0.0, 10.0),
        "Piston-rod diameter d of cylinder 1 through its crank-end chamber (double-acting; < D)"),
    param!("cylinder_2.phase", Real, cylinder[1].phase, Fixed, "rad", Range::within(1e6),
        "Crank phase phi_2 of cylinder 2: its link sees the model angle theta + phi_2 (cylinder 1 is the reference, phi_1 = 0; duplex phi_2 = pi/2, triplex phi_2 = 2*pi/3, phi_3 = 4*pi/3)"),
    param!("cylinder_2.acting", Integer, cylinder[1].acting, Fixed, "", Range::closed(1.0, 2.0),
        "Cylinder 2: 1 single-acting (head-end chamber only, area pi*D^2/4), 2 double-acting (also the crank-end chamber, area pi*(D^2 - d^2)/4)"),
    param!("cylinder_2.piston_diameter", Real, cylinder[1].piston_diameter, Fixed, "m", Range::positive_to(10.0),
        "Piston (liner) diameter D of cylinder 2"),
    param!("cylinder_2.rod_diameter", Real, cylinder[1].rod_diameter, Fixed, "m", Range::closed(0.0, 10.0),
        "Piston-rod diameter d of cylinder 2 through its crank-end chamber (double-acting; < D)"),
    param!("cylinder_3.phase", Real, cylinder[2].phase, Fixed, "rad", Range::within(1e6),
        "Crank phase phi_3 of cylinder 3: its link sees the model angle theta + phi_3 (duplex 0, pi/2; triplex 0, 2*pi/3, 4*pi/3)"),
    param!("cylinder_3.acting", Integer, cylinder[2].acting, Fixed, "", Range::closed(1.0, 2.0),
        "Cylinder 3: 1 single-acting (head-end chamber only, area pi*D^2/4), 2 double-acting (also the crank-end chamber, area pi*(D^2 - d^2)/4)"),
    param!("cylinder_3.piston_diameter", Real, cylinder[2].piston_diameter, Fixed, "m", Range::positive_to(10.0),
        "Piston (liner) diameter D of cylinder 3"),
    param!("cylinder_3.rod_diameter", Real, cylinder[2].rod_diameter, Fixed, "m", Range::closed(0.0, 10.0),
        "Piston-rod diameter d of cylinder 3 through its crank-end chamber (double-acting; < D)"),
    output!(KINEMATICS => "cylinder_1.position", position, "m", [CrankAngle],
        "Stroke coordinate s_1 of cylinder 1's link (0 at the outer end, increasing toward the crank)"),
    output!(KINEMATICS => "cylinder_1.velocity", velocity, "m/s", [CrankAngle, CrankSpeed],
        "Velocity v_1 = TF(theta + phi_1)*omega of cylinder 1's link"),
    output!(KINEMATICS => "cylinder_1.acceleration", acceleration, "m/s2", [CrankAngle, CrankSpeed, CrankAcceleration],
        "Acceleration a_1 of cylinder 1's link"),
    cyl_output!(LOADS => "cylinder_1.fluid_force", |o| o.cylinders[0].fluid_force, "N", [CrankAngle, CrankSpeed, DischargePressure, SuctionPressure],
        "Process force of load.profile on cylinder 1's piston along +s (load.profile 3: the chambers' pressures times their areas), without link.external_force"),
    output!(LOADS => "cylinder_1.inertia_force", inertia_force, "N", [CrankAngle, CrankSpeed, CrankAcceleration],
        "Inertia force -m*a_1 of cylinder 1's reciprocating mass"),
    output!(FORCES => "cylinder_1.friction", guide.friction_total, "N", [CrankAngle, CrankSpeed, CrankAcceleration, ExternalForce, DischargePressure, SuctionPressure],
        "Friction F_fr of the supports of cylinder 1's link (A, B, C) along +s"),
    output!(FORCES => "cylinder_1.rod_force", rod_force, "N", [CrankAngle, CrankSpeed, CrankAcceleration, ExternalForce, DischargePressure, SuctionPressure],
        "Along-stroke force P_1 of cylinder 1's connecting rod, compression positive"),
    cyl_output!(FORCES => "cylinder_1.crank_torque", |o| o.cylinders[0].crank_torque, "N.m", [CrankAngle, CrankSpeed, CrankAcceleration, ExternalForce, DischargePressure, SuctionPressure],
        "Torque T_1 = -P_1*TF_1 cylinder 1 asks of the crankshaft (part of crank.torque)"),
    cyl_output!(FLOW => "cylinder_1.flow", |o| o.cylinders[0].flow, "m3/s", [CrankAngle, CrankSpeed],
        "Flow rate Q_1 cylinder 1 discharges: the shrinking rates of its chambers weighted (1 -+ tanh(v/v_eps))/2"),
    cyl_output!(CYLINDERS => "cylinder_2.position", |o| o.cylinders[1].position, "m", [CrankAngle],
        "Stroke coordinate s_2 of cylinder 2's link (0 at the outer end, increasing toward the crank)"),
    cyl_output!(CYLINDERS => "cylinder_2.velocity", |o| o.cylinders[1].velocity, "m/s", [CrankAngle, CrankSpeed],
        "Velocity v_2 = TF(theta + phi_2)*omega of cylinder 2's link"),
    cyl_output!(CYLINDERS => "cylinder_2.acceleration", |o| o.cylinders[1].acceleration, "m/s2", [CrankAngle, CrankSpeed, CrankAcceleration],
        "Acceleration a_2 of cylinder 2's link"),
    cyl_output!(CYLINDERS => "cylinder_2.fluid_force", |o| o.cylinders[1].fluid_force, "N", [CrankAngle, CrankSpeed, DischargePressure, SuctionPressure],
        "Process force of load.profile on cylinder 2's piston along +s (load.profile 3: the chambers' pressures times their areas)"),
    cyl_output!(CYLINDERS => "cylinder_2.inertia_force", |o| o.cylinders[1].inertia_force, "N", [CrankAngle, CrankSpeed, CrankAcceleration],
        "Inertia force -m*a_2 of cylinder 2's reciprocating mass"),
    cyl_output!(CYLINDERS => "cylinder_2.friction", |o| o.cylinders[1].friction, "N", [CrankAngle, CrankSpeed, CrankAcceleration, DischargePressure, SuctionPressure],
        "Friction F_fr of the supports of cylinder 2's link (A, B, C) along +s"),
    cyl_output!(CYLINDERS => "cylinder_2.rod_force", |o| o.cylinders[1].rod_force, "N", [CrankAngle, CrankSpeed, CrankAcceleration, DischargePressure, SuctionPressure],
        "Along-stroke force P_2 of cylinder 2's connecting rod, compression positive"),
    cyl_output!(CYLINDERS => "cylinder_2.crank_torque", |o| o.cylinders[1].crank_torque, "N.m", [CrankAngle, CrankSpeed, CrankAcceleration, DischargePressure, SuctionPressure],
        "Torque T_2 = -P_2*TF_2 cylinder 2 asks of the crankshaft (part of crank.torque)"),
    cyl_output!(FLOW => "cylinder_2.flow", |o| o.cylinders[1].flow, "m3/s", [CrankAngle, CrankSpeed],
        "Flow rate Q_2 cylinder 2 discharges: the shrinking rates of its chambers weighted (1 -+ tanh(v/v_eps))/2"),
    cyl_output!(CYLINDERS => "cylinder_3.position", |o| o.cylinders[2].position, "m", [CrankAngle],
        "Stroke coordinate s_3 of cylinder 3's link (0 at the outer end, increasing toward the crank)"),
    cyl_output!(CYLINDERS => "cylinder_3.velocity", |o| o.cylinders[2].velocity, "m/s", [CrankAngle, CrankSpeed],
        "Velocity v_3 = TF(theta + phi_3)*omega of cylinder 3's link"),
    cyl_output!(CYLINDERS => "cylinder_3.acceleration", |o| o.cylinders[2].acceleration, "m/s2", [CrankAngle, CrankSpeed, CrankAcceleration],
        "Acceleration a_3 of cylinder 3's link"),
    cyl_output!(CYLINDERS => "cylinder_3.fluid_force", |o| o.cylinders[2].fluid_force, "N", [CrankAngle, CrankSpeed, DischargePressure, SuctionPressure],
        "Process force of load.profile on cylinder 3's piston along +s (load.profile 3: the chambers' pressures times their areas)"),
    cyl_output!(CYLINDERS => "cylinder_3.inertia_force", |o| o.cylinders[2].inertia_force, "N", [CrankAngle, CrankSpeed, CrankAcceleration],
        "Inertia force -m*a_3 of cylinder 3's reciprocating mass"),
    cyl_output!(CYLINDERS => "cylinder_3.friction", |o| o.cylinders[2].friction, "N", [CrankAngle, CrankSpeed, CrankAcceleration, DischargePressure, SuctionPressure],
        "Friction F_fr of the supports of cylinder 3's link (A, B, C) along +s"),
    cyl_output!(CYLINDERS => "cylinder_3.rod_force", |o| o.cylinders[2].rod_force, "N", [CrankAngle, CrankSpeed, CrankAcceleration, DischargePressure, SuctionPressure],
        "Along-stroke force P_3 of cylinder 3's connecting rod, compression positive"),
    cyl_output!(CYLINDERS => "cylinder_3.crank_torque", |o| o.cylinders[2].crank_torque, "N.m", [CrankAngle, CrankSpeed, CrankAcceleration, DischargePressure, SuctionPressure],
        "Torque T_3 = -P_3*TF_3 cylinder 3 asks of the crankshaft (part of crank.torque)"),
    cyl_output!(FLOW => "cylinder_3.flow", |o| o.cylinders[2].flow, "m3/s", [CrankAngle, CrankSpeed],
        "Flow rate Q_3 cylinder 3 discharges: the shrinking rates of its chambers weighted (1 -+ tanh(v/v_eps))/2"),
    output!(FLOW => "fluid_end.flow", flow, "m3/s", [CrankAngle, CrankSpeed],
        "Instantaneous flow rate Q of the pump, the sum of cylinder_k.flow over the active cylinders"),
    output!(FLOW => "fluid_end.hydraulic_power", hydraulic_power, "W", [CrankAngle, CrankSpeed, DischargePressure, SuctionPressure],
        "Hydraulic power (p_d - p_s)*Q"),
    output!(TORQUE => "crank.mechanical_power", mechanical_power, "W", [CrankAngle, CrankSpeed, CrankAcceleration, ExternalForce, DischargePressure, SuctionPressure],
        "Mechanical power crank.torque*omega the drive delivers to the crankshaft"),
];

/// Units used by the table, with their SI base-unit exponents (kg, m, s, rad) for
/// `<UnitDefinitions>`.
pub static UNITS: &[(&str, [i32; 4])] = &[
    ("m", [0, 1, 0, 0]),
    ("m/s", [0, 1, -1, 0]),
    ("m/s2", [0, 1, -2, 0]),
    ("rad", [0, 0, 0, 1]),
    ("rad/s", [0, 0, -1, 1]),
    ("rad/s2", [0, 0, -2, 1]),
    ("N", [1, 1, -2, 0]),
    ("N.m", [1, 2, -2, 0]),
    ("kg", [1, 0, 0, 0]),
    ("N/m", [1, 0, -2, 0]),
    ("Pa", [1, -1, -2, 0]),
    ("kg.m2", [1, 2, 0, 0]),
    ("N.m.s/rad", [1, 2, -1, -1]),
    ("m3/s", [0, 3, -1, 0]),
    ("W", [1, 2, -3, 0]),
];

/// The table as the glue reads it.
pub static TABLE: Table<ReciprocatingDrive> = Table::new(VARIABLES, UNITS);

/// Value reference of a variable by name (tests, set-up code; not the hot path).
pub fn value_reference(name: &str) -> Option<usize> {
    TABLE.value_reference(name)
}

/// Value reference of the input bound to `slot` (found once, then an array look-up: the step
/// reads inputs through it).
pub fn input_vr(slot: InputSlot) -> usize {
    input_vrs()[slot as usize]
}

/// The value references of the inputs every evaluation reads besides the crank's (`inputs` in
/// mod.rs), as constants: looked up in [`input_vrs`] they cost the single cylinder's loop step
/// 8 instructions (docs/performance.md). The table appends new variables, so these stay; a test
/// checks them against the table.
pub const EXTERNAL_FORCE_VR: usize = 3;
pub const DISCHARGE_PRESSURE_VR: usize = 100;
pub const SUCTION_PRESSURE_VR: usize = 101;

/// The value references of every input, by [`InputSlot`] (found once).
#[inline]
pub fn input_vrs() -> &'static [usize; 6] {
    static VRS: std::sync::OnceLock<[usize; 6]> = std::sync::OnceLock::new();
    VRS.get_or_init(|| {
        [
            CrankAngle,
            CrankSpeed,
            CrankAcceleration,
            ExternalForce,
            DischargePressure,
            SuctionPressure,
        ]
        .map(|slot| {
            VARIABLES
                .iter()
                .position(|v| matches!(v.binding, Binding::Input { slot: s, .. } if s == slot))
                .unwrap_or(usize::MAX)
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmi::variables::VarType::*;
    use crate::model::params::Params;

    #[test]
    fn the_glue_accepts_the_table() {
        crate::fmi::variables::check_table::<ReciprocatingDrive>();
    }

    #[test]
    fn names_are_unique_and_units_defined() {
        for (i, v) in VARIABLES.iter().enumerate() {
            assert_eq!(value_reference(v.name), Some(i), "duplicate name {}", v.name);
            assert!(v.unit.is_empty() || UNITS.iter().any(|u| u.0 == v.unit), "unit {}", v.unit);
            if let Some(s) = v.start() {
                assert!(v.range.contains(s), "start of {} outside its range", v.name);
            }
        }
        for slot in [
            CrankAngle,
            CrankSpeed,
            CrankAcceleration,
            ExternalForce,
            DischargePressure,
            SuctionPressure,
        ] {
            assert!(input_vr(slot) < VARIABLES.len());
        }
        assert_eq!(input_vr(ExternalForce), EXTERNAL_FORCE_VR);
        assert_eq!(input_vr(DischargePressure), DISCHARGE_PRESSURE_VR);
        assert_eq!(input_vr(SuctionPressure), SUCTION_PRESSURE_VR);
    }

    #[test]
    fn setters_and_getters_address_the_same_field() {
        // Each parameter's set followed by get returns the value, and touches no other parameter.
        for v in VARIABLES {
            if let Binding::Param { get, set } = v.binding {
                let mut p = Params::default();
                let x = match v.ty {
                    Real => 0.123,
                    Integer => 2.0,
                    Boolean => 1.0,
                };
                set(&mut p, x);
                assert_eq!(get(&p), x, "{}", v.name);
                for w in VARIABLES {
                    if let Binding::Param { get: g2, .. } = w.binding {
                        if w.name != v.name {
                            assert_eq!(
                                g2(&p),
                                g2(&Params::default()),
                                "{} changed {}",
                                v.name,
                                w.name
                            );
                        }
                    }
                }
            }
        }
    }
}
