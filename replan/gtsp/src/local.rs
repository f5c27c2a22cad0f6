//! Local optimisation of a GTSP tour, run on every tour the search makes:
//! 2-opt and or-opt (symmetric costs), moving one set to its cheapest place
//! and vertex, and re-choosing every set's vertex by a shortest path over the
//! fixed set order. Moves look only near each vertex (its nearest sets), the
//! usual neighbour-list pruning, so a pass costs O(sets), not O(sets²).

use super::Instance;
use super::search::{best_insertion, removal_gain};

/// For each vertex, the nearest other sets (by their nearest vertex), best
/// first, with that distance.
pub(crate) struct Neighbours {
    k: usize,
    near: Vec<(u32, i64)>,
}

impl Neighbours {
    pub(crate) fn new(inst: &Instance, k: usize) -> Neighbours {
        let (n, m) = (inst.vertices(), inst.sets().len());
        let k = k.min(m.saturating_sub(1));
        let mut near = vec![(u32::MAX, i64::MAX); n * k];
        let mut by_set = vec![i64::MAX; m];
        for w in 0..n as u32 {
            let Some(own) = inst.set_of(w) else { continue };
            by_set.fill(i64::MAX);
            for u in 0..n as u32 {
                if let Some(s) = inst.set_of(u).filter(|&s| s != own) {
                    let d = inst.cost(w, u).min(inst.cost(u, w));
                    by_set[s] = by_set[s].min(d);
                }
            }
            let mut ranked: Vec<(i64, u32)> = (0..m)
                .filter(|&s| s != own)
                .map(|s| (by_set[s], s as u32))
                .collect();
            if k > 0 && ranked.len() > k {
                ranked.select_nth_unstable(k - 1);
                ranked.truncate(k);
            }
            ranked.sort_unstable();
            for (slot, (d, s)) in ranked.into_iter().enumerate() {
                near[w as usize * k + slot] = (s, d);
            }
        }
        Neighbours { k, near }
    }

    fn of(&self, v: u32) -> &[(u32, i64)] {
        &self.near[v as usize * self.k..(v as usize + 1) * self.k]
    }
}

/// Reusable buffers and the work queue of the local optimisation.
#[derive(Default)]
pub(crate) struct Scratch {
    /// Tour index of each set.
    pos: Vec<usize>,
    /// Sets whose surroundings changed since their moves were last tried
    /// (don't-look bits, Bentley 1992): only those are tried again.
    queued: Vec<bool>,
    queue: std::collections::VecDeque<usize>,
    layer_cost: Vec<Vec<i64>>,
    layer_from: Vec<Vec<u32>>,
}

impl Scratch {
    fn index(&mut self, inst: &Instance, tour: &[u32]) {
        self.pos.resize(inst.sets().len(), usize::MAX);
        for (i, &v) in tour.iter().enumerate() {
            self.pos[set_of(inst, v)] = i;
        }
    }

    fn push(&mut self, set: usize) {
        if !std::mem::replace(&mut self.queued[set], true) {
            self.queue.push_back(set);
        }
    }

    /// Queues the sets at these tour indices and their tour neighbours.
    fn touch(&mut self, inst: &Instance, tour: &[u32], indices: &[usize]) {
        let len = tour.len();
        for &i in indices {
            for j in [i + len - 1, i, i + 1] {
                self.push(set_of(inst, tour[j % len]));
            }
        }
    }
}

fn set_of(inst: &Instance, v: u32) -> usize {
    inst.set_of(v).expect("tour vertices are in sets")
}

