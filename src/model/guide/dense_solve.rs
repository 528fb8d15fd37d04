//! Small dense linear solve on fixed-size arrays (no allocation) for the bordered flexibility
//! system of `supports.rs` (at most 6 support constraints + 2 rigid-body unknowns = 8 equations,
//! at most 4 right-hand sides). The factorisation is nalgebra's LU with partial pivoting on a
//! stack-allocated 8×8 matrix; the unused trailing block is padded with the identity.

#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use nalgebra::{SMatrix, SVector};

/// Largest system: six lateral/slope constraints (three supports × two) plus a, b.
pub(super) const MAX_EQ: usize = 8;
/// Right-hand sides: prescribed displacements + lateral load, unit Q, unit M0, unit V.
pub(super) const MAX_RHS: usize = 4;

pub(super) type Matrix = [[f64; MAX_EQ]; MAX_EQ];
pub(super) type Rhs = [[f64; MAX_RHS]; MAX_EQ];

/// The matrix is (numerically) singular: reported by the caller with the physical context.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Singular {
    pub column: usize,
}

/// Solves `A X = B` for the leading `n × n` block of `a` and the first `nrhs` columns of `b`;
/// the solution overwrites `b`. The system is well scaled by construction (entries of order one,
/// see `link_beam.rs`), so a pivot below `1e-13 · max|A|` means a constraint set that does not
/// determine the reactions (a rigid-body mode remains).
pub(super) fn solve_in_place(
    a: &mut Matrix,
    b: &mut Rhs,
    n: usize,
    nrhs: usize,
) -> Result<(), Singular> {
    let mut m = SMatrix::<f64, MAX_EQ, MAX_EQ>::identity();
    let mut scale = 0.0f64;
    for i in 0..n {
        for j in 0..n {
            m[(i, j)] = a[i][j];
            scale = scale.max(a[i][j].abs());
        }
    }
    let lu = m.lu();
    let tiny = 1e-13 * scale;
    let u = lu.u();
    // `!(d > tiny)` also catches NaN.
    if let Some(column) = (0..n).find(|&k| !(u[(k, k)].abs() > tiny)) {
        return Err(Singular { column });
    }
    for c in 0..nrhs {
        let mut x = SVector::<f64, MAX_EQ>::zeros();
        for i in 0..n {
            x[i] = b[i][c];
        }
        if !lu.solve_mut(&mut x) {
            return Err(Singular { column: 0 });
        }
        for i in 0..n {
            b[i][c] = x[i];
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_saddle_system_and_flags_singular() {
        // [[2,1,1],[1,3,0],[1,0,0]] x = [1,2,3] → x = [3, -1/3, -14/3]
        let mut a: Matrix = [[0.0; MAX_EQ]; MAX_EQ];
        a[0][..3].copy_from_slice(&[2.0, 1.0, 1.0]);
        a[1][..3].copy_from_slice(&[1.0, 3.0, 0.0]);
        a[2][..3].copy_from_slice(&[1.0, 0.0, 0.0]);
        let mut b: Rhs = [[0.0; MAX_RHS]; MAX_EQ];
        b[0][0] = 1.0;
        b[1][0] = 2.0;
        b[2][0] = 3.0;
        solve_in_place(&mut a, &mut b, 3, 1).unwrap();
        let x = [b[0][0], b[1][0], b[2][0]];
        let expect = [3.0, -1.0 / 3.0, -14.0 / 3.0];
        for i in 0..3 {
            assert!((x[i] - expect[i]).abs() < 1e-14);
        }
        let mut s: Matrix = [[0.0; MAX_EQ]; MAX_EQ];
        s[0][..2].copy_from_slice(&[1.0, 2.0]);
        s[1][..2].copy_from_slice(&[2.0, 4.0]);
        let mut r: Rhs = [[0.0; MAX_RHS]; MAX_EQ];
        assert!(solve_in_place(&mut s, &mut r, 2, 1).is_err());
    }
}
