//! A frame made ready for the model: its windows (the whole frame, or its
//! tiles), each letterboxed to the model's input and in its pixel
//! convention (the [`Feed`]).

use ingest::Recordings;
use postflight_core::Frame;
use postflight_core::outputs::detect::{FailedFrame, InputConvention};

use crate::choose::FrameWork;
use crate::convention;
use crate::letterbox::{InputSize, Placement, letterbox};
use crate::stage::DetectOptions;
use crate::tiles::{Window, windows};

/// A frame ready for the model.
pub(crate) struct Prepared {
    pub(crate) frame: u32,
    pub(crate) time_ns: i64,
    /// One model input per window (the whole frame, then tiles).
    pub(crate) views: Vec<View>,
    pub(crate) width: u32,
    pub(crate) height: u32,
}

/// A window of a frame, letterboxed for the model.
pub(crate) struct View {
    pub(crate) window: Window,
    /// Model input, `[3, height, width]`.
    pub(crate) input: Vec<f32>,
    /// The input's `(width, height)`.
    pub(crate) size: (u32, u32),
    pub(crate) placement: Placement,
}

/// The frame of `work` decoded and its chosen windows made ready (every
/// window, should the image not be the size ingest recorded).
pub(crate) fn prepare(
    recording: &Recordings,
    work: &FrameWork<'_>,
    feed: Feed,
    options: &DetectOptions,
) -> Result<Prepared, FailedFrame> {
    let frame = work.frame;
    let img = recording
        .image(frame)
        .map_err(|e| FailedFrame {
            frame: frame.index,
            why: e.to_string(),
        })?
        .to_rgb8();
    let recorded = (frame.width, frame.height) == (Some(img.width()), Some(img.height()));
    let chosen = if recorded {
        work.windows.clone()
    } else {
        windows(
            img.width(),
            img.height(),
            feed.tile(options, img.width(), img.height()),
            options.settings.tile_overlap,
        )
    };
    let views = chosen
        .into_iter()
        .map(|window| {
            let mut input = Vec::new();
            let (size, placement) = if window.tile < 0 {
                letterbox(&img, feed.size, &mut input)
            } else {
                let crop = image::imageops::crop_imm(
                    &img,
                    window.x,
                    window.y,
                    window.width,
                    window.height,
                )
                .to_image();
                letterbox(&crop, feed.size, &mut input)
            };
            convention::apply(&feed.convention, &mut input);
            View {
                window,
                input,
                size,
                placement,
            }
        })
        .collect();
    Ok(Prepared {
        frame: frame.index,
        time_ns: frame.time_ns,
        views,
        width: img.width(),
        height: img.height(),
    })
}

/// How each view is fed to the model: its input size and pixel convention.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Feed {
    pub(crate) size: InputSize,
    pub(crate) convention: InputConvention,
}

impl Feed {
    /// What a whole frame runs as (tiles at the tile size): the model's
    /// input for the first of `frames` of known size, and its tile size;
    /// a warning in `warnings` where an untiled frame shrinks so far that
    /// thin cracks vanish.
    pub(crate) fn input_shape(
        &self,
        frames: &[&Frame],
        options: &DetectOptions,
        warnings: &mut Vec<String>,
    ) -> ([u32; 2], Option<u32>) {
        let first = frames.iter().find_map(|f| Some((f.width?, f.height?)));
        let (w, h) = first
            .map(|(fw, fh)| self.size.place(fw, fh).0)
            .unwrap_or((options.settings.image_size, options.settings.image_size));
        let tile = first.and_then(|(fw, fh)| self.tile(options, fw, fh));
        if let (None, InputSize::Fixed(mw, mh), Some((fw, fh))) = (tile, self.size, first) {
            let shrink = (fw as f32 / mw as f32).max(fh as f32 / mh as f32);
            if shrink > 1.5 {
                warnings.push(format!(
                    "frames of {fw}x{fh} were shrunk {shrink:.1} times to the model's fixed {mw}x{mh} input; thin cracks vanish: tile them ([detect] tile = \"auto\" or --tile {})",
                    mw.min(mh)
                ));
            }
        }
        ([w, h], tile)
    }

    /// The tile size a `width` x `height` frame runs with: the setting's,
    /// or with `auto` a fixed-size model's input when the frame is larger.
    pub(crate) fn tile(&self, options: &DetectOptions, width: u32, height: u32) -> Option<u32> {
        let fixed = match self.size {
            InputSize::Fixed(w, h) => Some((w, h)),
            InputSize::Rect { .. } => None,
        };
        options.settings.tile.size(fixed, width, height)
    }
}
