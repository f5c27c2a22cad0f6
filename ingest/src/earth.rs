//! Where the map frame is on the Earth: a photo folder's origin exactly,
//! else the GPS fixes fitted to the trajectory at their times.

use nalgebra::Point3;
use postflight_core::geo::{GeoAlignment, Geodetic};
use postflight_core::outputs::ingest::GnssFix;
use postflight_core::{PoseAt, Trajectory};

use crate::ingested::Ingested;

/// A photo folder's frame on the Earth: exactly its origin (its photos are
/// posed there); `None` for a recording.
pub(crate) fn photos_on_earth(ingested: &Ingested) -> Option<GeoAlignment> {
    let photos = ingested.summary.photos.as_ref()?;
    let local: Vec<Point3<f64>> = ingested
        .fixes
        .iter()
        .map(|f| photos.origin.to_local(&f.position))
        .collect();
    let centre = local
        .iter()
        .map(|p| p.coords)
        .sum::<nalgebra::Vector3<f64>>()
        / local.len() as f64;
    Some(GeoAlignment {
        origin: photos.origin,
        fixes: local.len(),
        rms_m: 0.0,
        spread_m: local
            .iter()
            .map(|p| (p.coords - centre).xy().norm())
            .fold(0.0, f64::max),
    })
}

/// The map frame on the Earth from the GPS fixes (those with a fix, at
/// times the trajectory has a pose); a warning when they cannot tell.
pub(crate) fn geo_origin(
    fixes: &[GnssFix],
    trajectories: &[Trajectory],
    max_gap_ns: i64,
    warnings: &mut Vec<String>,
) -> Option<GeoAlignment> {
    let (local, geodetic) = fixes_on(
        fixes,
        |f| trajectories.get(usize::from(f.recording)),
        max_gap_ns,
    )?;
    GeoAlignment::fit(&local, &geodetic)
        .map_err(|why| {
            warnings.push(format!(
                "the GPS fixes do not place the map on the Earth: {why}; give `postflight replan` the map's origin (--geo-origin, or geo_origin in postflight.toml's [replan])"
            ));
        })
        .ok()
}

/// The fixes with a fix status and a pose at their time (on the trajectory
/// `trajectory_of` gives each): the pose's position and the fix's; `None`
/// without fixes.
pub(crate) fn fixes_on<'a>(
    fixes: &[GnssFix],
    trajectory_of: impl Fn(&GnssFix) -> Option<&'a Trajectory>,
    max_gap_ns: i64,
) -> Option<(Vec<Point3<f64>>, Vec<Geodetic>)> {
    if fixes.is_empty() {
        return None;
    }
    Some(
        fixes
            .iter()
            .filter(|f| f.status >= 0)
            .filter_map(|f| match trajectory_of(f)?.at(f.time_ns, max_gap_ns) {
                PoseAt::Pose(pose) => Some((Point3::from(pose.translation.vector), f.position)),
                _ => None,
            })
            .unzip(),
    )
}
