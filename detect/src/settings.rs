//! The stage's settings, declared once: the `[detect]` table of
//! `postflight.toml` and the flags of `postflight detect`.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::runtime::Device;

postflight_core::settings! {
    table = "detect", keys = keys;
    /// `[detect]`: how the detector runs.
    pub struct DetectSettings =>
    /// How a detect runs the model.
    struct DetectConfig {
        /// Class prompt for open-vocabulary models (repeatable).
        #[arg(long = "prompt", value_name = "PROMPT")]
        prompts: Vec<String> = vec!["crack".to_string()],
        /// Prompt embeddings for open-vocabulary models (JSON: prompt to
        /// vector, or a .npy array with prompts.txt beside it).
        #[arg(long, value_name = "FILE")]
        embeddings: PathBuf,
        /// Lowest score kept.
        #[arg(long, value_name = "SCORE")]
        confidence: f32 = 0.25,
        /// Overlap above which NMS drops the weaker box of a class.
        #[arg(long, value_name = "IOU")]
        iou: f32 = 0.5,
        /// Same-class boxes of comparable score this many frame pixels
        /// apart or closer merge into one finding (a faint stretch of a
        /// crack splits the detector's response into pieces); 'off' keeps
        /// every box NMS kept.
        #[arg(long, value_name = "PIXELS|off")]
        merge_gap: MergeGap = MergeGap::Pixels(20.0),
        /// Input size for models with dynamic input, pixels: a frame is
        /// scaled to fit this square, then padded only to the model's stride.
        #[arg(long = "imgsz", value_name = "PIXELS")]
        image_size: u32 = 640,
        /// Also run square tiles of this size at full resolution (for small
        /// cracks in large frames).
        #[arg(long, value_name = "PIXELS")]
        tile: u32,
        /// Overlap of neighbouring tiles, as a share of the tile size.
        #[arg(long, value_name = "SHARE")]
        tile_overlap: f32 = 0.2,
        /// Views per inference call, for models whose batch size is dynamic
        /// (a fixed batch size is the model's).
        #[arg(long, value_name = "N")]
        batch: usize = 4,
        /// Where inference runs; falls back to the CPU with a warning when
        /// the ONNX Runtime library lacks the provider.
        #[arg(long, value_enum, value_name = "DEVICE")]
        device: Device = Device::Cpu,
    }
}

/// How far apart detection boxes may be and still merge, as `--merge-gap`
/// and `merge_gap` take it: pixels, or `off`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum MergeGap {
    Pixels(f32),
    Off(Off),
}

/// The word `off` (a unit variant serialises as its name).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Off {
    Off,
}

impl MergeGap {
    /// The gap in pixels; `None` when merging is off.
    pub fn pixels(self) -> Option<f32> {
        match self {
            MergeGap::Pixels(gap) => Some(gap),
            MergeGap::Off(_) => None,
        }
    }
}

impl std::str::FromStr for MergeGap {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        if s.eq_ignore_ascii_case("off") {
            return Ok(MergeGap::Off(Off::Off));
        }
        s.parse()
            .map(MergeGap::Pixels)
            .map_err(|_| format!("'{s}' is neither a number of pixels nor 'off'"))
    }
}
