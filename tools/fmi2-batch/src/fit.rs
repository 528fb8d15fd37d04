//! The digital twin's speed and acceleration estimate (docs/twin.md "Conditioning"): at each
//! centre sample, the first and second derivative of a cubic fitted by least squares to the
//! samples of its window, on the measured timestamps (a Savitzky–Golay smoother). The same
//! algorithm as python/reciprocating_drive/twin/conditioning.py (`window` and `fit`, which the tests
//! compare it with).
//!
//! The window is a time: the samples within ±half of the centre's time, shifted inward at the
//! segment's start and end so that it keeps its width in time (the whole segment if it is
//! shorter). Which samples it holds depends only on the times around the centre, never on the
//! interval between the first two samples of a run, so a record and any slice of it give the
//! same window, and the same numbers bit for bit, to every sample whose window lies inside the
//! slice. A dropout (an interval shorter than a gap) that cuts one side of the window short
//! widens that side by its length. A window holding fewer than `MIN_SAMPLES` samples (a
//! sparse stretch) takes the `MIN_SAMPLES` samples nearest in time to the centre instead; the
//! caller reports it. τ is scaled to x ∈ [−1, 1] and the normal equations solved by Gaussian
//! elimination with partial pivoting. Each centre is computed on its own, so the result for a
//! sample does not depend on which other samples share the call.

const DEGREE: usize = 3;
const N: usize = DEGREE + 1;

/// The fewest samples a window may hold: one more than the cubic's coefficients, so that the
/// fit has at least one residual and does not interpolate the noise.
pub const MIN_SAMPLES: usize = DEGREE + 2;

/// The window of centre `c` of a segment whose samples `t` (strictly increasing) span the
/// times `t_start` .. `t_end` (`t_end` infinite while the segment goes on; the caller holds
/// every sample of the window): the index range `lo..hi` the fit uses, and the number of
/// samples within the window's time span (below `MIN_SAMPLES`: a sparse window, whose range
/// is then the `MIN_SAMPLES` samples nearest in time to `c`).
pub fn window(t: &[f64], c: usize, half: f64, t_start: f64, t_end: f64) -> (usize, usize, usize) {
    window_in(t, &long_intervals(t, half), c, half, t_start, t_end)
}

/// `long[i]`: how many of the intervals between the samples `0..=i` are longer than a quarter
/// of the window (`half / 2`), the only ones that can widen a window (`window_in`): computed
/// once for many centres, so that a window without one costs no scan of its intervals.
pub fn long_intervals(t: &[f64], half: f64) -> Vec<u32> {
    let mut long = Vec::with_capacity(t.len());
    let mut k = 0u32;
    long.push(0);
    for w in t.windows(2) {
        k += u32::from(w[1] - w[0] > 0.5 * half);
        long.push(k);
    }
    long
}

/// `window` with `long` = `long_intervals(t, half)`.
pub fn window_in(
    t: &[f64],
    long: &[u32],
    c: usize,
    half: f64,
    t_start: f64,
    t_end: f64,
) -> (usize, usize, usize) {
    let n = t.len();
    let (mut a, mut b) = (t[c] - half, t[c] + half);
    let mut shifted = false;
    if a < t_start {
        (a, b, shifted) = (t_start, t_start + 2.0 * half, true);
    }
    if b > t_end {
        (a, b, shifted) = ((t_end - 2.0 * half).max(t_start), t_end, true);
    }
    let mut lo = t.partition_point(|&x| x < a);
    let mut hi = t.partition_point(|&x| x <= b);
    let inside = hi - lo;
    if !shifted && lo > 0 && hi < n && long[hi] > long[lo - 1] {
        // A dropout (an interval shorter than a gap) that cuts a side of the window short: the
        // longest interval from the sample to the first one beyond the window on a side,
        // longer than a quarter of the window and than twice the other side's; that side then
        // reaches further by it, so that the sample stays inside its fit (docs/twin.md
        // "Conditioning").
        let longest = |w: &[f64]| w.windows(2).fold(0.0f64, |m, p| m.max(p[1] - p[0]));
        let (right, left) = (longest(&t[c..=hi]), longest(&t[lo - 1..=c]));
        if right > 0.5 * half && right > 2.0 * left {
            b += right;
            hi = t.partition_point(|&x| x <= b);
        } else if left > 0.5 * half && left > 2.0 * right {
            a -= left;
            lo = t.partition_point(|&x| x < a);
        }
    }
    let inside = if hi - lo > inside { hi - lo } else { inside };
    if inside >= MIN_SAMPLES {
        return (lo, hi, inside);
    }
    // Sparse: widened around the centre, one sample at a time, to the nearer of the next
    // sample before and the next after (the earlier on a tie), to MIN_SAMPLES samples or the
    // whole segment. It reaches at most MIN_SAMPLES - 1 samples to either side.
    let tc = t[c];
    let (mut lo, mut hi) = (c, c + 1);
    while hi - lo < MIN_SAMPLES && (lo > 0 || hi < n) {
        if hi == n || (lo > 0 && tc - t[lo - 1] <= t[hi] - tc) {
            lo -= 1;
        } else {
            hi += 1;
        }
    }
    (lo, hi, inside)
}

