//! A flight as later stages see it: what a completed ingest wrote into the
//! run directory (its summary, frames, cameras and trajectory). Pixels and
//! the recorded map stay in the recording, which `ingest` reads on demand.

use std::path::Path;

use crate::camera::Camera;
use crate::error::Error;
use crate::frame::Frame;
use crate::outputs::Stage;
use crate::outputs::ingest::{self, IngestSummary, files};
use crate::run_dir::RunDir;
use crate::trajectory::Trajectory;

pub struct Flight {
    pub run: RunDir,
    pub summary: IngestSummary,
    pub frames: Vec<Frame>,
    pub cameras: Vec<Camera>,
    /// Each recording's body trajectory, in the order of
    /// `summary.recordings`.
    pub trajectories: Vec<Trajectory>,
}

impl Flight {
    /// Load the ingest outputs of `run_dir`.
    pub fn load(run_dir: &Path) -> Result<Self, Error> {
        let run = RunDir::open(run_dir, Stage::Ingest)?;
        let summary: IngestSummary = run.read_json(files::SUMMARY)?;
        Ok(Self {
            frames: ingest::read_frames(&run)?,
            trajectories: ingest::read_trajectories(&run, summary.recordings.len())?,
            summary,
            cameras: run.read_json(files::CAMERAS)?,
            run,
        })
    }

    /// The frame with this index (its place in time order).
    pub fn frame(&self, index: u32) -> Option<&Frame> {
        self.frames
            .binary_search_by_key(&index, |f| f.index)
            .ok()
            .map(|i| &self.frames[i])
    }

    /// The camera that took a frame.
    pub fn camera(&self, frame: &Frame) -> Option<&Camera> {
        self.cameras
            .iter()
            .find(|c| c.recording == frame.recording && c.topic == frame.topic)
    }

    /// The trajectory of the drone that took a frame (its recording's).
    pub fn trajectory(&self, frame: &Frame) -> &Trajectory {
        static EMPTY: std::sync::OnceLock<Trajectory> = std::sync::OnceLock::new();
        self.trajectories
            .get(usize::from(frame.recording))
            .unwrap_or_else(|| EMPTY.get_or_init(Trajectory::default))
    }
}
