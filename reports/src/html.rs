//! `report.html`: one self-contained page (styles, pictures and thumbnails
//! inline, no scripts, nothing fetched) that reads on screen and prints:
//! the flight, coverage achieved against planned, the defect candidates in
//! review order, the follow-up flight and how the run went. Written with
//! maud's templates, which escape every value unless told it is markup
//! (the SVG pictures, built by [`crate::svg`], which escapes its own text).

use std::collections::BTreeMap;

use base64::Engine;
use maud::{Markup, PreEscaped, html};
use postflight_core::ViewModel;
use postflight_core::outputs::changes::{ChangeKind, ChangeRecord, files as changes_files};
use postflight_core::outputs::coverage::CoverageSummary;
use postflight_core::outputs::ingest::{
    PhotoFolderSummary, PlacedBy, Placement, ReconstructionFormat, ReconstructionPlacedBy,
    SkippedPhoto,
};
use postflight_core::outputs::localise::DefectRecord;
use postflight_core::outputs::replan::{
    GapChoice, ReplanSummary, Unplannable, files as replan_files,
};
use postflight_core::outputs::report::{DEFAULT_REVIEW_ADDR, RunSummary};
use postflight_core::table::Named;

use page::{
    STYLE, condition_text, document, evidence_text, length_text, place_text, readable_time,
    width_cell,
};
use postflight_core::condition::ConditionState;

use crate::results::{ElementCracks, RunResults, VoxelStatus, review_priority};
use crate::svg::bar_chart;
use crate::views::{HEIGHT_COLOURS, Marker, Overlay, Side, colour, view, width_m};

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
        (replan_section(results))
        (run_section(summary))
        (detections_appendix(results))
    };
    document(&title, html! { style { (PreEscaped(STYLE)) } }, body)
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

fn legend() -> Markup {
    html! {
        p.legend {
            @for s in VoxelStatus::ALL {
                span { i style=(format!("background:{}", colour(s))) {} (s.label()) }
            }
            span { "\u{25CF} defect candidate (number = review order)" }
        }
    }
}

fn coverage_section(r: &RunResults) -> Markup {
    html! {
        h2 { "Coverage: achieved against planned" }
        @match &r.coverage {
            None => p {
                "Coverage was not computed for this run (it needs an inspection plan: "
                code { "--plan" } ")."
            },
            Some(c) => {
                (view_model(c))
                (coverage_table(c))
                (element_table(r))
                (legend())
                (coverage_views(r, c))
                (miss_reasons(c))
            }
        }
    }
}

fn view_model(c: &CoverageSummary) -> Markup {
    html! {
        p {
            "Under the View model: " (view_rules(&c.view))
            (format!("; {:.2} m voxels, targets from ", c.resolution_m))
            (c.targets) "."
        }
        @if !c.focus.is_empty() {
            p { "Focus regions, judged under a stricter View model:" }
            ul {
                @for f in &c.focus {
                    li {
                        b { (f.model.region.name) } ": " (view_rules(&f.model.view))
                        (format!(
                            "; {} of its {} target voxels inspected.",
                            f.inspected_voxels, f.target_voxels
                        ))
                    }
                }
            }
        }
    }
}

/// A View model's rules in a line.
fn view_rules(v: &ViewModel) -> String {
    format!(
        "cone apex {:.0}\u{b0}, distance {:.1}\u{2013}{:.1} m, incidence up to {:.0}\u{b0}, blur up to {:.1} px, GSD up to {:.1} mm/px, {} view(s) per face",
        v.cone_apex_deg,
        v.min_distance_m,
        v.max_distance_m,
        v.max_incidence_deg,
        v.max_blur_px,
        v.max_gsd_mm,
        v.views_required,
    )
}

