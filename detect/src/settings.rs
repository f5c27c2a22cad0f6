//! The stage's settings, declared once: the `[detect]` table of
//! `postflight.toml` and the flags of `postflight detect`.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use postflight_core::outputs::detect::ChannelOrder;

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
        /// What a class of the model finds, NAME=KIND (repeatable; KIND
        /// one of crack, spall, exposed_rebar, efflorescence, rust_stain,
        /// corrosion, or none to ignore the class) [default: the kind the
        /// class's name means (spalling: spall), the rest ignored; a model
        /// whose classes name no kind finds cracks].
        #[arg(long = "class-kind", value_name = "NAME=KIND")]
        class_kinds: Vec<String> = Vec::new(),
        /// A second model for area defects (spalls, exposed reinforcement,
        /// ...), run over the whole frame at the scale it was trained at
        /// (its metadata's postflight.train_px, else imgsz) beside the
        /// crack model: a spall does not need a crack's fine pixels.
        #[arg(long, value_name = "FILE")]
        area_model: PathBuf,
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
        /// cracks in large frames); 'auto' tiles at a fixed-size model's
        /// input size when the frame is larger (so the frame is not shrunk
        /// to the model), 'off' runs the whole frame alone.
        #[arg(long, value_name = "PIXELS|auto|off")]
        tile: Tile = Tile::Auto(Auto::Auto),
        /// Run the model only where it matters: on the tiles that show a
        /// patch of the map among its best N views, by the View model's
        /// measure (within its distance band, GSD and blur first, then the
        /// finest on the surface; twice N for a patch no view sees within
        /// them); 0 runs every tile. Without a map every tile runs.
        #[arg(long, value_name = "N")]
        views_per_patch: u32 = 2,
        /// Overlap of neighbouring tiles, as a share of the tile size.
        #[arg(long, value_name = "SHARE")]
        tile_overlap: f32 = 0.2,
        /// Views per inference call, for models whose batch size is dynamic
        /// (a fixed batch size is the model's).
        #[arg(long, value_name = "N")]
        batch: usize = 4,
        /// Colour channel order the model takes, rgb or bgr [default: the
        /// model's metadata (ONNX's Image.BitmapPixelFormat), else rgb].
        #[arg(long, value_enum, value_name = "ORDER")]
        channel_order: ChannelOrder,
        /// What a white pixel is in the model's input before the mean and
        /// std: 1 (values 0..1) or 255 (raw 0..255) [default: the model's
        /// metadata (Image.NominalPixelRange), else 1].
        #[arg(long, value_name = "SCALE")]
        pixel_scale: f32,
        /// Mean subtracted from each channel, red, green, blue, on 0..1
        /// (ImageNet's: 0.485,0.456,0.406) [default: from the model's
        /// metadata, else 0,0,0].
        #[arg(long, value_name = "R,G,B", value_parser = rgb)]
        mean: [f32; 3],
        /// Standard deviation each channel is divided by, red, green,
        /// blue, on 0..1 (ImageNet's: 0.229,0.224,0.225) [default: from
        /// the model's metadata, else 1,1,1].
        #[arg(long, value_name = "R,G,B", value_parser = rgb)]
        std: [f32; 3],
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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
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

/// Three numbers `R,G,B` (`--mean`, `--std`).
fn rgb(text: &str) -> Result<[f32; 3], String> {
    match postflight_core::setting::comma_numbers(text).as_deref() {
        Some(&[r, g, b]) => Ok([r as f32, g as f32, b as f32]),
        _ => Err(format!("expected three numbers R,G,B, not '{text}'")),
    }
}

/// Whether and how frames are tiled, as `--tile` and `tile` take it:
/// pixels, `auto` or `off`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Tile {
    Pixels(u32),
    Auto(Auto),
    Off(Off),
}

/// The word `auto`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Auto {
    Auto,
}

impl Tile {
    /// The tile size for a model whose fixed input is `fixed` (width,
    /// height; `None` when dynamic) on a `width` x `height` frame.
    pub fn size(self, fixed: Option<(u32, u32)>, width: u32, height: u32) -> Option<u32> {
        match self {
            Tile::Pixels(size) => Some(size),
            Tile::Off(_) => None,
            Tile::Auto(_) => {
                let (w, h) = fixed?;
                (width > w || height > h).then_some(w.min(h))
            }
        }
    }
}

impl std::str::FromStr for Tile {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        if s.eq_ignore_ascii_case("off") {
            return Ok(Tile::Off(Off::Off));
        }
        if s.eq_ignore_ascii_case("auto") {
            return Ok(Tile::Auto(Auto::Auto));
        }
        s.parse()
            .map(Tile::Pixels)
            .map_err(|_| format!("'{s}' is neither a number of pixels nor 'auto' or 'off'"))
    }
}
