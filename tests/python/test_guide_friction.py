"""Guide friction from the link's redundant supports (docs/model.md §4, §5) through fmpy, against an
independent model written here.

The independent model (class `BeamFE`) solves the §5 beam problem by a different method from
production: production uses the flexibility method on the free link with closed-form Mohr
integrals (src/model/guide/link_beam.rs, supports.rs); here the link is an Euler–Bernoulli
finite-element model with Hermite cubic elements, nodes at every section boundary, contact point
and load point (re-meshed at every s, because frame-fixed contacts slide along the link), elastic
contacts as springs in the stiffness matrix, rigid contacts (lateral and a clamp's slope) as
Lagrange multipliers, and the reactions read from the multipliers and spring forces. Hermite cubics
reproduce the exact deflection of a prismatic beam under end loads, so with nodes at every point
load and every change of EJ the FE solution is exact: the comparison is limited by rounding only.
Everything else is written from docs/model.md as well: the prescribed support displacements
y = δ + α(Z − Z_ref) of §5.2 in frame coordinates (Z = z + s; Z_ref = the frame position of the
support's centre at mid-stroke: z_X + S/2 for a support moving with the link, z_X for a
frame-fixed one, whose centre is at link coordinate z_X − s), the edge forces and friction law of
§5.3 as f·(|N1| + |N2|), the side load Q = −P·tanβ + link.lateral_load at B's centre (§5.4), the
exact crank-slider kinematics of §3.1 by differentiating the vector loop by hand, and the implicit
rod force P = F_ext + Φ + F_fr(P) solved by scipy's brentq.

Tolerances. A stiffness-method FE solve loses digits to cancellation: reactions of ~1e2–1e4 N are
differences of nodal forces up to ~1e7 N (a 0.3 m crosshead next to a 0.07 m rod, stiff contacts,
and more so on a finer mesh: in double precision the reactions move by ~1e-11 of their largest
value on the minimal mesh and by ~1e-9 with three extra nodes per element). So the reference is
assembled and solved in x87 extended precision (np.longdouble, 64-bit mantissa; own Gaussian
elimination, since numpy.linalg is double only). `test_reference_self_consistency` measures what
remains: against the same system solved in 40-digit mpmath ≤ 1e-13, and with extra nodes inserted
(the result must not change, §5.5) ≤ 1e-11 of the largest reaction; measured 4e-15 and 5e-13. The
FMU (double precision, flexibility method) agrees to ≤ 2e-11 of the largest magnitude of each
output over the revolution (the outputs cross zero, so a pointwise relative test is meaningless).
The tolerance RTOL = 1e-9 leaves a factor 50 over that, and is 1e5 times smaller than what a wrong
model produces (`test_reference_distinguishes_wrong_models`: Z_ref at s = 0 instead of mid-stroke
≥ 1e-4, the seed's friction formula ≥ 1e-2 of the largest friction; a support point misplaced by
1 mm or a one-step lag move the reactions by ~1e-3 to 1e-2).
"""

from __future__ import annotations

import math
import pathlib
import sys

import mpmath
import numpy as np
import pytest
from scipy.optimize import brentq

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "scripts"))
from reciprocating_drive.presets import preset_values  # noqa: E402

OMEGA = 2 * math.pi * 65 / 60
N_REV = 720  # points per revolution (0.5°)
RTOL = 1e-9

COMPARED = [
    "guide.friction",
    "guide.reaction",
    "guide.moment",
    "guide.edge_force_1",
    "guide.edge_force_2",
    "support_A.reaction",
    "support_C.reaction",
    "link.friction_total",
    "rod.force",
]


# ---------------------------------------------------------------------------------------------
# Parameters


def default_parameters(model_description) -> dict:
    """Start values of every parameter of the FMU (the default machine of docs/model.md §8)."""
    out = {}
    for v in model_description.modelVariables:
        if v.causality != "parameter" or v.start is None:
            continue
        if v.type == "Real":
            out[v.name] = float(v.start)
        elif v.type == "Integer":
            out[v.name] = int(v.start)
        elif v.type == "Boolean":
            out[v.name] = str(v.start).lower() in ("true", "1")
    return out


