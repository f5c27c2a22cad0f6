//! The report's changes since the earlier inspection: each candidate new,
//! grown, unchanged or not found again, with its crops before and now.

use super::defects::{crop_data, jpeg_data};

use maud::{Markup, html};
use postflight_core::outputs::changes::{ChangeKind, ChangeRecord, ChangesSummary};

use page::{place_text, readable_time};

use crate::results::RunResults;

/// What moved between condition states in the element record, where both
/// runs have one.
fn element_changes(c: &ChangesSummary) -> Markup {
    let moved: Vec<String> = c.elements.iter().flat_map(|e| e.moved()).collect();
    html! {
        @if !c.elements.is_empty() {
            h3 { "Element record, then and now" }
            @if moved.is_empty() {
                p { "No element's quantity moved between condition states." }
            } @else {
                ul { @for line in &moved { li { (line) } } }
            }
        }
    }
}

/// What changed since the earlier inspection `postflight compare` was given.
pub(super) fn changes_section(r: &RunResults) -> Markup {
    let Some(c) = &r.changes else {
        return html! {};
    };
    let since = c.before_date();
    let g = &c.registration;
    let t = g.transform.translation;
    let listed: Vec<&ChangeRecord> = c
        .changes
        .iter()
        .filter(|ch| ch.change != ChangeKind::Unchanged)
        .collect();
    html! {
        h2 { "Changes since " (since) }
        p {
            "Compared with the inspection of " (readable_time(&c.before_flight_start)) " ("
            code { (c.before.display()) } "). Its map was registered onto this flight's: shifted "
            (format!("{:.2}, {:.2}, {:.2} m", t[0], t[1], t[2])) " and turned "
            (format!("{:.1}\u{b0}", g.yaw_deg)) ", leaving "
            (format!("{:.0} mm", 1000.0 * g.rms_m)) " RMS between the surfaces over "
            (format!("{:.0}%", g.overlap_pct)) " of the earlier map."
        }
        div.cards {
            @for &k in ChangeKind::ALL {
                div.card { b { (c.count(k)) } span { (k.words()) } }
            }
        }
        (element_changes(c))
        @if listed.is_empty() {
            p { "Every crack seen before is seen again, and none has grown or is new." }
        } @else {
            p.sub {
                "New, first seen, grown and widened cracks first. A crack is new where the earlier flight inspected its place, "
                "first seen where it did not, or too coarsely to see a crack this narrow; "
                "grown when it is longer along its trace by more than both flights' measurement spread, "
                "or its trace runs on beyond the earlier one where the earlier flight would have seen it; "
                "widened when its widest is wider by more than both flights' width uncertainties combined and a fifth of its earlier width; "
                "one not measured was seen by both, but neither its length nor its width was measured in both, so whether it changed is not known; "
                "one not re-inspected was not inspected by this flight, so nothing is known of it now. "
                (c.count(ChangeKind::Unchanged)) " unchanged cracks are listed in changes.parquet."
            }
            table {
                tr {
                    th { "change" } th { "before" } th { "now" } th { "where" }
                    th.n { "length, before \u{2192} now" } th.n { "widest, before \u{2192} now" }
                }
                @for ch in listed { (change_row(r, ch)) }
            }
        }
    }
}

fn change_row(r: &RunResults, ch: &ChangeRecord) -> Markup {
    let now = ch
        .after
        .as_ref()
        .and_then(|id| r.defects.iter().find(|d| &d.id == id));
    let before = ch
        .before
        .as_ref()
        .and_then(|id| r.earlier_crop(id))
        .map(|b| jpeg_data(&b));
    let metres =
        |m: Option<f64>| m.map_or_else(|| "\u{2013}".to_string(), |m| format!("{m:.2}\u{a0}m"));
    let millimetres =
        |m: Option<f64>| m.map_or_else(|| "\u{2013}".to_string(), |m| format!("{m:.2}\u{a0}mm"));
    let place = match now {
        Some(d) => place_text(r.place(d).map(|p| p.to_string()).as_deref(), d),
        None => ch.element.clone().unwrap_or_default(),
    };
    html! {
        tr {
            td {
                @match ch.change {
                    k if k.stands_out() => b.flag { (ch.change.words()) },
                    other => (other.words()),
                }
                @if ch.change == ChangeKind::FirstSeen {
                    br;
                    @match (ch.earlier_inspected, ch.earlier_mm_per_px) {
                        (Some(true), Some(px)) => span.sub { (format!("the earlier flight saw here at {px:.1} mm/px, too coarse for it")) },
                        _ => span.sub { "the earlier flight did not inspect here" },
                    }
                }
            }
            td { @if let Some(src) = before { img.thumb alt="the crack before" src=(src); } }
            td { @if let Some(src) = now.and_then(|d| crop_data(r, d)) { img.thumb alt="the crack now" src=(src); } }
            td {
                (place) br;
                span.sub { (ch.after.as_deref().or(ch.before.as_deref()).unwrap_or_default()) }
            }
            td.n {
                (before_now(metres(ch.length_before_m), metres(ch.length_after_m), ch.before.is_some()))
                @if let (Some(g), Some(s)) = (ch.growth_m, ch.spread_m) {
                    br; span.sub { (format!("{g:+.2} m, spread {s:.2} m")) }
                }
            }
            td.n {
                (before_now(millimetres(ch.width_before_mm), millimetres(ch.width_after_mm), ch.before.is_some()))
                @if let (Some(w), Some(s)) = (ch.widening_mm, ch.width_spread_mm) {
                    br; span.sub { (format!("{w:+.2} mm, uncertainty {s:.2} mm")) }
                }
            }
        }
    }
}

/// "before \u{2192} now", or now alone for a crack the earlier flight did not
/// find.
fn before_now(before: String, now: String, was_found: bool) -> String {
    if was_found {
        format!("{before} \u{2192} {now}")
    } else {
        now
    }
}
