//! The variable table of the DriveTrain FMU (docs/closed-loop.md): the one source of truth for
//! its names, value references, units, start values, ranges, descriptions and dependencies.

use crate::fmi::variables::{input, output, param, Range, Table, Var};
use crate::fmus::drive_train::DriveTrainFmu;

/// Where an input's value goes in the model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputSlot {
    LoadTorque,
}

use InputSlot::*;

const OPEN_UNIT: Range = Range { min: 0.0, max: 1.0, min_open: true, max_open: true };

pub static VARIABLES: &[Var<DriveTrainFmu>] = &[
    input!("load.torque", LoadTorque, 0.0, "N.m",
        "Load torque T_L on the crank shaft (the pump's crank.torque), held constant over each communication step"),
    output!("crank.angle", angle, "rad", [],
        "Crank angle theta (integrated; connect to the pump's crank.angle)"),
    output!("crank.speed", speed, "rad/s", [],
        "Crank speed omega (connect to the pump's crank.speed)"),
    output!("crank.acceleration", acceleration, "rad/s2", [LoadTorque],
        "Crank angular acceleration d(omega)/dt = (i*T_m - T_L)/J at the end of the step, with T_L as set (connect to the pump's crank.acceleration)"),
    output!("motor.speed", motor_speed, "rad/s", [],
        "Motor shaft speed omega_m = i*omega"),
    output!("motor.torque", motor_torque, "N.m", [],
        "Motor shaft torque by Kloss's curve, T_m = 2*T_b*s*s_b/(s^2 + s_b^2)"),
    output!("motor.slip", slip, "", [],
        "Motor slip s = 1 - omega_m/omega_s (negative when the pump drives the motor)"),
    output!("motor.power", motor_power, "W", [],
        "Motor shaft power T_m*omega_m"),
    param!("drive.gear_ratio", Real, gear_ratio, Fixed, "", Range::POSITIVE,
        "Gear ratio i = motor speed / crank speed"),
    param!("motor.synchronous_speed", Real, synchronous_speed, Fixed, "rad/s", Range::POSITIVE,
        "Synchronous speed omega_s of the motor shaft (2*pi*f/p; 157.08 rad/s = 1500 rpm: 4 poles at 50 Hz)"),
    param!("motor.breakdown_torque", Real, breakdown_torque, Fixed, "N.m", Range::POSITIVE,
        "Breakdown (pull-out) torque T_b of the motor"),
    param!("motor.breakdown_slip", Real, breakdown_slip, Fixed, "", OPEN_UNIT,
        "Breakdown slip s_b (slip at the breakdown torque)"),
    param!("motor.inertia", Real, motor_inertia, Fixed, "kg.m2", Range::NON_NEGATIVE,
        "Moment of inertia J_m of the motor rotor and flywheel, motor shaft"),
    param!("crank.inertia", Real, crank_inertia, Fixed, "kg.m2", Range::NON_NEGATIVE,
        "Moment of inertia J_c of the crank shaft, gear and crank-side rotating parts; J = J_c + i^2*J_m"),
    param!("crank.angle_start", Real, angle_start, Fixed, "rad", Range::within(1e6),
        "Crank angle at the start (within +-1e6 rad, as the pump's crank.angle_offset)"),
    param!("crank.speed_start", Real, speed_start, Fixed, "rad/s", Range::within(1e4),
        "Crank speed at the start (within +-1e4 rad/s, about 95 000 rpm: beyond any reciprocating machine)"),
    param!("solver.tolerance", Real, tolerance, Fixed, "", Range::TOLERANCE,
        "Integrator tolerance (relative, and absolute on theta [rad] and omega/omega_0) when fmi2SetupExperiment gives none"),
];

pub static UNITS: &[(&str, [i32; 4])] = &[
    ("rad", [0, 0, 0, 1]),
    ("rad/s", [0, 0, -1, 1]),
    ("rad/s2", [0, 0, -2, 1]),
    ("N.m", [1, 2, -2, 0]),
    ("W", [1, 2, -3, 0]),
    ("kg.m2", [1, 2, 0, 0]),
];

pub static TABLE: Table<DriveTrainFmu> = Table::new(VARIABLES, UNITS);

/// Value reference of the load torque input.
pub const LOAD_TORQUE_VR: usize = 0;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmi::variables::Binding;

    #[test]
    fn the_glue_accepts_the_table() {
        crate::fmi::variables::check_table::<DriveTrainFmu>();
        assert!(matches!(
            VARIABLES[LOAD_TORQUE_VR].binding,
            Binding::Input { slot: LoadTorque, .. }
        ));
    }
}
