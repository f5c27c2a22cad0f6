//! The element record as people read it, on the report and the review
//! queue alike: each element with how much of it the flight inspected, its
//! quantities in condition states as a bar and in numbers, and its cracking
//! defect beneath it with the candidates behind it.

use maud::{Markup, html};
use postflight_core::outputs::record::{
    ElementRecord, NotInspectedRule, PendingRule, RecordSummary, Submission, Unit,
};

/// The colours of condition states 1 to 4.
const STATE_COLOURS: [&str; 4] = ["#16a34a", "#eab308", "#f97316", "#dc2626"];

/// The record's styles (the bars), for a page that shows it.
pub const RECORD_STYLE: &str = r#"
.states{display:flex;height:12px;min-width:160px;border:1px solid #d1d5db;border-radius:2px;overflow:hidden}
.states i{display:block;height:100%}.seen{height:4px;background:#e5e7eb;margin-top:3px;min-width:160px}.seen i{display:block;height:100%;background:#6b7280}
tr.defect td:first-child{padding-left:22px}#record details{font-size:12px;max-width:220px}#record summary{cursor:pointer}
"#;

/// A unit as the record writes it for people.
fn unit_text(unit: Unit) -> &'static str {
    match unit {
        Unit::SquareMetres => "m\u{b2}",
        Unit::Metres => "m",
        Unit::Each => "each",
    }
}

/// What the rule did with the part not inspected, in words.
pub fn rule_text(rule: NotInspectedRule) -> &'static str {
    match rule {
        NotInspectedRule::Previous => "in the states of the earlier record (--previous)",
        NotInspectedRule::Cs1 => {
            "as condition state 1 (no defect seen), the common practice: it was not seen"
        }
        NotInspectedRule::Refuse => {
            "in the shares of the states its inspected part shows; no submission files while an element is under the minimum"
        }
    }
}

/// A quantity in its unit: whole for elements counted each.
fn quantity(q: f64, unit: Unit) -> String {
    match unit {
        Unit::Each => format!("{q:.0}"),
        _ => format!("{q:.1}"),
    }
}

/// The states of `row` as a bar the width of its total.
fn states_bar(row: &ElementRecord) -> Markup {
    let states = [row.cs1, row.cs2, row.cs3, row.cs4];
    let total = row.total.max(1e-12);
    html! {
        div.states title=(states.iter().enumerate().map(|(i, q)| format!("state {}: {}", i + 1, quantity(*q, row.unit))).collect::<Vec<_>>().join(", ")) {
            @for (q, colour) in states.iter().zip(STATE_COLOURS) {
                @if *q > 0.0 {
                    i style=(format!("width:{:.2}%;background:{colour}", 100.0 * q / total)) {}
                }
            }
        }
    }
}

/// The candidates behind a row: how many, and on a defect's row, which
/// (folded, each linked where the page has it).
fn candidates_cell(row: &ElementRecord, link: &dyn Fn(&str) -> Option<String>) -> Markup {
    let ids: Vec<&str> = row
        .candidates
        .split(',')
        .filter(|s| !s.is_empty())
        .collect();
    html! {
        @if ids.is_empty() {
            "\u{2013}"
        } @else if row.parent.is_none() {
            (ids.len())
        } @else {
            details {
                summary { (ids.len()) }
                @for (i, id) in ids.iter().enumerate() {
                    @if i > 0 { ", " }
                    @match link(id) {
                        Some(href) => a href=(href) { (id) },
                        None => (id),
                    }
                }
            }
        }
    }
}

/// The record's section: what it rests on, whether the files an owner
/// submits were written (linked where `files_beside` the page), and each
/// element and defect; `link` gives a candidate's address on the page,
/// where it has one.
pub fn record_section(
    summary: &RecordSummary,
    rows: &[ElementRecord],
    files_beside: bool,
    link: &dyn Fn(&str) -> Option<String>,
) -> Markup {
    let pending = rows.iter().map(|r| r.pending).max().unwrap_or(0);
    html! {
        p.sub {
            "Each element as the " (summary.manual) " numbers it, its total quantity and its quantities in condition states 1 to 4 (state 1 good, 2 fair, 3 poor, 4 severe), with its cracking defect beneath it: each cell of "
            (format!("{:.2}", summary.cell_m)) " m on an area element, and each stretch along a linear one, in the worst state of the cracks over it. Structure "
            b { (if summary.structure_number.is_empty() { "(no number given)" } else { &summary.structure_number }) }
            @if !summary.state_code.is_empty() { ", state " (summary.state_code) }
            ". What the flight did not inspect counts " (rule_text(summary.not_inspected)) "."
        }
        @match &summary.submission {
            Submission::Written { files } => {
                p { "Submission files: "
                    @for (i, f) in files.iter().enumerate() {
                        @if i > 0 { ", " }
                        @if files_beside { a href=(f) { (f) } } @else { code { (f) } }
                    }
                    " (FHWA element XML in metric units; the SNBI's element items in square feet, feet and each)."
                }
            }
            Submission::Refused { why } => {
                p.warn { b { "No submission files: " } (why) "." }
            }
        }
        @if summary.not_inspected == NotInspectedRule::Cs1 && rows.iter().any(|r| r.not_inspected > 0.0) {
            p.flag { "Parts the flight did not inspect are counted as state 1: no defect was seen there because nothing was seen there." }
        }
        @if pending > 0 && summary.pending == PendingRule::Count {
            p.flag { "Candidates no reviewer has decided yet count as measured; the pending column says how many stand behind each row." }
        }
        @if !summary.candidates.unmeasured.is_empty() {
            p.flag {
                (summary.candidates.unmeasured.len()) " candidate(s) no view measured across are in no state until a reviewer sets one (or a gauge on site): "
                (summary.candidates.unmeasured.join(", "))
            }
        }
        table #record {
            tr {
                th { "element" } th { "AASHTO" } th.n { "total" } th { "inspected" } th { "states" }
                @for s in 1..=4 { th.n { "CS" (s) } }
                th { "candidates behind states 2-4" } th.n { "pending" }
            }
            @for row in rows {
                tr class=[row.parent.map(|_| "defect")] {
                    td { @if row.parent.is_none() { (row.element) } }
                    td { (row.number) " " (row.name) }
                    td.n { (quantity(row.total, row.unit)) " " (unit_text(row.unit)) }
                    td {
                        @if row.parent.is_none() {
                            (format!("{:.0}%", 100.0 * row.inspected / row.total.max(1e-12)))
                            div.seen { i style=(format!("width:{:.1}%", 100.0 * row.inspected / row.total.max(1e-12))) {} }
                        }
                    }
                    td { (states_bar(row)) }
                    @for q in [row.cs1, row.cs2, row.cs3, row.cs4] { td.n { (quantity(q, row.unit)) } }
                    td { (candidates_cell(row, link)) }
                    td.n { @if row.pending > 0 { (row.pending) } @else { "\u{2013}" } }
                }
            }
        }
    }
}
