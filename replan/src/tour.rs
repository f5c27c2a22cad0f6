//! The follow-up tour: a GTSP over the clusters (gap voxels' viewpoints,
//! plus home), solved with straight-line costs first; then, as in GATSBI,
//! the legs of the tour are flown on collision-free paths and, while a
//! leg's path is more than [`DETOUR_LIMIT`] times its cost, those costs are
//! replaced by the paths' lengths and the tour is repaired: a local search
//! from the last tour, since a changed leg rarely needs a full solve. Every
//! [`RESOLVE_EVERY`] rounds still re-costing, a full solve with every cost
//! learnt so far breaks repairs that trade one detour for another.

use std::collections::{HashMap, HashSet};
use std::time::Duration;

use gtsp::{Instance, SolveOptions, SolveStats, repair, solve};
use nalgebra::Point3;
use postflight_core::outputs::replan::{FirstSolve, ReplanSolverStats};

use crate::free_space::{FreeSpace, length};

/// A leg whose path is longer than this times its cost is re-costed.
pub const DETOUR_LIMIT: f64 = 1.25;
/// Solves before the lazy collision check gives up re-solving.
const MAX_ROUNDS: usize = 20;
/// Repairs that have not settled the tour after this many rounds give way
/// to a full solve with every cost learnt so far.
const RESOLVE_EVERY: usize = 5;
/// The first solve's time limit is this...
const SOLVE_BASE: Duration = Duration::from_secs(1);
/// ...and this much more per cluster, within the configured limit: the
/// search usually ends on its own well before.
const SOLVE_PER_CLUSTER: Duration = Duration::from_millis(2);
/// GTSP costs are integers: centimetres.
const UNITS_PER_M: f64 = 100.0;

/// The solver's statistics as `replan.json` records them.
fn first_solve(stats: &SolveStats) -> FirstSolve {
    FirstSolve {
        threads: stats.threads,
        trials: stats.trials,
        rounds: stats.rounds,
        iterations: stats.iterations,
        initial_cost: stats.initial_cost,
        best_found_s: stats.best_found_s,
        time_s: stats.time_s,
        timed_out: stats.timed_out,
    }
}
/// Cost of a leg with no collision-free path, metres.
const NO_PATH_M: f64 = 1.0e5;

/// Where the tour goes: stop 0 is home, stop k > 0 is candidate k - 1.
pub struct Stops<'a> {
    pub points: &'a [Point3<f64>],
    /// Sets of candidates (as stops) of which the tour visits one each.
    pub clusters: &'a [Vec<usize>],
}

/// The tour found, with the path of each leg.
pub struct Tour {
    /// Stops in visiting order, starting at home (not repeated at the end);
    /// a candidate serving several clusters appears once.
    pub stops: Vec<usize>,
    /// For each stop, the gap voxels (indices into the clusters) it serves.
    pub serves: Vec<Vec<usize>>,
    /// Path of the leg from stop i to stop i + 1 (the last leg returns home).
    pub legs: Vec<Vec<Point3<f64>>>,
    pub stats: ReplanSolverStats,
}

/// Why no tour could be made.
#[derive(Debug, Clone, PartialEq)]
pub enum TourError {
    /// These stops have no collision-free path from home.
    Unreachable(Vec<usize>),
}

