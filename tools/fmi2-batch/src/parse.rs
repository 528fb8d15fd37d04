//! The clean lines of the digital twin's input CSV, parsed natively. A line is clean when it has
//! exactly the header's number of fields (docs/twin.md "Input": a row with more fields is as
//! wrong as one with fewer) and each wanted field is a finite decimal number that
//! Rust's correctly rounded parser reads (spaces around it allowed; an empty optional field gives
//! its default). Such a field reads to the same double in Python's float(), so the caller parses
//! the clean prefix here and anything else (blank lines, bad or unusual fields) in Python, which
//! gives the messages.

/// Parses lines of `text` (separated by '\n') while they are clean; `cols` are the field indices
/// of the values wanted, `defaults[j]` the value of an empty field j (None: the field is required).
/// Values go to `out[j][line]`. Returns the number of clean lines parsed.
pub fn clean_prefix(
    text: &[u8],
    n_fields: usize,
    cols: &[usize],
    defaults: &[Option<f64>],
    out: &mut [&mut [f64]],
) -> usize {
    let mut parsed = 0;
    for line in text.split(|&c| c == b'\n') {
        if parsed >= out.first().map_or(0, |o| o.len()) {
            break;
        }
        let fields: Vec<&[u8]> = line.split(|&c| c == b',').collect();
        if fields.len() != n_fields {
            break;
        }
        for (j, &c) in cols.iter().enumerate() {
            let f = fields[c].trim_ascii();
            let v = match (f.is_empty(), defaults[j]) {
                (true, Some(d)) => d,
                _ => match std::str::from_utf8(f).ok().and_then(|s| s.parse::<f64>().ok()) {
                    Some(v) if v.is_finite() => v,
                    _ => return parsed,
                },
            };
            out[j][parsed] = v;
        }
        parsed += 1;
    }
    parsed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stops_at_the_first_line_python_must_read() {
        let text = b"0.5, 1e-3 ,x,\n2,3,4,5\r\n7,8,,\n9,nan,1,1\n10,11,12,13";
        let (mut a, mut b, mut c) = ([0.0; 5], [0.0; 5], [0.0; 5]);
        let n = clean_prefix(
            text,
            4,
            &[0, 1, 3],
            &[None, None, Some(-1.0)],
            &mut [&mut a, &mut b, &mut c],
        );
        assert_eq!(n, 3);
        assert_eq!(
            (a[..3].to_vec(), b[..3].to_vec(), c[..3].to_vec()),
            (vec![0.5, 2.0, 7.0], vec![1e-3, 3.0, 8.0], vec![-1.0, 5.0, -1.0])
        );
    }

    #[test]
    fn a_line_with_more_fields_than_the_header_is_not_clean() {
        let text = b"1,2\n3,4,5\n6,7";
        let (mut a, mut b) = ([0.0; 3], [0.0; 3]);
        let n = clean_prefix(text, 2, &[0, 1], &[None, None], &mut [&mut a, &mut b]);
        assert_eq!(n, 1);
    }

    #[test]
    fn underscores_are_not_numbers() {
        let text = b"1_0,2";
        let (mut a, mut b) = ([0.0; 1], [0.0; 1]);
        assert_eq!(clean_prefix(text, 2, &[0, 1], &[None, None], &mut [&mut a, &mut b]), 0);
    }
}
