//! A flight's recordings reopened after ingest, for what later stages read
//! from them on demand: a frame's image (decoded, or still compressed) and
//! the recorded SLAM maps. Frames and `ingest.json` say which recording
//! holds each message and where, so nothing is searched and nothing else
//! is read.

use std::collections::HashMap;
use std::path::Path;

use image::DynamicImage;
use postflight_core::frame::ImageEncoding;
use postflight_core::map::{PointCloud, SlamMap, VoxelGrid, merged};
use postflight_core::outputs::ingest::RecordingSummary;
use postflight_core::{Flight, Frame, ImageLocation, MessageLocation};

use crate::error::IngestError;
use crate::image::{decode_compressed, decode_raw};
use crate::photos::PhotoFolder;
use crate::reconstruction::Reconstruction;
use crate::recording::Recording;
use crate::ros::{Wire, msg, pointcloud2};
use crate::source::Source;

/// Two recordings' map points closer than this are of one surface, metres
/// (a registration's inlier distance).
const SAME_SURFACE_M: f64 = 0.1;

/// Every recording (or photo folder) of a flight, reopened.
pub struct Recordings {
    /// In the order of `ingest.json`'s `recordings`, as frames name them.
    recordings: Vec<Source>,
}

impl Recordings {
    /// The recordings a flight was ingested from; an error if one changed
    /// size since (then the message locations are stale).
    pub fn reopen(flight: &Flight) -> Result<Self, IngestError> {
        let recordings = flight.summary.recordings.iter();
        let recordings = recordings
            .map(|r| match r.photos {
                Some(_) => PhotoFolder::open(&r.path).map(Source::Photos),
                None => Recording::reopen(flight, r).map(Source::Recording),
            })
            .collect::<Result<_, _>>()?;
        Ok(Self { recordings })
    }

    /// The recording (or photo folder) holding a frame.
    fn of(&self, frame: &Frame) -> Result<&Source, IngestError> {
        let index = usize::from(frame.recording);
        self.recordings.get(index).ok_or_else(|| {
            postflight_core::Error::RunDir {
                path: Default::default(),
                why: format!(
                    "frame {} names recording {index}, but ingest.json lists {}; rerun `postflight ingest`",
                    frame.index,
                    self.recordings.len()
                ),
            }
            .into()
        })
    }

    /// Decode a frame's image.
    pub fn image(&self, frame: &Frame) -> Result<DynamicImage, IngestError> {
        match (self.of(frame)?, &frame.location) {
            (Source::Recording(r), ImageLocation::Message(m)) => r.image(frame, *m),
            (Source::Photos(folder), ImageLocation::Photo(name)) => folder.image(name),
            _ => Err(mismatched(frame)),
        }
    }

    /// A frame's image as recorded, still compressed (JPEG or PNG bytes), for
    /// passing on without decoding; `None` for raw images.
    pub fn compressed_image(&self, frame: &Frame) -> Result<Option<Vec<u8>>, IngestError> {
        match (self.of(frame)?, &frame.location) {
            (Source::Recording(r), ImageLocation::Message(m)) => r.compressed_image(frame, *m),
            (Source::Photos(folder), ImageLocation::Photo(name)) => folder.photo(name).map(Some),
            _ => Err(mismatched(frame)),
        }
    }

    /// The SLAM maps recorded in the flight's recordings, in the run's map
    /// frame, as one cloud (`None` when none had one; where two agree, the
    /// first's points: [`merged`]), and the topics and files it came from.
    pub fn recorded_map(
        &self,
        flight: &Flight,
    ) -> Result<Option<(PointCloud, String)>, IngestError> {
        let mut clouds = Vec::new();
        let mut sources = Vec::new();
        for (source, summary) in self.recordings.iter().zip(&flight.summary.recordings) {
            let Source::Recording(recording) = source else {
                continue;
            };
            let Some(mut cloud) = recording.recorded_map(summary)? else {
                continue;
            };
            // Into the run's map frame.
            let t = summary.placement.transform;
            if t != nalgebra::Isometry3::identity() {
                cloud.points.iter_mut().for_each(|p| *p = t * *p);
            }
            let topic = summary.map.as_ref().map(|m| m.topic.as_str());
            sources.push(match flight.summary.recordings.len() {
                1 => format!("recorded {}", topic.unwrap_or_default()),
                _ => format!(
                    "recorded {} of {}",
                    topic.unwrap_or_default(),
                    summary.name()
                ),
            });
            clouds.push(cloud);
        }
        Ok(merged(clouds, SAME_SURFACE_M).map(|m| (m, sources.join(", "))))
    }
}

/// The map recorded in `recording`, where `summary` (its ingest) says it
/// is, in its own SLAM frame.
pub(crate) fn recorded_map_of(
    recording: &mut Recording,
    summary: &RecordingSummary,
) -> Result<Option<PointCloud>, IngestError> {
    recording.wires = wires(summary);
    recording.recorded_map(summary)
}

impl Recording {
    /// One recording of a flight, as ingest found it; an error if it
    /// changed size since.
    fn reopen(flight: &Flight, summary: &RecordingSummary) -> Result<Self, IngestError> {
        let mut recording = Self::open(&summary.path)?;
        if recording.len() != summary.size_bytes {
            return Err(postflight_core::Error::RunDir {
                path: flight.run.path().to_owned(),
                why: format!(
                    "the recording {} changed size since ingest ({} bytes, was {}); rerun `postflight ingest`",
                    summary.path.display(),
                    recording.len(),
                    summary.size_bytes
                ),
            }
            .into());
        }
        recording.wires = wires(summary);
        Ok(recording)
    }

