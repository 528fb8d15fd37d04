//! The digital twin's speed and acceleration estimate (docs/twin.md "Conditioning"): at each
//! centre sample, the first and second derivative of a cubic fitted by least squares to the
//! samples of its window, on the measured timestamps (a Savitzky–Golay smoother). The same
//! algorithm as python/reciprocating_drive/conditioning.py `fit` (which the tests compare it
//! with): a window of 2·half+1 samples (fewer if the segment is shorter) shifted inward at the
//! ends, τ scaled to x ∈ [−1, 1], the normal equations solved by Gaussian elimination with
//! partial pivoting. Each centre is computed on its own, so the result for a sample does not
//! depend on which other samples share the call.

const DEGREE: usize = 3;
const N: usize = DEGREE + 1;

/// ω and ε at centre `c` of a segment (times `t`, unwrapped angles `theta`); None when the normal
/// equations are singular (fewer than four distinct times in the window).
pub fn at(t: &[f64], theta: &[f64], half: usize, c: usize) -> Option<(f64, f64)> {
    let n = t.len();
    let width = (2 * half + 1).min(n);
    let lo = c.saturating_sub(half).min(n - width);
    let (tw, thw) = (&t[lo..lo + width], &theta[lo..lo + width]);
    let (tc, thc) = (t[c], theta[c]);
    let mut scale = tw.iter().fold(0.0f64, |m, &ti| m.max((ti - tc).abs()));
    if scale == 0.0 {
        scale = 1.0;
    }
    let mut s = [0.0f64; 2 * DEGREE + 1];
    let mut b = [0.0f64; N];
    for (&ti, &thi) in tw.iter().zip(thw) {
        let x = (ti - tc) / scale;
        let y = thi - thc;
        let mut p = 1.0;
        for (j, sj) in s.iter_mut().enumerate() {
            *sj += p;
            if j < N {
                b[j] += p * y;
            }
            p *= x;
        }
    }
    let mut m = [[0.0f64; N + 1]; N];
    for (i, row) in m.iter_mut().enumerate() {
        row[..N].copy_from_slice(&s[i..i + N]);
        row[N] = b[i];
    }
    let c = solve(m)?;
    Some((c[1] / scale, 2.0 * c[2] / (scale * scale)))
}

/// Gaussian elimination with partial pivoting of an augmented N×(N+1) system.
// Index loops mirror the elimination's formulas; `!(x > 0)` also rejects NaN.
#[allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]
fn solve(mut m: [[f64; N + 1]; N]) -> Option<[f64; N]> {
    for k in 0..N {
        let p = (k..N).max_by(|&i, &j| m[i][k].abs().total_cmp(&m[j][k].abs()))?;
        if !(m[p][k].abs() > 0.0) {
            return None;
        }
        m.swap(k, p);
        for i in k + 1..N {
            let f = m[i][k] / m[k][k];
            for j in k..=N {
                m[i][j] -= f * m[k][j];
            }
        }
    }
    let mut x = [0.0f64; N];
    for k in (0..N).rev() {
        let mut v = m[k][N];
        for j in k + 1..N {
            v -= m[k][j] * x[j];
        }
        x[k] = v / m[k][k];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cubic_is_differentiated_exactly() {
        // θ = 1 + 2τ + 3τ² + 4τ³ on jittered times: ω = 2 + 6τ + 12τ², ε = 6 + 24τ.
        let t: Vec<f64> =
            (0..40).map(|k| k as f64 * 1e-3 + if k % 3 == 0 { 2e-5 } else { -1e-5 }).collect();
        let th: Vec<f64> =
            t.iter().map(|&x| 1.0 + 2.0 * x + 3.0 * x * x + 4.0 * x * x * x).collect();
        for c in [0, 5, 20, 39] {
            let (w, e) = at(&t, &th, 6, c).unwrap();
            let x = t[c];
            assert!((w - (2.0 + 6.0 * x + 12.0 * x * x)).abs() < 1e-9, "{c}: {w}");
            assert!((e - (6.0 + 24.0 * x)).abs() < 1e-5, "{c}: {e}");
        }
    }

    #[test]
    fn equal_times_are_singular() {
        let t = [0.0, 0.0, 0.0, 0.0, 0.0];
        assert_eq!(at(&t, &[0.0, 1.0, 2.0, 3.0, 4.0], 2, 2), None);
    }
}