fn coverage_table(c: &CoverageSummary) -> Markup {
    let pct = |n: usize, of: usize| {
        if of == 0 {
            "\u{2013}".to_string()
        } else {
            format!("{:.1}%", 100.0 * n as f64 / of as f64)
        }
    };
    let t = c.target_voxels;
    // Each column one denominator: the targets, then the planned voxels.
    let row = |what: &str, n: usize, of_planned: Option<usize>| {
        html! {
            tr {
                td { (what) } td.n { (n) } td.n { (pct(n, t)) }
                @if let Some(p) = c.planned_voxels {
                    td.n { (of_planned.map_or("\u{2013}".into(), |n| pct(n, p))) }
                }
            }
        }
    };
    html! {
        table {
            tr {
                th { "voxels" } th.n { "count" } th.n { "of target" }
                @if c.planned_voxels.is_some() { th.n { "of planned" } }
            }
            (row("target", t, None))
            @if let Some(p) = c.planned_voxels { (row("planned", p, Some(p))) }
            (row("inspected", c.inspected_voxels, None))
            @if let (Some(p), Some(missed)) = (c.planned_voxels, c.planned_missed_voxels) {
                (row("planned and inspected", p - missed, Some(p - missed)))
                (row("planned but missed", missed, Some(missed)))
            }
            (row("gaps (a follow-up flight can inspect them)", c.gap_voxels, None))
            (row("uninspectable (no free viewpoint satisfies the View)", c.uninspectable_voxels, None))
        }
        p.sub {
            (format!("{:.1}% of the exposed face area was inspected.", c.face_area_coverage_pct))
        }
    }
}

/// Per element: surface area by coverage status (where the gaps are) and
/// crack length by condition state (what element-level records keep).
fn element_table(r: &RunResults) -> Markup {
    let m2 = |a: f64| format!("{a:.1}");
    let cracks = r.element_cracks();
    html! {
        @if !r.element_areas.is_empty() || !cracks.is_empty() {
            h3 { "By element" }
        }
        @if !r.element_areas.is_empty() {
            p.sub {
                "Exposed surface of the target voxels, m\u{b2}. Elements are found from the map's geometry: piers numbered from the west (south) end, girders from the south (east) side."
            }
            table #element-areas {
                tr {
                    th { "element" } th.n { "surface" } th.n { "inspected" }
                    th.n { "planned, missed" } th.n { "not planned" } th.n { "uninspectable" }
                }
                @for a in &r.element_areas {
                    tr {
                        td { (a.element) }
                        td.n { (m2(a.target_m2)) }
                        td.n {
                            (m2(a.inspected_m2))
                            span.sub { (format!(" ({:.0}%)", 100.0 * a.inspected_m2 / a.target_m2.max(1e-9))) }
                        }
                        td.n { (m2(a.planned_missed_m2)) }
                        td.n { (m2(a.not_planned_m2)) }
                        td.n { (m2(a.uninspectable_m2)) }
                    }
                }
            }
        }
        @if !cracks.is_empty() {
            (crack_states_table(&cracks))
        }
    }
}

/// Crack length per element in each condition state.
fn crack_states_table(cracks: &[ElementCracks]) -> Markup {
    let m = |l: f64| {
        if l > 0.0 {
            format!("{l:.2}")
        } else {
            "\u{2013}".into()
        }
    };
    html! {
        p.sub {
            "Crack length, m, in each condition state its widest point puts it in (AASHTO MBEI cracking defect; docs/condition.md), before review: the review queue's exports carry each inspector's corrections."
        }
        table #crack-states {
            tr {
                th { "element" } th.n { "cracks" }
                @for state in ConditionState::ALL {
                    th.n { (condition_text(Some(*state))) }
                }
                th.n { "no state" } th.n { "length unknown" }
            }
            @for e in cracks {
                tr {
                    td { (e.element.as_deref().unwrap_or("on no element")) }
                    td.n { (e.cracks) }
                    @for l in e.state_m { td.n { (m(l)) } }
                    td.n { (m(e.no_state_m)) }
                    td.n { @if e.unmeasured > 0 { (e.unmeasured) } @else { "\u{2013}" } }
                }
            }
        }
    }
}

