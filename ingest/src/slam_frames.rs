//! The recordings' SLAM frames put into one map frame. Sorties flown with
//! one SLAM session share its frame; a SLAM system started afresh after a
//! landing (or each drone of a team) has a frame of its own, and its map
//! says where: the first recording with a map is the reference, and every
//! other map is registered onto it (`postflight_core::map::register`). A
//! recording without a map of its own (a camera-only drone) is where the
//! settings put it; else where its GPS fixes put it against the
//! reference's, when that is away from the reference's frame; else it is
//! taken to be in the reference's frame.

use nalgebra::{Isometry3, Point3, Vector3};
use postflight_core::InvalidSetting;
use postflight_core::geo::GeoAlignment;
use postflight_core::map::register::{RegisterOptions, register};
use postflight_core::map::{PointCloud, SlamMap, VoxelGrid};
use postflight_core::outputs::ingest::{PlacedBy, Placement};

use crate::earth::{fixes_on, photos_on_earth};
use crate::error::IngestError;
use crate::ingested::Ingested;
use crate::reopen::recorded_map_of;
use crate::settings::{RecordingFrame, keys};
use crate::source::Source;
use crate::stage::IngestOptions;

/// A registration closer to the identity than this is the same SLAM frame
/// (one session's map at two times): metres, and degrees.
const SAME_FRAME: (f64, f64) = (0.02, 0.2);

/// A GPS placement this close to the reference's frame (metres, degrees)
/// is taken to be that frame: within what GPS can tell.
const GPS_SAME_FRAME: (f64, f64) = (1.0, 3.0);

/// One recording as placing it needs: its name, its map, if it has one,
/// where the settings put it, and its frame on the Earth by its GPS fixes.
pub(crate) struct RecordedFrame<'a> {
    pub(crate) name: String,
    pub(crate) map: Option<&'a PointCloud>,
    pub(crate) given: Option<Isometry3<f64>>,
    pub(crate) on_earth: Option<GeoAlignment>,
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
    let reference = recordings.iter().position(|r| r.map.is_some()).unwrap_or(0);
    placements[reference].by = PlacedBy::Reference;
    for (i, r) in recordings
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != reference)
    {
        if let Some(given) = r.given {
            placements[i] = Placement {
                transform: given,
                by: PlacedBy::Given,
            };
        } else if r.map.is_none()
            && let Some(by_gps) = by_gps(r, &recordings[reference])
        {
            placements[i] = by_gps;
        }
    }
    let to_register: Vec<usize> = (0..recordings.len())
        .filter(|&i| i != reference && recordings[i].map.is_some() && recordings[i].given.is_none())
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
        .zip(&placements)
        .filter(|(r, p)| registered && r.map.is_none() && p.by == PlacedBy::SharedFrame)
        .map(|(r, _)| {
            format!(
                "{} has no map of its own: it is taken to be in {}'s SLAM frame, though other recordings are in frames of their own",
                r.name, recordings[reference].name
            )
        })
        .collect();
    Ok((placements, warnings))
}

/// `recording` placed by its GPS fixes against `reference`'s: `None`
/// without a fit of both, or when the two frames are the same within what
/// GPS tells.
fn by_gps(recording: &RecordedFrame, reference: &RecordedFrame) -> Option<Placement> {
    let (own, onto) = (recording.on_earth.as_ref()?, reference.on_earth.as_ref()?);
    // A point of the recording's frame, on the Earth, in the reference's.
    let to_reference = |p: Point3<f64>| onto.origin.to_local(&own.origin.to_geodetic(&p));
    let origin = to_reference(Point3::origin());
    let x = to_reference(Point3::new(1.0, 0.0, 0.0)) - origin;
    let yaw = x.y.atan2(x.x);
    let transform = Isometry3::new(origin.coords, Vector3::z() * yaw);
    let same = origin.coords.norm() < GPS_SAME_FRAME.0 && yaw.abs().to_degrees() < GPS_SAME_FRAME.1;
    (!same).then_some(Placement {
        transform,
        by: PlacedBy::Gps {
            rms_m: own.rms_m + onto.rms_m,
            fixes: own.fixes,
        },
    })
}

/// A recording's map as a map to register, on the default grid; `None`
/// without points.
fn slam_map(recording: &RecordedFrame) -> Option<SlamMap> {
    SlamMap::on_grid(recording.map?.clone(), VoxelGrid::default())
}

/// Every recording's poses in the run's map frame ([`slam_frames`], by
/// the maps recorded in them); the warnings that gives.
pub(crate) fn place_recordings(
    ingested: &mut [Ingested],
    sources: &mut [Source],
    options: &IngestOptions,
) -> Result<Vec<String>, IngestError> {
    let mut maps = Vec::new();
    for (one, source) in ingested.iter().zip(sources) {
        maps.push(match source {
            Source::Recording(recording) => recorded_map_of(recording, &one.summary)?,
            Source::Photos(_) => None,
        });
    }
    let names: Vec<String> = ingested.iter().map(|i| i.summary.name()).collect();
    let given = given_frames(&options.settings.recording_frame, &names, &maps)?;
    let max_gap_ns = (options.settings.max_pose_gap_s * 1e9) as i64;
    let frames: Vec<RecordedFrame> = ingested
        .iter()
        .zip(&maps)
        .zip(given)
        .map(|((i, map), given)| RecordedFrame {
            name: i.summary.name(),
            map: map.as_ref().filter(|c| !c.is_empty()),
            given,
            on_earth: photos_on_earth(i).or_else(|| {
                fixes_on(&i.fixes, |_| Some(&i.trajectory), max_gap_ns)
                    .and_then(|(local, geodetic)| GeoAlignment::fit(&local, &geodetic).ok())
            }),
        })
        .collect();
    let (placements, warnings) = place(&frames)?;
    for (one, placement) in ingested.iter_mut().zip(placements) {
        one.place(placement);
    }
    Ok(warnings)
}

/// Each recording's frame as the settings give it (by file name); refused
/// when one names no recording of the flight, or the reference recording
/// (the first with a map), whose frame is the map frame.
fn given_frames(
    given: &[RecordingFrame],
    names: &[String],
    maps: &[Option<PointCloud>],
) -> Result<Vec<Option<Isometry3<f64>>>, IngestError> {
    let reference = maps
        .iter()
        .position(|m| m.as_ref().is_some_and(|c| !c.is_empty()))
        .unwrap_or(0);
    let mut out = vec![None; names.len()];
    for frame in given {
        let expected = match names.iter().position(|n| *n == frame.recording) {
            None => format!("a recording of the flight ({})", names.join(", ")),
            Some(i) if i == reference => format!(
                "a recording other than {}, the reference, whose frame is the map frame",
                names[i]
            ),
            Some(i) => {
                out[i] = Some(frame.isometry());
                continue;
            }
        };
        return Err(InvalidSetting::new(keys::recording_frame, &frame.recording, expected).into());
    }
    Ok(out)
}
