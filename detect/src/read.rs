//! What a run's outputs hold for each view (boxes, instance masks, a
//! probability map per class), in frame pixels, gathered per frame and
//! finished there: suppressed, merged, each detection with its kind and
//! its pixels.

use postflight_core::defect_kind::DefectKind;
use postflight_core::detection::{BoxXyxy, Detection};

use crate::boxes::{merge_touching, nms, nms_with};
use crate::classes::Classes;
use crate::decode::decode;
use crate::masks::{
    MASK_THRESHOLD, Plane, ProbabilityMap, Prototypes, ViewPlace, finest_first, from_maps, regions,
};
use crate::signature::Head;
use crate::stage::DetectOptions;
use crate::tiles::Window;
use crate::views::{Prepared, View};

/// Reads a run's outputs for what each view found.
pub(crate) struct Reader<'a> {
    pub(crate) head: &'a Head,
    /// Classes a boxes output scores.
    pub(crate) box_classes: usize,
    /// The model's classes and the kinds they find.
    pub(crate) classes: &'a Classes,
    /// Images in the run.
    pub(crate) images: usize,
}

impl Reader<'_> {
    /// What image `b` of a run's `outputs` found in `view`: its detections
    /// in frame pixels (with their crack pixels for instance masks), and
    /// its probability map, into the frame's `found`.
    pub(crate) fn read_view(
        &self,
        outputs: &ort::session::SessionOutputs<'_>,
        b: usize,
        view: &View,
        options: &DetectOptions,
        found: &mut FrameFound,
    ) -> Result<(), String> {
        let output = Output {
            outputs,
            image: b,
            images: self.images,
            input_width: view.size.0,
        };
        let place = ViewPlace {
            window: view.window,
            placement: view.placement,
        };
        let confidence = options.settings.confidence;
        let mut detections = match &self.head {
            Head::Boxes { output: name }
            | Head::BoxesAndMap { output: name, .. }
            | Head::Instances { output: name, .. } => self.boxes(&output, name, confidence)?,
            Head::Semantic { output: name } => {
                let mut found_here = Vec::new();
                for (class, kind, probability) in class_probabilities(&output, name, self.classes)?
                {
                    found_here.extend(regions(&probability, confidence, class, kind));
                    let class = Some(class);
                    found.maps.push(ProbabilityMap {
                        place,
                        class,
                        probability,
                    });
                }
                found_here
            }
        };
        // What each class finds; a class that finds no kind is ignored.
        detections.retain_mut(|(d, _)| match self.classes.kind(d.class) {
            Some(kind) => {
                d.kind = kind;
                true
            }
            None => false,
        });
        if let Head::BoxesAndMap { map, .. } = &self.head {
            let probability = output.plane(map, 0)?;
            let class = None;
            found.maps.push(ProbabilityMap {
                place,
                class,
                probability,
            });
        }
        // Into frame pixels; boxes are clipped to the frame after NMS, as
        // Ultralytics does.
        let Window { x, y, tile, .. } = view.window;
        for (d, _) in &mut detections {
            let b = view.placement.to_image(&d.bbox);
            d.bbox = BoxXyxy {
                x0: b.x0 + x as f32,
                y0: b.y0 + y as f32,
                x1: b.x1 + x as f32,
                y1: b.y1 + y as f32,
            };
            d.tile = tile;
        }
        match &self.head {
            Head::Instances {
                prototypes,
                coefficients,
                ..
            } => {
                let protos = Prototypes {
                    place,
                    planes: (0..*coefficients)
                        .map(|k| output.plane(prototypes, k))
                        .collect::<Result<_, _>>()?,
                };
                found.add_instances(detections, &protos, options.settings.iou);
            }
            _ => found
                .detections
                .extend(detections.into_iter().map(|(d, _)| d)),
        }
        Ok(())
    }

    /// The detections of a boxes output `name` scoring at least
    /// `confidence`, in model input pixels, each with its mask
    /// coefficients (none for a model of boxes only).
    pub(crate) fn boxes(
        &self,
        output: &Output<'_, '_>,
        name: &str,
        confidence: f32,
    ) -> Result<Vec<(Detection, Vec<f32>)>, String> {
        let (shape, data) = output.tensor(name)?;
        let extra = self.head.extra_rows();
        if shape.len() != 3 || shape[1] != 4 + self.box_classes + extra {
            let coefficients = if extra > 0 {
                format!(" + {extra} mask coefficients")
            } else {
                String::new()
            };
            return Err(format!(
                "output shape {shape:?}, expected [batch, 4 + {} classes{coefficients}, anchors]",
                self.box_classes
            ));
        }
        Ok(decode(
            data,
            self.box_classes,
            extra,
            shape[2],
            output.image,
            confidence,
        ))
    }
}

/// One image's outputs of a run.
pub(crate) struct Output<'a, 's> {
    pub(crate) outputs: &'a ort::session::SessionOutputs<'s>,
    /// The image in the batch, and the batch's size.
    pub(crate) image: usize,
    pub(crate) images: usize,
    /// The model input's width, pixels.
    pub(crate) input_width: u32,
}

impl Output<'_, '_> {
    /// The output `name`: its shape and values, for the whole batch.
    pub(crate) fn tensor(&self, name: &str) -> Result<(Vec<usize>, &[f32]), String> {
        let (shape, data) = self.outputs[name]
            .try_extract_tensor::<f32>()
            .map_err(|e| e.to_string())?;
        let shape = shape
            .iter()
            .map(|d| usize::try_from(*d).unwrap_or(0))
            .collect();
        Ok((shape, data))
    }