/// Runs all moves to a common local optimum; returns the tour's cost.
/// `touched` lists the sets whose neighbourhood changed since the tour was
/// last optimised (`None`: all of them).
pub(crate) fn improve(
    inst: &Instance,
    near: &Neighbours,
    tour: &mut Vec<u32>,
    scratch: &mut Scratch,
    touched: Option<&[usize]>,
) -> i64 {
    let m = inst.sets().len();
    scratch.queued.clear();
    scratch.queued.resize(m, false);
    scratch.queue.clear();
    match touched {
        Some(sets) => sets.iter().for_each(|&s| scratch.push(s)),
        None => (0..m).for_each(|s| scratch.push(s)),
    }
    if tour.len() < 8 {
        // Too short for neighbour lists: try every place.
        while move_sets_exhaustive(inst, tour) | choose_vertices(inst, tour, scratch) {}
        return inst.tour_cost(tour);
    }
    let symmetric = inst.is_symmetric();
    // From scratch, don't-look bits can miss moves opened up far away, so
    // the optimum is confirmed by one more pass over every set.
    let full = touched.is_none();
    let mut confirmed = !full;
    loop {
        scratch.index(inst, tour);
        let mut moved = false;
        while let Some(set) = scratch.queue.pop_front() {
            scratch.queued[set] = false;
            let i = scratch.pos[set];
            let changed = (symmetric
                && (two_opt_at(inst, near, tour, scratch, i)
                    || or_opt_at(inst, near, tour, scratch, i)))
                || move_set_at(inst, near, tour, scratch, i);
            if changed {
                moved = true;
                scratch.index(inst, tour);
                scratch.push(set);
            }
        }
        let before = tour.clone();
        let chose = choose_vertices(inst, tour, scratch);
        if chose {
            let changed: Vec<usize> = (0..tour.len()).filter(|&i| tour[i] != before[i]).collect();
            scratch.touch(inst, tour, &changed);
        }
        if full && (moved || chose) {
            confirmed = false;
        }
        if chose {
            continue;
        }
        if !confirmed {
            confirmed = true;
            (0..m).for_each(|s| scratch.push(s));
            continue;
        }
        return inst.tour_cost(tour);
    }
}

/// Reverses the stretch of a closed tour from index `from` forward to `to`.
fn reverse(tour: &mut [u32], from: usize, to: usize) {
    let len = tour.len();
    let span = (to + len - from) % len + 1;
    for k in 0..span / 2 {
        tour.swap((from + k) % len, (to + len - k) % len);
    }
}

/// 2-opt from the vertex at `i`: replace its edge to a neighbour and another
/// edge by the two that reconnect the tour the other way, trying only
/// partners among its nearest sets. Symmetric costs.
fn two_opt_at(
    inst: &Instance,
    near: &Neighbours,
    tour: &mut [u32],
    scratch: &mut Scratch,
    i: usize,
) -> bool {
    let len = tour.len();
    let a = tour[i];
    let (succ, pred) = (tour[(i + 1) % len], tour[(i + len - 1) % len]);
    let (to_succ, from_pred) = (inst.cost(a, succ), inst.cost(pred, a));
    for &(s, bound) in near.of(a) {
        if bound >= to_succ.max(from_pred) {
            break;
        }
        let j = scratch.pos[s as usize];
        let c = tour[j];
        let ac = inst.cost(a, c);
        // a->succ and c->c_next become a->c and succ->c_next.
        let c_next = tour[(j + 1) % len];
        if ac + inst.cost(succ, c_next) < to_succ + inst.cost(c, c_next) {
            reverse(tour, (i + 1) % len, j);
            scratch.touch(inst, tour, &[i, (i + 1) % len, j, (j + 1) % len]);
            return true;
        }
        // pred->a and c_prev->c become pred->c_prev and a->c.
        let c_prev = tour[(j + len - 1) % len];
        if ac + inst.cost(pred, c_prev) < from_pred + inst.cost(c_prev, c) {
            reverse(tour, i, (j + len - 1) % len);
            scratch.touch(
                inst,
                tour,
                &[i, (i + len - 1) % len, j, (j + len - 1) % len],
            );
            return true;
        }
    }
    false
}

/// Or-opt: move the run of two or three sets starting at `start` next to a
/// near set, either way round. Symmetric costs.
fn or_opt_at(
    inst: &Instance,
    near: &Neighbours,
    tour: &mut Vec<u32>,
    scratch: &mut Scratch,
    start: usize,
) -> bool {
    let len = tour.len();
    for run in [2usize, 3] {
        let inside = |j: usize| (j + len - start) % len < run;
        let (first, last) = (tour[start], tour[(start + run - 1) % len]);
        let (p, q) = (tour[(start + len - 1) % len], tour[(start + run) % len]);
        let gain = inst.cost(p, first) + inst.cost(last, q) - inst.cost(p, q);
        // (profit, index of the vertex the run goes after, reversed)
        let mut best = (0i64, 0usize, false);
        for end in [first, last] {
            for &(s, bound) in near.of(end) {
                if bound >= gain {
                    break;
                }
                let j = scratch.pos[s as usize];
                if inside(j) {
                    continue;
                }
                for (ga, gb) in [((j + len - 1) % len, j), (j, (j + 1) % len)] {
                    if inside(ga) || inside(gb) {
                        continue;
                    }
                    let (a, b) = (tour[ga], tour[gb]);
                    let ab = inst.cost(a, b);
                    let forward = inst.cost(a, first) + inst.cost(last, b) - ab;
                    let backward = inst.cost(a, last) + inst.cost(first, b) - ab;
                    let profit = gain - forward.min(backward);
                    if profit > best.0 {
                        best = (profit, ga, backward < forward);
                    }
                }
            }
        }
        if best.0 > 0 {
            let (_, after, reversed) = best;
            // Rotate so the tour starts just past the run, take the run off
            // the end, and splice it in after `after`.
            let shift = (start + run) % len;
            tour.rotate_left(shift);
            let mut moved = tour.split_off(len - run);
            if reversed {
                moved.reverse();
            }
            let at = (after + len - shift) % len + 1;
            tour.splice(at..at, moved);
            // The old gap (now the tour's two ends) and both ends of the run.
            scratch.touch(inst, tour, &[0, len - 1, at, at + run - 1]);
            return true;
        }
    }
    false
}

