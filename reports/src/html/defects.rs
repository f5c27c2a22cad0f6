//! The report's defect candidates in review order (each with its crop,
//! place, length, width and condition state), and the appendix of their
//! detection boxes.

use base64::Engine;
use maud::{Markup, html};
use postflight_core::outputs::localise::DefectRecord;

use page::{evidence_text, length_text, place_text, state_cell, width_cell};

use crate::results::{RunResults, review_priority};

pub(super) fn defects_section(r: &RunResults) -> Markup {
    let order = r.defects_for_review();
    html! {
        h2 { "Defect candidates, in review order" }
        @if r.localise.is_none() {
            p { "Detections have not been placed on the map for this run." }
        } @else if order.is_empty() {
            p { "No defect candidates: the detector found no cracks that could be placed on the structure." }
        } @else {
            p {
                (order.len())
                " candidates, likeliest and largest first (fused confidence \u{d7} length, or extent where the length is unknown). Each is one physical crack fused from its supporting views; the picture is its best view (meeting the View model if one does, then the finest). Candidates whose evidence is weak are flagged for a re-shoot, and the follow-up flight goes back for them."
            }
            table {
                tr {
                    th { "#" } th { "best view" } th { "candidate" } th.n { "length" }
                    th.n { "width" } th { "state" } th.n { "GSD" } th.n { "range" }
                    th.n { "confidence" }
                }
                @for (i, d) in order.iter().enumerate() {
                    (defect_row(r, i + 1, d))
                }
            }
        }
    }
}

/// The id of a candidate's row in the defects table.
pub(super) fn candidate_anchor(id: &str) -> String {
    format!("candidate-{id}")
}

fn defect_row(r: &RunResults, rank: usize, d: &DefectRecord) -> Markup {
    let thumb = crop_data(r, d);
    let p = d.position;
    html! {
        tr id=(candidate_anchor(&d.id)) {
            td { (rank) }
            td {
                @match (thumb, &d.crop) {
                    (Some(src), Some(crop)) => a href=(crop) {
                        img.thumb alt=(format!("best view of {}", d.id)) src=(src);
                    },
                    _ => "(no image)",
                }
            }
            td {
                b { (place_text(r.place(d).map(|p| p.to_string()).as_deref(), d)) } br;
                span.sub {
                    (d.id) (format!(" at ({:.2}, {:.2}, {:.2}) m", p[0], p[1], p[2]))
                    @if let Some(u) = d.position_uncertainty_m { (format!(" \u{b1} {:.0} cm", u * 100.0)) }
                    "; "
                    (d.frames) " supporting frames, best frame " (d.best.frame)
                    " (" a href=(format!("#boxes-{rank}")) { "boxes" } ")"
                    @if r.flight.summary.recordings.len() > 1 {
                        "; seen in " (r.recording_names_of(d))
                    }
                }
                @if let Some(weak) = evidence_text(d) { br; span.flag { (weak) } }
            }
            td.n { (length_text(d)) }
            td.n { (width_cell(d)) }
            td { (state_cell(d.condition)) }
            td.n { (format!("{:.1} mm/px", d.best.oblique_gsd_mm)) }
            td.n { (format!("{:.1} m", d.best.range_m)) }
            td.n {
                (format!("{:.2}", d.confidence)) br;
                span.sub { (format!("priority {:.2}", review_priority(d))) }
            }
        }
    }
}

/// A JPEG as a `data:` address, for a page that carries its pictures.
pub(super) fn jpeg_data(bytes: &[u8]) -> String {
    format!(
        "data:image/jpeg;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

/// A candidate's best-view crop as a `data:` address.
pub(super) fn crop_data(r: &RunResults, d: &DefectRecord) -> Option<String> {
    let bytes = std::fs::read(r.file(d.crop.as_ref()?)).ok()?;
    Some(jpeg_data(&bytes))
}

/// Every supporting detection box of every candidate, out of the way of
/// the table above.
pub(super) fn detections_appendix(r: &RunResults) -> Markup {
    let order = r.defects_for_review();
    html! {
        @if !order.is_empty() {
            h2 { "Appendix: supporting detections" }
            p.sub { "Per candidate, its boxes: frame, [x0, y0, x1, y1] in pixels, detector score." }
            table.frames {
                tr { th { "#" } th { "candidate" } th { "boxes" } }
                @for (i, d) in order.iter().enumerate() {
                    tr id=(format!("boxes-{}", i + 1)) {
                        td { (i + 1) }
                        td { (d.id) }
                        td {
                            @for (k, v) in d.views.iter().enumerate() {
                                @if k > 0 { "; " }
                                (format!(
                                    "frame {} [{:.0}, {:.0}, {:.0}, {:.0}] {:.2}",
                                    v.frame, v.bbox[0], v.bbox[1], v.bbox[2], v.bbox[3], v.score
                                ))
                            }
                        }
                    }
                }
            }
        }
    }
}