fn coverage_views(r: &RunResults, c: &CoverageSummary) -> Markup {
    let markers: Vec<Marker> = r
        .defects_for_review()
        .iter()
        .enumerate()
        .map(|(i, d)| Marker {
            label: (i + 1).to_string(),
            position: d.position,
            normal: d.normal,
            trace: &d.trace,
            condition: d.condition,
        })
        .collect();
    let overlay = Overlay {
        markers,
        ..Overlay::default()
    };
    // Every side at one scale: the widest 500 px.
    let widths = Side::ALL.map(|side| width_m(&r.voxels, c.resolution_m, side));
    let widest = widths.iter().copied().fold(1e-9, f64::max);
    html! {
        div.views {
            @for (side, w) in Side::ALL.into_iter().zip(widths) {
                figure {
                    (PreEscaped(view(&r.voxels, c.resolution_m, side, &overlay, (500.0 * w / widest).max(160.0))))
                    figcaption { "Target voxels " (side.title()) }
                }
            }
        }
        p.sub { "Candidates are marked in the views that face their surface: solid where the spot is in front, hollow where nearer parts hide it; the line over it is the crack's trace, coloured by its condition state (green 1, amber 2, red 3, purple 4, grey none)." }
    }
}

fn miss_reasons(c: &CoverageSummary) -> Markup {
    let mut bars: Vec<(String, f64)> = c
        .reasons
        .iter()
        .map(|(k, n)| (k.name().replace('_', " "), *n as f64))
        .collect();
    bars.sort_by(|a, b| b.1.total_cmp(&a.1));
    html! {
        @if !bars.is_empty() {
            h3 { "Why voxels were not inspected" }
            p.sub { "Each not-inspected voxel counted once, by the furthest View rule any frame reached." }
            (PreEscaped(bar_chart(&bars, "#d7301f", "Reasons voxels were not inspected")))
        }
    }
}

