//! The follow-up's sorties: the one tour cut into battery sorties (for a
//! team, first into a stretch per drone), or, where a drone's camera or
//! home differ, each drone's stretch flown as a route of its own,
//! rebalanced over a few rounds, its uninspectable gaps offered to a drone
//! with another camera.

use std::collections::HashSet;

use nalgebra::Point3;
use postflight_core::Intrinsics;
use postflight_core::map::VoxelIndex;
use postflight_core::outputs::replan::{
    ReplanSummary, Sortie, Uninspectable, Unplannable, Waypoint,
};

use crate::error::ReplanError;
use crate::free_space::{FreeSpace, length, lift_home};
use crate::gaps::ChosenGaps;
use crate::route::{Route, Scene};
use crate::team::Member;
use crate::tour::Budget;

/// The route shared out to the team.
pub(crate) struct Shared<'a> {
    pub(crate) scene: &'a Scene<'a>,
    pub(crate) route: &'a Route,
    pub(crate) team: &'a [Member],
    pub(crate) chosen: &'a ChosenGaps,
    pub(crate) launch: Point3<f64>,
    pub(crate) lens: &'a Intrinsics,
}

impl Shared<'_> {
    /// The team's sorties into `summary`: the one tour cut into stretches
    /// where every drone shares the launch and lens, else each drone's
    /// gaps flown as a route of its own.
    pub(crate) fn sorties(&self, summary: &mut ReplanSummary) -> Result<(), ReplanError> {
        let (space, map) = (self.scene.space, self.scene.map);
        if self.team.iter().all(|m| m.shares(&self.launch, self.lens)) {
            let shares = split_sorties(self.team, self.route, space)?;
            for (drone, (member, sorties)) in (0u32..).zip(self.team.iter().zip(&shares)) {
                for indices in sorties {
                    summary
                        .sorties
                        .push(fly(member, drone, self.route, space, indices));
                }
            }
            return Ok(());
        }
        let (sorties, left) = own_routes(self.scene, self.route, self.team, self.chosen)?;
        summary.sorties = sorties;
        summary.uninspectable_gaps.extend(left);
        summary.uninspectable_gaps.sort_by_key(|u| u.voxel);
        summary.uninspectable_gaps.dedup_by_key(|u| u.voxel);
        for member in self.team.iter().filter(|m| m.home != self.launch) {
            let (_, by) = lift_home(space, map, member.home)?;
            if by > 0.0 {
                summary.warnings.push(format!(
                    "{}'s home is within {} m of the map; its sorties start and end {by:.1} m above it",
                    member.name, space.clearance_m
                ));
            }
        }
        Ok(())
    }
}

/// The gaps a route leaves out, as replan.json lists them.
pub(crate) fn left_out(route: &Route) -> Vec<Uninspectable> {
    route
        .left_out
        .iter()
        .map(|(&g, &reason)| Uninspectable {
            voxel: route.gaps[g],
            reason,
        })
        .collect()
}

/// Rounds of [`own_routes`]' rebalancing.
const REBALANCE_ROUNDS: usize = 3;

