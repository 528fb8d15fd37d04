//! Which guide configurations are rejected at initialization, and the messages (docs/model.md §5.2).
//!
//! Every message names the contract variables (docs/model.md §10), their values and what is allowed,
//! because the FMI layer turns it into the single log line a user sees.

use super::link_beam::Dof;
use super::{GuideSpec, SupportKind, SupportSpec};
use crate::model::error::{given, num, ModelError};

/// Contract names of one support's parameters.
pub(super) struct SupportNames {
    pub label: &'static str,
    pub kind: &'static str,
    pub z: &'static str,
    pub offset: &'static str,
    pub tilt: &'static str,
    pub length: &'static str,
    pub stiffness: &'static str,
    pub friction: &'static str,
}

pub(super) const NAMES: [SupportNames; 3] = [
    SupportNames {
        label: "support_A",
        kind: "support_A.kind",
        z: "support_A.z",
        offset: "support_A.offset",
        tilt: "support_A.tilt",
        length: "support_A.length",
        stiffness: "support_A.stiffness",
        friction: "support_A.friction",
    },
    SupportNames {
        label: "support_B",
        kind: "support_B.kind",
        z: "support_B.z",
        offset: "support_B.offset",
        tilt: "support_B.tilt",
        length: "support_B.length",
        stiffness: "support_B.stiffness",
        // B is "the guide": its coefficient is guide.friction_coefficient (docs/model.md §5.2).
        friction: "guide.friction_coefficient",
    },
    SupportNames {
        label: "support_C",
        kind: "support_C.kind",
        z: "support_C.z",
        offset: "support_C.offset",
        tilt: "support_C.tilt",
        length: "support_C.length",
        stiffness: "support_C.stiffness",
        friction: "support_C.friction",
    },
];

/// One contact (constraint) of a support relative to its centre: a lateral contact (pin, clamp's
/// lateral restraint, guide edge) or a clamp's slope restraint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Contact {
    pub dof: Dof,
    /// Link-coordinate offset from the support's centre [m] (guide edges at ±length/2).
    pub offset: f64,
}

/// The contacts of a support (at most two), docs/model.md §5.2.
pub(super) fn contacts(spec: &SupportSpec) -> ([Contact; 2], usize) {
    let none = Contact { dof: Dof::Deflection, offset: 0.0 };
    match spec.kind {
        SupportKind::None => ([none, none], 0),
        SupportKind::Pin => ([none, none], 1),
        SupportKind::Clamp => ([none, Contact { dof: Dof::Slope, offset: 0.0 }], 2),
        SupportKind::TwoEdgeGuide => {
            // Edge 1 is the crank-side edge (z_centre + l_n/2), §5.3.
            let h = spec.length / 2.0;
            (
                [
                    Contact { dof: Dof::Deflection, offset: h },
                    Contact { dof: Dof::Deflection, offset: -h },
                ],
                2,
            )
        }
    }
}

/// Whether a contact is rigid: a clamp's slope restraint always is; lateral contacts are rigid
/// when the support's stiffness is 0 (§5.2).
pub(super) fn is_rigid(spec: &SupportSpec, contact: &Contact) -> bool {
    contact.dof == Dof::Slope || spec.stiffness == 0.0
}

/// A derived number (a position or stroke coordinate computed from several parameters) for a
/// message, to 6 significant digits without the noise digits of its rounding:
/// `0.19999999999999996` → `0.2` (docs/hardening.md "Messages"); a rounded −0 reads 0.
pub(super) fn short(x: f64) -> String {
    if x == 0.0 {
        "0".to_string()
    } else {
        num(x)
    }
}

fn finite(name: &'static str, value: f64, allowed: &str) -> Result<(), ModelError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(ModelError::out_of_range(name, value, allowed))
    }
}

fn non_negative(name: &'static str, value: f64, unit: &str) -> Result<(), ModelError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(ModelError::out_of_range(name, value, format!("[0, inf) {unit}")))
    }
}

