//! The ReciprocatingDrive FMU's documentation/index.html text before the generated variable list:
//! the conventions a user needs (from docs/model.md).

pub const CONVENTIONS: &str = r#"
<h2>What it is</h2>
<p>A co-simulation FMU (FMI 2.0) of a crank-driven reciprocating mechanism. The master supplies the crank
motion (angle, speed, optionally angular acceleration) and optionally a process force; the FMU returns the
exact kinematics of the link (the "suspension point"), its inertia load, the guide friction caused by the
link's redundant supports, the rod force, the crank torque, support reactions, the balancer force and, for
an elastic connecting rod clamped in the piston, the rod's angular oscillation (integrated inside the FMU)
and its stress.</p>
<ul>
<li><code>mechanism</code> 1: crank-slider with optional guide offset (drilling mud pump, compressor, small piston machine);</li>
<li><code>mechanism</code> 2: beam pumping unit, conventional (API class I); 3: class III (Mark II / air balanced), API 11E notation;</li>
<li><code>rod.kind</code> 1 (thin rod) or 2 (helical spring): elastic connecting rod clamped in the piston (crank-slider only).</li>
</ul>

<h2>Conventions</h2>
<ul>
<li>SI units throughout; angles in radians.</li>
<li><b>Model angle</b> &theta; = <code>crank.angle</code> + <code>crank.angle_offset</code>; it increases in the direction of rotation.</li>
<li><b>Crank-slider angle origin</b>: &theta; = 0 with the crank pointing along the stroke axis toward the crosshead; for zero
offset that is the outer dead centre (crosshead farthest from the crank axis). <code>rotation</code> is ignored.</li>
<li><b>Beam units</b>: API 11E convention, &theta; = 0 with the crank at 12 o'clock, the unit viewed with the well on the right;
<code>rotation</code> = +1 clockwise, &minus;1 counter-clockwise. Seed 001's angle &phi;1 (from the line of centres, counter-clockwise)
is &phi;1 = &theta; + 90&deg; &minus; atan2(H&minus;G, I). For a class III unit the upstroke takes more than 180&deg; of crank rotation
with <code>rotation</code> = &minus;1.</li>
<li><b>Stroke coordinate</b> <code>suspension.position</code> s: 0 at the outer end of the stroke (outer dead centre of the slider,
bottom of stroke of a beam unit), increasing toward the crank (slider) or upward (beam unit). v = ds/dt, a = d&sup2;s/dt&sup2;;
in steady rotation a &gt; 0 at the outer end.</li>
<li><b>Torque factor</b> TF = ds/d&theta; [m/rad]; v = TF&middot;&omega;, a = TF&middot;&epsilon; + TF'&middot;&omega;&sup2;, computed from the exact
position function by analytic derivatives (no series approximation). With an elastic rod the piston follows the
crank pin's axial coordinate, s = r(1 &minus; cos&theta;) (first-order theory of the clamped rod).</li>
<li><b>Forces</b> on the link are positive along +s. Inertia force &Phi; = &minus;m&middot;a. Process force F_ext = input
<code>link.external_force</code> + the <code>load.profile</code> force (for a beam unit the polished-rod load pulls down: negative).
Rod force P = F_ext + &Phi; + F_fr + F_bal (compression positive), solved exactly although the friction depends on P.
Crank torque T = &minus;P&middot;TF is the torque the drive supplies (T&middot;&omega; = &minus;P&middot;v); an elastic rod adds the work of its
lateral pin force.</li>
<li><b>Guide friction</b>: the link is a stepped Euler&ndash;Bernoulli beam (z = 0 at the piston end) on up to three supports
A, B (the guide), C, each a pin, clamp or two-edge guide, moving with the link or fixed in the frame, possibly offset,
tilted and elastic. Lateral forces are positive along +y, moments positive when they turn +z toward +y. For B,
N1 = R/2 + M/l (crank-side edge), N2 = R/2 &minus; M/l, friction magnitude f&middot;(|N1| + |N2|), signed
&minus;|F|&middot;tanh(v/v_&epsilon;). With every support kind 0 the friction model is off.</li>
<li><b>Rod angle</b>: crank-slider &beta; from l&middot;sin&beta; = r&middot;sin&theta; &minus; e; beam unit: the pitman's inclination from the vertical,
positive when its crank-pin end is nearer the well; elastic rod: the rotation &theta;<sub>cage</sub> of its lower cage on the pin,
the FMU's continuous state, integrated with error control to the tolerance of fmi2SetupExperiment (else
<code>solver.tolerance</code>). A warning (category logStatusWarning) is logged when it exceeds 0.2 rad.</li>
<li><b>Inside a communication step</b> the FMU extrapolates the crank with constant acceleration:
&theta;(t+&tau;) = &theta; + &omega;&tau; + &epsilon;&tau;&sup2;/2. At the next communication point the master's inputs are authoritative.
Masters that vary the speed should supply <code>crank.acceleration</code>.</li>
<li>Outputs reflect inputs set since the last step (direct feedthrough, declared in ModelStructure).</li>
</ul>

