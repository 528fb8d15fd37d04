//! Core layer (docs/architecture.md "The FMUs (Rust)").
//!
//! An FMU's documentation/index.html: the model's own text (its conventions) and the variable
//! list, generated from the variable table so it cannot drift from the interface.

use std::fmt::Write;

use crate::fmi::model::FmuModel;
use crate::fmi::variables::{Causality, VarType, Variability};

pub fn generate<M: FmuModel>() -> String {
    let info = M::info();
    let mut h = String::new();
    let _ = writeln!(
        h,
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{} FMU</title>",
        info.model_name
    );
    h.push_str("<style>body{font-family:sans-serif;max-width:70em;margin:auto}td,th{border:1px solid #ccc;padding:2px 6px;vertical-align:top}table{border-collapse:collapse}code{background:#f4f4f4}</style>\n");
    let _ = writeln!(h, "</head><body>\n<h1>{}</h1>", info.model_name);
    h.push_str(info.documentation);
    h.push_str("\n<h2>Variables</h2>\n<table><tr><th>name</th><th>vr</th><th>causality</th><th>type</th><th>unit</th><th>start</th><th>allowed</th><th>description</th></tr>\n");
    for (vr, v) in M::table().variables.iter().enumerate() {
        let causality = match (v.causality, v.variability) {
            (Causality::Parameter, Variability::Tunable) => "parameter (tunable)",
            (Causality::Parameter, _) => "parameter",
            (Causality::CalculatedParameter, _) => "calculated parameter",
            (Causality::Input, _) => "input",
            (Causality::Output, _) => "output",
        };
        let start = v.start().map(|s| format!("{s}")).unwrap_or_default();
        let allowed = if v.causality == Causality::Parameter {
            v.range.describe_as(v.ty, "")
        } else {
            String::new()
        };
        let ty = match v.ty {
            VarType::Real => "Real",
            VarType::Integer => "Integer",
            VarType::Boolean => "Boolean",
        };
        let _ = writeln!(
            h,
            "<tr><td><code>{}</code></td><td>{vr}</td><td>{causality}</td><td>{ty}</td><td>{}</td><td>{start}</td><td>{}</td><td>{}</td></tr>",
            v.name,
            v.unit,
            allowed.replace("a finite number in ", "").replace("an integer in ", ""),
            v.description.replace('&', "&amp;").replace('<', "&lt;")
        );
    }
    h.push_str("</table>\n</body></html>\n");
    h
}

/// The documentation pages (Markdown files of the repository's docs/) an FMU carries as HTML:
/// (file stem, title).
pub type Pages<'a> = &'a [(String, String)];

