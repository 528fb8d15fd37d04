"""Independent reference for the elastic connecting rod clamped in the piston (docs/model.md §6, with
§2, §4, §5.3-5.4), written from the specification alone in plain Python (math module) + scipy.
It shares no code with the FMU and deliberately takes other routes where the FMU has a choice:

* fundamental functions: power series only for |x z²| <= 1 (summed until the terms vanish),
  cos/sin or cosh/sinh beyond (the FMU switches at 4 with a fixed 12-term Horner series);
* W*, W and w_Δ in the literal §6 product forms (the FMU uses rearranged, cancellation-free
  identities), C(z_j), S(z_j) at each stress station directly (the FMU uses addition theorems);
* the link carrying the rod clamp: only the statically determinate layout of kvo630 (a single
  two-edge guide B moving with the link, no misalignment, rigid), whose reactions follow from the
  two equilibrium equations of the link (the FMU solves a general beam problem by flexibilities);
  friction as f·(|N1| + |N2|) from the edge forces (the FMU uses f·max(|R|, 2|M|/l_n));
* the rod force P = F_ext + Φ + F_fr(P) by scipy's brentq on a bracket (the FMU iterates a fixed
  point);
* the cage equation integrated by scipy's solve_ivp (DOP853 or Radau) at rtol ~1e-11 on the exact
  crank motion θ(t), ω(t), ε(t) (the FMU: Verner 6(5) inside each communication step).

Sign conventions (docs/model.md §5.3): lateral forces on the link along +y, moments positive when they
turn +z toward +y; z along the link from the piston end (0) to the clamp (L). The rod exerts on the
link at z = L the moment M_0 = A2·C3/s_N and the force V = -A2·C4/s_N² (§5.4). Equilibrium of the
link loaded by these, the lateral load Q at B's centre z_B and B's reaction (R_B, M_B about z_B):

    R_B + V + Q = 0,          M_B + M_0 + (L - z_B)·V = 0.

(Checked in the Euler-Bernoulli limit, P = 0, f = 0, ϑ = 0: the rod is a beam clamped at both ends
with end offset Δ; the support at its clamp exerts R = -12·A2·Δ/l³, M = -6·A2·Δ/l² on it (§5.5),
so the rod exerts V = +12·A2·Δ/l³, M_0 = +6·A2·Δ/l² on the link: C3 = 6Δ/l², C4 = -12Δ/l³.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

SHEAR_FACTOR_THIN_ROD = 0.9
SERIES_CUT = 1.0  # |u| = |x z²| up to which the power series is summed


class Buckled(Exception):
    """s_N <= 0 or K_ϑ <= 0 (or W* <= 0): the rod is at or beyond its buckling load."""


def fundamental(x: float, z: float) -> tuple[float, float, float, float]:
    """C, S, V3, V4 of v'''' - x v'' = 0 at z (docs/model.md §6)."""
    u = x * z * z
    if abs(u) <= SERIES_CUT:
        # C = Σ uⁿ/(2n)!, S = z Σ uⁿ/(2n+1)!, V3 = z² Σ uⁿ/(2n+2)!, V4 = z³ Σ uⁿ/(2n+3)!
        sums = [0.0, 0.0, 0.0, 0.0]
        for k in range(4):
            term = 1.0 / math.factorial(k)  # n = 0 term of Σ uⁿ/(2n+k)!
            n = 0
            while True:
                sums[k] += term
                n += 1
                term *= u / ((2 * n + k - 1) * (2 * n + k))
                if abs(term) < 1e-19 * abs(sums[k]) or n > 60:
                    break
        return sums[0], z * sums[1], z * z * sums[2], z**3 * sums[3]
    if x > 0:
        a = math.sqrt(x)
        c, s = math.cosh(a * z), math.sinh(a * z) / a
    else:
        a = math.sqrt(-x)
        c, s = math.cos(a * z), math.sin(a * z) / a
    return c, s, (c - 1.0) / x, (s - z) / x


@dataclass
class RodColumn:
    """Everything §6 defines at one rod force P (compression positive)."""

    P: float
    s_n: float
    x: float
    eta: float
    f1: float
    c: float
    s: float
    v3: float
    v4: float
    e_bar: float
    d_bar: float
    w_star: float
    k_theta: float
    k_delta: float


class Rod:
    """The elastic rod's stiffnesses A1, A2, A3 and P-dependent coefficients (docs/model.md §6)."""

    def __init__(
        self,
        kind: int,
        flex_length: float,
        rigid_length: float,
        wire_diameter: float,
        coil_diameter: float,
        coils: float,
        e_modulus: float,
        poisson: float,
    ):
        self.kind, self.l, self.f = kind, flex_length, rigid_length
        self.d, self.D, self.i = wire_diameter, coil_diameter, coils
        E, d = e_modulus, wire_diameter
        G = E / (2.0 * (1.0 + poisson))
        if kind == 1:
            self.a2 = E * math.pi * d**4 / 64.0
            self.a1 = SHEAR_FACTOR_THIN_ROD * G * math.pi * d**2 / 4.0
            self.a3 = E * math.pi * d**2 / 4.0
        elif kind == 2:
            h = flex_length / coils  # pitch
            bt = G * math.pi * d**4 / 32.0
            bb = E * math.pi * d**4 / 64.0
            D3 = math.pi * coil_diameter**3
            self.a1 = 8.0 * h * bb / D3
            self.a3 = 4.0 * h * bt / D3
            self.a2 = (2.0 * h / (math.pi * coil_diameter)) * bt * bb / (bt + bb)
        else:
            raise ValueError(f"rod.kind {kind}")

    @classmethod
    def from_values(cls, v: dict) -> Rod:
        return cls(
            int(v["rod.kind"]),
            v["rod.flex_length"],
            v["rod.rigid_length"],
            v["rod.wire_diameter"],
            v["rod.coil_diameter"],
            v["rod.coils"],
            v["rod.E"],
            v["rod.poisson"],
        )

    def column(self, P: float) -> RodColumn:
        a1, a2, l = self.a1, self.a2, self.l
        N = -P
        s_n = 1.0 - N / a1
        if not s_n > 0:
            raise Buckled(f"s_N = {s_n}")
        x = N * s_n / a2
        eta = a2 / (a1 * s_n * s_n)
        f1 = self.f / s_n
        c, s, v3, v4 = fundamental(x, l)
        # V3' = S, V3'' = C, V3''' = x S, V4' = V3, V4'' = S, V4''' = C
        e_bar = v3 + f1 * s
        d_bar = v4 + f1 * v3 - eta * l
        l3 = c + f1 * x * s
        l4 = s + f1 * c
        w_star = v3 * v3 - s * v4 + eta * l * s
        w = e_bar * l4 - d_bar * l3
        w_delta = s * l4 - v3 * l3
        k_theta = a2 * w / w_star
        k_delta = a2 * w_delta / (s_n * w_star)
        if x < 0 and math.sqrt(-x) * l >= 2 * math.pi or not (w_star > 0 and k_theta > 0):
            raise Buckled(f"P = {P}: W* = {w_star}, K_theta = {k_theta}")
        return RodColumn(P, s_n, x, eta, f1, c, s, v3, v4, e_bar, d_bar, w_star, k_theta, k_delta)

    def constants(self, col: RodColumn, delta: float, theta: float) -> tuple[float, float]:
        c3 = (col.v3 * delta - col.s_n * col.d_bar * theta) / col.w_star
        c4 = (col.s_n * col.e_bar * theta - col.s * delta) / col.w_star
        return c3, c4

    def clamp_loads(self, col: RodColumn, delta: float, theta: float) -> tuple[float, float]:
        """(M_0, V) the rod exerts on the link at the clamp (§5.4)."""
        c3, c4 = self.constants(col, delta, theta)
        return self.a2 * c3 / col.s_n, -self.a2 * c4 / col.s_n**2

    def stations(self) -> int:
        return 16 if self.kind == 1 else int(math.ceil(self.i))

    def stress_max(self, col: RodColumn, delta: float, theta: float) -> float:
        c3, c4 = self.constants(col, delta, theta)
        n = self.stations()
        m_max = 0.0
        for j in range(n + 1):
            c, s, _, _ = fundamental(col.x, j * self.l / n)
            m_max = max(m_max, abs(self.a2 / col.s_n * (c3 * c + c4 * s)))
        N = abs(col.P)
        d = self.d
        if self.kind == 2:
            ci = self.D / d
            kw = (4 * ci - 1) / (4 * ci - 4) + 0.615 / ci
            return kw * (m_max + N * self.D / 2) / (math.pi * d**3 / 16)
        return m_max * 32 / (math.pi * d**3) + N * 4 / (math.pi * d**2)


