//! A flight's recording reopened after ingest, for what later stages read
//! from it on demand: a frame's image (decoded, or still compressed) and
//! the recorded SLAM map. Frames and `ingest.json` say where each message
//! is, so nothing is searched and nothing else is read.

use std::collections::HashMap;
use std::path::Path;

use image::DynamicImage;
use postflight_core::map::{PointCloud, SlamMap, VoxelGrid};
use postflight_core::{Flight, Frame};

use crate::error::IngestError;
use crate::image::{decode_compressed, decode_raw};
use crate::recording::Recording;
use crate::ros::{Wire, msg, pointcloud2};

impl Recording {
    /// The recording a flight was ingested from; an error if it changed
    /// size since (then the message locations are stale).
    pub fn reopen(flight: &Flight) -> Result<Self, IngestError> {
        let file = &flight.summary.flight;
        let mut recording = Self::open(&file.path)?;
        if recording.len() != file.size_bytes {
            return Err(postflight_core::Error::RunDir {
                path: flight.run.path().to_owned(),
                why: format!(
                    "the recording {} changed size since ingest ({} bytes, was {}); rerun `postflight ingest`",
                    file.path.display(),
                    recording.len(),
                    file.size_bytes
                ),
            }
            .into());
        }
        recording.wires = wires(flight);
        Ok(recording)
    }

    /// How the messages of `topic` decode.
    fn wire(&self, topic: &str) -> Wire {
        self.wires.get(topic).cloned().unwrap_or(Wire::Cdr)
    }

    /// Decode a frame's image.
    pub fn image(&self, frame: &Frame) -> Result<DynamicImage, IngestError> {
        let payload = self.read_message(frame.location)?;
        let bad = |why: String| self.bad_frame(frame, why);
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

    /// A frame's image as recorded, still compressed (JPEG or PNG bytes), for
    /// passing on without decoding; `None` for raw images.
    pub fn compressed_image(&self, frame: &Frame) -> Result<Option<Vec<u8>>, IngestError> {
        if !is_compressed(frame) {
            return Ok(None);
        }
        let payload = self.read_message(frame.location)?;
        let (_, data) = self
            .wire(&frame.topic)
            .compressed_image(&payload)
            .map_err(|e| self.bad_frame(frame, e.to_string()))?;
        Ok(Some(data.to_vec()))
    }

    /// The SLAM map recorded in the flight, if it had one.
    pub fn recorded_map(&self, flight: &Flight) -> Result<Option<PointCloud>, IngestError> {
        let Some(map) = &flight.summary.map else {
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

    fn bad_frame(&self, frame: &Frame, why: String) -> IngestError {
        IngestError::BadLocation {
            path: self.path().to_owned(),
            location: frame.location,
            why,
        }
    }
}

/// The map's points: the file given, else the one recorded in the flight
/// (`None` without either); and which it is (the path, or `recorded TOPIC`).
pub fn map_cloud(
    flight: &Flight,
    given: Option<&Path>,
) -> Result<Option<(PointCloud, String)>, IngestError> {
    if let Some(path) = given {
        return Ok(Some((PointCloud::load(path)?, path.display().to_string())));
    }
    let Some(cloud) = Recording::reopen(flight)?.recorded_map(flight)? else {
        return Ok(None);
    };
    let topic = flight.summary.map.as_ref().map(|m| m.topic.as_str());
    Ok(Some((
        cloud,
        format!("recorded {}", topic.unwrap_or_default()),
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

fn is_compressed(frame: &Frame) -> bool {
    matches!(frame.encoding.as_str(), "jpeg" | "png")
}

/// How the ROS 1 topics read again decode, from the definitions ingest
/// kept in `ingest.json` (every other topic is CDR).
fn wires(flight: &Flight) -> HashMap<String, Wire> {
    let summaries = flight.summary.messages.iter();
    summaries
        .filter_map(|(topic, summary)| {
            let definition = summary.definition.as_deref()?;
            let wire = Wire::of(&summary.encoding, &summary.schema, definition).ok()?;
            Some((topic.clone(), wire))
        })
        .collect()
}
