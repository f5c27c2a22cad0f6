//! Recordings ingested before, kept in the run directory so that adding a
//! sortie to a run reads only the new recording. Each recording's frames,
//! trajectory, cameras and fixes, as ingest found them in its own SLAM
//! frame, are kept in `recordings/<key>/`, keyed by the file (path, size
//! and modification time), the settings and postflight's version; placing
//! the recordings in one frame is redone every time.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use postflight_core::RunDir;
use postflight_core::geo::GeoOrigin;
use postflight_core::outputs::ingest::{self as outputs, RecordingSummary};
use postflight_core::run_log::sha256;
use serde::{Deserialize, Serialize};

use crate::error::IngestError;
use crate::ingested::Ingested;
use crate::stage::IngestOptions;

/// The run directory's folder of recordings ingested before.
pub(crate) const DIR: &str = "recordings";
/// Size and modification time of a recording, or of each photo of a
/// folder, by name: what says the source changed.
fn stamps(path: &Path) -> Vec<(String, u64, String)> {
    let stamp = |p: &Path| {
        let meta = std::fs::metadata(p).ok();
        let modified_ns = meta
            .as_ref()
            .and_then(|m| m.modified().ok())
            .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
            .map_or(0, |d| d.as_nanos());
        let name = p.file_name().map(|n| n.to_string_lossy().into_owned());
        (
            name.unwrap_or_default(),
            meta.map_or(0, |m| m.len()),
            modified_ns.to_string(),
        )
    };
    if !path.is_dir() {
        return vec![stamp(path)];
    }
    let mut photos: Vec<PathBuf> = std::fs::read_dir(path)
        .map(|entries| entries.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    photos.retain(|p| crate::PhotoFolder::is_photo_name(p));
    photos.sort();
    photos.iter().map(|p| stamp(p)).collect()
}

/// What a kept recording holds besides its tables.
const RECORD: &str = "recording.json";

/// A recording's summary, cameras and warnings, as kept.
#[derive(Serialize, Deserialize)]
struct Kept {
    summary: RecordingSummary,
    cameras: Vec<postflight_core::Camera>,
    warnings: Vec<String>,
}

/// Where the source at `path` (a recording or a photo folder), ingested
/// with `options` (photos posed at `photo_origin`), is kept.
pub(crate) fn place_of(
    path: &Path,
    photo_origin: Option<&GeoOrigin>,
    options: &IngestOptions,
) -> PathBuf {
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_owned());
    // Where recordings are placed is not how one is read.
    let settings = crate::IngestConfig {
        recording_frame: Vec::new(),
        ..options.settings.clone()
    };
    let key = serde_json::json!({
        "path": absolute,
        "files": stamps(path),
        "settings": settings,
        "photo_origin": photo_origin,
        "postflight": env!("CARGO_PKG_VERSION"),
    });
    let key = sha256(key.to_string().as_bytes());
    options.out.join(DIR).join(&key[..16])
}

/// The recording kept at `place`, with its frames and fixes numbered as
/// recording `index`; `None` when it is not kept (or unreadable: then it is
/// read again).
pub(crate) fn load(place: &Path, index: u16) -> Option<Ingested> {
    if !place.join(RECORD).is_file() {
        return None;
    }
    let dir = RunDir::create(place).ok()?;
    let kept: Kept = dir.read_json(RECORD).ok()?;
    let mut frames = outputs::read_frames(&dir).ok()?;
    let trajectory = outputs::read_trajectories(&dir, 1).ok()?.pop()?;
    let mut fixes = outputs::read_gnss(&dir).ok()?;
    let mut cameras = kept.cameras;
    frames.iter_mut().for_each(|f| f.recording = index);
    fixes.iter_mut().for_each(|f| f.recording = index);
    cameras.iter_mut().for_each(|c| c.recording = index);
    let mut summary = kept.summary;
    summary.reused = true;
    Some(Ingested {
        summary,
        frames,
        trajectory,
        cameras,
        fixes,
        warnings: kept.warnings,
    })
}

/// Keep a recording as found at `place` (its record written last: a
/// folder without it is not kept).
pub(crate) fn keep(place: &Path, found: &Ingested) -> Result<(), IngestError> {
    let dir = RunDir::create(place)?;
    dir.remove(RECORD)?;
    outputs::write_frames(&dir, &found.frames)?;
    outputs::write_trajectories(&dir, std::slice::from_ref(&found.trajectory))?;
    outputs::write_gnss(&dir, &found.fixes)?;
    let kept = Kept {
        summary: found.summary.clone(),
        cameras: found.cameras.clone(),
        warnings: found.warnings.clone(),
    };
    dir.write_json(RECORD, &kept)?;
    Ok(())
}

/// Remove kept recordings the run no longer has.
pub(crate) fn forget_all_but(out: &Path, places: &[PathBuf]) -> Result<(), IngestError> {
    let keep: BTreeSet<&Path> = places.iter().map(PathBuf::as_path).collect();
    let Ok(entries) = std::fs::read_dir(out.join(DIR)) else {
        return Ok(());
    };
    for entry in entries.flatten() {
        let path = entry.path();
        // Only the folders `keep` made.
        if path.join(RECORD).is_file() && !keep.contains(path.as_path()) {
            std::fs::remove_dir_all(&path).map_err(|cause| postflight_core::Error::Write {
                path: path.clone(),
                cause,
            })?;
        }
    }
    Ok(())
}
