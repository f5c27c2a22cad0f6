//! The recordings' SLAM frames put into one map frame. Sorties flown with
//! one SLAM session share its frame; a SLAM system started afresh after a
//! landing (or each drone of a team) has a frame of its own, and its map
//! says where: the first recording with a map is the reference, and every
//! other map is registered onto it (`postflight_core::map::register`). A
//! recording without a map of its own is taken to be in the reference's
//! frame.

use nalgebra::Isometry3;
use postflight_core::map::register::{RegisterOptions, register};
use postflight_core::map::{PointCloud, SlamMap, VoxelGrid};
use postflight_core::outputs::ingest::{PlacedBy, Placement};

use crate::error::IngestError;

/// A registration closer to the identity than this is the same SLAM frame
/// (one session's map at two times): metres, and degrees.
const SAME_FRAME: (f64, f64) = (0.02, 0.2);

/// One recording as placing it needs: its name and its map, if it has one.
pub(crate) struct RecordedFrame<'a> {
    pub(crate) name: String,
    pub(crate) map: Option<&'a PointCloud>,
}

/// Where each recording's SLAM frame is in the run's map frame, and
/// warnings for recordings taken to share the reference's frame without a
/// map to tell.
pub(crate) fn place(
    recordings: &[RecordedFrame],
) -> Result<(Vec<Placement>, Vec<String>), IngestError> {
    let shared = Placement {
        transform: Isometry3::identity(),
        by: PlacedBy::SharedFrame,
    };
    let mut placements = vec![shared; recordings.len()];
    let Some(reference) = recordings.iter().position(|r| r.map.is_some()) else {
        placements[0].by = PlacedBy::Reference;
        return Ok((placements, Vec::new()));
    };
    placements[reference].by = PlacedBy::Reference;
    let to_register: Vec<usize> = (0..recordings.len())
        .filter(|i| *i != reference && recordings[*i].map.is_some())
        .collect();
    if to_register.is_empty() {
        return Ok((placements, Vec::new()));
    }
    let unregistered = |i: usize, why: String| IngestError::Unregistered {
        recording: recordings[i].name.clone(),
        reference: recordings[reference].name.clone(),
        why,
    };
    let onto = slam_map(&recordings[reference])
        .ok_or_else(|| unregistered(reference, "the reference map has no points".into()))?;
    for i in to_register {
        let map = slam_map(&recordings[i])
            .ok_or_else(|| unregistered(i, "its map has no points".into()))?;
        let registration = register(&map, &onto, &RegisterOptions::default())
            .map_err(|why| unregistered(i, why.to_string()))?;
        let t = registration.transform;
        let same = t.translation.vector.norm() < SAME_FRAME.0
            && t.rotation.angle().to_degrees() < SAME_FRAME.1;
        if !same {
            placements[i] = Placement {
                transform: t,
                by: PlacedBy::Registered {
                    rms_m: registration.rms_m,
                    overlap: registration.overlap,
                },
            };
        }
    }
    let registered = placements
        .iter()
        .any(|p| matches!(p.by, PlacedBy::Registered { .. }));
    let warnings = recordings
        .iter()
        .filter(|r| registered && r.map.is_none())
        .map(|r| {
            format!(
                "{} has no map of its own: it is taken to be in {}'s SLAM frame, though other recordings are in frames of their own",
                r.name, recordings[reference].name
            )
        })
        .collect();
    Ok((placements, warnings))
}

/// A recording's map as a map to register, on the default grid; `None`
/// without points.
fn slam_map(recording: &RecordedFrame) -> Option<SlamMap> {
    SlamMap::on_grid(recording.map?.clone(), VoxelGrid::default())
}
