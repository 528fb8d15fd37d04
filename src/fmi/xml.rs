//! Core layer: the text helpers both model-description writers (`fmi2::model_description`,
//! `fmi3::model_description`) share.

/// Text escaped for an XML attribute value.
pub fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// xs:double text that round-trips (Rust's shortest representation).
pub fn num(v: f64) -> String {
    format!("{v:?}")
}

/// An xs:boolean attribute value, e.g. `providesDirectionalDerivative(s)` of both standards
/// ([`FmuModel::DIRECTIONAL_DERIVATIVES`](crate::fmi::model::FmuModel::DIRECTIONAL_DERIVATIVES)).
pub fn bool_attr(b: bool) -> &'static str {
    if b {
        "true"
    } else {
        "false"
    }
}