    /// How the messages of `topic` decode.
    fn wire(&self, topic: &str) -> Wire {
        self.wires.get(topic).cloned().unwrap_or(Wire::Cdr)
    }

    /// Decode a frame's image, the message at `location`.
    fn image(&self, frame: &Frame, location: MessageLocation) -> Result<DynamicImage, IngestError> {
        let payload = self.read_message(location)?;
        let bad = |why: String| self.bad_frame(location, why);
        let wire = self.wire(&frame.topic);
        if is_compressed(frame) {
            let (_, data) = wire
                .compressed_image(&payload)
                .map_err(|e| bad(e.to_string()))?;
            decode_compressed(data).map_err(bad)
        } else {
            let (head, data) = wire.image(&payload).map_err(|e| bad(e.to_string()))?;
            decode_raw(
                &head.encoding,
                head.width,
                head.height,
                head.step,
                head.is_bigendian != 0,
                data,
            )
            .map_err(bad)
        }
    }

    /// A frame's image (the message at `location`) still compressed;
    /// `None` for raw images.
    fn compressed_image(
        &self,
        frame: &Frame,
        location: MessageLocation,
    ) -> Result<Option<Vec<u8>>, IngestError> {
        if !is_compressed(frame) {
            return Ok(None);
        }
        let payload = self.read_message(location)?;
        let (_, data) = self
            .wire(&frame.topic)
            .compressed_image(&payload)
            .map_err(|e| self.bad_frame(location, e.to_string()))?;
        Ok(Some(data.to_vec()))
    }

    /// The SLAM map recorded in this recording, if it had one.
    fn recorded_map(&self, summary: &RecordingSummary) -> Result<Option<PointCloud>, IngestError> {
        let Some(map) = &summary.map else {
            return Ok(None);
        };
        let payload = self.read_message(map.location)?;
        let bad = |why: String| postflight_core::Error::Map {
            path: self.path().to_owned(),
            why: format!("topic {}: {why}", map.topic),
        };
        let msg = self
            .wire(&map.topic)
            .decode::<msg::PointCloud2>(&payload)
            .map_err(|e| bad(e.to_string()))?;
        Ok(Some(pointcloud2::decode(&msg).map_err(bad)?))
    }

    fn bad_frame(&self, location: MessageLocation, why: String) -> IngestError {
        IngestError::BadLocation {
            path: self.path().to_owned(),
            location,
            why,
        }
    }
}

/// The map's points: the file given, else the ones recorded in the
/// flight's recordings, else the points of the reconstruction that posed
/// its photos (`None` without any); and which it is (the path, `recorded
/// TOPIC`, or `reconstruction PATH`).
pub fn map_cloud(
    flight: &Flight,
    given: Option<&Path>,
) -> Result<Option<(PointCloud, String)>, IngestError> {
    if let Some(path) = given {
        let origin = flight.summary.geo_origin.as_ref().map(|g| &g.origin);
        let cloud = PointCloud::load_placed(path, origin)?;
        return Ok(Some((cloud, path.display().to_string())));
    }
    if let Some(recorded) = Recordings::reopen(flight)?.recorded_map(flight)? {
        return Ok(Some(recorded));
    }
    let Some(r) = &flight.summary.reconstruction else {
        return Ok(None);
    };
    let unusable = |why: String| IngestError::Reconstruction {
        path: r.path.clone(),
        why,
    };
    let points = Reconstruction::load(&r.path).map_err(unusable)?.points;
    let cloud = PointCloud {
        frame_id: String::new(),
        points: points.iter().map(|p| r.similarity.apply(p)).collect(),
        grid: None,
        mesh_spacing_m: None,
    };
    Ok(Some((
        cloud,
        format!("reconstruction {}", r.path.display()),
    )))
}

/// The map a stage works on ([`map_cloud`]), voxelised on `grid` (without
/// one, on the map's own grid if it is a voxel map, else the default grid);
/// an error without a map.
pub fn load_map(
    flight: &Flight,
    given: Option<&Path>,
    grid: Option<VoxelGrid>,
) -> Result<(SlamMap, String), IngestError> {
    let (cloud, name) = map_cloud(flight, given)?.ok_or(IngestError::NoMap)?;
    let grid = grid.or(cloud.grid).unwrap_or_default();
    let map = SlamMap::on_grid(cloud, grid).ok_or_else(|| postflight_core::Error::Map {
        path: name.clone().into(),
        why: format!(
            "the map has no points; pass a map with {}",
            postflight_core::setting::inputs::MAP
        ),
    })?;
    Ok((map, name))
}

/// A frame said to be in a photo folder that ingest found a recording, or
/// the other way round: the run directory is stale.
fn mismatched(frame: &Frame) -> IngestError {
    postflight_core::Error::RunDir {
        path: Default::default(),
        why: format!(
            "frame {} is not where ingest.json says its recording is; rerun `postflight ingest`",
            frame.index
        ),
    }
    .into()
}

fn is_compressed(frame: &Frame) -> bool {
    matches!(frame.encoding, ImageEncoding::Compressed(_))
}

/// How a recording's ROS 1 topics read again decode, from the definitions
/// ingest kept in `ingest.json` (every other topic is CDR).
fn wires(recording: &RecordingSummary) -> HashMap<String, Wire> {
    let summaries = recording.messages.iter();
    summaries
        .filter_map(|(topic, summary)| {
            let definition = summary.definition.as_deref()?;
            let wire = Wire::of(&summary.encoding, &summary.schema, definition).ok()?;
            Some((topic.clone(), wire))
        })
        .collect()
}
