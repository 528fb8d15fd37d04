"""Independent reference for the crank-slider (docs/model.md §2, §3.1, §4), evaluated with mpmath at
30 significant digits. It shares no code and no formula with the FMU: the FMU uses the closed-form
derivatives of §3.1; here only the vector loop is written down, and every derivative is taken
numerically by mpmath.diff (at 30 digits, so its own error is far below double precision).

Vector loop: crank pin (r cos θ, r sin θ); crosshead on the line y = e at distance X from the crank
centre along the stroke axis, |pin − crosshead| = l:

    X(θ) = r cos θ + sqrt(l² − (r sin θ − e)²),     s = X_max − X(θ),
    X_max = sqrt((l + r)² − e²)  (crank and rod in line: the farthest crosshead position),
    β(θ) = asin((r sin θ − e) / l)  (rod angle from the stroke axis).
"""

from __future__ import annotations

from dataclasses import dataclass

import mpmath

DPS = 30

# Outputs the reference computes, in FMU naming (docs/model.md §10).
OUTPUTS = (
    "suspension.position",
    "suspension.velocity",
    "suspension.acceleration",
    "kinematics.torque_factor",
    "inertia.force",
    "rod.force",
    "crank.torque",
    "rod.angle",
    "rod.angular_velocity",
)


@dataclass
class Machine:
    """The parameters the reference needs; defaults = the default machine of docs/model.md §8."""

    r: float = 0.2
    l: float = 1.19
    e: float = 0.0
    m: float = 300.0
    angle_offset: float = 0.0
    load_mean: float = 0.0
    load_amplitude: float = 0.0
    load_phase: float = 0.0

    def start_values(self) -> dict:
        """The same machine as FMU start values (the names of docs/model.md §10). The reference has
        no guide friction, so the FMU's friction model is switched off (every support kind 0,
        docs/model.md §5.2); friction is tested in test_guide_friction.py."""
        return {
            "support_A.kind": 0,
            "support_B.kind": 0,
            "support_C.kind": 0,
            "geometry.crank_radius": self.r,
            "geometry.rod_length": self.l,
            "geometry.slider_offset": self.e,
            "mass.reciprocating": self.m,
            "crank.angle_offset": self.angle_offset,
            "load.profile": 0,
            "load.mean": self.load_mean,
            "load.amplitude": self.load_amplitude,
            "load.phase": self.load_phase,
        }

    # ---- geometry at 30 digits
    def _X(self, th):
        r, l, e = mpmath.mpf(self.r), mpmath.mpf(self.l), mpmath.mpf(self.e)
        return r * mpmath.cos(th) + mpmath.sqrt(l**2 - (r * mpmath.sin(th) - e) ** 2)

    def _beta(self, th):
        r, l, e = mpmath.mpf(self.r), mpmath.mpf(self.l), mpmath.mpf(self.e)
        return mpmath.asin((r * mpmath.sin(th) - e) / l)

    def xmax(self):
        r, l, e = mpmath.mpf(self.r), mpmath.mpf(self.l), mpmath.mpf(self.e)
        return mpmath.sqrt((l + r) ** 2 - e**2)

    def outputs(self, theta_in, omega, eps=0.0, f_ext=0.0) -> dict:
        """All outputs at input angle θ_in (model angle θ = θ_in + offset), speed ω, acceleration
        ε and input process force F_ext. Returns floats."""
        with mpmath.workdps(DPS):
            vals = self.outputs_mp(theta_in, omega, eps, f_ext)
            return {k: float(x) for k, x in vals.items()}

    def outputs_mp(self, theta_in, omega, eps=0.0, f_ext=0.0) -> dict:
        """`outputs` as mpf, at DPS digits or the caller's higher precision (mpmath.diff raises it
        to differentiate)."""
        with mpmath.workdps(max(DPS, mpmath.mp.dps)):
            th = mpmath.mpf(theta_in) + mpmath.mpf(self.angle_offset)
            w, ep = mpmath.mpf(omega), mpmath.mpf(eps)
            s = self.xmax() - self._X(th)
            tf = -mpmath.diff(self._X, th, 1)
            tf2 = -mpmath.diff(self._X, th, 2)
            v = tf * w
            a = tf * ep + tf2 * w**2
            phi = -mpmath.mpf(self.m) * a
            # Process force, profile 0 (docs/model.md §4) + the input.
            f = (
                mpmath.mpf(f_ext)
                + mpmath.mpf(self.load_mean)
                + mpmath.mpf(self.load_amplitude) * mpmath.cos(th + mpmath.mpf(self.load_phase))
            )
            p = f + phi
            torque = -p * tf
            beta = self._beta(th)
            beta_dot = mpmath.diff(self._beta, th, 1) * w
            vals = (s, v, a, tf, phi, p, torque, beta, beta_dot)
            return dict(zip(OUTPUTS, vals))

    def scales(self, omega, eps=0.0, f_ext=0.0) -> dict:
        """The natural magnitude of each output, to make tolerances relative to it."""
        r, l, m = self.r, self.l, self.m
        w2 = omega**2 + abs(eps)
        force = m * r * w2 + abs(f_ext) + abs(self.load_mean) + abs(self.load_amplitude)
        return {
            "suspension.position": r,
            "suspension.velocity": r * abs(omega),
            "suspension.acceleration": r * w2,
            "kinematics.torque_factor": r,
            "inertia.force": m * r * w2,
            "rod.force": force,
            "crank.torque": force * r,
            "rod.angle": r / l,
            "rod.angular_velocity": r / l * abs(omega),
        }

    def odc_check(self):
        """Self-check of the reference: X_max is the maximum of X (X'(θ*) = 0 near θ = 0 with
        X(θ*) = X_max), so s ≥ 0 with s = 0 at the outer dead centre."""
        with mpmath.workdps(DPS):
            th = mpmath.findroot(lambda t: mpmath.diff(self._X, t, 1), mpmath.mpf(0))
            return float(th), float(self._X(th) - self.xmax())