/// Solves the tour. `unreachable` stops (found on the way) are reported so
/// that the caller can drop them and call again.
pub fn plan_tour(
    stops: &Stops,
    space: &FreeSpace,
    options: &SolveOptions,
) -> Result<Tour, TourError> {
    let essential = essential_clusters(stops.clusters);
    let (vertex_stop, sets) = vertices(stops, &essential);
    let n = vertex_stop.len();
    // Known path lengths of legs between stops (both ways), metres.
    let mut flown: FlownLegs = HashMap::new();
    let mut stats = ReplanSolverStats {
        vertices: n,
        clusters: essential.len(),
        rounds: 0,
        legs_checked: 0,
        legs_recosted: 0,
        converged: false,
        first_solve: FirstSolve::default(),
        solve_seconds: 0.0,
        paths_seconds: 0.0,
    };
    let started = std::time::Instant::now();
    let mut last: Option<Vec<u32>> = None;
    loop {
        let cost = costs(&vertex_stop, &flown, stops);
        let inst = Instance::new("replan", n, cost, sets.clone())
            .expect("clusters are disjoint and not empty");
        let solution = match &last {
            Some(tour) if !stats.rounds.is_multiple_of(RESOLVE_EVERY) => repair(&inst, tour),
            _ => solve(&inst, &scaled_limit(options, essential.len())),
        };
        if stats.rounds == 0 {
            stats.first_solve = first_solve(&solution.stats);
        }
        stats.rounds += 1;
        let order = visits(&solution.tour, &vertex_stop);
        last = Some(solution.tour);
        let paths_started = std::time::Instant::now();
        let flying = fly_legs(&order, stops, space, &mut flown, &mut stats);
        stats.paths_seconds += paths_started.elapsed().as_secs_f64();
        let recosted = flying?;
        stats.legs_recosted += recosted;
        stats.converged = recosted == 0;
        // After MAX_ROUNDS the last tour is flown as it is: every leg has a
        // collision-free path; only its order may be improvable.
        if recosted == 0 || stats.rounds == MAX_ROUNDS {
            stats.solve_seconds = started.elapsed().as_secs_f64();
            let legs = (0..order.len())
                .map(|i| leg_path(&flown, stops, order[i], order[(i + 1) % order.len()]))
                .collect();
            return Ok(Tour {
                serves: first_visits(&order, stops.clusters),
                stops: order,
                legs,
                stats,
            });
        }
    }
}

/// The GTSP's vertices: home, then one per (cluster, member), a candidate
/// in several clusters copied (its copies 0 apart); each vertex's stop,
/// and the sets of vertices, home's first.
fn vertices(stops: &Stops, essential: &[usize]) -> (Vec<usize>, Vec<Vec<u32>>) {
    let mut vertex_stop = vec![0usize];
    let mut sets = vec![vec![0u32]];
    for members in essential.iter().map(|&c| &stops.clusters[c]) {
        let set = members
            .iter()
            .map(|&stop| {
                vertex_stop.push(stop);
                (vertex_stop.len() - 1) as u32
            })
            .collect();
        sets.push(set);
    }
    (vertex_stop, sets)
}

/// Every leg's cost, centimetres: its path's length where flown, else the
/// straight line.
fn costs(vertex_stop: &[usize], flown: &FlownLegs, stops: &Stops) -> Vec<i32> {
    let n = vertex_stop.len();
    (0..n * n)
        .map(|k| {
            let (a, b) = (vertex_stop[k / n], vertex_stop[k % n]);
            let len = flown.get(&key(a, b)).map_or_else(
                || (stops.points[a] - stops.points[b]).norm(),
                |(len, _)| *len,
            );
            (len * UNITS_PER_M).round() as i32
        })
        .collect()
}

/// Fly every leg of the tour `order` not flown yet, finding its
/// collision-free path; the legs over the detour limit, re-costed, or the
/// stops no path reaches from home.
fn fly_legs(
    order: &[usize],
    stops: &Stops,
    space: &FreeSpace,
    flown: &mut FlownLegs,
    stats: &mut ReplanSolverStats,
) -> Result<usize, TourError> {
    let mut recosted = 0;
    let mut unreachable = Vec::new();
    for i in 0..order.len() {
        let (a, b) = (order[i], order[(i + 1) % order.len()]);
        if a == b || flown.contains_key(&key(a, b)) {
            continue;
        }
        let estimate = (stops.points[a] - stops.points[b]).norm();
        let path = space.path(&stops.points[a], &stops.points[b]);
        stats.legs_checked += 1;
        let Some(mut path) = path else {
            unreachable.extend(
                [a, b].into_iter().filter(|&s| {
                    s != 0 && space.path(&stops.points[0], &stops.points[s]).is_none()
                }),
            );
            flown.insert(key(a, b), (NO_PATH_M, Vec::new()));
            continue;
        };
        let len = length(&path);
        if key(a, b) != (a, b) {
            path.reverse();
        }
        flown.insert(key(a, b), (len, path));
        if len > DETOUR_LIMIT * estimate + 1e-9 {
            recosted += 1;
        }
    }
    if !unreachable.is_empty() {
        unreachable.sort_unstable();
        unreachable.dedup();
        return Err(TourError::Unreachable(unreachable));
    }
    Ok(recosted)
}