/// ω and ε at centre `c` from the samples `lo..hi` of a segment (times `t`, unwrapped angles
/// `theta`); None when the normal equations are singular (fewer than four distinct times).
pub fn at(t: &[f64], theta: &[f64], lo: usize, hi: usize, c: usize) -> Option<(f64, f64)> {
    let (tw, thw) = (&t[lo..hi], &theta[lo..hi]);
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
            let (lo, hi, _) = window(&t, c, 6e-3, t[0], t[39]);
            let (w, e) = at(&t, &th, lo, hi, c).unwrap();
            let x = t[c];
            assert!((w - (2.0 + 6.0 * x + 12.0 * x * x)).abs() < 1e-9, "{c}: {w}");
            assert!((e - (6.0 + 24.0 * x)).abs() < 1e-5, "{c}: {e}");
        }
    }

    #[test]
    fn the_window_is_a_time_shifted_inward_at_the_ends() {
        // Samples every 1 ms (in ms: exact doubles) but a 7 ms interval after 10 ms: ±3 ms holds
        // 7 samples in the middle and keeps 6 ms at the ends.
        let mut t: Vec<f64> = (0..=10).map(f64::from).collect();
        t.extend((0..20).map(|k| 17.0 + f64::from(k)));
        let (s, e) = (t[0], *t.last().unwrap());
        assert_eq!(window(&t, 5, 3.0, s, e), (2, 9, 7));
        assert_eq!(window(&t, 0, 3.0, s, e), (0, 7, 7));
        assert_eq!(window(&t, 30, 3.0, s, e), (24, 31, 7));
        // While the segment goes on, its end does not shift the window.
        assert_eq!(window(&t, 28, 3.0, s, f64::INFINITY), (25, 31, 6));
        assert_eq!(window(&t, 28, 3.0, s, e), (24, 31, 7));
        // Sample 10 (t = 10 ms) sees 7..10 and nothing after: the 7 ms interval (longer than
        // 1.5 ms and twice the 1 ms before) widens the window's end by 7 ms, to 20 ms.
        assert_eq!(window(&t, 10, 3.0, s, e), (7, 15, 8));
        // Sample 11 (t = 17 ms): the same interval widens its start, to 7 ms.
        assert_eq!(window(&t, 11, 3.0, s, e), (7, 15, 8));
        // ±0.5 ms holds one sample: sparse, the 5 nearest (the earlier on a tie) instead.
        assert_eq!(window(&t, 5, 0.5, s, e), (3, 8, 1));
        // A segment of four samples is one window.
        assert_eq!(window(&t[..4], 1, 0.5, 0.0, 3.0), (0, 4, 1));
    }

    #[test]
    fn equal_times_are_singular() {
        let t = [0.0, 0.0, 0.0, 0.0, 0.0];
        assert_eq!(at(&t, &[0.0, 1.0, 2.0, 3.0, 4.0], 0, 5, 2), None);
    }
}