/// Single-variable checks of every present support and of the guide-wide parameters.
/// Parameters of absent supports (kind 0) are not used and not checked.
pub(super) fn check_scalars(spec: &GuideSpec, stroke: f64) -> Result<(), ModelError> {
    if !stroke.is_finite() || stroke < 0.0 {
        return Err(ModelError::invalid(format!(
            "the stroke S = {} m handed to the guide model must be finite and >= 0 \
             (it follows from the kinematic parameters, docs/model.md §2)",
            num(stroke)
        )));
    }
    finite("link.lateral_load", spec.lateral_load, "a finite force (N)")?;
    if !spec.velocity_scale.is_finite() || spec.velocity_scale <= 0.0 {
        return Err(ModelError::out_of_range(
            "guide.velocity_scale",
            spec.velocity_scale,
            "(0, inf) m/s",
        ));
    }
    for (x, s) in spec.supports.iter().enumerate() {
        if s.kind == SupportKind::None {
            continue;
        }
        let n = &NAMES[x];
        finite(n.z, s.z, "a finite link coordinate (m)")?;
        finite(n.offset, s.offset, "a finite lateral offset (m)")?;
        finite(n.tilt, s.tilt, "a finite tilt (rad)")?;
        non_negative(n.length, s.length, "m")?;
        non_negative(n.stiffness, s.stiffness, "N/m (0 = rigid)")?;
        non_negative(n.friction, s.friction, "(friction coefficient)")?;
        if s.kind == SupportKind::TwoEdgeGuide && s.length <= 0.0 {
            return Err(ModelError::out_of_range(
                n.length,
                s.length,
                format!(
                    "(0, inf) m for a two-edge guide ({} = 3): its two edges sit at ±length/2 \
                     about its centre and carry the moment as an edge-force couple (docs/model.md §5.2)",
                    n.kind
                ),
            ));
        }
        if s.kind == SupportKind::Clamp && s.friction > 0.0 && s.length <= 0.0 {
            return Err(ModelError::out_of_range(
                n.length,
                s.length,
                format!(
                    "(0, inf) m for a clamp with friction ({} = {} > 0): its friction is \
                     f·max(|R|, 2|M|/length) (docs/model.md §5.3)",
                    n.friction, s.friction
                ),
            ));
        }
    }
    Ok(())
}

/// Every contact must stay on the link, [0, L] with tolerance 1e-9·L, for all s in [0, S]
/// (§5.2). A frame-fixed support's centre is at link coordinate `z − s`.
pub(super) fn check_positions(
    spec: &GuideSpec,
    length: f64,
    stroke: f64,
) -> Result<(), ModelError> {
    let tol = 1e-9 * length;
    for (x, s) in spec.supports.iter().enumerate() {
        let (cs, count) = contacts(s);
        let n = &NAMES[x];
        if s.kind == SupportKind::TwoEdgeGuide && s.length <= tol {
            return Err(ModelError::out_of_range(
                n.length,
                s.length,
                format!(
                    "({}, inf) m: the two edges of a guide must be distinct points (1e-9·L)",
                    short(tol)
                ),
            ));
        }
        for c in cs.iter().take(count) {
            let z = s.z + c.offset;
            // Range of the contact's link coordinate over the stroke.
            let (lo, hi) = if s.frame_fixed { (z - stroke, z) } else { (z, z) };
            if lo >= -tol && hi <= length + tol {
                continue;
            }
            let what = if s.frame_fixed {
                format!(
                    "{} is frame-fixed ({}.attached = 1), so {} is its link coordinate at s = 0 and \
                     it sits at {} − s; over the stroke S = {} m that is [{}, {}] m",
                    n.label,
                    n.label,
                    n.z,
                    n.z,
                    short(stroke),
                    short(lo),
                    short(hi)
                )
            } else {
                format!(
                    "{} moves with the link and sits at link coordinate {} m",
                    n.label,
                    short(z)
                )
            };
            if s.kind == SupportKind::TwoEdgeGuide {
                return Err(ModelError::invalid(format!(
                    "a guide edge leaves the link: {} = {} m, {} = {} m put the edge at {}{}{}/2 = {} m; \
                     {what}; every edge must stay within [0, L] = [0, {}] m, L = link.l1 + … + \
                     link.l4 (docs/model.md §5.2)",
                    n.z,
                    given(s.z),
                    n.length,
                    given(s.length),
                    n.z,
                    if c.offset >= 0.0 { " + " } else { " − " },
                    n.length,
                    short(z),
                    short(length),
                )));
            }
            let allowed = if s.frame_fixed {
                format!(
                    "[S, L] = [{}, {}] m: {what}, which must stay on the link [0, L] \
                     (docs/model.md §5.2)",
                    short(stroke),
                    short(length)
                )
            } else {
                format!(
                    "[0, L] = [0, {}] m: the support's centre must lie on the link (docs/model.md §5.2)",
                    short(length)
                )
            };
            return Err(ModelError::out_of_range(n.z, s.z, allowed));
        }
    }
    Ok(())
}

/// A lateral contact for the rigid-body check: link coordinate at s = 0, and whether it moves
/// along the link (`z − s`).
#[derive(Clone, Copy)]
struct Point {
    support: usize,
    z: f64,
    moving: bool,
}

/// Whether two contact points coincide (within tol) for some s in [0, S]; returns that s.
fn coincide(a: &Point, b: &Point, stroke: f64, tol: f64) -> Option<f64> {
    match (a.moving, b.moving) {
        (false, false) | (true, true) => ((a.z - b.z).abs() <= tol).then_some(0.0),
        (true, false) | (false, true) => {
            let (m, f) = if a.moving { (a, b) } else { (b, a) };
            let s = m.z - f.z;
            (s >= -tol && s <= stroke + tol).then_some(s.clamp(0.0, stroke))
        }
    }
}

