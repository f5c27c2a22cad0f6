//! A follow-up flight shared by a team of drones: the tour cut into one
//! stretch per drone so that the slowest drone is done soonest (route
//! first, split second, after Beasley's split of a giant tour), each
//! stretch flown in battery sorties from home. Stretches of one tour keep
//! the drones' areas apart: they meet only near home, where [`stagger`]
//! spaces their take-offs. A drone with its own camera or home then flies
//! its stretch's gaps on a route of its own ([`Member`], resolved from the
//! `[[replan.drone]]` entries by [`members`]).

use std::path::PathBuf;

use nalgebra::Point3;
use postflight_core::Intrinsics;
use postflight_core::outputs::replan::{Sortie, Waypoint};

use crate::error::ReplanError;
use crate::settings::{ReplanConfig, keys};
use crate::tour::{Budget, Cutter, Tour};

/// A drone of the team, as its route and sorties are planned.
#[derive(Debug, Clone, PartialEq)]
pub struct Member {
    pub name: String,
    /// Where it takes off and lands.
    pub home: Point3<f64>,
    pub budget: Budget,
    pub battery_minutes: f64,
    /// Its camera's lens, from `camera` (`None`: the flight's camera).
    pub lens: Intrinsics,
    pub camera: Option<PathBuf>,
}

impl Member {
    /// Whether it can fly a stretch of a tour planned from `home` (the
    /// take-off point, before any lift) with the flight's camera as it is:
    /// same home, same camera.
    pub fn shares(&self, home: &Point3<f64>, lens: &Intrinsics) -> bool {
        self.home == *home && self.lens == *lens
    }
}

/// Each drone's sorties (indices into `tour.stops`), drone by drone, the
/// first stretch of the tour to the first drone; each drone flies within
/// its own budget. Fewer drones than `budgets` when that is as quick. An
/// error (the stop and its round trip) when a stop's round trip alone does
/// not fit a battery.
pub fn split(
    tour: &Tour,
    budgets: &[Budget],
    home_m: &dyn Fn(usize) -> f64,
) -> Result<Vec<Vec<Vec<usize>>>, (usize, f64)> {
    // The mission can take no less than the longest single stop's round
    // trip (for the quickest drone), nor more than the slowest drone
    // flying everything.
    let (mut lo, mut hi) = (0.0f64, 0.0f64);
    for budget in budgets {
        let mut whole = Cutter::new(tour, budget, home_m);
        for i in 1..tour.stops.len() {
            whole.push(i)?;
        }
        hi = hi.max(whole.time_s());
    }
    for i in 1..tour.stops.len() {
        let quickest = budgets
            .iter()
            .map(|b| Cutter::new(tour, b, home_m).time_with(i))
            .collect::<Result<Vec<f64>, _>>()?
            .into_iter()
            .fold(f64::INFINITY, f64::min);
        lo = lo.max(quickest);
    }
    let mut best = stretches(tour, budgets, home_m, hi)?;
    // Bisect the mission's time: the shortest whose greedy cut needs at
    // most a stretch per drone.
    for _ in 0..60 {
        if hi - lo <= 1e-3 * hi.max(1.0) {
            break;
        }
        let mid = 0.5 * (lo + hi);
        let cut = stretches(tour, budgets, home_m, mid)?;
        if cut.len() <= budgets.len() {
            (best, hi) = (cut, mid);
        } else {
            lo = mid;
        }
    }
    Ok(best)
}

