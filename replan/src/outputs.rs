//! The stage's files: `replan.csv` (and each drone's, for a team), with a
//! geo origin the missions, KML and GeoJSON, then `replan.json`; the last
//! run's ground-station files removed first.

use std::time::Instant;

use nalgebra::Point3;
use postflight_core::RunDir;
use postflight_core::outputs::replan::{ReplanSummary, Sortie, files};

use crate::error::ReplanError;
use crate::ground_station::{self, Placement};
use crate::wpml;

/// Writes `replan.csv` (every point of every sortie's path, `X,Y,Z,Yaw`,
/// yaw of the waypoint being flown to), with a geo origin the missions, KML
/// and GeoJSON, and then `replan.json`.
pub(crate) fn write(
    run: &RunDir,
    mut summary: ReplanSummary,
    placement: Option<&Placement>,
    started: Instant,
) -> Result<ReplanSummary, ReplanError> {
    run.write_text(
        files::PATH_CSV,
        &ground_station::path_csv(&summary.sorties, &summary.frame_id),
    )?;
    remove_ground_station_files(run)?;
    let team = summary.drones.len() > 1;
    if team {
        for d in 0..summary.drones.len() {
            let own: Vec<Sortie> = summary
                .sorties
                .iter()
                .filter(|s| s.drone as usize == d)
                .cloned()
                .collect();
            let name = files::drone_path_csv(d);
            run.write_text(&name, &ground_station::path_csv(&own, &summary.frame_id))?;
        }
    }
    if let Some(placement) = placement.filter(|_| !summary.sorties.is_empty()) {
        let count = summary.sorties.len();
        let mut in_drone = 0;
        for (i, sortie) in summary.sorties.iter().enumerate() {
            let drone = sortie.drone as usize;
            in_drone = match i > 0 && summary.sorties[i - 1].drone == sortie.drone {
                true => in_drone + 1,
                false => 0,
            };
            let name = |format| match team {
                false => files::mission(i, count, format),
                true => {
                    files::drone_mission(drone, in_drone, summary.drones[drone].sorties, format)
                }
            };
            let launch = Point3::from(summary.drones[drone].home);
            let qgc = name(files::Mission::QGroundControl);
            run.write_json(&qgc, &placement.mission(sortie, launch))?;
            let dji = name(files::Mission::DjiWpml);
            run.write_with(&dji, |file| {
                wpml::write_kmz(file, placement, sortie, launch).map_err(|cause| {
                    postflight_core::Error::Write {
                        path: run.file(&dji),
                        cause,
                    }
                })
            })?;
            summary.ground_station_files.extend([qgc, dji]);
        }
        run.write_text(files::KML, &placement.kml(&summary.sorties))?;
        run.write_json(files::GEOJSON, &placement.geojson(&summary.sorties))?;
        summary
            .ground_station_files
            .extend([files::KML.to_string(), files::GEOJSON.to_string()]);
    }
    summary.seconds = started.elapsed().as_secs_f64();
    run.write_json(files::SUMMARY, &summary)?;
    Ok(summary)
}

/// The last run's missions, KML and GeoJSON: a new plan may have fewer
/// sorties, or no geo origin.
fn remove_ground_station_files(run: &RunDir) -> Result<(), ReplanError> {
    let names = std::fs::read_dir(run.path())
        .map_err(|cause| postflight_core::Error::Open {
            path: run.path().to_owned(),
            cause,
        })?
        .filter_map(|entry| entry.ok()?.file_name().into_string().ok());
    for name in names.filter(|n| files::is_mission(n) || files::is_drone_path_csv(n)) {
        run.remove(&name)?;
    }
    run.remove(files::KML)?;
    run.remove(files::GEOJSON)?;
    Ok(())
}