/// The supports must hold the link (no rigid-body mode, §5.2) at every s, and no two rigid
/// contacts of the same kind may coincide (the split of the reaction between them would be
/// indeterminate: the beam problem would be singular there).
pub(super) fn check_held(spec: &GuideSpec, length: f64, stroke: f64) -> Result<(), ModelError> {
    let tol = 1e-9 * length;
    let mut lateral = [Point { support: 0, z: 0.0, moving: false }; 6];
    let mut n_lat = 0usize;
    let mut has_slope = false;
    for (x, s) in spec.supports.iter().enumerate() {
        let (cs, count) = contacts(s);
        for c in cs.iter().take(count) {
            match c.dof {
                Dof::Slope => has_slope = true,
                Dof::Deflection => {
                    lateral[n_lat] = Point { support: x, z: s.z + c.offset, moving: s.frame_fixed };
                    n_lat += 1;
                }
            }
        }
    }
    let lateral = &lateral[..n_lat];
    // A clamp (lateral + slope restraint at one point) holds the link by itself; otherwise two
    // lateral contacts at distinct points are needed at every s.
    if !has_slope {
        let mut held_everywhere = false;
        let mut failing_s = 0.0;
        let pairs = (0..n_lat).flat_map(|i| ((i + 1)..n_lat).map(move |j| (i, j)));
        let mut any_pair = false;
        for (i, j) in pairs {
            any_pair = true;
            match coincide(&lateral[i], &lateral[j], stroke, tol) {
                None => held_everywhere = true,
                Some(s) => failing_s = s,
            }
        }
        // Pairs that each coincide somewhere can only fail together at the same s: with all
        // link-fixed contacts at one point and all frame-fixed ones at another (a second
        // distinct point in either group would give a pair that never coincides).
        if !held_everywhere {
            let listing: Vec<String> = spec
                .supports
                .iter()
                .enumerate()
                .filter(|(_, s)| s.kind != SupportKind::None)
                .map(|(x, s)| {
                    format!(
                        "{} = {} ({}), {} = {} m{}",
                        NAMES[x].kind,
                        s.kind as i32,
                        kind_name(s.kind),
                        NAMES[x].z,
                        given(s.z),
                        if s.frame_fixed { " (frame-fixed)" } else { "" }
                    )
                })
                .collect();
            let why = if any_pair {
                format!(
                    "all lateral contacts coincide at s = {} m, so the link can rotate \
                     about that point",
                    short(failing_s)
                )
            } else {
                "a single pin leaves the link free to rotate about it".to_string()
            };
            return Err(ModelError::invalid(format!(
                "the supports do not hold the link (a rigid-body mode remains): {why}; supports: \
                 {}; add a clamp or a second lateral support at a different point (docs/model.md §5.2)",
                listing.join("; ")
            )));
        }
    }
    // Coincident rigid contacts of the same kind, from different supports.
    let mut rigid = [(Point { support: 0, z: 0.0, moving: false }, Dof::Deflection); 6];
    let mut n_rigid = 0usize;
    for (x, s) in spec.supports.iter().enumerate() {
        let (cs, count) = contacts(s);
        for c in cs.iter().take(count) {
            if is_rigid(s, c) {
                rigid[n_rigid] =
                    (Point { support: x, z: s.z + c.offset, moving: s.frame_fixed }, c.dof);
                n_rigid += 1;
            }
        }
    }
    for i in 0..n_rigid {
        for j in (i + 1)..n_rigid {
            let (a, da) = rigid[i];
            let (b, db) = rigid[j];
            if a.support == b.support || da != db {
                continue;
            }
            if let Some(s) = coincide(&a, &b, stroke, tol) {
                let za = if a.moving { a.z - s } else { a.z };
                let (na, nb) = (&NAMES[a.support], &NAMES[b.support]);
                let what = match da {
                    Dof::Deflection => "laterally",
                    Dof::Slope => "in slope (two clamps)",
                };
                return Err(ModelError::invalid(format!(
                    "{} and {} both hold the link rigidly {what} at the same point (link coordinate \
                     {} m at s = {} m; {} = {} m, {} = {} m): the split of the reaction between \
                     them is indeterminate; move one of them or give one a positive stiffness \
                     ({} / {}) (docs/model.md §5.2)",
                    na.label,
                    nb.label,
                    short(za),
                    short(s),
                    na.z,
                    given(spec.supports[a.support].z),
                    nb.z,
                    given(spec.supports[b.support].z),
                    na.stiffness,
                    nb.stiffness
                )));
            }
        }
    }
    Ok(())
}

pub(super) fn kind_name(kind: SupportKind) -> &'static str {
    match kind {
        SupportKind::None => "none",
        SupportKind::Pin => "pin",
        SupportKind::Clamp => "clamp",
        SupportKind::TwoEdgeGuide => "two-edge guide",
    }
}