/// Takes the set at `p` out and puts it back at its cheapest vertex and
/// place among its vertices' near sets (or where it was), when strictly
/// cheaper.
fn move_set_at(
    inst: &Instance,
    near: &Neighbours,
    tour: &mut Vec<u32>,
    scratch: &mut Scratch,
    p: usize,
) -> bool {
    let len = tour.len();
    let v = tour[p];
    let gain = removal_gain(inst, tour, p);
    // Neighbours of index j in the tour without p.
    let before = |j: usize| {
        let b = (j + len - 1) % len;
        if b == p { (b + len - 1) % len } else { b }
    };
    let after = |j: usize| {
        let a = (j + 1) % len;
        if a == p { (a + 1) % len } else { a }
    };
    let (prev, next) = ((p + len - 1) % len, (p + 1) % len);
    // (added cost, vertex, index it goes after)
    let mut best = (i64::MAX, v, prev);
    let consider = |w: u32, ga: usize, gb: usize, best: &mut (i64, u32, usize)| {
        let (a, b) = (tour[ga], tour[gb]);
        let delta = inst.cost(a, w) + inst.cost(w, b) - inst.cost(a, b);
        if delta < best.0 {
            *best = (delta, w, ga);
        }
    };
    for &w in &inst.sets()[set_of(inst, v)] {
        consider(w, prev, next, &mut best);
        for &(s, _) in near.of(w) {
            let j = scratch.pos[s as usize];
            consider(w, before(j), j, &mut best);
            consider(w, j, after(j), &mut best);
        }
    }
    if best.0 >= gain {
        return false;
    }
    let (_, w, after_index) = best;
    tour.remove(p);
    let at = if after_index > p {
        after_index
    } else {
        after_index + 1
    };
    tour.insert(at, w);
    // Old neighbours (now adjacent around p's old place) and the new place.
    let old = if at <= p { p } else { (p + len - 1) % len };
    scratch.touch(inst, tour, &[old, at]);
    true
}

/// Moving sets for short tours: every place is tried.
fn move_sets_exhaustive(inst: &Instance, tour: &mut Vec<u32>) -> bool {
    let mut any = false;
    let mut p = 0;
    let mut since_change = 0;
    while since_change < tour.len() && tour.len() > 1 {
        p %= tour.len();
        let gain = removal_gain(inst, tour, p);
        let v = tour.remove(p);
        let (delta, w, at) = best_insertion(inst, tour, set_of(inst, v));
        if delta < gain {
            tour.insert(at, w);
            any = true;
            since_change = 0;
        } else {
            tour.insert(p, v);
            p += 1;
            since_change += 1;
        }
    }
    any
}