/// Each drone's stretch of the team's route flown as a route of its own,
/// from its home with its camera: the sorties, and the gaps the drones'
/// routes leave out. The stretches were cut by times estimated on the
/// team's route (the flight's camera, the shared home), which a drone's
/// own route beats or misses; so the route is cut again with each drone's
/// estimates scaled by how far its own route's time was from the team's
/// mean, and the quickest mission of [`REBALANCE_ROUNDS`] is kept.
fn own_routes(
    scene: &Scene,
    route: &Route,
    team: &[Member],
    chosen: &ChosenGaps,
) -> Result<(Vec<Sortie>, Vec<Uninspectable>), ReplanError> {
    let (tour, _) = route.tour.as_ref().expect("a route with a tour");
    let home_m = |stop: usize| route.home_m(scene.space, stop);
    let mut scale = vec![1.0f64; team.len()];
    let mut best: Option<(f64, Vec<Sortie>, Vec<Uninspectable>)> = None;
    for _ in 0..REBALANCE_ROUNDS {
        let budgets: Vec<Budget> = team
            .iter()
            .zip(&scale)
            .map(|(m, s)| Budget {
                speed_m_s: m.budget.speed_m_s / s,
                hover_s: m.budget.hover_s * s,
                ..m.budget
            })
            .collect();
        let shares = crate::team::split(tour, &budgets, &home_m)
            .map_err(|e| sortie_too_long(&team[0], &route.points, e))?;
        let mut own: Vec<(Vec<VoxelIndex>, Route)> = Vec::new();
        for (member, share) in team.iter().zip(&shares) {
            let gaps = share_gaps(route, share);
            own.push((gaps.clone(), own_route(scene, gaps, chosen, member)?));
        }
        second_chance(scene, team, chosen, &mut own)?;
        let (mut sorties, mut left) = (Vec::new(), Vec::new());
        let mut times = vec![0.0; team.len()];
        for (drone, (member, (_, own))) in (0u32..).zip(team.iter().zip(&own)) {
            left.extend(left_out(own));
            let Some((own_tour, _)) = &own.tour else {
                continue;
            };
            let cut = crate::tour::sorties(own_tour, &member.budget, &|stop| {
                own.home_m(scene.space, stop)
            })
            .map_err(|e| sortie_too_long(member, &own.points, e))?;
            for indices in &cut {
                let sortie = fly(member, drone, own, scene.space, indices);
                times[drone as usize] += sortie.time_s;
                sorties.push(sortie);
            }
        }
        left.sort_by_key(|u| u.voxel);
        left.dedup_by_key(|u| u.voxel);
        let mission = times.iter().copied().fold(0.0, f64::max);
        // Fewest gaps left out first, then the quickest.
        if best
            .as_ref()
            .is_none_or(|(m, _, l)| (left.len(), mission) < (l.len(), *m))
        {
            best = Some((mission, sorties, left));
        }
        let used: Vec<f64> = times.iter().copied().filter(|t| *t > 0.0).collect();
        let mean = used.iter().sum::<f64>() / used.len().max(1) as f64;
        for (s, t) in scale.iter_mut().zip(&times) {
            if *t > 0.0 && mean > 0.0 {
                *s *= t / mean;
            }
        }
    }
    let (_, sorties, left) = best.expect("at least one round");
    Ok((sorties, left))
}

/// The gap voxels the stops of `share` of the team's route serve.
fn share_gaps(team_route: &Route, share: &[Vec<usize>]) -> Vec<VoxelIndex> {
    let mut gaps: Vec<VoxelIndex> = share
        .iter()
        .flatten()
        .flat_map(|&i| team_route.waypoint(i).gap_voxels)
        .collect();
    gaps.sort_unstable();
    gaps.dedup();
    gaps
}

/// A drone's own route over `gaps` (sorted), from its home (lifted clear
/// as the team's is) with its camera.
fn own_route(
    scene: &Scene,
    gaps: Vec<VoxelIndex>,
    chosen: &ChosenGaps,
    member: &Member,
) -> Result<Route, ReplanError> {
    let views: Vec<u32> = gaps
        .iter()
        .map(|v| chosen.views[chosen.voxels.binary_search(v).expect("a chosen gap")])
        .collect();
    let (home, _) = lift_home(scene.space, scene.map, member.home)?;
    Ok(Route::plan(
        scene,
        gaps,
        &views,
        &member.lens,
        home,
        &mut |_, _| {},
    ))
}