/// The tour cut greedily into stretches, the k-th flown within `limit_s`
/// by drone k (the last drone's budget for any beyond), a stop that alone
/// takes longer getting a stretch of its own; each cut into its sorties.
fn stretches(
    tour: &Tour,
    budgets: &[Budget],
    home_m: &dyn Fn(usize) -> f64,
    limit_s: f64,
) -> Result<Vec<Vec<Vec<usize>>>, (usize, f64)> {
    let budget = |k: usize| &budgets[k.min(budgets.len() - 1)];
    let mut out = Vec::new();
    let mut current = Cutter::new(tour, budget(0), home_m);
    let mut empty = true;
    for i in 1..tour.stops.len() {
        if !empty && current.time_with(i)? > limit_s {
            let next = Cutter::new(tour, budget(out.len() + 1), home_m);
            let full = std::mem::replace(&mut current, next);
            out.push(full.finish());
        }
        current.push(i)?;
        empty = false;
    }
    if !empty {
        out.push(current.finish());
    }
    Ok(out)
}

/// When each drone of a team takes off, seconds after the first, and how
/// close any two then come while flying: take-offs are staggered by the
/// shortest whole second that keeps every two drones at least `clearance_m`
/// apart at every moment (checked every [`STEP_S`]); drones already apart
/// take off together.
#[derive(Debug, Clone, PartialEq)]
pub struct Stagger {
    pub takeoff_s: Vec<f64>,
    /// The closest two drones come, metres; `None` for one drone.
    pub closest_m: Option<f64>,
}

/// How often drones' positions are compared, seconds.
const STEP_S: f64 = 0.25;
/// The longest stagger tried between two take-offs, seconds.
const MAX_STAGGER_S: u32 = 300;

/// Take-offs for `sorties` (each naming its drone), drone `d` flying at
/// `speeds_m_s[d]` with `hover_s` at each waypoint, each drone's sorties
/// one after the other.
pub fn stagger(sorties: &[Sortie], speeds_m_s: &[f64], hover_s: f64, clearance_m: f64) -> Stagger {
    let drones = sorties
        .iter()
        .map(|s| s.drone as usize + 1)
        .max()
        .unwrap_or(0);
    let timelines: Vec<Timeline> = (0..drones)
        .map(|d| {
            let own = sorties.iter().filter(|s| s.drone as usize == d);
            Timeline::of(own, speeds_m_s[d], hover_s)
        })
        .collect();
    if drones < 2 {
        return Stagger {
            takeoff_s: vec![0.0; drones],
            closest_m: None,
        };
    }
    let closest = |gap: f64| {
        let takeoff: Vec<f64> = (0..drones).map(|d| d as f64 * gap).collect();
        (closest_approach(&timelines, &takeoff), takeoff)
    };
    let mut best = closest(0.0);
    for gap in 1..=MAX_STAGGER_S {
        if best.0 >= clearance_m {
            break;
        }
        best = closest(f64::from(gap));
    }
    Stagger {
        takeoff_s: best.1,
        closest_m: Some(best.0),
    }
}

/// A drone's position over time: knots of time and place, moving straight
/// between them.
struct Timeline {
    knots: Vec<(f64, Point3<f64>)>,
}

impl Timeline {
    fn of<'a>(sorties: impl Iterator<Item = &'a Sortie>, speed_m_s: f64, hover_s: f64) -> Self {
        let mut knots: Vec<(f64, Point3<f64>)> = Vec::new();
        for sortie in sorties {
            let mut next = 0;
            for p in &sortie.path {
                let p = Point3::from(*p);
                let t = match knots.last() {
                    None => 0.0,
                    Some((t, q)) => t + (p - q).norm() / speed_m_s,
                };
                knots.push((t, p));
                let at = |w: &Waypoint| Point3::new(w.x, w.y, w.z) == p;
                while sortie.waypoints.get(next).is_some_and(at) {
                    knots.push((t + hover_s, p));
                    next += 1;
                }
            }
        }
        Self { knots }
    }

    fn end_s(&self) -> f64 {
        self.knots.last().map_or(0.0, |k| k.0)
    }

    /// Where it is `t` seconds into its flight; `None` before or after.
    fn at(&self, t: f64) -> Option<Point3<f64>> {
        if t < 0.0 || t > self.end_s() {
            return None;
        }
        let i = self.knots.partition_point(|k| k.0 <= t).max(1);
        let (t0, a) = self.knots[i - 1];
        let Some(&(t1, b)) = self.knots.get(i) else {
            return Some(a);
        };
        let share = if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
        Some(a + (b - a) * share)
    }
}

