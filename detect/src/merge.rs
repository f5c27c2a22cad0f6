//! A flight's shares put together (`postflight detect --merge`): every
//! share's detections as the one `detections.parquet`,
//! `detections.coco.json` and `detect.json` a single process writes, the
//! rows in frame order.

use postflight_core::detection::FrameDetection;
use postflight_core::outputs::detect::{DetectSummary, DetectionRow, Shard};
use postflight_core::{Flight, RunDir};

use crate::error::DetectError;
use crate::stage::write_outputs;

/// The shares of a flight the run directory holds whole (their summary
/// written last): `None` when it holds none.
pub fn shares_written(run: &RunDir) -> Result<Option<Vec<Shard>>, DetectError> {
    let entries = std::fs::read_dir(run.path()).map_err(|cause| postflight_core::Error::Open {
        path: run.path().to_owned(),
        cause,
    })?;
    let mut shards: Vec<Shard> = entries
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            Shard::of_file(&name).filter(|s| s.summary() == name)
        })
        .collect();
    shards.sort_by_key(|s| (s.count, s.index));
    Ok((!shards.is_empty()).then_some(shards))
}

/// Whether every share of one split of the flight is there.
pub fn every_share(shards: &[Shard]) -> bool {
    shards.first().is_some_and(|first| {
        shards.iter().all(|s| s.count == first.count) && shards.len() == first.count as usize
    })
}

/// Merge the run's shares into the flight's detections; the merged
/// summary, and how many shares there were.
pub fn merge(run: &std::path::Path) -> Result<(DetectSummary, usize), DetectError> {
    let flight = Flight::load(run)?;
    let dir = &flight.run;
    let shards = shares_written(dir)?.unwrap_or_default();
    let shard_error = |why: String| DetectError::Shards {
        run: run.to_owned(),
        why,
    };
    let Some(first) = shards.first().copied() else {
        return Err(shard_error(
            "it holds no share of the flight; run `postflight detect --shard K/N` for each K first"
                .into(),
        ));
    };
    if shards.iter().any(|s| s.count != first.count) {
        return Err(shard_error(format!(
            "it holds shares of two splits (of {} and of {}); rerun the shares of one",
            first.count,
            shards
                .iter()
                .find(|s| s.count != first.count)
                .map_or(0, |s| s.count)
        )));
    }
    let missing: Vec<Shard> = (1..=first.count)
        .map(|index| Shard {
            index,
            count: first.count,
        })
        .filter(|k| !shards.contains(k))
        .collect();
    if let Some(next) = missing.first() {
        let names: Vec<String> = missing.iter().map(Shard::to_string).collect();
        return Err(shard_error(format!(
            "share {} not done (no {}); run `postflight detect --run {} --shard {next}`",
            names.join(", "),
            next.summary(),
            run.display(),
        )));
    }
    let mut summaries: Vec<DetectSummary> = Vec::new();
    let mut found: Vec<FrameDetection> = Vec::new();
    for shard in &shards {
        let summary: DetectSummary = dir.read_json(&shard.summary())?;
        if let Some(other) = summaries.first()
            && (other.model_sha256 != summary.model_sha256
                || other.views_per_patch != summary.views_per_patch
                || other.tile_choice != summary.tile_choice
                || other.classes != summary.classes
                || other.area_model.as_ref().map(|a| &a.model_sha256)
                    != summary.area_model.as_ref().map(|a| &a.model_sha256))
        {
            return Err(shard_error(format!(
                "share {shard} ran another model or other settings than share {}; rerun it with the same",
                shards[0]
            )));
        }
        let rows: Vec<DetectionRow> = dir.read_rows(&shard.detections())?;
        for row in &rows {
            found.push(
                row.detection()
                    .map_err(|why| shard_error(format!("{}: {why}", shard.detections())))?,
            );
        }
        summaries.push(summary);
    }
    // Frame order, each frame's detections in the order found.
    found.sort_by_key(|d| d.frame);
    let summary = merged(summaries, found.len() as u64);
    write_outputs(dir, &flight.frames, &found, &summary.classes, &summary)?;
    Ok((summary, shards.len()))
}

/// The shares' summaries as one: counts summed, the work's seconds summed.
fn merged(summaries: Vec<DetectSummary>, detections: u64) -> DetectSummary {
    let busy: f64 = summaries
        .iter()
        .map(|s| s.inference_share * s.seconds)
        .sum();
    let mut all = summaries.into_iter();
    let mut out = all.next().expect("at least one share");
    for s in all {
        out.frames += s.frames;
        out.frames_run += s.frames_run;
        out.tiles_run += s.tiles_run;
        out.tiles_skipped.add_all(&s.tiles_skipped);
        out.failed_frames.extend(s.failed_frames);
        out.seconds += s.seconds;
        out.estimate_s = out.estimate_s.zip(s.estimate_s).map(|(a, b)| a + b);
        if let (Some(mine), Some(theirs)) = (&mut out.area_model, &s.area_model) {
            mine.frames_run += theirs.frames_run;
            mine.detections += theirs.detections;
            let busy =
                mine.inference_share * mine.seconds + theirs.inference_share * theirs.seconds;
            mine.seconds += theirs.seconds;
            mine.inference_share = busy / mine.seconds.max(1e-9);
        }
        for w in s.warnings {
            if !out.warnings.contains(&w) {
                out.warnings.push(w);
            }
        }
    }
    out.failed_frames.sort_by_key(|f| f.frame);
    out.detections = detections;
    out.frames_per_s = out.frames_run as f64 / out.seconds.max(1e-9);
    out.inference_share = busy / out.seconds.max(1e-9);
    out.shard = None;
    out
}
