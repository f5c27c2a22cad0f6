//! The destroy-and-repair moves of the large-neighbourhood search: removals
//! that take sets out of a tour and the insertion that puts them back at
//! their cheapest vertex and position.
//!
//! A tour is the list of chosen vertices in visiting order, closed.

use super::Instance;
use super::rng::Rng;

/// How sets are chosen for removal.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Removal {
    /// Any sets.
    Random,
    /// A run of consecutive sets.
    Segment,
    /// Sets whose vertices are close to a random one (they can be reordered together).
    Distance,
    /// Sets whose vertices cost the most detour.
    Worst,
}

impl Removal {
    pub(crate) const ALL: [Removal; 4] = [
        Removal::Random,
        Removal::Segment,
        Removal::Distance,
        Removal::Worst,
    ];
}

/// Picks an index into a list sorted best first: mostly near the front,
/// sometimes further (randomised greedy, as in Ropke and Pisinger's LNS).
fn biased_index(len: usize, rng: &mut Rng) -> usize {
    ((len as f64) * rng.unit().powi(4)) as usize
}

/// Detour saved by removing the vertex at `p` from the closed tour.
pub(crate) fn removal_gain(inst: &Instance, tour: &[u32], p: usize) -> i64 {
    let len = tour.len();
    if len < 2 {
        return 0;
    }
    let (prev, v, next) = (tour[(p + len - 1) % len], tour[p], tour[(p + 1) % len]);
    inst.cost(prev, v) + inst.cost(v, next) - inst.cost(prev, next)
}

/// Removes `k` sets' vertices from the tour; returns the removed sets.
pub(crate) fn remove(
    inst: &Instance,
    tour: &mut Vec<u32>,
    k: usize,
    how: Removal,
    rng: &mut Rng,
) -> Vec<usize> {
    let len = tour.len();
    let k = k.min(len);
    let mut positions: Vec<usize> = match how {
        Removal::Random => {
            let mut all: Vec<usize> = (0..len).collect();
            rng.shuffle(&mut all);
            all.truncate(k);
            all
        }
        Removal::Segment => {
            let start = rng.below(len);
            (0..k).map(|i| (start + i) % len).collect()
        }
        Removal::Distance => {
            let seed = tour[rng.below(len)];
            let mut by_distance: Vec<(i64, usize)> = (0..len)
                .map(|p| {
                    let v = tour[p];
                    (inst.cost(seed, v).min(inst.cost(v, seed)), p)
                })
                .collect();
            by_distance.sort_unstable();
            pick_biased(by_distance, k, rng)
        }
        Removal::Worst => {
            let mut by_gain: Vec<(i64, usize)> = (0..len)
                .map(|p| (-removal_gain(inst, tour, p), p))
                .collect();
            by_gain.sort_unstable();
            pick_biased(by_gain, k, rng)
        }
    };
    positions.sort_unstable_by(|a, b| b.cmp(a));
    positions
        .into_iter()
        .map(|p| {
            inst.set_of(tour.remove(p))
                .expect("tour vertices are in sets")
        })
        .collect()
}

fn pick_biased(mut ranked: Vec<(i64, usize)>, k: usize, rng: &mut Rng) -> Vec<usize> {
    (0..k)
        .map(|_| ranked.remove(biased_index(ranked.len(), rng)).1)
        .collect()
}

/// The cheapest way to add `set` to the tour: (added cost, vertex, index
/// the vertex goes to).
pub(crate) fn best_insertion(inst: &Instance, tour: &[u32], set: usize) -> (i64, u32, usize) {
    let members = &inst.sets()[set];
    let len = tour.len();
    let mut best = (i64::MAX, members[0], 0);
    match len {
        0 => best = (0, members[0], 0),
        1 => {
            for &v in members {
                let delta = inst.cost(tour[0], v) + inst.cost(v, tour[0]);
                if delta < best.0 {
                    best = (delta, v, 1);
                }
            }
        }
        _ => {
            for i in 0..len {
                let (a, b) = (tour[i], tour[(i + 1) % len]);
                let ab = inst.cost(a, b);
                for &v in members {
                    let delta = inst.cost(a, v) + inst.cost(v, b) - ab;
                    if delta < best.0 {
                        best = (delta, v, i + 1);
                    }
                }
            }
        }
    }
    best
}

/// Puts the removed sets back one by one in random order, each at its
/// cheapest vertex and position; `noise` (a cost) perturbs the choice so the
/// search does not rebuild the same tour every time.
pub(crate) fn insert(
    inst: &Instance,
    tour: &mut Vec<u32>,
    mut sets: Vec<usize>,
    noise: f64,
    rng: &mut Rng,
) {
    rng.shuffle(&mut sets);
    for set in sets {
        let members = &inst.sets()[set];
        let len = tour.len();
        if len < 2 || noise <= 0.0 {
            let (_, v, at) = best_insertion(inst, tour, set);
            tour.insert(at, v);
            continue;
        }
        let mut best = (f64::INFINITY, members[0], 0);
        for i in 0..len {
            let (a, b) = (tour[i], tour[(i + 1) % len]);
            let ab = inst.cost(a, b);
            for &v in members {
                let delta = (inst.cost(a, v) + inst.cost(v, b) - ab) as f64 + noise * rng.unit();
                if delta < best.0 {
                    best = (delta, v, i + 1);
                }
            }
        }
        tour.insert(best.2, best.1);
    }
}

/// A starting tour: sets inserted in random order at their cheapest place.
pub(crate) fn random_insertion(inst: &Instance, rng: &mut Rng) -> Vec<u32> {
    let mut tour = Vec::with_capacity(inst.sets().len());
    insert(inst, &mut tour, (0..inst.sets().len()).collect(), 0.0, rng);
    tour
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn removal_and_insertion_keep_one_vertex_per_set() {
        let inst = crate::local::tests::line_instance();
        let mut rng = Rng::stream(7, 0);
        let mut tour = random_insertion(&inst, &mut rng);
        for how in Removal::ALL {
            for k in 1..=6 {
                let removed = remove(&inst, &mut tour, k, how, &mut rng);
                assert_eq!(removed.len(), k);
                assert_eq!(tour.len(), 6 - k);
                insert(&inst, &mut tour, removed, 5.0, &mut rng);
                inst.check_tour(&tour).unwrap();
            }
        }
    }
}
