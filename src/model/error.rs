//! Errors of the pure model, as values. The FMI layer turns each into `fmi2Error` plus one log
//! line, so every message names the variable(s), the value(s) and what is allowed.

use std::fmt;

#[derive(Clone, Debug, PartialEq)]
pub enum ModelError {
    /// A single variable outside its allowed range (includes NaN and ±inf).
    OutOfRange { variable: &'static str, value: f64, allowed: String },
    /// A combination of parameters that is not a valid machine (the linkage does not assemble,
    /// supports do not hold the link, ...). The message names the condition and the values.
    Invalid { message: String },
    /// The model cannot produce a valid result at the current inputs (self-locking guide,
    /// buckled rod, integrator failure). The FMU's state is left as it was.
    Evaluation { message: String },
}

impl ModelError {
    pub fn out_of_range(variable: &'static str, value: f64, allowed: impl Into<String>) -> Self {
        ModelError::OutOfRange { variable, value, allowed: allowed.into() }
    }
    pub fn invalid(message: impl Into<String>) -> Self {
        ModelError::Invalid { message: message.into() }
    }
    pub fn evaluation(message: impl Into<String>) -> Self {
        ModelError::Evaluation { message: message.into() }
    }
}

impl fmt::Display for ModelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ModelError::OutOfRange { variable, value, allowed } => {
                write!(f, "{variable} = {} is out of range; allowed: {allowed}", given(*value))
            }
            ModelError::Invalid { message } | ModelError::Evaluation { message } => {
                f.write_str(message)
            }
        }
    }
}

impl std::error::Error for ModelError {}

/// Checks that `value` is finite; the error names the variable.
pub fn require_finite(variable: &'static str, value: f64) -> Result<f64, ModelError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(ModelError::out_of_range(variable, value, "a finite number"))
    }
}

/// A number the FMU computed, in a message: at most 6 significant digits in the shortest form,
/// exactly as C's and Python's `%.6g` (`1e+300`, `-5.91963e-16`, `0.357516`, `592.25`, `0`,
/// `-0`); NaN and infinities as `NaN`, `inf`, `-inf` (docs/hardening.md "Messages").
pub fn num(v: f64) -> String {
    if let Some(s) = special(v) {
        return s.to_string();
    }
    // `{:.5e}` rounds the exact binary value to 6 significant digits, ties to even, as `%.6g`
    // does; its exponent is that of the rounded value, which picks the form.
    let sci = format!("{v:.5e}");
    let (mantissa, exp) = sci.split_once('e').unwrap_or((&sci, "0"));
    let exp: i32 = exp.parse().unwrap_or(0);
    if (-4..6).contains(&exp) {
        // The same digit position as the mantissa's last digit, so the same rounding.
        trim_zeros(format!("{v:.*}", (5 - exp) as usize))
    } else {
        with_exponent(&trim_zeros(mantissa.to_string()), exp)
    }
}

/// A value the user gave (a parameter or input echoed in a refusal), as given: the shortest
/// digits that read back to the same double, as Python's `repr` (`0.2000001`, `1e+300`,
/// `-5`, `1e-07`), so that a value refused next to a bound is not rounded onto it.
pub fn given(v: f64) -> String {
    if let Some(s) = special(v) {
        return s.to_string();
    }
    // `{:e}` gives the shortest round-trip digits; Python writes them in positional form for
    // exponents in [-4, 16).
    let sci = format!("{v:e}");
    let (mantissa, exp) = sci.split_once('e').unwrap_or((&sci, "0"));
    let exp: i32 = exp.parse().unwrap_or(0);
    if (-4..16).contains(&exp) {
        format!("{v}")
    } else {
        with_exponent(mantissa, exp)
    }
}

fn special(v: f64) -> Option<&'static str> {
    if v.is_nan() {
        Some("NaN")
    } else if v.is_infinite() {
        Some(if v > 0.0 { "inf" } else { "-inf" })
    } else if v == 0.0 {
        Some(if v.is_sign_negative() { "-0" } else { "0" })
    } else {
        None
    }
}