/// `options` with a time limit for `clusters` clusters.
fn scaled_limit(options: &SolveOptions, clusters: usize) -> SolveOptions {
    let scaled = SOLVE_BASE + SOLVE_PER_CLUSTER * clusters as u32;
    SolveOptions {
        time_limit: Some(options.time_limit.map_or(scaled, |t| t.min(scaled))),
        ..options.clone()
    }
}

/// Legs flown so far, by (lower stop, higher stop): the path's length
/// (metres) and the path from the lower stop to the higher one.
type FlownLegs = HashMap<(usize, usize), (f64, Vec<Point3<f64>>)>;

fn key(a: usize, b: usize) -> (usize, usize) {
    (a.min(b), a.max(b))
}

/// The stored path of a leg, in the direction a -> b.
fn leg_path(flown: &FlownLegs, stops: &Stops, a: usize, b: usize) -> Vec<Point3<f64>> {
    if a == b {
        return vec![stops.points[a]];
    }
    let path = &flown[&key(a, b)].1;
    if key(a, b) == (a, b) {
        path.clone()
    } else {
        path.iter().rev().copied().collect()
    }
}

/// The clusters a tour must visit (indices, ascending): each distinct one
/// once, and none holding every stop of another, since visiting that one
/// visits it. Any tour through these visits every cluster.
fn essential_clusters(clusters: &[Vec<usize>]) -> Vec<usize> {
    let sorted: Vec<Vec<usize>> = clusters
        .iter()
        .map(|c| {
            let mut c = c.clone();
            c.sort_unstable();
            c.dedup();
            c
        })
        .collect();
    // Smallest first, so any cluster inside another is kept before it.
    let mut order: Vec<usize> = (0..clusters.len()).collect();
    order.sort_by(|&a, &b| sorted[a].len().cmp(&sorted[b].len()).then(a.cmp(&b)));
    let mut kept = Vec::new();
    let mut kept_with: HashMap<usize, Vec<usize>> = HashMap::new();
    let inside =
        |small: &[usize], large: &[usize]| small.iter().all(|s| large.binary_search(s).is_ok());
    for c in order {
        let members = &sorted[c];
        let covered = members.iter().any(|s| {
            kept_with
                .get(s)
                .is_some_and(|ks| ks.iter().any(|&k| inside(&sorted[k], members)))
        });
        if !covered {
            for &s in members {
                kept_with.entry(s).or_default().push(c);
            }
            kept.push(c);
        }
    }
    kept.sort_unstable();
    kept
}

/// The stops of a GTSP tour from home, each candidate once (a candidate
/// chosen by several clusters is visited at its first copy).
fn visits(tour: &[u32], vertex_stop: &[usize]) -> Vec<usize> {
    let home = tour
        .iter()
        .position(|&v| v == 0)
        .expect("home is in every tour");
    let mut seen = HashSet::new();
    (0..tour.len())
        .map(|k| vertex_stop[tour[(home + k) % tour.len()] as usize])
        .filter(|&stop| seen.insert(stop))
        .collect()
}

/// For each stop of `order`, the clusters it is the first visit of.
fn first_visits(order: &[usize], clusters: &[Vec<usize>]) -> Vec<Vec<usize>> {
    let at: HashMap<usize, usize> = order.iter().enumerate().map(|(i, &s)| (s, i)).collect();
    let mut serves = vec![Vec::new(); order.len()];
    for (c, members) in clusters.iter().enumerate() {
        let first = members
            .iter()
            .filter_map(|s| at.get(s))
            .min()
            .expect("the tour visits a stop of every cluster");
        serves[*first].push(c);
    }
    serves
}

