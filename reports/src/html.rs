//! `report.html`: one self-contained page (styles, pictures and thumbnails
//! inline, no scripts, nothing fetched) that reads on screen and prints:
//! the flight, coverage achieved against planned, the defect candidates in
//! review order, the follow-up flight and how the run went.

use std::fmt::Write;

use base64::Engine;
use postflight_core::outputs::localise::DefectRecord;
use postflight_core::outputs::replan::Unplannable;
use postflight_core::outputs::report::RunSummary;

use crate::results::{RunResults, VoxelStatus, review_priority};
use crate::svg::{bar_chart, escape};
use crate::views::{Overlay, Side, colour, view};

const STYLE: &str = r#"
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;color:#1f2937;margin:0 auto;max-width:1060px;padding:24px}
h1{font-size:24px;margin:0 0 4px}h2{font-size:19px;margin:32px 0 10px;border-bottom:2px solid #e5e7eb;padding-bottom:4px}
.sub{color:#6b7280}.warn{background:#fef3c7;border-left:4px solid #f59e0b;padding:8px 12px;margin:10px 0}
.cards{display:flex;flex-wrap:wrap;gap:10px;margin:16px 0}.card{border:1px solid #e5e7eb;border-radius:6px;padding:8px 14px;min-width:120px}
.card b{display:block;font-size:22px}.card span{color:#6b7280;font-size:12px}
table{border-collapse:collapse;width:100%;margin:8px 0}th,td{text-align:left;padding:4px 8px;border-bottom:1px solid #e5e7eb;vertical-align:top}
th{background:#f9fafb;font-weight:600}td.n,th.n{text-align:right;font-variant-numeric:tabular-nums}
.views{display:grid;grid-template-columns:1fr 1fr;gap:12px}.views figure{margin:0}figcaption{color:#6b7280;font-size:12px}
svg{max-width:100%;height:auto}.legend span{display:inline-block;margin-right:14px}.legend i{display:inline-block;width:12px;height:12px;margin-right:4px;vertical-align:-1px}
img.thumb{width:160px;border:1px solid #d1d5db}.frames{font-size:12px;color:#4b5563}
@media print{body{max-width:none;padding:0}h2{break-after:avoid}tr,figure,.card{break-inside:avoid}.views{grid-template-columns:1fr 1fr}}
"#;

/// The page for `results`, with `summary` already computed from them.
pub fn page(results: &RunResults, summary: &RunSummary) -> String {
    let mut h = String::new();
    let title = format!(
        "Inspection report: {}",
        summary.flight.file_name().map_or_else(
            || summary.flight.display().to_string(),
            |n| n.to_string_lossy().into_owned()
        )
    );
    let _ = write!(
        h,
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><meta name=\"viewport\" content=\"width=device-width,initial-scale=1\"><title>{t}</title><style>{STYLE}</style></head><body><h1>{t}</h1><p class=\"sub\">Flight of {start}, {dur:.0} s, {frames} frames ({posed} with pose). Run directory <code>{run}</code>.</p>",
        t = escape(&title),
        start = escape(&readable_time(&summary.flight_start)),
        dur = summary.duration_s,
        frames = summary.frames,
        posed = summary.frames_with_pose,
        run = escape(&summary.run.display().to_string()),
    );
    if summary.truncated {
        h.push_str("<p class=\"warn\"><b>Truncated recording.</b> The flight file was cut short; postflight salvaged what it holds, and everything below describes only that part of the flight.</p>");
    }
    cards(&mut h, summary);
    coverage_section(&mut h, results);
    defects_section(&mut h, results);
    replan_section(&mut h, results);
    run_section(&mut h, summary);
    h.push_str("</body></html>\n");
    h
}

/// `2025-06-15T12:00:00.000000000Z` as `2025-06-15 12:00:00 UTC`.
/// An RFC 3339 UTC time as `YYYY-MM-DD HH:MM:SS UTC`.
pub fn readable_time(rfc3339: &str) -> String {
    match (rfc3339.get(..10), rfc3339.get(11..19)) {
        (Some(date), Some(time)) if rfc3339.ends_with('Z') => format!("{date} {time} UTC"),
        _ => rfc3339.to_string(),
    }
}

fn cards(h: &mut String, s: &RunSummary) {
    h.push_str("<div class=\"cards\">");
    let mut card = |value: String, what: &str| {
        let _ = write!(
            h,
            "<div class=\"card\"><b>{}</b><span>{}</span></div>",
            escape(&value),
            escape(what)
        );
    };
    card(s.frames.to_string(), "frames");
    if let Some(d) = s.detections {
        card(d.to_string(), "detections");
    }
    if let Some(d) = s.defects {
        card(d.to_string(), "defect candidates");
    }
    if let Some(c) = &s.coverage {
        card(
            format!("{:.1}%", c.inspected_pct),
            "of target voxels inspected",
        );
        if let Some(p) = c.planned_inspected_pct {
            card(format!("{p:.1}%"), "of planned voxels inspected");
        }
        card(c.gap_voxels.to_string(), "gap voxels");
        card(c.uninspectable_voxels.to_string(), "uninspectable voxels");
    }
    if let Some(r) = &s.replan {
        card(
            format!("{:.0} m", r.length_m),
            &format!("follow-up flight, {} sorties", r.sorties),
        );
    }
    h.push_str("</div>");
}

fn legend(h: &mut String) {
    h.push_str("<p class=\"legend\">");
    for s in VoxelStatus::ALL {
        let _ = write!(
            h,
            "<span><i style=\"background:{}\"></i>{}</span>",
            colour(s),
            s.label()
        );
    }
    h.push_str("<span>&#9679; defect candidate (number = review order)</span></p>");
}

fn coverage_section(h: &mut String, r: &RunResults) {
    h.push_str("<h2>Coverage: achieved against planned</h2>");
    let Some(c) = &r.coverage else {
        h.push_str("<p>Coverage was not computed for this run (it needs an inspection plan: <code>--plan</code>).</p>");
        return;
    };
    let v = &c.view;
    let _ = write!(
        h,
        "<p>Under the View model: cone apex {:.0}&deg;, distance {:.1}&ndash;{:.1} m, incidence up to {:.0}&deg;, blur up to {:.1} px, GSD up to {:.1} mm/px, {} view(s) per face; {:.2} m voxels, targets from {}.</p>",
        v.cone_apex_deg,
        v.min_distance_m,
        v.max_distance_m,
        v.max_incidence_deg,
        v.max_blur_px,
        v.max_gsd_mm,
        v.views_required,
        c.resolution_m,
        escape(&c.targets)
    );
    h.push_str(
        "<table><tr><th>voxels</th><th class=\"n\">count</th><th class=\"n\">share</th></tr>",
    );
    let pct = |n: usize, of: usize| {
        if of == 0 {
            0.0
        } else {
            100.0 * n as f64 / of as f64
        }
    };
    let mut row = |what: &str, n: usize, of: usize| {
        let _ = write!(
            h,
            "<tr><td>{what}</td><td class=\"n\">{n}</td><td class=\"n\">{:.1}%</td></tr>",
            pct(n, of)
        );
    };
    row("target", c.target_voxels, c.target_voxels);
    if let Some(p) = c.planned_voxels {
        row("planned", p, c.target_voxels);
    }
    row("inspected", c.inspected_voxels, c.target_voxels);
    if let (Some(p), Some(missed)) = (c.planned_voxels, c.planned_missed_voxels) {
        row("planned but missed", missed, p);
    }
    row(
        "gaps (a follow-up flight can inspect them)",
        c.gap_voxels,
        c.target_voxels,
    );
    row(
        "uninspectable (no free viewpoint satisfies the View)",
        c.uninspectable_voxels,
        c.target_voxels,
    );
    let _ = write!(
        h,
        "<tr><td>exposed face area inspected</td><td class=\"n\"></td><td class=\"n\">{:.1}%</td></tr></table>",
        c.face_area_coverage_pct
    );
    legend(h);
    let markers: Vec<(String, [f64; 3])> = r
        .defects_for_review()
        .iter()
        .enumerate()
        .map(|(i, d)| ((i + 1).to_string(), d.position))
        .collect();
    let overlay = Overlay {
        markers,
        ..Overlay::default()
    };
    h.push_str("<div class=\"views\">");
    for side in Side::ALL {
        let _ = write!(
            h,
            "<figure>{}<figcaption>Target voxels {}</figcaption></figure>",
            view(&r.voxels, c.resolution_m, side, &overlay, 500.0),
            side.title()
        );
    }
    h.push_str("</div>");
    if !c.reasons.is_empty() {
        let mut bars: Vec<(String, f64)> = c
            .reasons
            .iter()
            .map(|(k, n)| (k.replace('_', " "), *n as f64))
            .collect();
        bars.sort_by(|a, b| b.1.total_cmp(&a.1));
        let _ = write!(
            h,
            "<h3>Why voxels were not inspected</h3><p class=\"sub\">Each not-inspected voxel counted once, by the furthest View rule any frame reached.</p>{}",
            bar_chart(&bars, "#d7301f", "Reasons voxels were not inspected")
        );
    }
}

fn defects_section(h: &mut String, r: &RunResults) {
    h.push_str("<h2>Defect candidates, in review order</h2>");
    if r.localise.is_none() {
        h.push_str("<p>Detections have not been placed on the map for this run.</p>");
        return;
    }
    let order = r.defects_for_review();
    if order.is_empty() {
        h.push_str("<p>No defect candidates: the detector found no cracks that could be placed on the structure.</p>");
        return;
    }
    let _ = write!(
        h,
        "<p>{} candidates, likeliest and largest first (fused confidence &times; length). Each is one physical crack fused from its supporting views; the picture is its best view (closest and most frontal).</p>",
        order.len()
    );
    h.push_str("<table><tr><th>#</th><th>best view</th><th>candidate</th><th class=\"n\">length</th><th class=\"n\">GSD</th><th class=\"n\">range</th><th class=\"n\">confidence</th></tr>");
    for (i, d) in order.iter().enumerate() {
        let thumb = d
            .crop
            .as_ref()
            .and_then(|c| std::fs::read(r.file(c)).ok())
            .map(|bytes| {
                format!(
                    "<img class=\"thumb\" alt=\"best view of {}\" src=\"data:image/jpeg;base64,{}\">",
                    escape(&d.id),
                    base64::engine::general_purpose::STANDARD.encode(bytes)
                )
            })
            .unwrap_or_else(|| "(no image)".into());
        let length = length_html(d);
        let mut frames = String::new();
        for v in &d.views {
            let b = v.bbox;
            let _ = write!(
                frames,
                "{}frame {} [{:.0}, {:.0}, {:.0}, {:.0}] {:.2}",
                if frames.is_empty() { "" } else { "; " },
                v.frame,
                b[0],
                b[1],
                b[2],
                b[3],
                v.score
            );
        }
        let p = d.position;
        let _ = write!(
            h,
            "<tr><td>{n}</td><td>{thumb}</td><td><b>{id}</b><br>at ({x:.2}, {y:.2}, {z:.2}) m, face {face}<br>{views} supporting frames, best frame {best}<div class=\"frames\">{frames}</div></td><td class=\"n\">{length}</td><td class=\"n\">{gsd:.1} mm/px</td><td class=\"n\">{range:.1} m</td><td class=\"n\">{conf:.2}<br><span class=\"sub\">priority {prio:.2}</span></td></tr>",
            n = i + 1,
            id = escape(&d.id),
            x = p[0],
            y = p[1],
            z = p[2],
            face = d.face,
            views = d.frames,
            best = d.best.frame,
            gsd = d.best.oblique_gsd_mm,
            range = d.best.range_m,
            conf = d.confidence,
            prio = review_priority(d),
        );
    }
    h.push_str("</table>");
}

/// A candidate's estimated length as HTML: "&ge;" marks a lower bound (its
/// views were cut by the image border), a dash an unknown length.
pub fn length_html(d: &DefectRecord) -> String {
    match (d.length_m, d.length_partial) {
        (Some(l), false) => format!("{l:.2} m"),
        (Some(l), true) => format!("&ge; {l:.2} m"),
        (None, _) => "&ndash;".into(),
    }
}

fn replan_section(h: &mut String, r: &RunResults) {
    h.push_str("<h2>Follow-up flight for the gaps</h2>");
    let Some(p) = &r.replan else {
        h.push_str("<p>No follow-up flight was planned for this run.</p>");
        return;
    };
    if p.gap_voxels == 0 {
        h.push_str(
            "<p>No gaps: the flight inspected everything a flight can; no follow-up is needed.</p>",
        );
        return;
    }
    let _ = write!(
        h,
        "<p>{planned} of {gaps} gap voxels planned: {wp} waypoints in {sorties} sortie(s), {len:.0} m, about {min:.0} min at {speed:.1} m/s with {hover:.0} s per waypoint; at least {clear:.1} m from every occupied voxel. Flyable files: <code>replan.json</code> (waypoints with yaw and gimbal pitch) and <code>replan.csv</code> (X,Y,Z,Yaw).</p>",
        planned = p.planned_gap_voxels,
        gaps = p.gap_voxels,
        wp = p.waypoints,
        sorties = p.sorties.len(),
        len = p.length_m,
        min = p.time_s / 60.0,
        speed = p.speed_m_s,
        hover = p.hover_s,
        clear = p.clearance_m,
    );
    if !p.uninspectable_gaps.is_empty() {
        let count = |reason| {
            p.uninspectable_gaps
                .iter()
                .filter(|u| u.reason == reason)
                .count()
        };
        let _ = write!(
            h,
            "<p class=\"warn\">{} gap voxels cannot be planned: {} with no viewpoint that keeps the clearance, {} unreachable from home.</p>",
            p.uninspectable_gaps.len(),
            count(Unplannable::NoClearViewpoint),
            count(Unplannable::Unreachable)
        );
    }
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
    h.push_str("<div class=\"views\">");
    for side in [Side::Top, Side::South] {
        let _ = write!(
            h,
            "<figure>{}<figcaption>Follow-up flight over the structure, {}</figcaption></figure>",
            view(&r.voxels, p.resolution, side, &overlay, 500.0),
            side.title()
        );
    }
    h.push_str("</div><table><tr><th>sortie</th><th class=\"n\">waypoints</th><th class=\"n\">gap voxels</th><th class=\"n\">length</th><th class=\"n\">time</th></tr>");
    for (i, s) in p.sorties.iter().enumerate() {
        let _ = write!(
            h,
            "<tr><td>{}</td><td class=\"n\">{}</td><td class=\"n\">{}</td><td class=\"n\">{:.0} m</td><td class=\"n\">{:.1} min</td></tr>",
            i + 1,
            s.waypoints.len(),
            s.waypoints
                .iter()
                .map(|w| w.gap_voxels.len())
                .sum::<usize>(),
            s.length_m,
            s.time_s / 60.0
        );
    }
    h.push_str("</table>");
}

fn run_section(h: &mut String, s: &RunSummary) {
    h.push_str("<h2>The run</h2><table><tr><th>stage</th><th class=\"n\">seconds</th></tr>");
    // Pipeline order, then anything else.
    const ORDER: [&str; 6] = [
        "ingest", "detect", "localise", "coverage", "replan", "report",
    ];
    let mut stages: Vec<(&String, &f64)> = s.timings_s.iter().collect();
    stages.sort_by_key(|(name, _)| ORDER.iter().position(|o| o == name).unwrap_or(ORDER.len()));
    for (stage, secs) in stages {
        let _ = write!(
            h,
            "<tr><td>{}</td><td class=\"n\">{secs:.1}</td></tr>",
            escape(stage)
        );
    }
    let v = &s.versions;
    let _ = write!(
        h,
        "</table><p>postflight {}; model {} (SHA-256 {}); ONNX Runtime {}.</p>",
        escape(&v.postflight),
        escape(
            &v.model
                .as_ref()
                .map_or("-".into(), |m| m.display().to_string())
        ),
        escape(v.model_sha256.as_deref().unwrap_or("-")),
        escape(v.onnxruntime.as_deref().unwrap_or("-"))
    );
    if !s.warnings.is_empty() {
        h.push_str("<h3>Warnings</h3><ul>");
        for w in &s.warnings {
            let _ = write!(h, "<li>{}</li>", escape(w));
        }
        h.push_str("</ul>");
    }
}