fn trim_zeros(s: String) -> String {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// `1.5` and 7 as `1.5e+07`: sign always, at least two exponent digits (C's `%e`).
fn with_exponent(mantissa: &str, exp: i32) -> String {
    let sign = if exp < 0 { '-' } else { '+' };
    format!("{mantissa}e{sign}{:02}", exp.unsigned_abs())
}

#[cfg(test)]
mod num_tests {
    use super::{given, num};

    /// (bits of x, Python's format(x, '.6g'), Python's repr(x) without a trailing ".0"), generated
    /// by Python 3 from a hand-picked list (zeros, subnormals, 1e±300, the extremes of f64, integers,
    /// rounding ties, the numbers of the issue) and 70 pseudo-random values (random.seed(7)).
    const PYTHON: &[(u64, &str, &str)] = &[
        (0x0000000000000000, "0", "0"),
        (0x8000000000000000, "-0", "-0"),
        (0x3ff0000000000000, "1", "1"),
        (0xbff0000000000000, "-1", "-1"),
        (0x7e37e43c8800759c, "1e+300", "1e+300"),
        (0xfe37e43c8800759c, "-1e+300", "-1e+300"),
        (0x01a56e1fc2f8f359, "1e-300", "1e-300"),
        (0x81a56e1fc2f8f359, "-1e-300", "-1e-300"),
        (0x0000000000000001, "4.94066e-324", "5e-324"),
        (0x8000000000000001, "-4.94066e-324", "-5e-324"),
        (0x0010000000000000, "2.22507e-308", "2.2250738585072014e-308"),
        (0x000fffffffffffff, "2.22507e-308", "2.225073858507201e-308"),
        (0x000012688b70e62b, "1e-310", "1e-310"),
        (0x7fefffffffffffff, "1.79769e+308", "1.7976931348623157e+308"),
        (0xbcc553e457734c80, "-5.91963e-16", "-5.919626723903517e-16"),
        (0x3fd6e18999d0f12b, "0.357516", "0.3575157167540676"),
        (0x408281ffffffffff, "592.25", "592.2499999999999"),
        (0x3f50624dd2f1a9fc, "0.001", "0.001"),
        (0x3f1a36e2eb1c432d, "0.0001", "0.0001"),
        (0x3ee4f8b588e368f1, "1e-05", "1e-05"),
        (0x40fe240000000000, "123456", "123456"),
        (0x4132d68700000000, "1.23457e+06", "1234567"),
        (0x412e847ecccccccd, "999999", "999999.4"),
        (0x412e847f00000000, "1e+06", "999999.5"),
        (0x412e847f33333333, "1e+06", "999999.6"),
        (0x40f86a0000000000, "100000", "100000"),
        (0x412e848000000000, "1e+06", "1000000"),
        (0x4132d68500000000, "1.23456e+06", "1234565"),
        (0x3fc0000000000000, "0.125", "0.125"),
        (0x4004000000000000, "2.5", "2.5"),
        (0x44b52d02c7e14af6, "1e+23", "1e+23"),
        (0x3fb999999999999a, "0.1", "0.1"),
        (0x3fc999999999999a, "0.2", "0.2"),
        (0x3fd3333333333333, "0.3", "0.3"),
        (0x3fd5555555555555, "0.333333", "0.3333333333333333"),
        (0x3fe5555555555555, "0.666667", "0.6666666666666666"),
        (0xbfe5555555555555, "-0.666667", "-0.6666666666666666"),
        (0x400921fb54442d18, "3.14159", "3.141592653589793"),
        (0x430c6bf526340000, "1e+15", "1000000000000000"),
        (0x4341c37937e08000, "1e+16", "1e+16"),
        (0x3f1a36e20f35445e, "0.0001", "9.999995e-05"),
        (0x3f1a36e20acf5dfe, "9.99999e-05", "9.9999949e-05"),
        (0x3f50624d4c40fab7, "0.001", "0.00099999951"),
        (0x4045000000000000, "42", "42"),
        (0xc045000000000000, "-42", "-42"),
        (0x401c000000000000, "7", "7"),
        (0xbee4f8b588e368f1, "-1e-05", "-1e-05"),
        (0x401b3a259b49db84, "6.80678", "6.8067840827778845"),
        (0x4063a28c59d5433b, "157.08", "157.07963267948966"),
        (0x3d3c25c268497682, "1e-13", "1e-13"),
        (0x3e45798ee2308c3a, "1e-08", "1e-08"),
        (0x41e65a0bc0000000, "3e+09", "3000000000"),
        (0xc1e0000000000000, "-2.14748e+09", "-2147483648"),
        (0xf2a74de452e6b438, "-1.98903e+244", "-1.989032661366619e+244"),
        (0x6513270e269e0d37, "7.76112e+178", "7.761117632285041e+178"),
        (0x0c5c7fd0a6a3a450, "3.9805e-249", "3.980498358697587e-249"),
        (0xd23f0824128b2f33, "-1.54328e+88", "-1.5432835417340557e+88"),
        (0x1818e811892f902b, "1.36476e-192", "1.3647584518757569e-192"),
        (0x9531985d5d9dc9f8, "-1.37011e-206", "-1.3701135617873088e-206"),
        (0xe8e25d940ed90475, "-1.71605e+197", "-1.7160537630466207e+197"),
        (0x36f675cc81e74ef5, "6.29468e-44", "6.294675241195386e-44"),
        (0x1600a35a099950d8, "1.06134e-202", "1.0613447212142254e-202"),
        (0x6b0d549b6f03675a, "4.70833e+207", "4.708325160387546e+207"),
        (0x3d9c172411e20b8f, "6.38702e-12", "6.387016158513563e-12"),
        (0x8d116ece1738f7d9, "-9.97313e-246", "-9.973130378568733e-246"),
        (0x0f21ddb66cad4a26, "8.77975e-236", "8.779753225680271e-236"),
        (0x90c192cfd3ac94af, "-5.7955e-228", "-5.795503248498993e-228"),
        (0xf28c105d1fb17c23, "-5.98818e+243", "-5.988180159386011e+243"),
        (0xa170b33839263059, "-1.30605e-147", "-1.306052388527796e-147"),
        (0x953f48f1a09f76b5, "-2.43612e-206", "-2.436117699484841e-206"),
        (0x0fd630f1f29d0da9, "2.23339e-232", "2.233386999150174e-232"),
        (0x95e60af593bd04cf, "-3.51528e-203", "-3.51527970626667e-203"),
        (0x0cb1e29c658cda14, "1.59874e-247", "1.5987381841032883e-247"),
        (0x3898d190f9ebdacc, "4.66786e-36", "4.6678633181812096e-36"),
        (0x8e81973e0becd7b0, "-8.44187e-239", "-8.441872792105456e-239"),
        (0x2217beaddbc496cb, "1.90157e-144", "1.9015657400796622e-144"),
        (0x6b4cb2424a23d596, "7.37044e+208", "7.370437700706684e+208"),
        (0x8a6a63ec24ede6a4, "-1.7164e-258", "-1.7163996725272777e-258"),
        (0x922766581e27a1c0, "-3.23672e-221", "-3.2367190832119987e-221"),
        (0x8f6d05584ef8aa38, "-2.28183e-234", "-2.2818334634712625e-234"),
        (0xae97ba94d0eda82f, "-3.05364e-84", "-3.0536383926309363e-84"),
        (0x1a61dbe22e44158b, "1.34496e-181", "1.3449551894627777e-181"),
        (0x923a736994e3bf91, "-7.3175e-221", "-7.317495976062606e-221"),
        (0x301850c5a38fd547, "5.24982e-77", "5.249822308814304e-77"),
        (0x18f135d25f557203, "1.54508e-188", "1.5450754142984396e-188"),
        (0xb64ce4228c38fb29, "-3.95363e-47", "-3.953625698224792e-47"),
        (0x907a70c31012f037, "-2.72491e-229", "-2.72491267476498e-229"),
        (0x9e7769b10f4205b4, "-6.50514e-162", "-6.505141861548772e-162"),
        (0x7f15052434b9b5df, "1.44148e+304", "1.441484839555994e+304"),
        (0x881ed162ae2eb154, "-1.45837e-269", "-1.4583679262758548e-269"),
        (0xc6f877186d76b07e, "-7.93942e+33", "-7.939416668807721e+33"),
        (0x7731af10506bf2ef, "1.42552e+266", "1.4255183989699612e+266"),
        (0xec66a78795e761d1, "-1.52532e+214", "-1.525315701232403e+214"),
        (0xbf188b7c9455d8c5, "-9.36312e-05", "-9.36312472584493e-05"),
        (0xbe6b0332877a0c00, "-5.03147e-08", "-5.031468302849014e-08"),
        (0x3ed0b15f77ff76c9, "3.97989e-06", "3.9798886745914255e-06"),
        (0xbf4b674f0db9f02d, "-0.00083629", "-0.0008362899784084603"),
        (0x3f40834599332eb8, "0.00050393", "0.0005039300762290288"),
        (0x3f3e12e8075a8c08, "0.000458891", "0.0004588905788784352"),
        (0x3db7f5d8f3bcc60a, "2.17918e-11", "2.179180380728072e-11"),
        (0xc01e8e034ae173b5, "-7.63868", "-7.638684434900758"),
        (0xbf7b7241027ca3f8, "-0.00670076", "-0.006700757927128535"),
        (0xc085c03f589575a8, "-696.031", "-696.0309306789904"),
        (0xc1a2ab273617d057, "-1.56603e+08", "-156603291.04651138"),
        (0xc0f49fbe74ff5ba8, "-84475.9", "-84475.9035638409"),
        (0x3f57eddc20524085, "0.00146052", "0.0014605188055476792"),
        (0xbfa05f18aa4cdb2d, "-0.0319755", "-0.0319755275617609"),
        (0x41070a1e089f4595, "188740", "188739.75421003686"),
        (0x3dd0526212c6a461, "5.93784e-11", "5.937839516431886e-11"),
        (0x3f11d2f86631b67a, "6.79936e-05", "6.799355610250828e-05"),
        (0xc188b3a5e94922e2, "-5.18033e+07", "-51803325.160711065"),
        (0xc234419ab8f8c7f2, "-8.7e+10", "-87000004856.78104"),
        (0x4183373d22164ac2, "4.02984e+07", "40298404.26088478"),
        (0x41a29575dadef17f, "1.55892e+08", "155892461.43543622"),
        (0x3f4519006e258d6b, "0.00064385", "0.0006438495732194299"),
        (0x41b9d2f4a4cbee73, "4.33256e+08", "433255588.7966072"),
        (0xc03e9954b66f98e9, "-30.5989", "-30.59894886230987"),
        (0xc1460deee793a38b, "-2.89072e+06", "-2890717.80919308"),
        (0xbda0d71e3b5b926d, "-7.65808e-12", "-7.658084110365361e-12"),
        (0xbf4277b06433dfea, "-0.000563584", "-0.0005635844503606411"),
        (0xbedf17dbaddfd4ad, "-7.4132e-06", "-7.413195559626316e-06"),
        (0xc069868c6f486706, "-204.205", "-204.2046429075346"),
        (0xc054f88f3135d05f, "-83.8837", "-83.88373975997227"),
    ];

    #[test]
    fn six_significant_digits_as_python_g() {
        for &(bits, g, _) in PYTHON {
            let x = f64::from_bits(bits);
            assert_eq!(num(x), g, "{x:e}");
        }
    }

    #[test]
    fn given_values_read_back_as_python_repr() {
        for &(bits, _, r) in PYTHON {
            let x = f64::from_bits(bits);
            assert_eq!(given(x), r, "{x:e}");
            assert_eq!(given(x).parse::<f64>().map(f64::to_bits), Ok(bits), "round trip");
        }
    }

    #[test]
    fn non_finite_values_are_named() {
        for f in [num, given] {
            assert_eq!(f(f64::NAN), "NaN");
            assert_eq!(f(f64::INFINITY), "inf");
            assert_eq!(f(f64::NEG_INFINITY), "-inf");
        }
    }
}