    /// Channel `channel` of this image in a `[batch, channels, height,
    /// width]` output `name`.
    pub(crate) fn plane(&self, name: &str, channel: usize) -> Result<Plane, String> {
        let (shape, data) = self.tensor(name)?;
        if shape.len() != 4 || shape[0] < self.images || channel >= shape[1] {
            return Err(format!(
                "output {name} has shape {shape:?}, expected [batch, channels, height, width]"
            ));
        }
        let (c, h, w) = (shape[1], shape[2], shape[3]);
        let at = (self.image * c + channel) * h * w;
        Ok(Plane {
            width: w,
            height: h,
            stride: self.input_width as f32 / w as f32,
            values: data[at..at + h * w].to_vec(),
        })
    }
}

/// A semantic map's probability of each class that finds a kind, with the
/// class and its kind: one channel is the first class's probability (the
/// sigmoid of its logits where its values leave 0..1); several are logits
/// of each class, through their softmax, channel `c` the model's class `c`
/// (names for every channel) or `c - 1` (background first, unnamed).
pub(crate) fn class_probabilities(
    output: &Output<'_, '_>,
    name: &str,
    classes: &Classes,
) -> Result<Vec<(u32, DefectKind, Plane)>, String> {
    let sigmoid = |v: f32| 1.0 / (1.0 + (-v).exp());
    let channels = output.tensor(name)?.0.get(1).copied().unwrap_or(0);
    let named = classes.names.len();
    let unnamed = match channels.checked_sub(named) {
        Some(0) => 0,
        Some(1) if channels >= 2 => 1,
        _ => {
            return Err(format!(
                "output {name} has {channels} channels but the model names {named} classes ({}); give the model names metadata for every channel (or all but a first background)",
                classes.names.join(", ")
            ));
        }
    };
    if channels == 1 {
        let mut p = output.plane(name, 0)?;
        if p.values.iter().any(|v| !(0.0..=1.0).contains(v)) {
            p.values.iter_mut().for_each(|v| *v = sigmoid(*v));
        }
        return Ok(classes.kind(0).map(|k| (0, k, p)).into_iter().collect());
    }
    let logits: Vec<Plane> = (0..channels)
        .map(|c| output.plane(name, c))
        .collect::<Result<_, _>>()?;
    // Each pixel's softmax normaliser, once for every class: its largest
    // logit and the sum of the exponentials below it.
    // (Two channels need none: the sigmoid of their difference.)
    let pixels = if channels > 2 {
        logits[0].values.len()
    } else {
        0
    };
    let top: Vec<f32> = (0..pixels)
        .map(|i| logits.iter().map(|l| l.values[i]).fold(f32::MIN, f32::max))
        .collect();
    let sum: Vec<f32> = (0..pixels)
        .map(|i| logits.iter().map(|l| (l.values[i] - top[i]).exp()).sum())
        .collect();
    let mut out = Vec::new();
    for (channel, logit) in logits.iter().enumerate() {
        let Some(class) = channel.checked_sub(unnamed) else {
            continue;
        };
        let Some(kind) = classes.kind(class as u32) else {
            continue;
        };
        let mut p = logit.clone();
        for (i, v) in p.values.iter_mut().enumerate() {
            *v = if channels == 2 {
                // The softmax of two, as the reference pipeline computes it.
                sigmoid(*v - logits[1 - channel].values[i])
            } else {
                (*v - top[i]).exp() / sum[i]
            };
        }
        out.push((class as u32, kind, p));
    }
    Ok(out)
}

/// What a frame's views found, until the frame is finished.
pub(crate) struct FrameFound {
    pub(crate) detections: Vec<Detection>,
    /// Each view's probability maps (models that give them), one per class.
    pub(crate) maps: Vec<ProbabilityMap>,
    /// The frame's (width, height), pixels.
    pub(crate) size: (f32, f32),
}

impl FrameFound {
    pub(crate) fn new(frame: &Prepared) -> Self {
        Self {
            detections: Vec::new(),
            maps: Vec::new(),
            size: (frame.width as f32, frame.height as f32),
        }
    }

    /// Instances of one view: as Ultralytics does, suppressed first, then
    /// the survivors' masks decoded within their boxes clipped to the
    /// frame, and those left empty dropped.
    pub(crate) fn add_instances(
        &mut self,
        detections: Vec<(Detection, Vec<f32>)>,
        protos: &Prototypes,
        iou: f32,
    ) {
        let (w, h) = self.size;
        let kept = nms_with(detections, iou);
        self.detections
            .extend(kept.into_iter().filter_map(|(mut d, coefficients)| {
                d.mask = Some(protos.instance(&coefficients, &d.bbox.clip(w, h))?);
                Some(d)
            }));
    }

    /// The frame's findings: NMS'd and merged, each with its crack pixels
    /// from the probability maps where the model gives maps.
    pub(crate) fn finish(self, options: &DetectOptions) -> Vec<Detection> {
        let (w, h) = self.size;
        let mut detections = self.detections;
        detections.retain(|d| d.bbox.clip(w, h).area() > 0.0);
        // Grid cells and tiles report a long crack piecewise: join the pieces.
        let kept = nms(detections, options.settings.iou);
        let mut merged = match options.settings.merge_gap.pixels() {
            Some(gap) => merge_touching(kept, gap),
            None => kept,
        };
        for d in &mut merged {
            d.bbox = d.bbox.clip(w, h);
        }
        if !self.maps.is_empty() {
            let mut maps = self.maps;
            finest_first(&mut maps);
            for d in &mut merged {
                let of_class: Vec<&ProbabilityMap> = maps
                    .iter()
                    .filter(|m| m.class.is_none_or(|c| c == d.class))
                    .collect();
                d.mask = from_maps(&of_class, &d.bbox, MASK_THRESHOLD);
            }
        }
        merged
    }
}