<h2>Presets</h2>
<p>Complete parameter sets as SSP parameter-value files in <code>resources/presets/</code>: <code>unb600a</code> (UNB-600 duplex
double-acting drilling pump loaded by its pressures), <code>unb600a-simplex</code> (one of its cylinders with a double-acting pump
load), <code>triplex-1600</code> (triplex single-acting drilling pump, 1 600 hp class), <code>sk8-3.5-4000</code> (beam pumping unit, seed 001), <code>kvo630</code> (small cryogenic machine with a
helical-spring connecting rod). Apply one in fmpy as <code>start_values</code> (the repository's <code>scripts/presets.py</code>
reads them); each also gives the start value of <code>crank.speed</code> (the pump presets also of
<code>fluid_end.discharge_pressure</code> and <code>fluid_end.suction_pressure</code>).</p>

<h2>Errors</h2>
<p>Invalid parameters (out of range, a linkage that cannot assemble, supports that do not hold the link or leave it
during the stroke, a rod at or above its buckling load) make <code>fmi2ExitInitializationMode</code> return fmi2Error with a
message naming the variable, its value and the allowed range; the instance stays in initialization mode so the value
can be corrected. A non-finite input is refused by <code>fmi2SetReal</code> and not stored. A failed step (buckled rod)
leaves the FMU's state as it was. A rigid mechanism's outputs are evaluated when <code>fmi2GetReal</code> asks for them
(only the groups read: kinematics, loads, forces), so a guide that self-locks at the new crank angle is reported by the
<code>fmi2GetReal</code> of a force, while the kinematics stay readable. FMU states can be saved, restored and
serialized.</p>

<h2>Using it from fmpy</h2>
<pre>
import numpy as np
from fmpy import simulate_fmu
w = 2*np.pi*65/60
t = np.linspace(0, 3, 3001)
sig = np.zeros(t.size, dtype=[('time', float), ('crank.angle', float), ('crank.speed', float)])
sig['time'], sig['crank.angle'], sig['crank.speed'] = t, w*t, w
res = simulate_fmu('ReciprocatingDrive.fmu', stop_time=3, output_interval=1e-3, input=sig,
                   start_values={'load.profile': 1, 'load.mean': 150e3},
                   output=['suspension.position', 'suspension.acceleration', 'inertia.force',
                           'guide.friction', 'crank.torque'])
</pre>

<h2>Using it from libcosim (libcosimpy)</h2>
<pre>
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimSlave import CosimLocalSlave
ex = CosimExecution.from_step_size(step_size=int(1e6))          # 1 ms, in ns
idx = ex.add_local_slave(CosimLocalSlave(fmu_path='ReciprocatingDrive.fmu', instance_name='pump'))
# parameters: ex.real_initial_value / integer_initial_value / boolean_initial_value;
# drive crank.angle / crank.speed from another slave through connections, or with a manipulator
</pre>
"#;
