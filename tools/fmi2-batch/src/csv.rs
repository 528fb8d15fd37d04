//! Numbers written exactly as Python's `repr(float)` writes them: the shortest digits that read
//! back to the same double (Ryū), laid out by CPython's rule for `repr` (`float_repr_style`
//! 'short'): with the decimal point at position `decpt` of the digits (value = 0.d1d2… × 10^decpt),
//! scientific notation when decpt ≤ −4 or decpt > 16 (`1e-05`, `1.5e+16`, two exponent digits at
//! least), otherwise positional with at least one digit after the point (`100.0`, `0.0001`).

/// The longest number written: `-1.2345678901234567e-308`.
pub const MAX_NUMBER_LEN: usize = 24;

/// Writes `x` into `out` (at least MAX_NUMBER_LEN bytes); returns the length.
pub fn format_number(x: f64, out: &mut [u8]) -> usize {
    if x.is_finite() && out.len() >= MAX_NUMBER_LEN {
        // Ryū's positional notation ("123.45", "100.0", "0.001") is Python's too, except with
        // four zeros after the point ("0.0000123", Python "1.23e-05"); its scientific notation
        // ("1e16", "1.5e-7") differs in the exponent. Those few are laid out again below.
        // SAFETY: format64 writes at most 24 bytes (MAX_NUMBER_LEN) of a finite f64 into `out`.
        let n = unsafe { ryu::raw::format64(x, out.as_mut_ptr()) };
        // Between 1e-4 and 1e16 (and at zero) Ryū's shortest digits have 0.0001 ≤ value < 1e16,
        // where both write positional notation: no need to look (the search for an 'e' was a
        // fifth of the instructions of a number).
        let a = x.abs();
        if (1e-4..1e16).contains(&a) || a == 0.0 {
            return n;
        }
        let body = &out[usize::from(out[0] == b'-')..n];
        if !body.contains(&b'e') && !body.starts_with(b"0.0000") {
            return n;
        }
    }
    layout(x, out)
}

/// Python's layout of `x` from Ryū's digits, for any x.
fn layout(x: f64, out: &mut [u8]) -> usize {
    if !x.is_finite() {
        let s: &[u8] = if x.is_nan() {
            b"nan"
        } else if x > 0.0 {
            b"inf"
        } else {
            b"-inf"
        };
        out[..s.len()].copy_from_slice(s);
        return s.len();
    }
    let mut rb = ryu::Buffer::new();
    let s = rb.format_finite(x).as_bytes();
    // Ryū writes "-1.2345e-7", "123.45", "0.001" or "1e16": take its digits and exponent.
    let mut digits = [0u8; 32]; // "0.0000" and 17 digits at most
    let mut nd = 0usize;
    let mut point: Option<usize> = None;
    let mut exp10: i32 = 0;
    let mut i = 0usize;
    let neg = s[0] == b'-';
    if neg {
        i = 1;
    }
    let mut seen = 0usize; // mantissa digits seen, leading zeros included
    while i < s.len() {
        match s[i] {
            b'.' => point = Some(seen),
            b'e' | b'E' => {
                let (sign, start) = match s.get(i + 1) {
                    Some(b'-') => (-1, i + 2),
                    Some(b'+') => (1, i + 2),
                    _ => (1, i + 1),
                };
                let mut e = 0i32;
                for &c in &s[start..] {
                    e = e * 10 + i32::from(c - b'0');
                }
                exp10 = sign * e;
                break;
            }
            c => {
                seen += 1;
                if nd < digits.len() {
                    digits[nd] = c;
                    nd += 1;
                }
            }
        }
        i += 1;
    }
    // value = 0.d1d2…dn × 10^decpt
    let mut decpt = point.unwrap_or(seen) as i32 + exp10;
    let lead = digits[..nd].iter().take_while(|&&c| c == b'0').count();
    let mut w = 0usize;
    let mut put = |out: &mut [u8], bytes: &[u8]| {
        out[w..w + bytes.len()].copy_from_slice(bytes);
        w += bytes.len();
    };
    if neg {
        put(out, b"-");
    }
    if lead == nd {
        put(out, b"0.0");
        return w;
    }
    decpt -= lead as i32;
    let d = &digits[lead..nd];
    let d = &d[..d.iter().rposition(|&c| c != b'0').map_or(0, |p| p + 1)];
    if decpt <= -4 || decpt > 16 {
        put(out, &d[..1]);
        if d.len() > 1 {
            put(out, b".");
            put(out, &d[1..]);
        }
        let e = decpt - 1;
        put(out, if e < 0 { b"e-" } else { b"e+" });
        let e = e.unsigned_abs();
        let mut tmp = [0u8; 3];
        let n = if e >= 100 { 3 } else { 2 };
        let mut v = e;
        for j in (0..n).rev() {
            tmp[j] = b'0' + (v % 10) as u8;
            v /= 10;
        }
        put(out, &tmp[..n]);
    } else if decpt <= 0 {
        put(out, b"0.");
        for _ in 0..-decpt {
            put(out, b"0");
        }
        put(out, d);
    } else {
        let p = decpt as usize;
        if p >= d.len() {
            put(out, d);
            for _ in d.len()..p {
                put(out, b"0");
            }
            put(out, b".0");
        } else {
            put(out, &d[..p]);
            put(out, b".");
            put(out, &d[p..]);
        }
    }
    w
}

