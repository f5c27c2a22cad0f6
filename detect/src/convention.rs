//! How a model wants its pixels: the channel order, the value of a white
//! pixel, and a per-channel mean and standard deviation. Models are
//! published with their own: Ultralytics exports take RGB on 0..1, most
//! PyTorch segmenters ImageNet's mean and std, some raw BGR 0..255 (OpenCV
//! order). Each part is the `[detect]` setting where given, else what the
//! model's metadata says (ONNX's `Image.BitmapPixelFormat` and
//! `Image.NominalPixelRange`, or an Ultralytics export's author), else RGB
//! on 0..1 with no normalisation.

use std::collections::HashMap;

use postflight_core::outputs::detect::{ChannelOrder, InputConvention, Source};

use crate::settings::DetectConfig;

/// The metadata keys ONNX defines for an image input (its MetadataProps
/// document), case-insensitive as it says.
const PIXEL_FORMAT: &str = "image.bitmappixelformat";
const PIXEL_RANGE: &str = "image.nominalpixelrange";

/// What the model's metadata says of its input, where it says anything.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Declared {
    pub channel_order: Option<ChannelOrder>,
    /// `(scale, mean, std)` of a declared range.
    pub range: Option<(f32, f32, f32)>,
}

impl Declared {
    /// Read from a model's custom metadata (keys as written, any case).
    pub fn of(metadata: &HashMap<String, String>) -> Result<Self, String> {
        let get = |key: &str| {
            metadata
                .iter()
                .find(|(k, _)| k.eq_ignore_ascii_case(key))
                .map(|(_, v)| v.trim())
        };
        let channel_order = match get(PIXEL_FORMAT) {
            None => None,
            Some(v) if v.eq_ignore_ascii_case("rgb8") || v.eq_ignore_ascii_case("rgba8") => {
                Some(ChannelOrder::Rgb)
            }
            Some(v) if v.eq_ignore_ascii_case("bgr8") || v.eq_ignore_ascii_case("bgra8") => {
                Some(ChannelOrder::Bgr)
            }
            Some(v) => {
                return Err(format!(
                    "its metadata declares Image.BitmapPixelFormat '{v}'; postflight feeds three-channel images (Rgb8 or Bgr8)"
                ));
            }
        };
        let range = match get(PIXEL_RANGE) {
            None => None,
            Some(v) if v.eq_ignore_ascii_case("NominalRange_0_255") => Some((255.0, 0.0, 1.0)),
            Some(v) if v.eq_ignore_ascii_case("Normalized_0_1") => Some((1.0, 0.0, 1.0)),
            Some(v) if v.eq_ignore_ascii_case("Normalized_1_1") => Some((1.0, 0.5, 0.5)),
            Some(v) => {
                return Err(format!(
                    "its metadata declares Image.NominalPixelRange '{v}', which postflight does not feed (NominalRange_0_255, Normalized_0_1 or Normalized_1_1); set [detect] pixel_scale, mean and std instead"
                ));
            }
        };
        // Ultralytics writes no image metadata, and always takes RGB on 0..1.
        let ultralytics = get("author").is_some_and(|a| a.contains("Ultralytics"));
        Ok(Self {
            channel_order: channel_order.or(ultralytics.then_some(ChannelOrder::Rgb)),
            range: range.or(ultralytics.then_some((1.0, 0.0, 1.0))),
        })
    }
}

/// The convention to feed the model with: each part from the settings,
/// else the model's metadata, else the default (RGB on 0..1).
pub fn resolve(settings: &DetectConfig, declared: &Declared) -> InputConvention {
    let from = |given: bool, declared: bool| {
        if given {
            Source::Settings
        } else if declared {
            Source::Metadata
        } else {
            Source::Default
        }
    };
    let range = declared.range;
    let scale = settings.pixel_scale.or(range.map(|r| r.0)).unwrap_or(1.0);
    let mean = settings
        .mean
        .or(range.map(|r| [r.1; 3]))
        .unwrap_or([0.0; 3]);
    let std = settings.std.or(range.map(|r| [r.2; 3])).unwrap_or([1.0; 3]);
    let source = [
        from(
            settings.channel_order.is_some(),
            declared.channel_order.is_some(),
        ),
        from(
            settings.pixel_scale.is_some() || settings.mean.is_some() || settings.std.is_some(),
            range.is_some(),
        ),
    ]
    .into_iter()
    .max()
    .unwrap_or(Source::Default);
    InputConvention {
        channel_order: settings
            .channel_order
            .or(declared.channel_order)
            .unwrap_or(ChannelOrder::Rgb),
        pixel_scale: scale,
        mean,
        std,
        source,
    }
}