/// What one battery allows a sortie: a flown length and a time (flying at
/// `speed_m_s`, hovering `hover_s` at each waypoint).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Budget {
    pub max_length_m: f64,
    pub max_time_s: f64,
    pub speed_m_s: f64,
    pub hover_s: f64,
}

impl Budget {
    /// The time of a sortie flying `length_m` with `waypoints` stops, seconds.
    pub fn time_s(&self, length_m: f64, waypoints: usize) -> f64 {
        length_m / self.speed_m_s + self.hover_s * waypoints as f64
    }

    fn fits(&self, length_m: f64, waypoints: usize) -> bool {
        length_m <= self.max_length_m && self.time_s(length_m, waypoints) <= self.max_time_s
    }
}

/// Splits a tour into sorties that each start and end at home and fit the
/// `budget`, greedily in tour order. `home_m(s)` bounds the length of the
/// path between home and stop `s` from above. Returns indices into
/// `tour.stops`, or the first stop whose round trip alone does not fit,
/// with that round trip's length.
pub fn sorties(
    tour: &Tour,
    budget: &Budget,
    home_m: &dyn Fn(usize) -> f64,
) -> Result<Vec<Vec<usize>>, (usize, f64)> {
    let mut cutter = Cutter::new(tour, budget, home_m);
    for i in 1..tour.stops.len() {
        cutter.push(i)?;
    }
    Ok(cutter.finish())
}

/// A stop flown on to: the way back from it, the way to it in the current
/// sortie, and whether the battery allows both.
struct Next {
    back: f64,
    to_here: f64,
    in_this_sortie: bool,
}

/// A stretch of a tour cut into battery sorties as it grows, stop by stop
/// (the greedy rule of [`sorties`]), knowing how long flying it takes.
pub struct Cutter<'a> {
    tour: &'a Tour,
    budget: &'a Budget,
    home_m: &'a dyn Fn(usize) -> f64,
    done: Vec<Vec<usize>>,
    /// The finished sorties' time, seconds.
    done_s: f64,
    current: Vec<usize>,
    /// The current sortie's length from home to its last stop, metres.
    so_far: f64,
}

impl<'a> Cutter<'a> {
    pub fn new(tour: &'a Tour, budget: &'a Budget, home_m: &'a dyn Fn(usize) -> f64) -> Self {
        Self {
            tour,
            budget,
            home_m,
            done: Vec::new(),
            done_s: 0.0,
            current: Vec::new(),
            so_far: 0.0,
        }
    }

    /// Fly on to tour index `i` (the next one), in this sortie or, when it
    /// no longer fits the battery, in a new one; an error (the stop and its
    /// round trip) when its round trip alone does not fit.
    pub fn push(&mut self, i: usize) -> Result<(), (usize, f64)> {
        let next = self.next(i)?;
        if next.in_this_sortie {
            self.so_far = next.to_here;
        } else {
            self.done_s += self.current_s();
            self.done.push(std::mem::take(&mut self.current));
            self.so_far = next.back;
        }
        self.current.push(i);
        Ok(())
    }

    /// How long the sorties would take flown on to tour index `i`, seconds
    /// (without flying on).
    pub fn time_with(&self, i: usize) -> Result<f64, (usize, f64)> {
        let next = self.next(i)?;
        let count = self.current.len();
        Ok(if next.in_this_sortie {
            self.done_s + self.budget.time_s(next.to_here + next.back, count + 1)
        } else {
            self.time_s() + self.budget.time_s(2.0 * next.back, 1)
        })
    }

    /// Where flying on to tour index `i` leads.
    fn next(&self, i: usize) -> Result<Next, (usize, f64)> {
        let stop = self.tour.stops[i];
        let back = (self.home_m)(stop);
        if !self.budget.fits(2.0 * back, 1) {
            return Err((stop, 2.0 * back));
        }
        let to_here = match self.current.last() {
            None => back,
            Some(&last) => self.so_far + length(&self.tour.legs[last]),
        };
        let in_this_sortie = self.budget.fits(to_here + back, self.current.len() + 1);
        Ok(Next {
            back,
            to_here,
            in_this_sortie,
        })
    }

