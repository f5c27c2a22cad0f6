//! `replan.json` before anything is planned, and its totals once the
//! sorties are flown: waypoints, lengths, times and each drone's share.

use nalgebra::Point3;
use postflight_core::Viewpoint;
use postflight_core::outputs::coverage::CoverageSummary;
use postflight_core::outputs::replan::{DronePlan, ReplanSummary, Sortie};

use crate::gaps::ChosenGaps;
use crate::stage::ReplanOptions;
use crate::team::Member;

/// The plan before anything is planned: the settings and the gaps.
pub(crate) fn empty_plan(
    options: &ReplanOptions,
    coverage: &CoverageSummary,
    home: Point3<f64>,
    chosen: &ChosenGaps,
) -> ReplanSummary {
    ReplanSummary {
        frame_id: "map".into(),
        resolution: coverage.figures.resolution_m,
        origin: coverage.grid_origin,
        target_voxels: Vec::new(),
        viewpoints: Vec::new(),
        view: coverage.view,
        run: options.run.clone(),
        home: home.coords.into(),
        clearance_m: options.settings.clearance_m,
        speed_m_s: options.settings.speed_m_s,
        hover_s: options.settings.hover_s,
        max_sortie_length_m: options.settings.max_sortie_length_m,
        battery_minutes: options.settings.battery_minutes,
        gaps: options.settings.gaps,
        keep_out: Vec::new(),
        ceiling_z_m: None,
        coverage_gap_voxels: chosen.coverage_gaps,
        gap_voxels: chosen.voxels.len(),
        reshoot_spots: chosen.reshoot.clone(),
        planned_gap_voxels: 0,
        uninspectable_gaps: Vec::new(),
        candidate_viewpoints: 0,
        set_cover_viewpoints: 0,
        hover_time_s: 0.0,
        travel_time_s: 0.0,
        sorties: Vec::new(),
        waypoints: 0,
        length_m: 0.0,
        time_s: 0.0,
        drones: Vec::new(),
        mission_time_s: 0.0,
        closest_drones_m: None,
        solver: None,
        phases: Default::default(),
        geo_origin: None,
        geo_origin_from: None,
        ground_station_files: Vec::new(),
        seconds: 0.0,
        warnings: Vec::new(),
    }
}

/// The plan's totals, and its waypoints as an inspection plan's viewpoints.
pub(crate) fn summarise(summary: &mut ReplanSummary, team: &[Member]) {
    for s in &summary.sorties {
        for w in &s.waypoints {
            summary.viewpoints.push(Viewpoint {
                position: [w.x, w.y, w.z],
                yaw: w.yaw,
                gimbal_pitch: w.gimbal_pitch,
            });
            summary.target_voxels.extend(&w.gap_voxels);
        }
    }
    summary.target_voxels.sort_unstable();
    // A gap needing several views is at as many waypoints.
    summary.target_voxels.dedup();
    summary.planned_gap_voxels = summary.target_voxels.len();
    summary.waypoints = summary.viewpoints.len();
    summary.length_m = summary.sorties.iter().map(|s| s.length_m).sum();
    summary.time_s = summary.sorties.iter().map(|s| s.time_s).sum();
    summary.drones = drone_plans(&summary.sorties, team);
    let speeds: Vec<f64> = team.iter().map(|m| m.budget.speed_m_s).collect();
    let stagger = crate::team::stagger(
        &summary.sorties,
        &speeds,
        summary.hover_s,
        summary.clearance_m,
    );
    for (d, takeoff) in summary.drones.iter_mut().zip(stagger.takeoff_s) {
        d.takeoff_s = takeoff;
    }
    summary.closest_drones_m = stagger.closest_m;
    let ends = summary.drones.iter().map(|d| d.takeoff_s + d.time_s);
    summary.mission_time_s = ends.fold(0.0, f64::max);
    summary.hover_time_s = summary.hover_s * summary.waypoints as f64;
    summary.travel_time_s = summary
        .drones
        .iter()
        .map(|d| d.length_m / d.speed_m_s)
        .sum();
}

/// Each drone's share of the sorties: a plan per member of the team, the
/// unused ones with none.
fn drone_plans(sorties: &[Sortie], team: &[Member]) -> Vec<DronePlan> {
    let mut drones: Vec<DronePlan> = (0u32..)
        .zip(team)
        .map(|(drone, m)| DronePlan {
            drone,
            name: m.name.clone(),
            home: m.home.coords.into(),
            speed_m_s: m.budget.speed_m_s,
            battery_minutes: m.battery_minutes,
            camera: m.camera.clone(),
            image_size: [m.lens.width, m.lens.height],
            focal_px: m.lens.fx,
            sorties: 0,
            waypoints: 0,
            length_m: 0.0,
            time_s: 0.0,
            takeoff_s: 0.0,
        })
        .collect();
    for s in sorties {
        let d = &mut drones[s.drone as usize];
        d.sorties += 1;
        d.waypoints += s.waypoints.len();
        d.length_m += s.length_m;
        d.time_s += s.time_s;
    }
    drones
}