/// Rewrite a planar RGB input on 0..1 (`[3, h, w]`, as letterboxing writes
/// it) into `convention`'s values in place. The default convention leaves
/// it untouched, so the reference pipeline's inputs stay bit-identical.
pub fn apply(convention: &InputConvention, input: &mut [f32]) {
    if convention.is_identity() {
        return;
    }
    let plane = input.len() / 3;
    // Each RGB channel's gain and offset: scale * (v - mean) / std.
    let affine: Vec<(f32, f32)> = (0..3)
        .map(|c| {
            let gain = convention.pixel_scale / convention.std[c];
            (gain, -convention.mean[c] * gain)
        })
        .collect();
    for (c, &(gain, offset)) in affine.iter().enumerate() {
        input[c * plane..(c + 1) * plane]
            .iter_mut()
            .for_each(|v| *v = *v * gain + offset);
    }
    if convention.channel_order == ChannelOrder::Bgr {
        let (red, rest) = input.split_at_mut(plane);
        red.swap_with_slice(&mut rest[plane..2 * plane]);
    }
}

/// The value a padding pixel (grey `pad`, 0..255) has in each of the
/// model's channels under `convention`.
pub fn padding(convention: &InputConvention, pad: u8) -> [f32; 3] {
    let mut one = [f32::from(pad) / 255.0; 3];
    apply(convention, &mut one);
    one
}

#[cfg(test)]
mod tests {
    use super::*;

    fn metadata(pairs: &[(&str, &str)]) -> HashMap<String, String> {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect()
    }

    #[test]
    fn onnx_image_metadata_declares_order_and_range() {
        let d = Declared::of(&metadata(&[
            ("Image.BitmapPixelFormat", "Bgr8"),
            ("image.nominalpixelrange", "NominalRange_0_255"),
        ]))
        .unwrap();
        let c = resolve(&DetectConfig::default(), &d);
        assert_eq!(c.channel_order, ChannelOrder::Bgr);
        assert_eq!((c.pixel_scale, c.mean, c.std), (255.0, [0.0; 3], [1.0; 3]));
        assert_eq!(c.source, Source::Metadata);
        let minus_one = Declared::of(&metadata(&[("Image.NominalPixelRange", "Normalized_1_1")]));
        let c = resolve(&DetectConfig::default(), &minus_one.unwrap());
        let mut v = [0.0, 1.0, 0.5];
        apply(&c, &mut v);
        assert_eq!(v, [-1.0, 1.0, 0.0]);
        assert!(Declared::of(&metadata(&[("Image.BitmapPixelFormat", "Gray8")])).is_err());
    }

    #[test]
    fn settings_override_metadata_and_normalise_per_channel() {
        let d = Declared::of(&metadata(&[("author", "Ultralytics")])).unwrap();
        let settings = DetectConfig {
            channel_order: Some(ChannelOrder::Bgr),
            mean: Some([0.485, 0.456, 0.406]),
            std: Some([0.229, 0.224, 0.225]),
            ..DetectConfig::default()
        };
        let c = resolve(&settings, &d);
        assert_eq!(c.source, Source::Settings);
        // One pixel, planar: red 1, green 0.5, blue 0.
        let mut v = [1.0, 0.5, 0.0];
        apply(&c, &mut v);
        let expect = [
            (0.0 - 0.406) / 0.225,
            (0.5 - 0.456) / 0.224,
            (1.0 - 0.485) / 0.229,
        ];
        for (a, b) in v.iter().zip(expect) {
            assert!((a - b).abs() < 1e-6, "{v:?}");
        }
        assert!(resolve(&DetectConfig::default(), &d).is_identity());
    }
}
