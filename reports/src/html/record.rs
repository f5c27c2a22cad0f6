//! The report's element record: each AASHTO element, how much of it the
//! flight inspected, its states as bars and in numbers, and the candidates
//! behind its defect (linked to their rows above).

use maud::{Markup, html};

use super::defects::candidate_anchor;
use crate::results::RunResults;

pub(super) fn record_section(r: &RunResults) -> Markup {
    let Some((summary, rows)) = &r.record else {
        return html! {};
    };
    let link = |id: &str| {
        r.defects
            .iter()
            .any(|d| d.id == id)
            .then(|| format!("#{}", candidate_anchor(id)))
    };
    html! {
        h2 #element-record { "Element record" }
        (page::record::record_section(summary, rows, true, &link))
        p.sub {
            "After review decisions, " code { "postflight record --run RUN" } " rebuilds it from the decisions the review queue stored; its columns and rules are in docs/cli.md (postflight record)."
        }
    }
}
