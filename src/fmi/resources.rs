//! Core layer: where the resources folder is. FMI 2.0's `fmuResourceLocation`
//! (docs/fmi-interface.md "What importers pass"): `file:///path`, `file:/path`,
//! `file://host/path`, percent-encoding, an optional trailing slash, or NULL (fmusim passes NULL
//! when the FMU has no resources folder); FMI 3.0's `resourcePath`, a native path.

use std::path::PathBuf;

/// The resource folder as a local path, or None when absent or not a file URI.
pub fn resource_dir(location: Option<&str>) -> Option<PathBuf> {
    let uri = location?.trim();
    let rest = uri.strip_prefix("file:").or_else(|| uri.strip_prefix("FILE:"))?;
    let path = if let Some(after) = rest.strip_prefix("//") {
        // file://host/path: the authority ends at the next slash (empty host = localhost).
        match after.find('/') {
            Some(i) => &after[i..],
            None => return None,
        }
    } else {
        rest
    };
    let decoded = percent_decode(path)?;
    let trimmed = if decoded.len() > 1 { decoded.trim_end_matches('/') } else { decoded.as_str() };
    Some(PathBuf::from(trimmed))
}

/// FMI 3.0 passes the resources folder as a native path with a trailing separator (FMI 2.0: a
/// file URI); NULL or empty: none.
pub fn resource_path(p: Option<&str>) -> Option<PathBuf> {
    let p = p?;
    let trimmed = p.trim_end_matches(['/', '\\']);
    match (p.is_empty(), trimmed.is_empty()) {
        (true, _) => None,
        (false, true) => Some(PathBuf::from(&p[..1])),
        (false, false) => Some(PathBuf::from(trimmed)),
    }
}

fn percent_decode(s: &str) -> Option<String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = s.get(i + 1..i + 3)?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_form_of_fmi_md() {
        let p = |s| resource_dir(Some(s)).map(|p| p.to_string_lossy().into_owned());
        assert_eq!(p("file:///tmp/x/resources"), Some("/tmp/x/resources".into()));
        assert_eq!(p("file:///tmp/x/resources/"), Some("/tmp/x/resources".into()));
        assert_eq!(p("file:/tmp/x/resources"), Some("/tmp/x/resources".into()));
        assert_eq!(p("file://localhost/tmp/x/resources"), Some("/tmp/x/resources".into()));
        assert_eq!(p("file://somehost/tmp/a%20b/res"), Some("/tmp/a b/res".into()));
        assert_eq!(p("file:///"), Some("/".into()));
        assert_eq!(resource_dir(None), None);
        assert_eq!(p("http://example/x"), None);
        assert_eq!(p("file:///bad%zz"), None);
    }
}
