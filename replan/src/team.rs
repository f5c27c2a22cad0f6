//! A follow-up flight shared by a team of drones taking off from one home:
//! the tour cut into one stretch per drone so that the slowest drone is
//! done soonest (route first, split second, after Beasley's split of a
//! giant tour), each stretch flown in battery sorties from home. Stretches
//! of one tour keep the drones' areas apart: they meet only near home.

use crate::tour::{Budget, Cutter, Tour};

/// Each drone's sorties (indices into `tour.stops`), drone by drone; fewer
/// drones than `drones` when that is as quick. An error (the stop and its
/// round trip) when a stop's round trip alone does not fit a battery.
pub fn split(
    tour: &Tour,
    drones: usize,
    budget: &Budget,
    home_m: &dyn Fn(usize) -> f64,
) -> Result<Vec<Vec<Vec<usize>>>, (usize, f64)> {
    let stops = 1..tour.stops.len();
    // The mission can take no less than the longest single stop's round
    // trip, nor more than one drone flying everything.
    let mut whole = Cutter::new(tour, budget, home_m);
    let mut longest_stop: f64 = 0.0;
    for i in stops {
        longest_stop = longest_stop.max(Cutter::new(tour, budget, home_m).time_with(i)?);
        whole.push(i)?;
    }
    let (mut lo, mut hi) = (longest_stop, whole.time_s());
    let mut best = stretches(tour, budget, home_m, hi)?;
    // Bisect the mission's time: the shortest whose greedy cut needs at
    // most `drones` stretches.
    for _ in 0..60 {
        if hi - lo <= 1e-3 * hi.max(1.0) {
            break;
        }
        let mid = 0.5 * (lo + hi);
        let cut = stretches(tour, budget, home_m, mid)?;
        if cut.len() <= drones {
            (best, hi) = (cut, mid);
        } else {
            lo = mid;
        }
    }
    Ok(best)
}

/// The tour cut greedily into stretches each flown within `limit_s`
/// (a stop that alone takes longer gets a stretch of its own), each cut
/// into its sorties.
fn stretches(
    tour: &Tour,
    budget: &Budget,
    home_m: &dyn Fn(usize) -> f64,
    limit_s: f64,
) -> Result<Vec<Vec<Vec<usize>>>, (usize, f64)> {
    let mut out = Vec::new();
    let mut current = Cutter::new(tour, budget, home_m);
    let mut empty = true;
    for i in 1..tour.stops.len() {
        if !empty && current.time_with(i)? > limit_s {
            let full = std::mem::replace(&mut current, Cutter::new(tour, budget, home_m));
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
