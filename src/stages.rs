//! Running one stage: a progress bar while it works, its warnings logged,
//! and one line saying what it did. The stage commands and `postflight run`
//! share these.

use postflight_core::outputs::localise::Outcome;
use postflight_core::outputs::record::Submission;
use postflight_core::outputs::report::files;

use crate::progress::Bar;

pub fn ingest(options: &ingest::IngestOptions, quiet: bool) -> anyhow::Result<()> {
    let mut bar = Bar::bytes("ingest", quiet);
    let summary = ingest::ingest(options, &mut bar)?;
    bar.finish();
    for w in &summary.warnings {
        tracing::warn!("{w}");
    }
    if !quiet {
        println!(
            "ingested {} frames ({} with pose), {} poses, {:.1} s of flight{}{} into {}",
            summary.frames,
            summary.frames_with_pose,
            summary.poses,
            summary.duration_s,
            match summary.recordings.len() {
                1 => String::new(),
                n => {
                    let reused = summary.recordings.iter().filter(|r| r.reused).count();
                    match reused {
                        0 => format!(" from {n} recordings"),
                        r => format!(
                            " from {n} recordings ({r} read by an earlier ingest, not read again)"
                        ),
                    }
                }
            },
            if summary.truncated() {
                " (TRUNCATED recording, salvaged)"
            } else {
                ""
            },
            options.out.display()
        );
    }
    Ok(())
}

pub fn detect(options: &detect::DetectOptions, quiet: bool) -> anyhow::Result<()> {
    let bar = Bar::count("detect", quiet);
    let summary = detect::detect(options, &mut |done, total| bar.set(done, total))?;
    bar.finish();
    for w in &summary.warnings {
        tracing::warn!("{w}");
    }
    for f in &summary.failed_frames {
        tracing::warn!("frame {} skipped: {}", f.frame, f.why);
    }
    if !quiet {
        println!(
            "{} detections in {} frames ({:.1} frames/s on {}, {:.0}% of the time in ONNX Runtime) into {}",
            summary.detections,
            summary.frames_run,
            summary.frames_per_s,
            summary.device,
            100.0 * summary.inference_share,
            options.run.display()
        );
    }
    Ok(())
}

pub fn localise(options: &localise::LocaliseOptions, quiet: bool) -> anyhow::Result<()> {
    let bar = Bar::count("localise", quiet);
    let summary = localise::localise(options, &mut |done, total| bar.set(done, total))?;
    bar.finish();
    for w in &summary.warnings {
        tracing::warn!("{w}");
    }
    if !quiet {
        let o = &summary.outcomes;
        println!(
            "{} defect candidates from {} detections ({} placed, {} without pose, {} on no surface, {} on obstacles) into {}",
            summary.defects,
            summary.detections,
            o.get(Outcome::Placed),
            o.get(Outcome::NoPose),
            o.get(Outcome::NoSurface),
            o.get(Outcome::Obstacle),
            options.run.display()
        );
        if !summary.set_aside.is_empty() {
            println!(
                "{} set aside as formwork joints (straight, level or plumb; listed in localise.json)",
                summary.set_aside.len()
            );
        }
    }
    Ok(())
}

pub fn coverage(options: &coverage::CoverageOptions, quiet: bool) -> anyhow::Result<()> {
    let bar = Bar::count("coverage", quiet);
    let summary = coverage::coverage(options, &mut |done, total| bar.set(done, total))?;
    bar.finish();
    for w in &summary.warnings {
        tracing::warn!("{w}");
    }
    if !quiet {
        let planned = match (
            summary.figures.planned_voxels,
            summary.figures.planned_inspected_pct,
        ) {
            (Some(p), Some(pct)) => format!(", {pct:.1}% of {p} planned"),
            _ => String::new(),
        };
        println!(
            "inspected {} of {} target voxels ({:.1}%{planned}); {} gaps to replan, {} uninspectable; face area {:.1}% into {}",
            summary.figures.inspected_voxels,
            summary.figures.target_voxels,
            summary.figures.inspected_pct,
            summary.figures.gap_voxels,
            summary.figures.uninspectable_voxels,
            summary.figures.face_area_coverage_pct,
            options.run.display()
        );
    }
    Ok(())
}

pub fn replan(options: &replan::ReplanOptions, quiet: bool) -> anyhow::Result<()> {
    let bar = Bar::count("replan", quiet);
    let summary = replan::replan(options, &mut |done, total| bar.set(done, total))?;
    bar.finish();
    for w in &summary.warnings {
        tracing::warn!("{w}");
    }
    if !quiet {
        if let Some(why) = reports::html::nothing_to_fly(&summary) {
            println!("{why}; wrote an empty plan into {}", options.run.display());
        } else {
            let files: Vec<&str> = ["replan.json", "replan.csv"]
                .into_iter()
                .chain(summary.ground_station_files.iter().map(String::as_str))
                .collect();
            println!(
                "{} Uninspectable: {}. {} in {}",
                reports::html::follow_up_text(&summary),
                summary.uninspectable_gaps.len(),
                files.join(", "),
                options.run.display()
            );
            if summary.geo_origin.is_none() {
                println!(
                    "no geo origin (--geo-origin, or GPS fixes or geotagged photos in the flight): no QGroundControl or DJI mission, KML or GeoJSON"
                );
            }
        }
    }
    Ok(())
}

pub fn record(options: &record::RecordOptions, quiet: bool) -> anyhow::Result<()> {
    let summary = record::record(options)?;
    for w in &summary.warnings {
        tracing::warn!("{w}");
    }
    if !quiet {
        let seen: Vec<String> = summary
            .elements
            .iter()
            .map(|e| format!("{} {:.0}%", e.element, e.inspected_pct))
            .collect();
        println!(
            "recorded {} elements (inspected: {}), what was not inspected as {}, into {}",
            summary.elements.len(),
            seen.join(", "),
            summary.not_inspected.as_str(),
            options.run.display()
        );
        match &summary.submission {
            Submission::Written { files } => println!("submission: {}", files.join(", ")),
            Submission::Refused { why } => println!("no submission files: {why}"),
        }
    }
    Ok(())
}

pub fn report(options: &reports::ReportOptions, quiet: bool) -> anyhow::Result<()> {
    let bar = Bar::count("report", quiet);
    reports::report(options, &mut |done, total| bar.set(done, total))?;
    bar.finish();
    if !quiet {
        let file = |name| options.run.join(name).display().to_string();
        println!(
            "report: {}, {} and {}",
            file(files::REPORT),
            file(files::RECORDING),
            file(files::SUMMARY)
        );
    }
    Ok(())
}

pub fn simulate(options: &sim::SimOptions, quiet: bool) -> anyhow::Result<()> {
    let bar = Bar::count("simulate", quiet);
    let summary = sim::simulate(options, &mut |done, total| bar.set(done, total))
        .map_err(|e| anyhow::anyhow!("simulate: {e}"))?;
    bar.finish();
    if !quiet {
        println!(
            "simulated {} frames ({} dropped), {} cracks, {:.0} s of flight into {}",
            summary.frames,
            summary.dropped_frames,
            summary.cracks,
            summary.duration_s,
            options.out.display()
        );
        if summary.recordings.len() > 1 {
            let names: Vec<String> = summary
                .recordings
                .iter()
                .map(|r| r.display().to_string())
                .collect();
            println!("recorded as {} sorties: {}", names.len(), names.join(", "));
        }
    }
    Ok(())
}
