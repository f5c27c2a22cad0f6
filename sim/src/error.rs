//! Why a flight could not be simulated.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error("a flight needs at least 2 frames of at least 16x16 pixels")]
    FlightTooSmall,
    #[error("pose noise must be at least 0 (and below 10 m, 57 degrees)")]
    PoseNoise,
    #[error(
        "--lens-blur {px}: give 0 (a perfect lens) to {} pixels",
        crate::MAX_LENS_BLUR_PX
    )]
    LensBlur { px: f64 },
    /// The OBJ file could not be read or is not a mesh; `reason` is the
    /// parser's, with the line where it applies.
    #[error("mesh {}: {reason}", path.display())]
    Mesh { path: PathBuf, reason: String },
    /// `--repeat-of` names no flight this one can repeat.
    #[error("--repeat-of {}: {why}", path.display())]
    Repeat { path: PathBuf, why: String },
    #[error("cannot cut {frames} frames into {sorties} sorties: give --sorties from 1 to {frames}")]
    Sorties { sorties: u32, frames: u32 },
    #[error(
        "--overlap plans {viewpoints} viewpoints, a photo each, but --frames is {frames}: pass --frames {viewpoints}"
    )]
    SurveyFrames { viewpoints: usize, frames: u32 },
    #[error("the structure is too small to plan a flight around")]
    StructureTooSmall,
    #[error("cannot write {}: {cause}", path.display())]
    Write {
        path: PathBuf,
        cause: std::io::Error,
    },
    #[error("cannot record {}: {cause}", path.display())]
    Record {
        path: PathBuf,
        cause: mcap::McapError,
    },
    #[error("cannot encode a frame: {0}")]
    Encode(#[from] image::ImageError),
}

impl SimError {
    pub(crate) fn write(path: impl Into<PathBuf>) -> impl FnOnce(std::io::Error) -> Self {
        let path = path.into();
        move |cause| Self::Write { path, cause }
    }
}