fn defects_section(r: &RunResults) -> Markup {
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

/// A JPEG as a `data:` address, for a page that carries its pictures.
fn jpeg_data(bytes: &[u8]) -> String {
    format!(
        "data:image/jpeg;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

/// A candidate's best-view crop as a `data:` address.
fn crop_data(r: &RunResults, d: &DefectRecord) -> Option<String> {
    let bytes = std::fs::read(r.file(d.crop.as_ref()?)).ok()?;
    Some(jpeg_data(&bytes))
}

/// What changed since the earlier inspection `postflight compare` was given.
fn changes_section(r: &RunResults) -> Markup {
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

fn defect_row(r: &RunResults, rank: usize, d: &DefectRecord) -> Markup {
    let thumb = crop_data(r, d);
    let p = d.position;
    html! {
        tr {
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
            td { (condition_text(d.condition)) }
            td.n { (format!("{:.1} mm/px", d.best.oblique_gsd_mm)) }
            td.n { (format!("{:.1} m", d.best.range_m)) }
            td.n {
                (format!("{:.2}", d.confidence)) br;
                span.sub { (format!("priority {:.2}", review_priority(d))) }
            }
        }
    }
}

/// A flight of several recordings (sorties, or drones): what each held
/// and how many candidates its frames show. Nothing for one recording.
fn recordings_section(r: &RunResults) -> Markup {
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

/// Why the follow-up flight has nothing to fly, if it has not (the
/// report's and the command line's words).
pub fn nothing_to_fly(p: &ReplanSummary) -> Option<String> {
    if p.gap_voxels > 0 {
        return None;
    }
    Some(if p.coverage_gap_voxels == 0 {
        "no gaps: coverage found nothing to replan and no candidate needs a re-shoot".into()
    } else {
        format!(
            "nothing to fly: none of the {} gaps is of the kind chosen ({}) and no candidate needs a re-shoot; --gaps all flies every gap",
            p.coverage_gap_voxels,
            p.gaps.as_str()
        )
    })
}

/// What the follow-up flight goes back for and what it is, in a sentence
/// (the report's and the command line's words).
pub fn follow_up_text(p: &ReplanSummary) -> String {
    let n = p.coverage_gap_voxels;
    let chosen = match p.gaps {
        GapChoice::Missed => format!("the planned voxels the flight missed, of {n} gaps"),
        GapChoice::All => format!("all {n} gaps"),
        GapChoice::Reshoot => format!("none of the {n} gaps"),
    };
    let plural = |n: usize, word: &str| format!("{n} {word}{}", if n == 1 { "" } else { "s" });
    let team = match p.drones.len() {
        0 | 1 => String::new(),
        n => format!(
            ", shared by {n} drones: the mission takes about {:.1} min (first take-off to last landing), the sorties {:.1} min in all",
            p.mission_time_s / 60.0,
            p.time_s / 60.0
        ),
    };
    format!(
        "{} of {} chosen voxels planned ({chosen}, plus {} to re-shoot): {} (a greedy set cover needs {}) in {} within a {:.0}-minute battery{team}: {:.0} m, about {:.1} min ({:.1} min hovering, {:.0} s a waypoint; {:.1} min flying at {:.1} m/s); at least {:.1} m from every occupied voxel.",
        p.planned_gap_voxels,
        p.gap_voxels,
        plural(p.reshoot_spots.len(), "candidate"),
        plural(p.waypoints, "waypoint"),
        p.set_cover_viewpoints,
        plural(p.sorties.len(), "sortie"),
        p.battery_minutes,
        p.length_m,
        p.time_s / 60.0,
        p.hover_time_s / 60.0,
        p.hover_s,
        p.travel_time_s / 60.0,
        p.speed_m_s,
        p.clearance_m,
    )
}

/// The airspace the follow-up keeps to, in a sentence.
fn airspace_text(p: &ReplanSummary) -> String {
    let zones: Vec<String> = p
        .keep_out
        .iter()
        .map(|z| {
            let band = match (z.bottom_m, z.top_m) {
                (None, None) => "from the ground up".to_string(),
                (Some(b), None) => format!("above {b:.1} m"),
                (None, Some(t)) => format!("below {t:.1} m"),
                (Some(b), Some(t)) => format!("{b:.1}\u{2013}{t:.1} m"),
            };
            format!("{} ({band})", z.name)
        })
        .collect();
    let mut text = String::new();
    if !zones.is_empty() {
        text += &format!(
            "No waypoint and no point of the path is in the keep-out zones: {}",
            zones.join(", ")
        );
        if p.keep_out.iter().any(|z| z.is_column()) && !p.ground_station_files.is_empty() {
            text += "; the missions' geofence holds those from the ground up";
        }
        text += ". ";
    }
    if let Some(c) = p.ceiling_z_m {
        text += &format!("Every point is below the ceiling at {c:.1} m (map z).");
    }
    text.trim_end().to_string()
}

fn replan_section(r: &RunResults) -> Markup {
    html! {
        h2 { "Follow-up flight for the gaps" }
        @match &r.replan {
            None => p { "No follow-up flight was planned for this run." },
            Some(p) if nothing_to_fly(p).is_some() => p {
                (nothing_to_fly(p).unwrap_or_default())
            },
            Some(p) => (follow_up(r, p)),
        }
    }
}

fn follow_up(r: &RunResults, p: &ReplanSummary) -> Markup {
    let count = |reason| {
        p.uninspectable_gaps
            .iter()
            .filter(|u| u.reason == reason)
            .count()
    };
    let team = p.drones.len() > 1;
    let overlay = Overlay {
        paths: p.sorties.iter().map(|s| s.path.as_slice()).collect(),
        points: p
            .sorties
            .iter()
            .flat_map(|s| s.waypoints.iter().map(|w| [w.x, w.y, w.z]))
            .collect(),
        home: Some(p.home),
        grey: true,
        ..Overlay::default()
    };
    html! {
        p {
            (follow_up_text(p)) " "
            "Flyable files: " code { "replan.json" } " (waypoints with yaw and gimbal pitch), "
            code { "replan.csv" } " (X,Y,Z,Yaw with gimbal pitch, sortie and kind of point)"
            @if let (Some(o), false) = (&p.geo_origin, p.ground_station_files.is_empty()) {
                ", and for ground stations "
                @for (i, file) in p.ground_station_files.iter().enumerate() {
                    @if i > 0 { ", " }
                    code { (file) }
                }
                (format!(
                    " (the map's origin at {:.6}, {:.6}, {:.1} m, its x axis {:.1}° from east; from {}).",
                    o.position.latitude_deg,
                    o.position.longitude_deg,
                    o.position.altitude_m,
                    o.yaw_deg,
                    p.geo_origin_from.as_deref().unwrap_or("settings"),
                ))
            } @else {
                ". Given where the map is on the Earth ("
                code { "postflight replan --geo-origin LAT,LON,ALT[,YAW_DEG]" }
                ", or GPS fixes or geotagged photos in the flight), replan also writes QGroundControl and DJI missions, KML and GeoJSON."
            }
        }
        @if !p.keep_out.is_empty() || p.ceiling_z_m.is_some() {
            p { (airspace_text(p)) }
        }
        @if !p.uninspectable_gaps.is_empty() {
            p.warn {
                (format!(
                    "{} gap voxels cannot be planned: {} with no viewpoint that keeps the clearance{}, {} with fewer such viewpoints than the views they need, {} unreachable from home.",
                    p.uninspectable_gaps.len(),
                    count(Unplannable::NoClearViewpoint),
                    if p.keep_out.is_empty() && p.ceiling_z_m.is_none() { "" } else { " and the airspace" },
                    count(Unplannable::TooFewViewpoints),
                    count(Unplannable::Unreachable)
                ))
            }
        }
        div.views {
            @for side in [Side::Top, Side::South] {
                figure {
                    (PreEscaped(view(&r.voxels, p.resolution, side, &overlay, 500.0)))
                    figcaption {
                        "Follow-up flight, " (side.title())
                        ": waypoints numbered in flight order (numbers that would overlap left out), coloured by height (ramp, "
                        (HEIGHT_COLOURS.len()) " steps, low to high)"
                    }
                }
            }
        }
        (gaps_by_element(r, p))
        (team_plan(p))
        table {
            tr {
                @if team { th { "drone" } }
                th { "sortie" } th.n { "waypoints" } th.n { "gap voxels" }
                th.n { "length" } th.n { "time" }
            }
            @for (i, s) in p.sorties.iter().enumerate() {
                tr {
                    @if team { td { (s.drone + 1) } }
                    // A team's sorties are numbered within their drone.
                    td { (p.sorties[..i].iter().filter(|o| o.drone == s.drone).count() + 1) }
                    td.n { (s.waypoints.len()) }
                    td.n { (s.waypoints.iter().map(|w| w.gap_voxels.len()).sum::<usize>()) }
                    td.n { (format!("{:.0} m", s.length_m)) }
                    td.n { (format!("{:.1} min", s.time_s / 60.0)) }
                }
            }
        }
    }
}

/// A team's plan, drone by drone: its share of the flight and its files.
/// Nothing for one drone.
fn team_plan(p: &ReplanSummary) -> Markup {
    if p.drones.len() < 2 {
        return html! {};
    }
    let files_of = |drone: usize| -> Vec<String> {
        let prefix = format!("replan-drone-{}", drone + 1);
        let own = p.ground_station_files.iter().filter(|f| {
            f.strip_prefix(&prefix)
                .is_some_and(|rest| rest.starts_with('.') || rest.starts_with('-'))
        });
        std::iter::once(replan_files::drone_path_csv(drone))
            .chain(own.cloned())
            .collect()
    };
    html! {
        h3 { "Team plan" }
        p {
            (p.drones.len()) " drones take off one after another, each flying its share of the gaps in its own battery sorties from its home. "
            (format!("The mission takes about {:.1} min from the first take-off to the last landing", p.mission_time_s / 60.0))
            @if let Some(m) = p.closest_drones_m {
                (format!("; the take-offs are spaced so that no two drones come closer than {m:.1} m (clearance {:.1} m)", p.clearance_m))
            }
            "."
        }
        table {
            tr {
                th { "drone" } th { "camera" } th { "home" } th.n { "speed" } th.n { "takes off" } th.n { "sorties" }
                th.n { "waypoints" } th.n { "length" } th.n { "time" } th { "files" }
            }
            @for d in &p.drones {
                tr {
                    td { (d.drone + 1) @if !d.name.is_empty() { " " (d.name) } }
                    td {
                        (format!("{} x {} px, f {:.0} px", d.image_size[0], d.image_size[1], d.focal_px))
                        @match &d.camera {
                            Some(file) => { ", " code { (file.file_name().map_or_else(|| file.display().to_string(), |n| n.to_string_lossy().into_owned())) } }
                            None => { ", the flight's" }
                        }
                    }
                    td { (format!("{:.1}, {:.1}, {:.1}", d.home[0], d.home[1], d.home[2])) }
                    td.n { (format!("{:.1} m/s", d.speed_m_s)) }
                    td.n { (format!("+{:.0} s", d.takeoff_s)) }
                    td.n { (d.sorties) }
                    td.n { (d.waypoints) }
                    td.n { (format!("{:.0} m", d.length_m)) }
                    td.n { (format!("{:.1} min", d.time_s / 60.0)) }
                    td {
                        @for (i, f) in files_of(d.drone as usize).iter().enumerate() {
                            @if i > 0 { ", " }
                            code { (f) }
                        }
                    }
                }
            }
        }
    }
}

/// Which elements the follow-up flight goes back to, and at which of its
/// waypoints (numbered in flight order, as in the pictures).
fn gaps_by_element(r: &RunResults, p: &ReplanSummary) -> Markup {
    let mut by_element: BTreeMap<&str, (usize, Vec<usize>)> = BTreeMap::new();
    let waypoints = p.sorties.iter().flat_map(|s| &s.waypoints);
    for (i, w) in waypoints.enumerate() {
        for v in &w.gap_voxels {
            let element = r
                .elements
                .as_ref()
                .and_then(|m| m.element_of(*v))
                .map_or("off the targets", |e| e.name.as_str());
            let entry = by_element.entry(element).or_default();
            entry.0 += 1;
            if entry.1.last() != Some(&(i + 1)) {
                entry.1.push(i + 1);
            }
        }
    }
    html! {
        @if !by_element.is_empty() {
            table {
                tr { th { "element" } th.n { "gap voxels" } th { "at waypoints" } }
                @for (element, (voxels, at)) in &by_element {
                    tr { td { (element) } td.n { (voxels) } td { (number_ranges(at)) } }
                }
            }
        }
    }
}

/// Increasing numbers as ranges: `1–4, 7, 9–10`.
fn number_ranges(numbers: &[usize]) -> String {
    use postflight_core::runs;
    runs::write(&runs::consecutive(numbers), "\u{2013}", ", ")
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

/// Every supporting detection box of every candidate, out of the way of
/// the table above.
fn detections_appendix(r: &RunResults) -> Markup {
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

fn run_section(s: &RunSummary) -> Markup {
    // Pipeline order, then anything else.
    const ORDER: [&str; 6] = [
        "ingest", "detect", "localise", "coverage", "replan", "report",
    ];
    let mut stages: Vec<(&String, &f64)> = s.timings_s.iter().collect();
    stages.sort_by_key(|(name, _)| ORDER.iter().position(|o| o == name).unwrap_or(ORDER.len()));
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn waypoint_numbers_read_as_ranges() {
        assert_eq!(
            number_ranges(&[1, 2, 3, 4, 7, 9, 10]),
            "1\u{2013}4, 7, 9\u{2013}10"
        );
        assert_eq!(number_ranges(&[5]), "5");
        assert_eq!(number_ranges(&[]), "");
    }
}