/// documentation/index.html with links to the pages carried beside it.
pub fn generate_with_pages<M: FmuModel>(pages: Pages) -> String {
    let mut h = generate::<M>();
    if pages.is_empty() {
        return h;
    }
    let mut nav = String::from("<h2>Documentation</h2>\n<ul>\n");
    for (stem, title) in pages {
        let _ = writeln!(nav, "<li><a href=\"{}.html\">{}</a></li>", esc(stem), esc(title));
    }
    nav.push_str("</ul>\n");
    let at = h.find("\n<h2>Variables</h2>").unwrap_or(h.len());
    h.insert_str(at, &format!("\n{nav}"));
    h
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// The title of a Markdown page: its first heading.
pub fn markdown_title(markdown: &str) -> Option<String> {
    markdown
        .lines()
        .find(|l| l.starts_with('#'))
        .map(|l| l.trim_start_matches('#').trim().to_string())
}

/// The anchor of a heading as GitHub renders it (lower case, punctuation dropped, spaces to
/// hyphens), so that links like `model.md#8-default-machine-and-presets` work in the repository
/// and in the FMU alike.
pub fn anchor(heading: &str) -> String {
    heading
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || *c == ' ' || *c == '-' || *c == '_')
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// One Markdown page of docs/ as a standalone HTML page: relative links to other pages (`x.md`,
/// `x.md#anchor`) become `x.html`, headings get GitHub's anchors, images keep their relative
/// paths (the figures are copied beside the pages).
pub fn markdown_page(markdown: &str) -> String {
    use pulldown_cmark::{CowStr, Event, HeadingLevel, Options, Parser, Tag, TagEnd};

    let title = markdown_title(markdown).unwrap_or_else(|| "Documentation".into());
    let mut events: Vec<Event> = Vec::new();
    let mut heading: Option<(HeadingLevel, usize)> = None;
    for ev in Parser::new_ext(markdown, Options::ENABLE_TABLES) {
        match ev {
            Event::Start(Tag::Link { link_type, dest_url, title, id }) => {
                let dest = rewrite_link(&dest_url).map(CowStr::from).unwrap_or(dest_url);
                events.push(Event::Start(Tag::Link { link_type, dest_url: dest, title, id }));
            }
            Event::Start(Tag::Heading { level, .. }) => {
                heading = Some((level, events.len()));
                events.push(Event::Text(CowStr::from(""))); // replaced at the end of the heading
            }
            Event::End(TagEnd::Heading(level)) => {
                let (lvl, at) = heading.take().unwrap_or((level, events.len()));
                let text: String = events[at + 1..]
                    .iter()
                    .filter_map(|e| match e {
                        Event::Text(t) | Event::Code(t) => Some(t.to_string()),
                        _ => None,
                    })
                    .collect();
                let n = lvl as usize;
                events[at] =
                    Event::Html(CowStr::from(format!("<h{n} id=\"{}\">", esc(&anchor(&text)))));
                events.push(Event::Html(CowStr::from(format!("</h{n}>\n"))));
            }
            other => events.push(other),
        }
    }
    let mut body = String::new();
    pulldown_cmark::html::push_html(&mut body, events.into_iter());
    let mut h = String::new();
    let _ = writeln!(
        h,
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{}</title>",
        esc(&title)
    );
    h.push_str("<style>body{font-family:sans-serif;max-width:70em;margin:auto}td,th{border:1px solid #ccc;padding:2px 6px;vertical-align:top}table{border-collapse:collapse}code,pre{background:#f4f4f4}img{max-width:100%}</style>\n");
    h.push_str("</head><body>\n<p><a href=\"index.html\">Variables and index</a></p>\n");
    h.push_str(&body);
    h.push_str("</body></html>\n");
    h
}

/// `x.md` or `x.md#a` (relative) → `x.html`/`x.html#a`; anything else is left alone.
fn rewrite_link(dest: &str) -> Option<String> {
    if dest.contains("://") || dest.starts_with('/') {
        return None;
    }
    let (path, frag) = match dest.split_once('#') {
        Some((p, f)) => (p, Some(f)),
        None => (dest, None),
    };
    let stem = path.strip_suffix(".md")?;
    // README.md of docs/ is the index of the pages; in the FMU it is README.html.
    Some(match frag {
        Some(f) => format!("{stem}.html#{f}"),
        None => format!("{stem}.html"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn links_to_pages_become_html_and_headings_get_anchors() {
        let md = "# Title\n\n## 8. Default machine and presets\n\nSee [the model](model.md#8-default-machine-and-presets), \
                  [x](https://example.com/a.md) and ![fig](figures/a.png).\n\n| a | b |\n|---|---|\n| 1 | 2 |\n";
        let h = markdown_page(md);
        assert!(
            h.contains(
                r#"<h2 id="8-default-machine-and-presets">8. Default machine and presets</h2>"#
            ),
            "{h}"
        );
        assert!(h.contains(r#"href="model.html#8-default-machine-and-presets""#), "{h}");
        assert!(h.contains(r#"href="https://example.com/a.md""#), "{h}");
        assert!(h.contains(r#"src="figures/a.png""#), "{h}");
        assert!(h.contains("<table>") && h.contains("<title>Title</title>"), "{h}");
    }

    #[test]
    fn github_anchors() {
        assert_eq!(
            anchor("2. Crank motion and stroke coordinate"),
            "2-crank-motion-and-stroke-coordinate"
        );
        assert_eq!(anchor("5.3 Solution and friction"), "53-solution-and-friction");
        assert_eq!(anchor("What importers pass"), "what-importers-pass");
    }
}
