//! The ingest stage: one pass over each of a flight's recordings (one, or
//! one per sortie or drone), then the frames, trajectories, cameras and a
//! summary written into the run directory.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use postflight_core::outputs::ingest::{self as outputs, IngestSummary, files};
use postflight_core::{InvalidSetting, RunDir};

use crate::combine::{FlightTables, combine};
use crate::error::IngestError;
use crate::ingested::{Ingested, ingest_one};
use crate::photo_frame::{PhotoFrame, photo_origin, reconstruction};
use crate::reuse;
use crate::settings::{IngestConfig, keys};
use crate::slam_frames::place_recordings;
use crate::source::Source;
use crate::topics::{check_topic_flags, every_topic};

/// What to ingest and how. Serialised, it is what the stage's result
/// depends on besides its input files (`postflight run`'s fingerprint): the
/// settings, not the paths.
#[derive(Debug, Clone, serde::Serialize)]
pub struct IngestOptions {
    /// The flight's sources: recordings or photo folders, one or one per
    /// sortie or drone (see [`crate::source::sources_in`]).
    #[serde(skip)]
    pub flights: Vec<PathBuf>,
    #[serde(skip)]
    pub out: PathBuf,
    pub settings: IngestConfig,
}

impl IngestOptions {
    /// `flights` into `out` with the default settings.
    pub fn new(flights: Vec<PathBuf>, out: PathBuf) -> Self {
        Self {
            flights,
            out,
            settings: IngestConfig::default(),
        }
    }
}

/// Progress of an ingest, for progress bars.
pub trait Progress {
    /// `done` of `total` bytes of the recordings read.
    fn bytes(&mut self, done: u64, total: u64);
}

impl<F: FnMut(u64, u64)> Progress for F {
    fn bytes(&mut self, done: u64, total: u64) {
        self(done, total)
    }
}

/// Ingest a flight's recordings into a run directory.
pub fn ingest(
    options: &IngestOptions,
    progress: &mut dyn Progress,
) -> Result<IngestSummary, IngestError> {
    InvalidSetting::check(
        options.settings.max_pose_gap_s.is_finite() && options.settings.max_pose_gap_s > 0.0,
        keys::max_pose_gap_s,
        options.settings.max_pose_gap_s,
        "a positive number of seconds",
    )?;
    // A failed rerun must not leave the last ingest looking current (the
    // folder is created only once the flight reads).
    if options.out.is_dir() {
        RunDir::create(&options.out)?.remove(files::SUMMARY)?;
    }
    let mut sources = open_all(&options.flights)?;
    let origin = photo_origin(options, &sources)?;
    let reconstruction = reconstruction(options, &sources, origin.as_ref(), progress)?;
    let photos = origin.as_ref().map(|origin| PhotoFrame {
        origin,
        reconstruction: reconstruction.as_ref(),
    });
    let mut ingested = ingest_each(&sources, photos.as_ref(), options, progress)?;
    check_topic_flags(options, &every_topic(&ingested))?;
    if ingested.iter().all(|i| i.frames.is_empty()) {
        return Err(IngestError::NoImages {
            path: options.flights[0].clone(),
        });
    }
    let warnings = place_recordings(&mut ingested, &mut sources, options)?;
    let (mut summary, flight) = combine(ingested, options, warnings);
    summary.reconstruction = reconstruction.map(|r| {
        let posed = summary.recordings.iter().filter_map(|s| s.photos.as_ref());
        r.summary(posed.map(|p| p.reconstructed).sum())
    });
    write_outputs(&options.out, &flight, &summary)?;
    Ok(summary)
}

/// Each source ingested, or read back from the run directory when it was
/// ingested before with the same settings ([`reuse`]; photo folders posed
/// by a reconstruction are posed afresh, as the fit takes every folder).
fn ingest_each(
    sources: &[Source],
    photos: Option<&PhotoFrame>,
    options: &IngestOptions,
    progress: &mut dyn Progress,
) -> Result<Vec<Ingested>, IngestError> {
    let total: u64 = sources.iter().map(Source::len).sum();
    let mut done = 0;
    let mut ingested = Vec::new();
    let mut kept = Vec::new();
    for (index, source) in (0u16..).zip(sources) {
        let place = reuse::place_of(source.path(), photos.map(|p| p.origin), options);
        let reconstructed = photos.is_some_and(|p| p.reconstruction.is_some());
        let earlier = match (source, reconstructed) {
            (Source::Photos(_), true) => None,
            _ => reuse::load(&place, index),
        };
        let one = match earlier {
            Some(one) => one,
            None => {
                let mut progress = |bytes, _| progress.bytes(done + bytes, total);
                let one = match (source, photos) {
                    (Source::Recording(r), _) => ingest_one(index, r, options, &mut progress)?,
                    (Source::Photos(folder), Some(p)) => {
                        let strict = options.settings.strict;
                        folder.ingest(index, p.origin, p.reconstruction, strict, &mut progress)?
                    }
                    (Source::Photos(_), None) => unreachable!("photo folders have an origin"),
                };
                reuse::keep(&place, &one)?;
                one
            }
        };
        done += source.len();
        progress.bytes(done, total);
        ingested.push(one);
        kept.push(place);
    }
    reuse::forget_all_but(&options.out, &kept)?;
    Ok(ingested)
}

/// The sources, opened.
fn open_all(paths: &[PathBuf]) -> Result<Vec<Source>, IngestError> {
    check_recordings(paths)?;
    paths.iter().map(|p| Source::open(p)).collect()
}

/// A flight's recordings are at least one, each given once.
pub fn check_recordings(paths: &[PathBuf]) -> Result<(), IngestError> {
    let mut seen = BTreeSet::new();
    for p in paths {
        let key = std::fs::canonicalize(p).unwrap_or_else(|_| p.clone());
        if !seen.insert(key) {
            return Err(IngestError::GivenTwice { path: p.clone() });
        }
    }
    if paths.is_empty() {
        return Err(IngestError::NoRecordingsIn {
            path: PathBuf::new(),
        });
    }
    Ok(())
}

fn write_outputs(
    out: &Path,
    flight: &FlightTables,
    summary: &IngestSummary,
) -> Result<(), IngestError> {
    let run = RunDir::create(out)?;
    run.remove(files::SUMMARY)?;
    outputs::write_frames(&run, &flight.frames)?;
    outputs::write_trajectories(&run, &flight.trajectories)?;
    outputs::write_gnss(&run, &flight.fixes)?;
    run.write_json(files::CAMERAS, &flight.cameras)?;
    run.write_json(files::SUMMARY, summary)?;
    Ok(())
}
