//! `report.html`: one self-contained page (styles, pictures and thumbnails
//! inline, no scripts, nothing fetched) that reads on screen and prints:
//! the flight, coverage achieved against planned, the defect candidates in
//! review order, the follow-up flight and how the run went. Written with
//! maud's templates, which escape every value unless told it is markup
//! (the SVG pictures, built by [`crate::svg`], which escapes its own text).
//!
//! The page reads top to bottom as its sections, each written by its
//! module: the flight's [`recordings`], the [`changes`] since an earlier
//! inspection, [`coverage`], the [`defects`] in review order, the element
//! [`record`] and the follow-up flight ([`replan`]); the cards, the files
//! and the run's timings are here.

mod changes;
mod coverage;
mod defects;
mod record;
mod recordings;
mod replan;

pub use replan::{follow_up_text, nothing_to_fly};

use self::changes::changes_section;
use self::coverage::coverage_section;
use self::defects::{defects_section, detections_appendix};
use self::record::record_section;
use self::recordings::recordings_section;
use self::replan::replan_section;

use maud::{Markup, PreEscaped, html};
use postflight_core::Stage;
use postflight_core::outputs::changes::files as changes_files;
use postflight_core::outputs::ingest::{
    PhotoFolderSummary, ReconstructionFormat, ReconstructionPlacedBy, SkippedPhoto,
};
use postflight_core::outputs::report::{DEFAULT_REVIEW_ADDR, RunSummary};

use page::{STYLE, document, readable_time};

use crate::results::RunResults;

/// The flight as the title names it: its recording's file name, or with
/// several, the first and how many more.
fn flight_name(recordings: &[std::path::PathBuf]) -> String {
    let name = |p: &std::path::PathBuf| {
        p.file_name().map_or_else(
            || p.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        )
    };
    match recordings {
        [] => String::new(),
        [one] => name(one),
        [first, rest @ ..] => format!("{} and {} more recordings", name(first), rest.len()),
    }
}

/// The page for `results`, with `summary` already computed from them.
pub fn page(results: &RunResults, summary: &RunSummary) -> String {
    let title = format!("Inspection report: {}", flight_name(&summary.recordings));
    let body = html! {
        h1 { (title) }
        p.sub {
            "Flight of " (readable_time(&summary.flight_start)) ", "
            (format!("{:.0}", summary.duration_s)) " s, "
            (summary.frames) " frames (" (summary.frames_with_pose) " with pose). "
            "Files linked below are in the run directory, beside this page."
        }
        (photos_line(results))
        @if summary.truncated {
            p.warn {
                b { "Truncated recording." }
                " A flight file was cut short; postflight salvaged what it holds, and everything below describes only that part of the flight."
            }
        }
        (cards(summary))
        (recordings_section(results))
        (files_section(results))
        (changes_section(results))
        (coverage_section(results))
        (defects_section(results))
        (record_section(results))
        (replan_section(results))
        (run_section(summary))
        (detections_appendix(results))
    };
    let style = format!("{STYLE}{}", page::record::RECORD_STYLE);
    document(&title, html! { style { (PreEscaped(style)) } }, body)
}

/// Where a photo flight's poses came from: its photos (how many were
/// posed, how many with a fixed RTK solution, which were skipped and why),
/// the reconstruction that refined them, and the frame they are in.
fn photos_line(r: &RunResults) -> Markup {
    let summary = &r.flight.summary;
    let folders: Vec<&PhotoFolderSummary> = summary
        .recordings
        .iter()
        .filter_map(|rec| rec.photos.as_ref())
        .collect();
    let Some(first) = folders.first() else {
        return html! {};
    };
    let sum = |f: fn(&PhotoFolderSummary) -> u64| folders.iter().map(|p| f(p)).sum::<u64>();
    let photos = sum(|p| p.photos);
    let skipped: Vec<&SkippedPhoto> = folders.iter().flat_map(|p| &p.skipped).collect();
    let posed = photos - skipped.len() as u64;
    // Skipped photos by why, in the order first met.
    let mut why: Vec<(&str, Vec<&str>)> = Vec::new();
    for s in &skipped {
        match why.iter_mut().find(|(w, _)| *w == s.why) {
            Some((_, names)) => names.push(&s.photo),
            None => why.push((&s.why, vec![&s.photo])),
        }
    }
    let o = &first.origin.position;
    html! {
        p.sub {
            (posed) " of " (photos) " geotagged photos posed"
            @if folders.len() > 1 { " from " (folders.len()) " folders" }
            " (" (sum(|p| p.rtk_fixed)) " with a fixed RTK solution), in the east-north-up frame at "
            (format!("{:.6}, {:.6}, {:.1} m", o.latitude_deg, o.longitude_deg, o.altitude_m)) "; "
            @match &summary.reconstruction {
                Some(rec) => {
                    (rec.posed) " by the reconstruction " code { (rec.path.display()) }
                    " (" (match rec.format { ReconstructionFormat::Colmap => "COLMAP", ReconstructionFormat::OpenSfm => "OpenSfM" }) ", "
                    (match rec.placed_by {
                        ReconstructionPlacedBy::Reference => "on the Earth by its reference".to_string(),
                        ReconstructionPlacedBy::GpsFit { photos, rms_m } => format!("fitted to {photos} photos' GPS at {:.1} cm RMS", rms_m * 100.0),
                    }) "), the others by their tags."
                },
                None => "each by its tags (GPS, gimbal angles, lens).",
            }
            @for (reason, names) in &why {
                " " span.flag { (names.len()) " skipped" } ", " (reason) ": "
                @for (i, name) in names.iter().take(3).enumerate() {
                    @if i > 0 { ", " } code { (name) }
                }
                @if names.len() > 3 { " and " (names.len() - 3) " more" }
                "."
            }
        }
    }
}