/// Keeps the order of the sets and re-chooses every set's vertex by a
/// shortest path through the layered graph, starting from each vertex of
/// the smallest set (Fischetti et al.'s cluster optimisation).
pub(crate) fn choose_vertices(inst: &Instance, tour: &mut [u32], scratch: &mut Scratch) -> bool {
    let len = tour.len();
    if len < 2 {
        return false;
    }
    let sets = inst.sets();
    let first = (0..len)
        .min_by_key(|&i| sets[set_of(inst, tour[i])].len())
        .expect("non-empty tour");
    let order: Vec<usize> = (0..len)
        .map(|k| set_of(inst, tour[(first + k) % len]))
        .collect();
    scratch.layer_cost.resize_with(len, Vec::new);
    scratch.layer_from.resize_with(len, Vec::new);
    let current = inst.tour_cost(tour);
    let mut best_total = i64::MAX;
    let mut best_path = Vec::new();
    for &start in &sets[order[0]] {
        for k in 1..len {
            let (prev, here) = (&sets[order[k - 1]], &sets[order[k]]);
            let mut cost = std::mem::take(&mut scratch.layer_cost[k]);
            let mut from = std::mem::take(&mut scratch.layer_from[k]);
            cost.clear();
            from.clear();
            for &v in here {
                let (c, f) = if k == 1 {
                    (inst.cost(start, v), 0)
                } else {
                    let before = &scratch.layer_cost[k - 1];
                    prev.iter()
                        .enumerate()
                        .map(|(j, &u)| (before[j] + inst.cost(u, v), j as u32))
                        .min()
                        .expect("sets are not empty")
                };
                cost.push(c);
                from.push(f);
            }
            scratch.layer_cost[k] = cost;
            scratch.layer_from[k] = from;
        }
        let (total, mut j) = sets[order[len - 1]]
            .iter()
            .enumerate()
            .map(|(j, &v)| (scratch.layer_cost[len - 1][j] + inst.cost(v, start), j))
            .min()
            .expect("sets are not empty");
        if total < best_total {
            best_total = total;
            best_path.clear();
            for k in (1..len).rev() {
                best_path.push(sets[order[k]][j]);
                j = scratch.layer_from[k][j] as usize;
            }
            best_path.push(start);
            best_path.reverse();
        }
    }
    if best_total < current {
        for (k, &v) in best_path.iter().enumerate() {
            tour[(first + k) % len] = v;
        }
        true
    } else {
        false
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::rng::Rng;
    use crate::search::random_insertion;

    /// Points on a line; set i holds a near copy of point i and a far one.
    pub(crate) fn line_instance() -> Instance {
        let xs: Vec<f64> = (0..6).flat_map(|i| [i as f64, i as f64 + 50.0]).collect();
        let n = xs.len();
        let cost = (0..n * n)
            .map(|k| ((xs[k / n] - xs[k % n]).abs() * 10.0) as i32)
            .collect();
        let sets = (0..6).map(|i| vec![2 * i, 2 * i + 1]).collect();
        Instance::new("line", n, cost, sets).unwrap()
    }

    /// Random points in the plane, three per set.
    fn plane_instance(sets: usize, seed: u64) -> Instance {
        let mut rng = Rng::stream(seed, 0);
        let pts: Vec<(f64, f64)> = (0..sets * 3)
            .map(|_| (rng.unit() * 1000.0, rng.unit() * 1000.0))
            .collect();
        let n = pts.len();
        let cost = (0..n * n)
            .map(|k| {
                let (a, b) = (pts[k / n], pts[k % n]);
                (a.0 - b.0).hypot(a.1 - b.1).round() as i32
            })
            .collect();
        let sets = (0..sets as u32)
            .map(|s| vec![3 * s, 3 * s + 1, 3 * s + 2])
            .collect();
        Instance::new("plane", n, cost, sets).unwrap()
    }

    #[test]
    fn choosing_vertices_finds_the_best_for_a_fixed_order() {
        let inst = line_instance();
        // All far copies but one: the best for this order is all near copies.
        let mut tour: Vec<u32> = vec![1, 3, 5, 7, 9, 10];
        assert!(choose_vertices(&inst, &mut tour, &mut Scratch::default()));
        assert_eq!(tour, vec![0, 2, 4, 6, 8, 10]);
        assert_eq!(inst.tour_cost(&tour), 100);
    }

    #[test]
    fn local_optimisation_untangles_a_shuffled_tour() {
        let inst = line_instance();
        let near = Neighbours::new(&inst, 8);
        let mut tour: Vec<u32> = vec![1, 8, 2, 11, 4, 6];
        let cost = improve(&inst, &near, &mut tour, &mut Scratch::default(), None);
        assert_eq!(cost, 100, "{tour:?}");
        assert!(inst.check_tour(&tour).is_ok());
    }

    #[test]
    fn local_optimum_is_valid_and_no_worse_from_any_start() {
        for seed in 0..20 {
            let inst = plane_instance(40, seed);
            let near = Neighbours::new(&inst, 8);
            let mut rng = Rng::stream(seed, 1);
            let mut scratch = Scratch::default();
            let mut tour = random_insertion(&inst, &mut rng);
            rng.shuffle(&mut tour);
            let before = inst.tour_cost(&tour);
            let after = improve(&inst, &near, &mut tour, &mut scratch, None);
            inst.check_tour(&tour).unwrap();
            assert_eq!(after, inst.tour_cost(&tour));
            assert!(after < before, "seed {seed}: {before} -> {after}");
            // A local optimum: a second pass over every set finds nothing.
            let again = improve(&inst, &near, &mut tour, &mut scratch, None);
            assert_eq!(again, after, "seed {seed}");
        }
    }
}
