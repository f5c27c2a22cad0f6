//! Detections: boxes in a frame's pixels, each with the detector's score,
//! class and the kind of defect that class means, and its pixels where the
//! model segments.

use crate::defect_kind::DefectKind;
use crate::mask::Mask;

crate::table! {
    /// A box in pixels: `x0, y0` top-left, `x1, y1` bottom-right (exclusive
    /// edges); its columns are named so.
    #[derive(Copy)]
    pub struct BoxXyxy {
        x0: f32,
        y0: f32,
        x1: f32,
        y1: f32,
    }
}

impl BoxXyxy {
    /// From YOLO's centre and size.
    pub fn from_cxcywh(cx: f32, cy: f32, w: f32, h: f32) -> Self {
        Self {
            x0: cx - w / 2.0,
            y0: cy - h / 2.0,
            x1: cx + w / 2.0,
            y1: cy + h / 2.0,
        }
    }

    pub fn width(&self) -> f32 {
        (self.x1 - self.x0).max(0.0)
    }

    pub fn height(&self) -> f32 {
        (self.y1 - self.y0).max(0.0)
    }

    pub fn area(&self) -> f32 {
        self.width() * self.height()
    }

    /// Intersection over union; 0 for disjoint or empty boxes.
    pub fn iou(&self, other: &Self) -> f32 {
        let inter = Self {
            x0: self.x0.max(other.x0),
            y0: self.y0.max(other.y0),
            x1: self.x1.min(other.x1),
            y1: self.y1.min(other.y1),
        }
        .area();
        let union = self.area() + other.area() - inter;
        if union <= 0.0 { 0.0 } else { inter / union }
    }

    /// Clip to an image of `width` x `height` pixels.
    pub fn clip(&self, width: f32, height: f32) -> Self {
        Self {
            x0: self.x0.clamp(0.0, width),
            y0: self.y0.clamp(0.0, height),
            x1: self.x1.clamp(0.0, width),
            y1: self.y1.clamp(0.0, height),
        }
    }
}

/// One detection in one image.
#[derive(Debug, Clone, PartialEq)]
pub struct Detection {
    pub bbox: BoxXyxy,
    pub score: f32,
    pub class: u32,
    /// What its class means: a crack, or an area defect.
    pub kind: DefectKind,
    /// Tile of the frame that found it (numbered as the detect stage cuts
    /// them), -1 for the whole frame.
    pub tile: i32,
    /// Its pixels, from a model that segments (`None`: boxes only).
    pub mask: Option<Mask>,
}

/// One detection of one frame, in the frame's pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameDetection {
    pub frame: u32,
    pub time_ns: i64,
    pub detection: Detection,
}

/// Where inference runs (`--device`).
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Default,
    serde::Serialize,
    serde::Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum Device {
    #[default]
    Cpu,
    Cuda,
    #[value(name = "tensorrt")]
    TensorRt,
}

impl Device {
    pub fn as_str(self) -> &'static str {
        match self {
            Device::Cpu => "cpu",
            Device::Cuda => "cuda",
            Device::TensorRt => "tensorrt",
        }
    }
}

impl std::fmt::Display for Device {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}