fn cards(s: &RunSummary) -> Markup {
    let card = |value: String, what: &str| html! { div.card { b { (value) } span { (what) } } };
    html! {
        div.cards {
            (card(s.frames.to_string(), "frames"))
            @if let Some(d) = s.detections { (card(d.to_string(), "detections")) }
            @if let Some(d) = s.defects { (card(d.to_string(), "defect candidates")) }
            @if let Some(c) = &s.coverage {
                (card(format!("{:.1}%", c.inspected_pct), "of target voxels inspected"))
                @if let Some(p) = c.planned_inspected_pct {
                    (card(format!("{p:.1}%"), "of planned voxels inspected"))
                }
                (card(c.gap_voxels.to_string(), "gap voxels"))
                (card(c.uninspectable_voxels.to_string(), "uninspectable voxels"))
            }
            @if let Some(r) = &s.replan {
                (card(format!("{:.0} m", r.length_m), &format!("follow-up flight, {} sortie{}", r.sorties, if r.sorties == 1 { "" } else { "s" })))
            }
        }
    }
}

/// Where to go from here: the review queue and the run's files.
fn files_section(r: &RunResults) -> Markup {
    let link = |file: &str, what: &str| {
        html! {
            @if r.file(file).is_file() {
                li { a href=(file) { code { (file) } } " \u{2013} " (what) }
            }
        }
    };
    html! {
        h2 { "Review and files" }
        p {
            "Decide each candidate in the review queue: "
            code { "postflight review serve --run <this directory>" }
            ", then open " a href=(format!("http://{DEFAULT_REVIEW_ADDR}/")) { (format!("http://{DEFAULT_REVIEW_ADDR}/")) } "."
        }
        ul {
            (link("candidates.csv", "the candidates below, with their places, for spreadsheets"))
            (link("defects.parquet", "defect candidates (polars, pandas, DuckDB)"))
            (link("defects", "best-view crops of every candidate"))
            (link("coverage.parquet", "coverage of every target voxel, with its element and place"))
            (link(changes_files::TABLE, "every candidate's change since the earlier inspection"))
            (link("replan.csv", "the follow-up flight: X,Y,Z,Yaw with gimbal pitch, sortie and kind of point"))
            (link("replan.json", "the follow-up flight with every waypoint's gap voxels"))
            (link("detections.coco.json", "raw detections, COCO"))
            (link("flight.rrd", "the Rerun recording (rerun flight.rrd)"))
            (link("summary.json", "the run in numbers"))
        }
    }
}

fn run_section(s: &RunSummary) -> Markup {
    // Pipeline order, then anything else.
    let order = |name: &str| Stage::ALL.iter().position(|s| s.name() == name);
    let mut stages: Vec<(&String, &f64)> = s.timings_s.iter().collect();
    stages.sort_by_key(|(name, _)| order(name).unwrap_or(Stage::ALL.len()));
    let v = &s.versions;
    html! {
        h2 { "The run" }
        table {
            tr { th { "stage" } th.n { "seconds" } }
            @for (stage, secs) in stages {
                tr { td { (stage) } td.n { (format!("{secs:.1}")) } }
            }
        }
        p {
            "postflight " (v.postflight) "; model "
            (v.model.as_ref().and_then(|m| m.file_name()).map_or("-".into(), |m| m.to_string_lossy().into_owned()))
            " (SHA-256 " (v.model_sha256.as_deref().unwrap_or("-")) "); ONNX Runtime "
            (v.onnxruntime.as_deref().unwrap_or("-")) "."
        }
        @if !s.warnings.is_empty() {
            h3 { "Warnings" }
            ul { @for w in &s.warnings { li { (w) } } }
        }
    }
}
