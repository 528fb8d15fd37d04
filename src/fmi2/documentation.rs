//! The FMU's documentation/index.html: the conventions a user needs (from physics.md) and the
//! variable list, generated from the variable table so it cannot drift from the interface.

use std::fmt::Write;

use crate::fmi2::variables::{Causality, VarType, Variability, VARIABLES};

const CONVENTIONS: &str = r#"
<h2>What it is</h2>
<p>A co-simulation FMU (FMI 2.0) of a crank-driven reciprocating mechanism. The master supplies the crank
motion (angle, speed, optionally angular acceleration) and optionally a process force; the FMU returns the
exact kinematics of the link (the "suspension point"), its inertia load, the rod force and the crank torque.
Implemented mechanisms: 1 = crank-slider with optional guide offset (drilling mud pump, compressor).</p>

<h2>Conventions</h2>
<ul>
<li>SI units throughout; angles in radians.</li>
<li><b>Model angle</b> &theta; = <code>crank.angle</code> + <code>crank.angle_offset</code>; it increases in the direction of rotation.</li>
<li><b>Crank-slider angle origin</b>: &theta; = 0 with the crank pointing along the stroke axis toward the crosshead; for zero
offset that is the outer dead centre (crosshead farthest from the crank axis).</li>
<li><b>Stroke coordinate</b> <code>suspension.position</code> s: 0 at the outer end of the stroke, increasing toward the crank.
v = ds/dt, a = d&sup2;s/dt&sup2;; in steady rotation a &gt; 0 at the outer end.</li>
<li><b>Torque factor</b> TF = ds/d&theta; [m/rad]; v = TF&middot;&omega;, a = TF&middot;&epsilon; + TF'&middot;&omega;&sup2;, computed from the exact
position function by analytic derivatives (no series approximation).</li>
<li><b>Forces</b> on the link are positive along +s. Inertia force &Phi; = &minus;m&middot;a. Process force F_ext = input
<code>link.external_force</code> + the <code>load.profile</code> force. Rod force P = F_ext + &Phi; (compression positive).
Crank torque T = &minus;P&middot;TF is the torque the drive supplies (T&middot;&omega; = &minus;P&middot;v).</li>
<li><b>Rod angle</b> &beta; from l&middot;sin&beta; = r&middot;sin&theta; &minus; e (y positive on the side of the crank pin at &theta; = 90&deg;).</li>
<li><b>Inside a communication step</b> the FMU extrapolates the crank with constant acceleration:
&theta;(t+&tau;) = &theta; + &omega;&tau; + &epsilon;&tau;&sup2;/2. At the next communication point the master's inputs are authoritative.
Masters that vary the speed should supply <code>crank.acceleration</code>.</li>
<li>Outputs reflect inputs set since the last step (direct feedthrough, declared in ModelStructure).</li>
</ul>

<h2>Errors</h2>
<p>Invalid parameters (out of range, or a linkage that cannot assemble) make <code>fmi2ExitInitializationMode</code>
return fmi2Error with a message naming the variable, its value and the allowed range; the instance stays in
initialization mode so the value can be corrected. A non-finite input is refused by <code>fmi2SetReal</code> and
not stored. A failed call leaves the FMU's state as it was. FMU states can be saved, restored and serialized.</p>

<h2>Using it from fmpy</h2>
<pre>
import numpy as np
from fmpy import simulate_fmu
w = 2*np.pi*65/60
t = np.linspace(0, 3, 3001)
sig = np.zeros(t.size, dtype=[('time', float), ('crank.angle', float), ('crank.speed', float)])
sig['time'], sig['crank.angle'], sig['crank.speed'] = t, w*t, w
res = simulate_fmu('ReciprocatingDrive.fmu', stop_time=3, output_interval=1e-3, input=sig,
                   start_values={'mass.reciprocating': 300.0},
                   output=['suspension.position', 'suspension.acceleration', 'inertia.force', 'crank.torque'])
</pre>

<h2>Using it from libcosim (libcosimpy)</h2>
<pre>
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimSlave import CosimLocalSlave
ex = CosimExecution.from_step_size(step_size=int(1e6))          # 1 ms, in ns
idx = ex.add_local_slave(CosimLocalSlave(fmu_path='ReciprocatingDrive.fmu', instance_name='pump'))
# drive crank.angle / crank.speed from another slave through connections, or with a manipulator
</pre>
"#;

pub fn generate() -> String {
    let mut h = String::new();
    h.push_str("<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>ReciprocatingDrive FMU</title>\n");
    h.push_str("<style>body{font-family:sans-serif;max-width:70em;margin:auto}td,th{border:1px solid #ccc;padding:2px 6px;vertical-align:top}table{border-collapse:collapse}code{background:#f4f4f4}</style>\n");
    h.push_str("</head><body>\n<h1>ReciprocatingDrive</h1>\n");
    h.push_str(CONVENTIONS);
    h.push_str("\n<h2>Variables</h2>\n<table><tr><th>name</th><th>vr</th><th>causality</th><th>type</th><th>unit</th><th>start</th><th>allowed</th><th>description</th></tr>\n");
    for (vr, v) in VARIABLES.iter().enumerate() {
        let causality = match (v.causality, v.variability) {
            (Causality::Parameter, Variability::Tunable) => "parameter (tunable)",
            (Causality::Parameter, _) => "parameter",
            (Causality::CalculatedParameter, _) => "calculated parameter",
            (Causality::Input, _) => "input",
            (Causality::Output, _) => "output",
        };
        let start = v.start().map(|s| format!("{s}")).unwrap_or_default();
        let allowed = if v.causality == Causality::Parameter { v.range.describe("") } else { String::new() };
        let ty = match v.ty {
            VarType::Real => "Real",
            VarType::Integer => "Integer",
            VarType::Boolean => "Boolean",
        };
        let _ = writeln!(
            h,
            "<tr><td><code>{}</code></td><td>{vr}</td><td>{causality}</td><td>{ty}</td><td>{}</td><td>{start}</td><td>{}</td><td>{}</td></tr>",
            v.name,
            v.unit,
            allowed.replace("a finite number in ", ""),
            v.description.replace('&', "&amp;").replace('<', "&lt;")
        );
    }
    h.push_str("</table>\n</body></html>\n");
    h
}
