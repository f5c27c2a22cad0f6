//! Running one stage: a progress bar while it works, its warnings logged,
//! and one line saying what it did. The stage commands and `postflight run`
//! share these.

use postflight_core::outputs::localise::Outcome;
use postflight_core::outputs::record::Submission;
use postflight_core::outputs::report::files;

use std::path::{Path, PathBuf};

use postflight_core::best_views::BestViews;
use postflight_core::outputs::detect::{DetectSummary, Shard, TileChoice, files as DetectFiles};
use postflight_core::{Flight, FlownPlan, PlanFile, RunDir, ViewSettings};

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

/// Detect as `postflight detect` and `run` start it: the stage's options,
/// and what it chooses the tiles to run by (the map on the plan's grid,
/// the View model). Serialised, what its result depends on (no paths).
#[derive(Debug, Clone, serde::Serialize)]
pub struct DetectRun {
    pub detect: detect::DetectOptions,
    /// The map to choose by instead of the flight's.
    #[serde(skip)]
    pub map: Option<PathBuf>,
    /// The plan whose voxel grid and View model the map is judged on.
    #[serde(skip)]
    pub plan: Option<PlanFile>,
    pub view: ViewSettings,
    /// Only this share of the flight.
    #[serde(skip)]
    pub shard: Option<Shard>,
}

/// Views farther from a patch than this many times the View model's far
/// edge are not among its views (localise's reach is of that order).
const REACH_OVER_FAR_EDGE: f64 = 3.0;

impl DetectRun {
    /// The best views of each patch, or why every tile runs.
    fn best_views(&self) -> anyhow::Result<Result<BestViews, TileChoice>> {
        let per_patch = self.detect.settings.views_per_patch;
        if per_patch == 0 {
            return Ok(Err(TileChoice::Every));
        }
        let flight = Flight::load(&self.detect.run)?;
        let plan = self.plan.as_ref().map(PlanFile::load).transpose()?;
        let grid = plan.as_ref().and_then(FlownPlan::grid);
        let map = match ingest::load_map(&flight, self.map.as_deref(), grid) {
            Ok((map, _)) => map,
            Err(ingest::IngestError::NoMap) => return Ok(Err(TileChoice::NoMap)),
            Err(e) => return Err(e.into()),
        };
        let view = self
            .view
            .apply(plan.as_ref().and_then(FlownPlan::view).unwrap_or_default());
        view.check()?;
        let choosing = coverage::Choosing {
            views_per_patch: per_patch,
            reach_m: view.max_distance_m * REACH_OVER_FAR_EDGE,
            exposure_s: None,
        };
        // The structure's voxels where the plan names them: the ground and
        // the trees need no detector.
        let target = plan.as_ref().and_then(FlownPlan::target_voxels);
        match coverage::best_views(&flight, &map, target, &view, choosing) {
            Ok(best) => Ok(Ok(best)),
            Err(coverage::CoverageError::NoCamera | coverage::CoverageError::NoIntrinsics) => {
                Ok(Err(TileChoice::NoMap))
            }
            Err(e) => Err(e.into()),
        }
    }
}

pub fn detect(run: &DetectRun, quiet: bool) -> anyhow::Result<()> {
    let best = run.best_views()?;
    let mut tiles = match &best {
        Ok(best) => detect::TilesToRun::best(best),
        Err(choice) => detect::TilesToRun::every(*choice),
    };
    tiles.shard = run.shard;
    let bar = Bar::count("detect", quiet);
    let summary = detect::detect(&run.detect, tiles, &mut |told| match told {
        detect::Told::Progress { done, total } => bar.set(done, total),
        detect::Told::Estimate(e) => {
            if !quiet {
                bar.println(format!(
                    "detect: {} of {} tiles, {}: about {} on {}",
                    thousands(e.tiles_run),
                    thousands(e.tiles),
                    e.choice,
                    duration(e.seconds),
                    e.device
                ));
            }
        }
    })?;
    bar.finish();
    for w in &summary.warnings {
        tracing::warn!("{w}");
    }
    for f in &summary.failed_frames {
        tracing::warn!("frame {} skipped: {}", f.frame, f.why);
    }
    if !quiet {
        let skipped: Vec<String> = summary
            .tiles_skipped
            .iter()
            .filter(|(_, n)| *n > 0)
            .map(|(why, n)| format!("{} {}", thousands(n), why.as_str().replace('_', " ")))
            .collect();
        let share = summary
            .shard
            .map(|s| format!(" (share {s} of the flight)"))
            .unwrap_or_default();
        println!(
            "{} detections in {} frames{share}, {} tiles run{} ({:.1} frames/s on {}, {:.0}% of the time in ONNX Runtime) into {}",
            summary.detections,
            summary.frames_run,
            thousands(summary.tiles_run),
            if skipped.is_empty() {
                String::new()
            } else {
                format!(", skipped: {}", skipped.join(", "))
            },
            summary.frames_per_s,
            summary.device,
            100.0 * summary.inference_share,
            run.detect.run.display()
        );
        match &summary.area_model {
            Some(area) => println!(
                "  of which the area model ({}): {} detections in {} frames at {}x{}, {:.1} s ({:.0}% in ONNX Runtime)",
                area.kinds
                    .iter()
                    .map(|k| k.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
                area.detections,
                area.frames_run,
                area.input_size[0],
                area.input_size[1],
                area.seconds,
                100.0 * area.inference_share
            ),
            None if !summary.kinds.iter().any(|k| k.is_area()) => println!(
                "  area defects (spalls, exposed reinforcement, ...) not looked for: give an area model ([detect] area_model)"
            ),
            None => {}
        }
    }
    Ok(())
}

/// Merge the shares of a flight's detect (`postflight detect --merge`);
/// the flight's summary.
pub fn merge(run: &Path, quiet: bool) -> anyhow::Result<DetectSummary> {
    let (summary, shares) = detect::merge::merge(run)?;
    if !quiet {
        println!(
            "merged {} detections in {} frames from {shares} shares into {}",
            summary.detections,
            summary.frames_run,
            run.display()
        );
    }
    Ok(summary)
}

/// Before localise: a flight detected in shares and not yet merged is
/// merged, when every share is there.
fn merge_shares(run: &Path, quiet: bool) -> anyhow::Result<()> {
    // A run directory that is not there is localise's to name.
    if !run.is_dir() {
        return Ok(());
    }
    let dir = RunDir::create(run)?;
    if dir.file(DetectFiles::SUMMARY).is_file() {
        return Ok(());
    }
    match detect::merge::shares_written(&dir)? {
        Some(shards) if detect::merge::every_share(&shards) => merge(run, quiet).map(drop),
        _ => Ok(()),
    }
}

/// `n` with thousands separated: 3,904.
fn thousands(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// Seconds as people say them: 50 s, 12 min, 3.4 h.
fn duration(seconds: f64) -> String {
    if seconds < 120.0 {
        format!("{seconds:.0} s")
    } else if seconds < 7200.0 {
        format!("{:.0} min", seconds / 60.0)
    } else {
        format!("{:.1} h", seconds / 3600.0)
    }
}

pub fn localise(options: &localise::LocaliseOptions, quiet: bool) -> anyhow::Result<()> {
    merge_shares(&options.run, quiet)?;
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