    /// The current sortie's time, home to home, seconds.
    fn current_s(&self) -> f64 {
        let Some(&last) = self.current.last() else {
            return 0.0;
        };
        let back = (self.home_m)(self.tour.stops[last]);
        self.budget.time_s(self.so_far + back, self.current.len())
    }

    /// Flying every sortie so far, one after the other, seconds.
    pub fn time_s(&self) -> f64 {
        self.done_s + self.current_s()
    }

    /// The sorties: indices into `tour.stops`.
    pub fn finish(mut self) -> Vec<Vec<usize>> {
        if !self.current.is_empty() {
            self.done.push(self.current);
        }
        self.done
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use postflight_core::map::{VoxelGrid, VoxelMap};
    use std::time::Duration;

    /// Flat ground, and a wall between x = 0 and x = 0.5 for |y| < 5.
    fn wall() -> VoxelMap {
        let mut points = Vec::new();
        for x in -30..30 {
            for y in -30..30 {
                points.push(Point3::new(f64::from(x) * 0.5, f64::from(y) * 0.5, -0.25));
            }
        }
        for y in -10..10 {
            for z in 0..16 {
                points.push(Point3::new(
                    0.25,
                    f64::from(y) * 0.5 + 0.25,
                    f64::from(z) * 0.5 + 0.25,
                ));
            }
        }
        VoxelMap::from_points(VoxelGrid::new(0.5, Point3::origin()), &points, 1)
    }

    #[test]
    fn legs_through_the_wall_are_recosted_and_the_tour_goes_round_once() {
        let map = wall();
        let space = FreeSpace::new(&map, 1.0, &[], crate::airspace::Airspace::default()).unwrap();
        // Home west of the wall; two clusters east of it, each with a near
        // and a far choice; straight lines cross the wall.
        let points = vec![
            Point3::new(-3.0, 0.0, 3.0),
            Point3::new(3.0, 1.0, 3.0),
            Point3::new(9.0, 1.0, 3.0),
            Point3::new(3.0, -1.0, 3.0),
            Point3::new(9.0, -1.0, 3.0),
        ];
        let clusters = vec![vec![1, 2], vec![3, 4]];
        let stops = Stops {
            points: &points,
            clusters: &clusters,
        };
        let options = SolveOptions {
            time_limit: Some(Duration::from_secs(2)),
            threads: 1,
            ..SolveOptions::default()
        };
        let tour = plan_tour(&stops, &space, &options).unwrap();
        assert!(
            tour.stats.rounds >= 2,
            "straight lines cross the wall: {}",
            tour.stats.rounds
        );
        assert!(tour.stats.legs_recosted >= 1);
        assert_eq!(tour.stops[0], 0);
        let mut served: Vec<usize> = tour.serves.concat();
        served.sort_unstable();
        assert_eq!(served, vec![0, 1]);
        for leg in &tour.legs {
            assert!(leg.windows(2).all(|w| space.segment_is_clear(&w[0], &w[1])));
        }
        // The near choices, reached round one end of the wall.
        assert_eq!(
            &tour.stops[1..]
                .iter()
                .copied()
                .collect::<std::collections::BTreeSet<_>>(),
            &[1, 3].into()
        );
    }

    #[test]
    fn only_clusters_holding_no_other_cluster_are_solved_and_every_cluster_is_served() {
        let clusters = vec![vec![1, 2], vec![2, 1], vec![1, 2, 3], vec![3, 4], vec![4]];
        // [2, 1] repeats [1, 2]; [1, 2, 3] holds [1, 2]; [3, 4] holds [4].
        assert_eq!(essential_clusters(&clusters), vec![0, 4]);
        // A tour through 2 and 4 serves all five.
        let serves = first_visits(&[0, 2, 4], &clusters);
        assert_eq!(serves, vec![vec![], vec![0, 1, 2], vec![3, 4]]);
    }
}