/// Gaps a drone's camera cannot inspect (no clear viewpoint, or too few)
/// given to a drone with another camera: it plans its route again with
/// them, and keeps the new route when it inspects some.
fn second_chance(
    scene: &Scene,
    team: &[Member],
    chosen: &ChosenGaps,
    own: &mut [(Vec<VoxelIndex>, Route)],
) -> Result<(), ReplanError> {
    for d in 0..own.len() {
        let route = &own[d].1;
        let mut orphans: Vec<VoxelIndex> = route
            .left_out
            .iter()
            .filter(|(_, reason)| **reason != Unplannable::Unreachable)
            .map(|(&g, _)| route.gaps[g])
            .collect();
        for e in (0..own.len()).filter(|&e| team[e].lens != team[d].lens) {
            if orphans.is_empty() {
                break;
            }
            let mut gaps = own[e].0.clone();
            gaps.extend(&orphans);
            gaps.sort_unstable();
            gaps.dedup();
            let wider = own_route(scene, gaps.clone(), chosen, &team[e])?;
            let missed: HashSet<VoxelIndex> =
                wider.left_out.keys().map(|&g| wider.gaps[g]).collect();
            let taken: HashSet<VoxelIndex> = orphans
                .iter()
                .copied()
                .filter(|g| !missed.contains(g))
                .collect();
            if taken.is_empty() {
                continue;
            }
            orphans.retain(|g| !taken.contains(g));
            let gave = &mut own[d].1;
            let gave_gaps = gave.gaps.clone();
            gave.left_out.retain(|&g, _| !taken.contains(&gave_gaps[g]));
            own[e] = (gaps, wider);
        }
    }
    Ok(())
}

/// The team's route's stops (indices into its tour, from 1) as each
/// drone's sorties, each within the drone's battery (and the longest
/// sortie, if set): one drone's, the tour's sorties; a team's,
/// [`crate::team::split`]. Splitting bounds each way home by the lattice
/// distance (one search from home), then flies the legs home it chose.
fn split_sorties(
    team: &[Member],
    route: &Route,
    space: &FreeSpace,
) -> Result<Vec<Vec<Vec<usize>>>, ReplanError> {
    let (tour, _) = route.tour.as_ref().expect("a route with a tour");
    let home_m = |stop: usize| route.home_m(space, stop);
    let split = match team {
        [one] => crate::tour::sorties(tour, &one.budget, &home_m).map(|one| vec![one]),
        _ => {
            let budgets: Vec<Budget> = team.iter().map(|m| m.budget).collect();
            crate::team::split(tour, &budgets, &home_m)
        }
    };
    split.map_err(|e| sortie_too_long(&team[0], &route.points, e))
}

/// A stop whose round trip alone does not fit `member`'s battery.
fn sortie_too_long(
    member: &Member,
    points: &[Point3<f64>],
    (stop, round_trip_m): (usize, f64),
) -> ReplanError {
    ReplanError::SortieTooLong {
        point: points[stop].coords.into(),
        round_trip_m,
        round_trip_s: member.budget.time_s(round_trip_m, 1),
        max_m: member.budget.max_length_m,
        battery_minutes: member.battery_minutes,
    }
}

/// One sortie of drone `drone` over `route`'s tour stops `indices`: home,
/// the waypoints, home, on collision-free legs.
fn fly(member: &Member, drone: u32, route: &Route, space: &FreeSpace, indices: &[usize]) -> Sortie {
    let (tour, _) = route.tour.as_ref().expect("a route with a tour");
    let (home, points) = (route.home(), &route.points);
    let home_leg = |stop: usize| {
        space
            .path(&home, &points[stop])
            .expect("stops on the tour are reachable from home")
    };
    let first = indices[0];
    let last = *indices.last().expect("sorties are not empty");
    // Home to the first waypoint: the tour's own leg when it starts the tour.
    let mut legs: Vec<Vec<Point3<f64>>> = vec![if first == 1 {
        tour.legs[0].clone()
    } else {
        home_leg(tour.stops[first])
    }];
    for i in first..last {
        legs.push(tour.legs[i].clone());
    }
    legs.push(if last == tour.stops.len() - 1 {
        tour.legs[last].clone()
    } else {
        home_leg(tour.stops[last]).into_iter().rev().collect()
    });
    let waypoints: Vec<Waypoint> = indices.iter().map(|&i| route.waypoint(i)).collect();
    let mut path: Vec<Point3<f64>> = Vec::new();
    for leg in &legs {
        for p in leg {
            if path.last() != Some(p) {
                path.push(*p);
            }
        }
    }
    let length_m = length(&path);
    Sortie {
        drone,
        time_s: member.budget.time_s(length_m, waypoints.len()),
        waypoints,
        path: path.iter().map(|p| p.coords.into()).collect(),
        length_m,
    }
}