# Configuration (c): a frame-fixed elastic two-edge gland C with friction that the link slides
# through, tilted and offset axes everywhere, an elastic guide, a rubbing clamp A, a lateral load
# (weight) and a slider offset.
CONFIG_C = {
    "geometry.slider_offset": 0.02,
    "link.lateral_load": -3.0e3,
    "support_A.tilt": 5.0e-5,
    "support_A.friction": 0.05,
    "support_B.offset": -1.0e-4,
    "support_B.tilt": 2.0e-4,
    "support_B.stiffness": 5.0e7,
    "guide.friction_coefficient": 0.12,
    "support_C.kind": 3,
    "support_C.attached": 1,
    "support_C.z": 1.6,
    "support_C.length": 0.1,
    "support_C.offset": 1.5e-4,
    "support_C.tilt": 3.0e-4,
    "support_C.stiffness": 2.0e6,
    "support_C.friction": 0.1,
    "load.profile": 0,
    "load.mean": 2.0e4,
    "load.amplitude": 4.0e4,
    "load.phase": 0.5,
}


# ---------------------------------------------------------------------------------------------
# Independent reference


class Slider:
    """Exact crank-slider kinematics (docs/model.md §3.1) from the vector loop
    X(θ) = r cos θ + sqrt(l² − u²), u = r sin θ − e, differentiated by hand."""

    def __init__(self, r, l, e):
        self.r, self.l, self.e = r, l, e
        self.x_max = math.sqrt((l + r) ** 2 - e**2)
        self.x_min = math.sqrt((l - r) ** 2 - e**2)  # rod folded back over the crank
        self.stroke = self.x_max - self.x_min

    def at(self, th, w):
        r, l, e = self.r, self.l, self.e
        u, du, ddu = r * math.sin(th) - e, r * math.cos(th), -r * math.sin(th)
        root = math.sqrt(l * l - u * u)
        x = r * math.cos(th) + root
        dx = -r * math.sin(th) - u * du / root
        ddx = -r * math.cos(th) - (du * du + u * ddu) / root - (u * du) ** 2 / root**3
        s, tf, tfp = self.x_max - x, -dx, -ddx
        return {"s": s, "v": tf * w, "a": tfp * w * w, "tan_beta": u / root}


def solve_extended(A, B):
    """Gaussian elimination with partial pivoting in the dtype of A and B (np.longdouble here:
    numpy.linalg works in double precision only). Returns X with A X = B."""
    n = A.shape[0]
    M = np.concatenate([A, B], axis=1)
    for k in range(n):
        piv = k + int(np.argmax(np.abs(M[k:, k])))
        if M[piv, k] == 0:
            raise np.linalg.LinAlgError("singular beam problem")
        if piv != k:
            M[[k, piv]] = M[[piv, k]]
        M[k + 1 :, k:] -= np.outer(M[k + 1 :, k] / M[k, k], M[k, k:])
    X = np.zeros_like(B)
    for k in range(n - 1, -1, -1):
        X[k] = (M[k, n:] - M[k, k + 1 : n] @ X[k + 1 :]) / M[k, k]
    return X