/// The closest any two drones come while both fly, taking off at `takeoff`.
fn closest_approach(timelines: &[Timeline], takeoff: &[f64]) -> f64 {
    let end = timelines
        .iter()
        .zip(takeoff)
        .map(|(t, s)| s + t.end_s())
        .fold(0.0, f64::max);
    let mut closest = f64::INFINITY;
    let mut t = 0.0;
    while t <= end {
        let here: Vec<Point3<f64>> = timelines
            .iter()
            .zip(takeoff)
            .filter_map(|(line, s)| line.at(t - s))
            .collect();
        for (i, a) in here.iter().enumerate() {
            for b in &here[i + 1..] {
                closest = closest.min((a - b).norm());
            }
        }
        t += STEP_S;
    }
    closest
}

/// The team: the `[[replan.drone]]` entries, each resolved over the
/// `[replan]` settings, or `drones` drones alike.
pub(crate) fn members(
    s: &ReplanConfig,
    budget: Budget,
    launch: Point3<f64>,
    lens: &Intrinsics,
) -> Result<Vec<Member>, ReplanError> {
    if s.drone.is_empty() {
        return Ok((1..=s.drones)
            .map(|k| Member {
                name: format!("drone {k}"),
                home: launch,
                budget,
                battery_minutes: s.battery_minutes,
                lens: lens.clone(),
                camera: None,
            })
            .collect());
    }
    s.drone
        .iter()
        .map(|d| {
            let speed = d.speed_m_s.unwrap_or(s.speed_m_s);
            let minutes = d.battery_minutes.unwrap_or(s.battery_minutes);
            let lens = match &d.camera_info_file {
                Some(path) => ingest::calibration::from_calibration_file(
                    path,
                    &format!("{}'s camera_info_file in {}", d.name, keys::drone),
                )?,
                None => lens.clone(),
            };
            Ok(Member {
                name: d.name.clone(),
                home: d.home.map_or(launch, Point3::from),
                budget: Budget {
                    max_time_s: minutes * 60.0,
                    speed_m_s: speed,
                    ..budget
                },
                battery_minutes: minutes,
                lens,
                camera: d.camera_info_file.clone(),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sortie(drone: u32, path: &[[f64; 3]]) -> Sortie {
        Sortie {
            drone,
            waypoints: Vec::new(),
            path: path.to_vec(),
            length_m: 0.0,
            time_s: 0.0,
        }
    }

    #[test]
    fn drones_leaving_one_home_together_are_staggered_until_they_keep_the_clearance() {
        // Two drones fly out from home 10 m apart and back, one east, one
        // north: together at home at the start and the end.
        let east = sortie(0, &[[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 0.0, 0.0]]);
        let north = sortie(1, &[[0.0, 0.0, 0.0], [0.0, 10.0, 0.0], [0.0, 0.0, 0.0]]);
        let s = stagger(&[east, north], &[1.0, 1.0], 0.0, 2.0);
        // Taking off together they meet at home; 2 s apart they are 2 m
        // apart when the second takes off and when the first lands.
        assert_eq!(s.takeoff_s, vec![0.0, 2.0]);
        let closest = s.closest_m.unwrap();
        assert!((2.0..2.1).contains(&closest), "{closest}");
        // Apart already: no stagger.
        let far = sortie(1, &[[50.0, 0.0, 0.0], [60.0, 0.0, 0.0]]);
        let near = sortie(0, &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]);
        assert_eq!(
            stagger(&[near, far], &[1.0, 1.0], 0.0, 2.0).takeoff_s,
            vec![0.0, 0.0]
        );
    }
}
