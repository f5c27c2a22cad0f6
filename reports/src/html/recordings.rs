//! The report's recordings: each flight file and how its frames were
//! placed (its own poses, a reconstruction, the photos' tags).

use maud::{Markup, html};
use postflight_core::outputs::ingest::{PlacedBy, Placement};

use page::readable_time;

use crate::results::RunResults;

/// A flight of several recordings (sorties, or drones): what each held
/// and how many candidates its frames show. Nothing for one recording.
pub(super) fn recordings_section(r: &RunResults) -> Markup {
    let recordings = &r.flight.summary.recordings;
    if recordings.len() < 2 {
        return html! {};
    }
    let mut frames_with_pose = vec![0u64; recordings.len()];
    for f in r.flight.frames.iter().filter(|f| f.camera_pose.is_some()) {
        if let Some(n) = frames_with_pose.get_mut(usize::from(f.recording)) {
            *n += 1;
        }
    }
    let mut candidates = vec![0usize; recordings.len()];
    for d in &r.defects {
        for i in r.recordings_of(d) {
            if let Some(n) = candidates.get_mut(usize::from(i)) {
                *n += 1;
            }
        }
    }
    html! {
        h2 { "Recordings" }
        p {
            "The flight was recorded as " (recordings.len()) " recordings (sorties or drones), processed as one: "
            "coverage counts every frame of every recording, and the views of one crack are fused into one candidate whichever recording saw them."
        }
        table {
            tr {
                th { "#" } th { "recording" } th { "start" } th.n { "flown" } th.n { "frames" }
                th.n { "poses" } th { "map" } th { "frame" } th.n { "candidates seen" }
            }
            @for (i, rec) in recordings.iter().enumerate() {
                tr {
                    td { (i + 1) }
                    td { code { (rec.name()) } @if rec.truncated { br; span.flag { "truncated, salvaged" } } }
                    td { (readable_time(&postflight_core::time::rfc3339(rec.start_time_ns))) }
                    td.n { (format!("{:.0} s", rec.duration_s())) }
                    td.n { (rec.frames) br; span.sub { (frames_with_pose[i]) " with pose" } }
                    td.n { (rec.poses) }
                    td { @match &rec.map { Some(m) => { (m.points) " points on " code { (m.topic) } }, None => "\u{2013}" } }
                    td { (placed_by(&rec.placement)) }
                    td.n { (candidates[i]) }
                }
            }
        }
    }
}

/// How a recording's frame was put into the run's, in a few words, with
/// how far it was moved.
fn placed_by(placement: &Placement) -> String {
    let t = &placement.transform;
    let moved = format!(
        "{:.2} m, {:.1}\u{b0}",
        t.translation.vector.norm(),
        t.rotation.angle().to_degrees()
    );
    match placement.by {
        PlacedBy::Reference => "the run's".into(),
        PlacedBy::SharedFrame => "shared with the first".into(),
        PlacedBy::Registered { rms_m, overlap } => format!(
            "map registered ({moved}; {:.1} cm rms, {:.0}% overlap)",
            rms_m * 100.0,
            overlap * 100.0
        ),
        PlacedBy::Given => format!("as the settings give it ({moved})"),
        PlacedBy::Gps { rms_m, fixes } => {
            format!("by {fixes} GPS fixes ({moved}; fits {rms_m:.1} m rms)")
        }
    }
}