class BeamFE:
    """The link of docs/model.md §5 as a Hermite-cubic beam FE model (see the module docstring)."""

    def __init__(self, p: dict, stroke: float):
        self.lengths = [p[f"link.l{i}"] for i in range(1, 5)]
        self.ej = [p["link.E"] * math.pi * p[f"link.d{i}"] ** 4 / 64 for i in range(1, 5)]
        self.L = sum(self.lengths)
        self.bounds = np.cumsum([0.0] + self.lengths)
        self.stroke = stroke
        self.lateral = p["link.lateral_load"]
        self.side_force = bool(p["guide.rod_side_force"])
        self.v_eps = p["guide.velocity_scale"]
        self.supports = []
        for x in "ABC":
            kind = p[f"support_{x}.kind"]
            if kind == 0:
                self.supports.append(None)
                continue
            self.supports.append(
                {
                    "kind": kind,
                    "frame_fixed": p[f"support_{x}.attached"] == 1,
                    "z": p[f"support_{x}.z"],
                    "offset": p[f"support_{x}.offset"],
                    "tilt": p[f"support_{x}.tilt"],
                    "length": p[f"support_{x}.length"],
                    "k": p[f"support_{x}.stiffness"],
                    "f": p["guide.friction_coefficient"]
                    if x == "B"
                    else p[f"support_{x}.friction"],
                }
            )

    def ej_at(self, z):
        for i in range(4):
            if self.lengths[i] > 0 and self.bounds[i] <= z <= self.bounds[i + 1]:
                return self.ej[i]
        raise ValueError(z)

    def centre(self, sup, s):
        """Link coordinate of a support's centre at stroke position s."""
        return sup["z"] - s if sup["frame_fixed"] else sup["z"]

    def contacts(self, s):
        """(support index, 'w' or 'slope', link coordinate, prescribed value, stiffness or 0)."""
        out = []
        for i, sup in enumerate(self.supports):
            if sup is None:
                continue
            zc = self.centre(sup, s)
            # Frame position of the centre at mid-stroke (Z = z + s at s = S/2).
            z_ref = (zc + 0.5 * self.stroke) if not sup["frame_fixed"] else sup["z"]

            def axis(z_link, sup=sup, z_ref=z_ref):
                return sup["offset"] + sup["tilt"] * ((z_link + s) - z_ref)

            if sup["kind"] == 1:
                pts = [zc]
            elif sup["kind"] == 2:
                pts = [zc]
                out.append((i, "slope", zc, sup["tilt"], 0.0))
            else:
                pts = [zc + sup["length"] / 2, zc - sup["length"] / 2]
            for z in pts:
                out.append((i, "w", z, axis(z), sup["k"]))
        return out

    def load_point(self, s):
        b = self.supports[1]
        return self.L if b is None else self.centre(b, s)

    def mesh(self, points, refine):
        """Sorted nodes including the section boundaries and `points`; `refine` equally spaced
        extra nodes inside every element."""
        base = sorted(set([float(b) for b in self.bounds] + [float(z) for z in points]))
        nodes = [base[0]]
        for z in base[1:]:
            if z - nodes[-1] > 1e-12 * self.L:
                nodes.append(z)
        if refine:
            fine = []
            for a, b in zip(nodes[:-1], nodes[1:]):
                fine.extend(a + (b - a) * k / (refine + 1) for k in range(refine + 1))
            nodes = fine + [nodes[-1]]
        return nodes

    def system(self, s, refine=0, num=float):
        """KKT matrix and two right-hand sides (column 0: prescribed displacements and the
        lateral load; column 1: a unit side load Q at the load point), in units N, m.
        `num` converts numbers (float or mpmath.mpf)."""
        cons = self.contacts(s)
        zq = self.load_point(s)
        nodes = self.mesh([c[2] for c in cons] + [zq], refine)
        index = lambda z: int(np.argmin([abs(z - n) for n in nodes]))  # noqa: E731
        n = len(nodes)
        rigid = [c for c in cons if c[1] == "slope" or c[4] == 0.0]
        m = len(rigid)
        size = 2 * n + m
        A = [[num(0)] * size for _ in range(size)]
        rhs = [[num(0), num(0)] for _ in range(size)]
        for e in range(n - 1):
            za, zb = nodes[e], nodes[e + 1]
            h = num(zb) - num(za)
            ej = num(self.ej_at(0.5 * (za + zb)))
            k = [
                [12, 6 * h, -12, 6 * h],
                [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                [-12, -6 * h, 12, -6 * h],
                [6 * h, 2 * h * h, -6 * h, 4 * h * h],
            ]
            dofs = [2 * e, 2 * e + 1, 2 * e + 2, 2 * e + 3]
            for i in range(4):
                for j in range(4):
                    A[dofs[i]][dofs[j]] += ej / h**3 * k[i][j]
        # Scale of the constraint rows (keeps partial pivoting meaningful): EJ/L³.
        c_scale = num(max(self.ej)) / num(self.L) ** 3
        row = 2 * n
        for _sup, dof, z, value, k in cons:
            node = index(z)
            d = 2 * node + (0 if dof == "w" else 1)
            if dof == "w" and k > 0:
                # Spring to the frame axis: force on the link k·(value − w).
                A[d][d] += num(k)
                rhs[d][0] += num(k) * num(value)
            else:
                A[d][row] += c_scale
                A[row][d] += c_scale
                rhs[row][0] = c_scale * num(value)
                row += 1
        q = 2 * index(zq)
        rhs[q][0] += num(self.lateral)
        rhs[q][1] += num(1)
        return A, rhs, cons, nodes, index, c_scale

    def _gather(self, sol, cons, index, c_scale, s, n, col):
        """Per support (R, M about its centre) from the solution column `col`."""
        out = [[0.0, 0.0] for _ in range(3)]
        row = 2 * n
        for sup, dof, z, value, k in cons:
            node = index(z)
            if dof == "w" and k > 0:
                w = sol[2 * node][col]
                force = k * ((value if col == 0 else 0.0) - w)
            else:
                force = -c_scale * sol[row][col]  # the multiplier's reaction on the link
                row += 1
            arm = z - self.centre(self.supports[sup], s)
            if dof == "w":
                out[sup][0] += force
                out[sup][1] += force * arm
            else:
                out[sup][1] += force
        return out

    def influence(self, s, refine=0):
        """Reactions (R, M) per support as base + Q·per_q, assembled and solved in x87 extended
        precision (np.longdouble, 64-bit mantissa) by `solve_extended`."""
        A, rhs, cons, nodes, index, c_scale = self.system(s, refine, num=np.longdouble)
        sol = solve_extended(np.array(A, dtype=np.longdouble), np.array(rhs, dtype=np.longdouble))
        base = self._gather(sol, cons, index, c_scale, s, len(nodes), 0)
        per_q = self._gather(sol, cons, index, c_scale, s, len(nodes), 1)
        return np.array(base, dtype=float), np.array(per_q, dtype=float)

    def influence_mp(self, s, dps=40):
        """The same in mpmath at `dps` digits (Gaussian elimination with partial pivoting)."""
        with mpmath.workdps(dps):
            A, rhs, cons, nodes, index, c_scale = self.system(s, 0, num=mpmath.mpf)
            M = mpmath.matrix(A)
            x = [mpmath.lu_solve(M, mpmath.matrix([r[j] for r in rhs])) for j in range(2)]
            cols = [[x[0][i], x[1][i]] for i in range(len(rhs))]
            base = self._gather(cols, cons, index, c_scale, s, len(nodes), 0)
            per_q = self._gather(cols, cons, index, c_scale, s, len(nodes), 1)
            return np.array([[float(x) for x in r] for r in base]), np.array(
                [[float(x) for x in r] for r in per_q]
            )

    def friction(self, rm, sign):
        """Signed friction of each support for reactions rm = [(R, M)] and sign = tanh(v/v_ε)."""
        out = np.zeros(3)
        for i, sup in enumerate(self.supports):
            if sup is None or sup["f"] == 0.0:
                continue
            r, m = rm[i]
            if sup["kind"] == 1 or sup["length"] == 0.0:
                mag = sup["f"] * abs(r)
            else:
                n1, n2 = r / 2 + m / sup["length"], r / 2 - m / sup["length"]
                mag = sup["f"] * (abs(n1) + abs(n2))
            out[i] = -mag * sign
        return out


class Reference:
    """The whole §4/§5 evaluation at one crank angle, for a parameter set."""

    def __init__(self, params: dict):
        p = params
        assert p["mechanism"] == 1 and p.get("rod.kind", 0) == 0  # rigid crank-slider rod
        self.p = p
        self.kin = Slider(
            p["geometry.crank_radius"], p["geometry.rod_length"], p["geometry.slider_offset"]
        )
        self.fe = BeamFE(p, self.kin.stroke)

    def process_force(self, th, v, f_input):
        p = self.p
        prof = p["load.profile"]
        if prof == 0:
            f = p["load.mean"] + p["load.amplitude"] * math.cos(th + p["load.phase"])
        elif prof == 1:
            f = -p["load.mean"] * math.tanh(v / p["guide.velocity_scale"])
        else:
            f = p["load.mean"] * (1 - math.tanh(v / p["guide.velocity_scale"])) / 2
        return f_input + f

    def at(self, theta_in, w, f_input=0.0, refine=0):
        p = self.p
        th = theta_in + p["crank.angle_offset"]
        k = self.kin.at(th, w)
        phi = -p["mass.reciprocating"] * k["a"]
        p_base = self.process_force(th, k["v"], f_input) + phi
        assert not p["balancer.enabled"]
        base, per_q = self.fe.influence(k["s"], refine)
        sign = math.tanh(k["v"] / self.fe.v_eps)
        dq = -k["tan_beta"] if self.fe.side_force else 0.0

        def reactions(P):
            return base + (P * dq) * per_q

        def h(P):
            return P - p_base - self.fe.friction(reactions(P), sign).sum()

        f0 = h(p_base)
        if f0 == 0.0:
            P = p_base
        else:
            width = 2 * abs(f0) + 1.0
            while h(p_base - width) * h(p_base + width) > 0:
                width *= 2
            P = brentq(
                h,
                p_base - width,
                p_base + width,
                xtol=1e-15 * (abs(p_base) + width),
                rtol=8.9e-16,
                maxiter=500,
            )
        rm = reactions(P)
        fr = self.fe.friction(rm, sign)
        b = self.fe.supports[1]
        r_b, m_b = rm[1]
        # §5.3 edge forces of a guide (or of a clamp with a length); otherwise R/2 each.
        if b is not None and b["kind"] in (2, 3) and b["length"] > 0:
            n1, n2 = r_b / 2 + m_b / b["length"], r_b / 2 - m_b / b["length"]
        else:
            n1 = n2 = r_b / 2
        return {
            "theta": th,
            "s": k["s"],
            "v": k["v"],
            "tan_beta": k["tan_beta"],
            "rod.force": P,
            "guide.friction": fr[1],
            "guide.reaction": r_b,
            "guide.moment": m_b,
            "guide.edge_force_1": n1,
            "guide.edge_force_2": n2,
            "support_A.reaction": rm[0][0],
            "support_C.reaction": rm[2][0],
            "link.friction_total": fr.sum(),
        }


# ---------------------------------------------------------------------------------------------
# The FMU


def run_fmu(fmu_path, start_values, n=N_REV, omega=OMEGA, revolutions=1, f_input=None):
    """fmpy.simulate_fmu over `revolutions` at constant speed: crank.angle = ω t as an input
    signal, `n` points per revolution, ε = 0, link.external_force = f_input(t) (default 0).
    fmpy sets the inputs of t_k, steps, and records at t_{k+1} the outputs at the FMU's
    extrapolated crank ω t_k + ω h = ω t_{k+1} (docs/model.md §2); the process-force input is held
    over the step, so the outputs at t_{k+1} carry f_input(t_k) (`input_force_at`)."""
    from fmpy import simulate_fmu

    h = 2 * math.pi / omega / n
    steps = n * revolutions
    t = np.arange(steps + 1) * h
    names = ["crank.angle", "crank.speed", "crank.acceleration", "link.external_force"]
    sig = np.zeros(t.size, dtype=[("time", float)] + [(x, float) for x in names])
    sig["time"], sig["crank.angle"], sig["crank.speed"] = t, omega * t, omega
    if f_input is not None:
        sig["link.external_force"] = [f_input(x) for x in t]
    return simulate_fmu(
        fmu_path,
        stop_time=t[-1],
        step_size=h,
        output_interval=h,
        input=sig,
        start_values=start_values,
        output=COMPARED
        + [
            "suspension.position",
            "suspension.velocity",
            "rod.angle",
            "crank.torque",
            "inertia.force",
        ],
    )


def input_force_at(t_all, f_input):
    """The process-force input the FMU used for the outputs recorded at each time (see run_fmu)."""
    if f_input is None:
        return np.zeros(len(t_all))
    t = np.asarray(t_all, dtype=float)
    h = t[1] - t[0]
    return np.array([f_input(max(x - h, 0.0)) if k > 0 else f_input(0.0) for k, x in enumerate(t)])


def compare(res, ref: Reference, label, omega=OMEGA, f_input=None):
    f_in = input_force_at(res["time"], f_input)
    rows = [ref.at(omega * float(t), omega, f_input=f) for t, f in zip(res["time"], f_in)]
    # Kinematics first (the reference's own §3.1 against the FMU's): a sanity check of the angles.
    for key, out in (("s", "suspension.position"), ("v", "suspension.velocity")):
        err = np.max(np.abs(np.array([r[key] for r in rows]) - res[out]))
        assert err < 1e-12, (label, out, err)
    worst = {}
    for name in COMPARED:
        fmu = np.asarray(res[name], dtype=float)
        want = np.array([r[name] for r in rows])
        scale = np.max(np.abs(want))
        assert scale > 0, (label, name)
        err = np.max(np.abs(fmu - want)) / scale
        worst[name] = err
        k = int(np.argmax(np.abs(fmu - want)))
        assert err <= RTOL, (
            f"{label}: {name} at θ = {math.degrees(rows[k]['theta']):.2f}°: FMU {fmu[k]!r}, "
            f"reference {want[k]!r}, error {err:.3g} of max |{name}| = {scale:.4g}"
        )
    return rows, worst


@pytest.fixture(scope="module")
def params(model_description):
    return default_parameters(model_description)


def unb600a_values():
    v = preset_values("unb600a-simplex")
    assert v["load.profile"] == 1 and v["load.mean"] == 150e3
    return v


# ---------------------------------------------------------------------------------------------
# Tests


def test_reference_reproduces_the_textbook_limits():
    """The FE reference itself against the closed forms of docs/model.md §5.5 (uniform beam)."""
    L, d, E = 2.0, 0.1, 2.1e11
    EJ = E * math.pi * d**4 / 64

    def beam(supports):
        p = {f"link.l{i}": 0.0 for i in range(1, 5)} | {f"link.d{i}": d for i in range(1, 5)}
        p |= {
            "link.l1": 1.2,
            "link.l2": 0.8,
            "link.E": E,
            "link.lateral_load": 0.0,
            "guide.rod_side_force": True,
            "guide.velocity_scale": 0.02,
            "guide.friction_coefficient": 0.0,
        }
        for x in "ABC":
            p |= {
                f"support_{x}.kind": 0,
                f"support_{x}.attached": 0,
                f"support_{x}.z": 0.0,
                f"support_{x}.offset": 0.0,
                f"support_{x}.tilt": 0.0,
                f"support_{x}.length": 0.0,
                f"support_{x}.stiffness": 0.0,
                f"support_{x}.friction": 0.0,
            }
        for x, vals in supports.items():
            p |= {f"support_{x}.{k}": v for k, v in vals.items()}
        return BeamFE(p, 0.0)

    delta = 1e-4
    # Clamp at 0, clamp at L displaced δ: R_L = 12EJδ/L³, M_L = −6EJδ/L².
    fe = beam({"A": {"kind": 2}, "C": {"kind": 2, "z": L, "offset": delta}})
    base, _ = fe.influence(0.0)
    assert base[2][0] == pytest.approx(12 * EJ * delta / L**3, rel=1e-10)
    assert base[2][1] == pytest.approx(-6 * EJ * delta / L**2, rel=1e-10)
    # Clamp at L turned by α: R_L = −6EJα/L², M_L = 4EJα/L, M_0 = 2EJα/L.
    alpha = 1e-4
    fe = beam({"A": {"kind": 2}, "C": {"kind": 2, "z": L, "tilt": alpha}})
    base, _ = fe.influence(0.0)
    assert base[2][0] == pytest.approx(-6 * EJ * alpha / L**2, rel=1e-10)
    assert base[2][1] == pytest.approx(4 * EJ * alpha / L, rel=1e-10)
    assert base[0][1] == pytest.approx(2 * EJ * alpha / L, rel=1e-10)
    # Propped cantilever: R = 3EJδ/L³; on a spring k: series combination.
    fe = beam({"A": {"kind": 2}, "C": {"kind": 1, "z": L, "offset": delta}})
    assert fe.influence(0.0)[0][2][0] == pytest.approx(3 * EJ * delta / L**3, rel=1e-10)
    k = 2e5
    fe = beam({"A": {"kind": 2}, "C": {"kind": 1, "z": L, "offset": delta, "stiffness": k}})
    k_beam = 3 * EJ / L**3
    assert fe.influence(0.0)[0][2][0] == pytest.approx(delta / (1 / k + 1 / k_beam), rel=1e-10)
    # Pin displaced δ at the middle of a beam clamped at both ends: 192EJδ/L³.
    fe = beam(
        {"A": {"kind": 2}, "B": {"kind": 1, "z": L / 2, "offset": delta}, "C": {"kind": 2, "z": L}}
    )
    assert fe.influence(0.0)[0][1][0] == pytest.approx(192 * EJ * delta / L**3, rel=1e-10)


def test_reference_self_consistency(params):
    """The reference's own rounding: inserting nodes must not change the result (§5.5), and a
    40-digit solve of the same system agrees (to ≤ 1e-11 and ≤ 1e-13 of the largest reaction, far
    below the RTOL = 1e-9 of the FMU comparison). Also: lateral equilibrium of the reference."""
    for p in (params, params | CONFIG_C):
        ref = Reference(p)
        for s in np.linspace(0.0, ref.kin.stroke, 7):
            base, per_q = ref.fe.influence(s)
            scale_b = np.max(np.abs(base[:, 0]))
            scale_q = np.max(np.abs(per_q[:, 0]))
            fine_b, fine_q = ref.fe.influence(s, refine=3)
            assert np.max(np.abs(fine_b - base)) <= 1e-11 * scale_b
            assert np.max(np.abs(fine_q - per_q)) <= 1e-11 * scale_q
            mp_b, mp_q = ref.fe.influence_mp(s)
            assert np.max(np.abs(mp_b - base)) <= 1e-13 * scale_b, (
                np.max(np.abs(mp_b - base)) / scale_b
            )
            assert np.max(np.abs(mp_q - per_q)) <= 1e-13 * scale_q
            # ΣR + lateral load = 0 and ΣR per unit Q = −1.
            assert abs(base[:, 0].sum() + p["link.lateral_load"]) <= 1e-10 * scale_b
            assert abs(per_q[:, 0].sum() + 1.0) <= 1e-10


def test_default_machine_matches_the_independent_model(fmu_path, params):
    res = run_fmu(fmu_path, {})
    assert len(res) == N_REV + 1
    rows, worst = compare(res, Reference(params), "default")
    print("default machine, worst errors:", {k: f"{v:.2g}" for k, v in worst.items()})
    # The friction is substantial and changes sign with the velocity.
    fr = res["guide.friction"]
    assert fr.max() > 10 and fr.min() < -10


def test_unb600a_matches_the_independent_model(fmu_path, params):
    values = unb600a_values()
    start = {k: v for k, v in values.items() if k != "crank.speed"}
    res = run_fmu(fmu_path, start, omega=values["crank.speed"])
    rows, worst = compare(res, Reference(params | values), "unb600a", omega=values["crank.speed"])
    print("unb600a, worst errors:", {k: f"{v:.2g}" for k, v in worst.items()})
    assert np.max(np.abs(res["guide.friction"])) > 1e3


def test_frame_fixed_elastic_gland_with_tilts_matches_the_independent_model(fmu_path, params):
    f_input = lambda t: 1.5e4 * math.sin(2 * OMEGA * t + 0.2)  # noqa: E731
    res = run_fmu(fmu_path, CONFIG_C, f_input=f_input)
    rows, worst = compare(
        res, Reference(params | CONFIG_C), "frame-fixed elastic C", f_input=f_input
    )
    print("config (c), worst errors:", {k: f"{v:.2g}" for k, v in worst.items()})
    # Every support carries load and A and C rub: the total differs from B's friction.
    for name in ("support_A.reaction", "support_C.reaction", "guide.reaction", "guide.moment"):
        assert np.max(np.abs(res[name])) > 10, name
    assert np.max(np.abs(res["link.friction_total"] - res["guide.friction"])) > 1.0


def test_reference_distinguishes_wrong_models(params):
    """The comparison above has teeth: plausible wrong models differ from the reference by far
    more than 1e-8 (here ≥ 1e-4 of the largest friction), e.g. Z_ref at s = 0 instead of
    mid-stroke, or the seed's friction formula f·(0.5 R_B + M_B/l_n) (docs/model.md §9)."""
    ref = Reference(params | CONFIG_C)
    thetas = np.linspace(0.05, 2 * math.pi - 0.05, 40)
    good = np.array([ref.at(t, OMEGA)["guide.friction"] for t in thetas])
    scale = np.max(np.abs(good))
    # Z_ref at s = 0.
    wrong = Reference(params | CONFIG_C)
    wrong.fe.stroke = 0.0
    bad = np.array([wrong.at(t, OMEGA)["guide.friction"] for t in thetas])
    assert np.max(np.abs(bad - good)) > 1e-4 * scale
    # The seed's friction formula.
    seed = Reference(params | CONFIG_C)

    def seed_friction(rm, sign, fe=seed.fe):
        out = np.zeros(3)
        for i, sup in enumerate(fe.supports):
            if sup is None or sup["f"] == 0.0:
                continue
            r, m = rm[i]
            mag = (
                sup["f"] * abs(r)
                if sup["kind"] == 1 or sup["length"] == 0
                else sup["f"] * abs(0.5 * r + m / sup["length"])
            )
            out[i] = -mag * sign
        return out

    seed.fe.friction = seed_friction
    bad = np.array([seed.at(t, OMEGA)["guide.friction"] for t in thetas])
    assert np.max(np.abs(bad - good)) > 1e-2 * scale


@pytest.mark.parametrize("case", ["default", "unb600a"])
def test_friction_work_per_revolution(fmu_path, params, case):
    """∮ F_fr·v dt over one revolution (trapezoid on the 0.5° grid of the FMU's outputs) is
    negative — friction dissipates — and equals the independent model's on the same grid.
    For the default machine (no process work: profile 0 with load.mean = 0) the drive's work
    ∮ T ω dt equals the dissipated energy −∮ F_fr v dt: ∮ Φ v dt vanishes over a revolution
    (the kinetic energy is periodic; the trapezoid rule on a periodic smooth integrand is exact
    to rounding)."""
    if case == "default":
        values, start, w = params, {}, OMEGA
    else:
        values = unb600a_values()
        start = {k: v for k, v in values.items() if k != "crank.speed"}
        w = values["crank.speed"]
        values = params | values
    res = run_fmu(fmu_path, start, omega=w)
    t = np.asarray(res["time"])
    work_fmu = np.trapezoid(res["link.friction_total"] * res["suspension.velocity"], t)
    ref = Reference(values)
    rows = [ref.at(w * float(x), w) for x in t]
    work_ref = np.trapezoid([r["link.friction_total"] * r["v"] for r in rows], t)
    print(f"{case}: friction work per revolution {work_fmu:.10g} J (reference {work_ref:.10g} J)")
    assert work_fmu < 0 and work_ref < 0
    assert abs(work_fmu - work_ref) <= RTOL * abs(work_ref)
    if case == "default":
        drive = np.trapezoid(res["crank.torque"] * w, t)
        inertia_power = np.abs(res["inertia.force"] * res["suspension.velocity"])
        assert abs(drive + work_fmu) <= 1e-9 * np.trapezoid(inertia_power, t), (drive, work_fmu)


@pytest.mark.parametrize("case", ["default", "unb600a-simplex"])
def test_friction_report_figures_agree_with_the_independent_model(fmu_path, params, case):
    """scripts/friction_report.py (the closing-note figures, computed from the FMU alone): its
    extremes of guide.friction are extremes of the independent model too (same value to RTOL at
    the reported angle; the reference's own golden-section search finds the same angle to 1e-4°),
    and its 0.1°-grid friction work equals the reference's trapezoid on the same grid."""
    import friction_report

    rep = friction_report.report(fmu_path, case)
    values = params | (unb600a_values() if case == "unb600a-simplex" else {})
    ref = Reference(values)
    w = rep["omega"]
    print(f"{case}: max {rep['max']}, min {rep['min']}, work {rep['work']:.9g} J")
    for key, sign in (("max", 1.0), ("min", -1.0)):
        th, val = rep[key]

        def f(deg, sign=sign):
            return sign * ref.at(math.radians(deg), w)["guide.friction"]

        assert abs(sign * f(th) - val) <= RTOL * abs(val), (key, th, val, sign * f(th))
        th_ref, _ = friction_report.golden_max(f, th - 0.1, th + 0.1, 1e-7)
        assert abs(th_ref - th) <= 1e-4, (key, th, th_ref)
    assert rep["max"][1] > 0 > rep["min"][1]
    th = np.linspace(0.0, 2 * math.pi, 3601)
    rows = [ref.at(x, w) for x in th]
    work_ref = np.trapezoid([r["link.friction_total"] * r["v"] / w for r in rows], th)
    assert abs(rep["work_coarse"] - work_ref) <= RTOL * abs(work_ref)
    # The 0.01° value is converged: it differs from the 0.1° one by the trapezoid error only.
    assert rep["work"] < 0 and abs(rep["work"] - rep["work_coarse"]) <= 1e-6 * abs(rep["work"])