/// Rows of numbers as CSV lines into `out` (sized by the caller: rows·cols·(MAX_NUMBER_LEN + 1)).
pub fn format_rows(
    values: &[f64],
    rows: usize,
    cols: usize,
    row_stride: usize,
    out: &mut [u8],
) -> usize {
    let mut w = 0;
    for r in 0..rows {
        for (c, &x) in values[r * row_stride..][..cols].iter().enumerate() {
            if c > 0 {
                out[w] = b',';
                w += 1;
            }
            w += format_number(x, &mut out[w..]);
        }
        out[w] = b'\n';
        w += 1;
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;

    fn repr(x: f64) -> String {
        let mut b = [0u8; MAX_NUMBER_LEN];
        let n = format_number(x, &mut b);
        String::from_utf8(b[..n].to_vec()).unwrap()
    }

    #[test]
    fn layout_of_pythons_repr() {
        // Each pair is what CPython's repr() prints.
        for (x, s) in [
            (0.0, "0.0"),
            (-0.0, "-0.0"),
            (1.0, "1.0"),
            (0.1, "0.1"),
            (100.0, "100.0"),
            (0.0001, "0.0001"),
            (1e-5, "1e-05"),
            (1.5e-7, "1.5e-07"),
            (1e15, "1000000000000000.0"),
            (1e16, "1e+16"),
            (1.2345e16, "1.2345e+16"),
            (9999999999999998.0, "9999999999999998.0"),
            (123.456, "123.456"),
            (-2.5e-300, "-2.5e-300"),
            (1.7976931348623157e308, "1.7976931348623157e+308"),
            (5e-324, "5e-324"),
            (f64::NAN, "nan"),
            (f64::NEG_INFINITY, "-inf"),
            (0.30000000000000004, "0.30000000000000004"),
            (-1.2345678901234567e-308, "-1.2345678901234567e-308"),
        ] {
            assert_eq!(repr(x), s, "{x:e}");
        }
    }

    #[test]
    fn rows() {
        let v = [1.0, 2.5, 99.0, -3.0, 1e-9, 7.0];
        let mut out = vec![0u8; 2 * 2 * (MAX_NUMBER_LEN + 1)];
        // two rows of two numbers, stride three (the third column is skipped)
        let n = format_rows(&v, 2, 2, 3, &mut out);
        assert_eq!(std::str::from_utf8(&out[..n]).unwrap(), "1.0,2.5\n-3.0,1e-09\n");
    }
}