# ------------------------------------------------------------------------------ crank motion


@dataclass
class Motion:
    """θ_in(t) = θ0 + ω0 t + ε t²/2 (the crank input the master supplies, exactly)."""

    omega0: float
    eps: float = 0.0
    theta0: float = 0.0

    def at(self, t: float) -> tuple[float, float, float]:
        return (
            self.theta0 + self.omega0 * t + 0.5 * self.eps * t * t,
            self.omega0 + self.eps * t,
            self.eps,
        )


# ------------------------------------------------------------------------------ the drive


class Drive:
    """Crank-slider with an elastic rod clamped in the piston (docs/model.md §6) on a link that is
    either unsupported (all support kinds 0: no friction) or held by a single two-edge guide B
    moving with the link, aligned and rigid (kvo630). Values by FMU variable name."""

    def __init__(self, v: dict):
        self.v = dict(v)
        assert int(v["mechanism"]) == 1 and int(v["rod.kind"]) in (1, 2)
        self.rod = Rod.from_values(v)
        self.r, self.e = v["geometry.crank_radius"], v["geometry.slider_offset"]
        self.offset = v.get("crank.angle_offset", 0.0)
        self.m = v["mass.reciprocating"]
        self.profile = int(v["load.profile"])
        self.mean, self.amp, self.phase = v["load.mean"], v["load.amplitude"], v["load.phase"]
        self.v_eps = v["guide.velocity_scale"]
        self.J = v["rod.cage_inertia"]
        self.e_p = v["rod.load_eccentricity"]
        self.mf_fm = v["rod.rigid_mass"] * v["rod.rigid_lever"]
        k0 = self.rod.column(0.0).k_theta
        self.omega0 = math.sqrt(k0 / self.J)
        self.B = (
            v["rod.damping"]
            if v["rod.damping"] > 0
            else 2 * v["rod.damping_ratio"] * math.sqrt(k0 * self.J)
        )
        kinds = [int(v[f"support_{x}.kind"]) for x in "ABC"]
        self.guide = kinds[1] == 3 and kinds[0] == 0 and kinds[2] == 0
        if not self.guide:
            assert kinds == [0, 0, 0], "the reference knows no other support layout"
        else:
            assert int(v["support_B.attached"]) == 0
            for k in ("offset", "tilt", "stiffness"):
                assert v[f"support_B.{k}"] == 0.0, k
            assert bool(v["guide.rod_side_force"])
            self.L = sum(v[f"link.l{i}"] for i in range(1, 5))
            self.z_b = v["support_B.z"]
            self.l_n = v["support_B.length"]
            self.mu = v["guide.friction_coefficient"]
            self.q_lat = v["link.lateral_load"]

    # -- one instant ------------------------------------------------------------------------

    def kinematics(self, theta_in: float, w: float, eps: float) -> dict:
        th = theta_in + self.offset
        r, sn, cs = self.r, math.sin(th), math.cos(th)
        return dict(
            theta=th,
            s=r * (1 - cs),
            v=r * sn * w,
            a=r * sn * eps + r * cs * w * w,
            delta=r * sn - self.e,
            delta_dot=r * cs * w,
            delta_ddot=r * (eps * cs - w * w * sn),
        )

    def p_base(self, k: dict, f_ext_input: float) -> float:
        if self.profile == 0:
            f = self.mean + self.amp * math.cos(k["theta"] + self.phase)
        elif self.profile == 1:
            f = -self.mean * math.tanh(k["v"] / self.v_eps)
        else:
            f = self.mean * (1 - math.tanh(k["v"] / self.v_eps)) / 2
        return f_ext_input + f - self.m * k["a"]

    def guide_state(self, P: float, delta: float, theta: float, v: float) -> dict:
        """Reaction, moment, edge forces and friction of B at rod force P."""
        if not self.guide:
            return dict(R=0.0, M=0.0, N1=0.0, N2=0.0, F=0.0)
        m0, vc = self.rod.clamp_loads(self.rod.column(P), delta, theta)
        R = -vc - self.q_lat
        M = -m0 - (self.L - self.z_b) * vc
        n1, n2 = R / 2 + M / self.l_n, R / 2 - M / self.l_n
        F = -self.mu * (abs(n1) + abs(n2)) * math.tanh(v / self.v_eps)
        return dict(R=R, M=M, N1=n1, N2=n2, F=F)

    def rod_force(self, k: dict, theta: float, f_ext_input: float = 0.0) -> float:
        """P = F_ext + Φ + F_fr(P) by brentq."""
        pb = self.p_base(k, f_ext_input)
        if not self.guide or k["v"] == 0.0:
            return pb

        def g(P):
            return P - pb - self.guide_state(P, k["delta"], theta, k["v"])["F"]

        g0 = g(pb)
        if g0 == 0.0:
            return pb
        width = 2.0 * abs(g0) + 1e-12
        for _ in range(60):
            lo, hi = pb - width, pb + width
            try:
                if g(lo) < 0 < g(hi):
                    break
            except Buckled:
                pass
            width *= 1.5
        else:
            raise RuntimeError("no bracket for P")
        return brentq(g, lo, hi, xtol=1e-15 * max(1.0, abs(pb)), rtol=1e-15, maxiter=200)

    def accel(self, k: dict, P: float, theta: float, rate: float) -> float:
        col = self.rod.column(P)
        return (
            col.k_delta * k["delta"]
            + self.e_p * P
            + self.mf_fm * k["delta_ddot"]
            - self.B * rate
            - col.k_theta * theta
        ) / self.J

    def outputs(self, k: dict, theta: float, rate: float, f_ext_input: float = 0.0) -> dict:
        P = self.rod_force(k, theta, f_ext_input)
        col = self.rod.column(P)
        g = self.guide_state(P, k["delta"], theta, k["v"])
        return {
            "rod.angle": theta,
            "rod.angular_velocity": rate,
            "rod.force": P,
            "rod.stress_max": self.rod.stress_max(col, k["delta"], theta),
            "guide.friction": g["F"],
            "guide.reaction": g["R"],
            "guide.moment": g["M"],
            "rod.axial_deflection": P * self.rod.l / self.rod.a3,
        }

    # -- initial state and integration -------------------------------------------------------

    def initial_state(self, motion: Motion, f_ext_input: float = 0.0) -> tuple[float, float]:
        """rod.initial_state = 1: K_ϑ ϑ = K_Δ Δ + e_P P + m_f f_m Δ̈ together with P(ϑ);
        ϑ̇ = K_Δ Δ̇ / K_ϑ with P fixed."""
        k = self.kinematics(*motion.at(0.0))
        theta = 0.0
        for _ in range(200):
            P = self.rod_force(k, theta, f_ext_input)
            col = self.rod.column(P)
            new = (
                col.k_delta * k["delta"] + self.e_p * P + self.mf_fm * k["delta_ddot"]
            ) / col.k_theta
            if abs(new - theta) <= 1e-16 * max(abs(new), 1e-300):
                theta = new
                break
            theta = new
        P = self.rod_force(k, theta, f_ext_input)
        col = self.rod.column(P)
        return theta, col.k_delta * k["delta_dot"] / col.k_theta

    def rhs(self, motion: Motion, f_ext_input: float = 0.0):
        def f(t, y):
            k = self.kinematics(*motion.at(t))
            P = self.rod_force(k, y[0], f_ext_input)
            return [y[1], self.accel(k, P, y[0], y[1])]

        return f

    def integrate(
        self,
        motion: Motion,
        times,
        y0=None,
        method="DOP853",
        rtol=1e-11,
        atol_theta=1e-14,
        f_ext_input: float = 0.0,
    ):
        """ϑ, ϑ̇ at `times` (from times[0] = 0). atol on ϑ̇ is atol_theta·Ω0 (the FMU's scaling)."""
        times = np.asarray(times, dtype=float)
        if y0 is None:
            y0 = self.initial_state(motion, f_ext_input)
        sol = solve_ivp(
            self.rhs(motion, f_ext_input),
            (times[0], times[-1]),
            list(y0),
            method=method,
            t_eval=times,
            rtol=rtol,
            atol=[atol_theta, atol_theta * self.omega0],
        )
        assert sol.success, sol.message
        return sol

    def outputs_along(self, motion: Motion, times, y, f_ext_input: float = 0.0) -> dict:
        rows = [
            self.outputs(self.kinematics(*motion.at(t)), th, rt, f_ext_input)
            for t, th, rt in zip(times, y[0], y[1])
        ]
        return {n: np.array([r[n] for r in rows]) for n in rows[0]}
