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
    pub trajectory: Trajectory,
}

impl Flight {
    /// Load the ingest outputs of `run_dir`.
    pub fn load(run_dir: &Path) -> Result<Self, Error> {
        let run = RunDir::open(run_dir, Stage::Ingest)?;
        Ok(Self {
            summary: run.read_json(files::SUMMARY)?,
            frames: ingest::read_frames(&run)?,
            trajectory: ingest::read_trajectory(&run)?,
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
        self.cameras.iter().find(|c| c.topic == frame.topic)
    }
}
