//! The GTSP solver: adaptive large-neighbourhood search in the manner of
//! GLNS (Smith and Imeson, 2017) — randomised removals, best insertion with
//! noise, simulated-annealing acceptance, operator weights adapted to what
//! pays — with every candidate tour locally optimised (2-opt, or-opt, set
//! moves, and re-choosing every vertex by shortest path over the set order,
//! the local search of Gutin and Karapetyan's memetic algorithm).
//!
//! Independent cold trials run in parallel; then warm rounds restart from
//! the best tour until rounds stop paying. Each trial's random stream
//! depends only on the seed and the trial's number, and rounds are joined in
//! trial order, so a seed and thread count give the same tour whenever the
//! search ends on its own rather than on the time limit.

use std::time::{Duration, Instant};

use rayon::prelude::*;

use super::Instance;
use super::local::{Neighbours, Scratch, improve};
use super::rng::Rng;
use super::search::{Removal, insert, random_insertion, remove};

/// How long and how widely to search.
#[derive(Debug, Clone)]
pub struct SolveOptions {
    /// Hard wall-clock bound; the best tour found so far is returned.
    pub time_limit: Option<Duration>,
    pub seed: u64,
    /// Worker threads; 0 means one per core.
    pub threads: usize,
    /// Independent trials from random tours before the warm rounds
    /// (default: at least 4, and at least one per thread).
    pub cold_trials: Option<usize>,
    /// Iterations of each trial per set (GLNS's default is 60).
    pub iterations_per_set: usize,
    /// Warm rounds without improvement before a search ends.
    pub patience: usize,
    /// Independent searches (a cold round, then warm rounds); the best
    /// tour of all is returned. Searches after the first start only while
    /// time remains.
    pub searches: usize,
}

impl Default for SolveOptions {
    fn default() -> SolveOptions {
        SolveOptions {
            time_limit: None,
            seed: 1,
            threads: 0,
            cold_trials: None,
            iterations_per_set: 60,
            patience: 3,
            searches: 3,
        }
    }
}

/// What the search did.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct SolveStats {
    pub threads: usize,
    pub trials: usize,
    pub rounds: usize,
    pub iterations: u64,
    /// Cost of the best tour of the first cold trial's starting tour.
    pub initial_cost: i64,
    /// Seconds until the returned tour was first found.
    pub best_found_s: f64,
    pub time_s: f64,
    /// The search was cut by the time limit.
    pub timed_out: bool,
}

/// A tour with one vertex per set (0-based, visiting order) and its cost.
#[derive(Debug, Clone)]
pub struct Solution {
    pub tour: Vec<u32>,
    pub cost: i64,
    pub stats: SolveStats,
}

/// Solves a GTSP instance.
pub fn solve(inst: &Instance, options: &SolveOptions) -> Solution {
    let started = Instant::now();
    let deadline = options.time_limit.map(|t| started + t);
    let threads = if options.threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        options.threads
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool of this size can be built");
    let m = inst.sets().len();
    let budget = (options.iterations_per_set * m).max(100) as u64;
    let cold = options.cold_trials.unwrap_or(4).max(threads).max(1);
    let clock = Clock { started, deadline };
    let near = Neighbours::new(inst, NEIGHBOURS);

    let mut trial_index = 0u64;
    let mut run_round = |start: Option<&[u32]>, count: usize| -> Vec<TrialResult> {
        let first = trial_index;
        trial_index += count as u64;
        pool.install(|| {
            (first..first + count as u64)
                .into_par_iter()
                .map(|t| {
                    let rng = Rng::stream(options.seed, t);
                    trial(inst, &near, start, rng, budget, &clock)
                })
                .collect()
        })
    };

    let mut stats = SolveStats {
        threads,
        trials: cold,
        rounds: 1,
        iterations: 0,
        initial_cost: 0,
        best_found_s: 0.0,
        time_s: 0.0,
        timed_out: false,
    };
    let mut best: Option<TrialResult> = None;
    for search in 0..options.searches.max(1) {
        if search > 0 && (m <= 2 || clock.expired()) {
            break;
        }
        let results = run_round(None, cold);
        if search == 0 {
            stats.initial_cost = results[0].initial_cost;
        } else {
            stats.trials += cold;
            stats.rounds += 1;
        }
        let mut search_best = pick_best(results, &mut stats);
        let mut stale = 0;
        while m > 2 && stale < options.patience && !clock.expired() {
            let warm = threads.max(2);
            let results = run_round(Some(&search_best.tour), warm);
            stats.trials += warm;
            stats.rounds += 1;
            let round_best = pick_best(results, &mut stats);
            if round_best.cost < search_best.cost {
                search_best = round_best;
                stale = 0;
            } else {
                stale += 1;
            }
        }
        if best.as_ref().is_none_or(|b| search_best.cost < b.cost) {
            best = Some(search_best);
        }
    }
    let best = best.expect("at least one search runs");
    stats.timed_out = clock.expired();
    stats.best_found_s = best.found_s;
    stats.time_s = started.elapsed().as_secs_f64();
    Solution {
        tour: best.tour,
        cost: best.cost,
        stats,
    }
}

/// Improves `tour` (one vertex of every set) to a local optimum of every
/// move the search uses, without any randomised search: a tour whose costs
/// changed on a few arcs is repaired in milliseconds where a full solve
/// takes seconds.
pub fn repair(inst: &Instance, tour: &[u32]) -> Solution {
    let started = Instant::now();
    let near = Neighbours::new(inst, NEIGHBOURS);
    let mut tour = tour.to_vec();
    let initial_cost = inst.tour_cost(&tour);
    let cost = improve(inst, &near, &mut tour, &mut Scratch::default(), None);
    let time_s = started.elapsed().as_secs_f64();
    Solution {
        tour,
        cost,
        stats: SolveStats {
            threads: 1,
            initial_cost,
            best_found_s: time_s,
            time_s,
            ..SolveStats::default()
        },
    }
}

struct Clock {
    started: Instant,
    deadline: Option<Instant>,
}

impl Clock {
    fn expired(&self) -> bool {
        self.deadline.is_some_and(|d| Instant::now() >= d)
    }

    fn seconds(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }
}

struct TrialResult {
    tour: Vec<u32>,
    cost: i64,
    found_s: f64,
    initial_cost: i64,
    iterations: u64,
}

/// The best of a round, ties to the lowest trial number (so the answer
/// does not depend on which thread finished first).
fn pick_best(results: Vec<TrialResult>, stats: &mut SolveStats) -> TrialResult {
    stats.iterations += results.iter().map(|r| r.iterations).sum::<u64>();
    results
        .into_iter()
        .reduce(|a, b| if b.cost < a.cost { b } else { a })
        .expect("a round has trials")
}

/// One operator choice: how to remove, and how much noise in re-inserting.
#[derive(Clone, Copy)]
struct Arm {
    removal: Removal,
    /// Insertion noise as a fraction of the tour's mean edge cost.
    noise: f64,
}

/// Nearest sets each vertex's local moves look at.
const NEIGHBOURS: usize = 10;
const NOISE_LEVELS: [f64; 3] = [0.0, 0.2, 1.0];
/// Iterations between updates of the operator weights.
const SEGMENT: u64 = 100;
/// How fast weights follow recent success (GLNS's epsilon).
const REACTION: f64 = 0.5;
/// Simulated annealing: a tour this much worse (fraction of the cost) is
/// accepted half the time at the start of a trial...
const START_WORSE: f64 = 0.02;
/// ...and this much worse at its end.
const END_WORSE: f64 = 0.0002;

fn trial(
    inst: &Instance,
    near: &Neighbours,
    start: Option<&[u32]>,
    mut rng: Rng,
    budget: u64,
    clock: &Clock,
) -> TrialResult {
    let m = inst.sets().len();
    let mut scratch = Scratch::default();
    let mut current = starting_tour(inst, start, &mut rng);
    let initial_cost = inst.tour_cost(&current);
    let mut current_cost = improve(inst, near, &mut current, &mut scratch, None);
    let mut best = current.clone();
    let mut best_cost = current_cost;
    let mut found_s = clock.seconds();
    if m < 3 {
        return TrialResult {
            tour: best,
            cost: best_cost,
            found_s,
            initial_cost,
            iterations: 0,
        };
    }

    let mut arms = Arms::new();
    let max_removals = ((0.3 * m as f64).round() as usize).clamp(1, 100).min(m - 1);
    let min_removals = if max_removals > 1 { 2 } else { 1 };
    let warm_scale = if start.is_some() { 0.3 } else { 1.0 };
    let mut last_improvement = 0u64;
    let mut iterations = 0u64;
    let mut candidate = Vec::with_capacity(m);
    let mut arcs = vec![(0u32, 0u32); m];
    for it in 0..budget {
        if clock.expired() || it - last_improvement > budget / 2 {
            break;
        }
        iterations += 1;
        let progress = it as f64 / budget as f64;
        let worse = warm_scale * START_WORSE * (END_WORSE / START_WORSE).powf(progress);
        let temperature = worse * current_cost as f64 / std::f64::consts::LN_2;

        let a = arms.pick(&mut rng);
        let k = min_removals + rng.below(max_removals - min_removals + 1);
        candidate.clear();
        candidate.extend_from_slice(&current);
        let removed = remove(inst, &mut candidate, k, arms.arms[a].removal, &mut rng);
        let mean_edge = current_cost as f64 / m as f64;
        insert(
            inst,
            &mut candidate,
            removed,
            arms.arms[a].noise * mean_edge,
            &mut rng,
        );
        let touched = changed_sets(inst, &current, &candidate, &mut arcs);
        let cost = improve(inst, near, &mut candidate, &mut scratch, Some(&touched));

        arms.uses[a] += 1;
        if cost < best_cost {
            best_cost = cost;
            best.clone_from(&candidate);
            found_s = clock.seconds();
            last_improvement = it;
            arms.score[a] += 3.0;
        }
        let accept = cost <= current_cost
            || (temperature > 0.0
                && rng.unit() < (-((cost - current_cost) as f64) / temperature).exp());
        if accept {
            arms.score[a] += if cost < current_cost { 1.0 } else { 0.3 };
            std::mem::swap(&mut current, &mut candidate);
            current_cost = cost;
        }
        if (it + 1) % SEGMENT == 0 {
            arms.end_segment();
        }
    }
    TrialResult {
        tour: best,
        cost: best_cost,
        found_s,
        initial_cost,
        iterations,
    }
}

/// A trial's first tour: at random, or for a warm start the best tour
/// shaken hard (the search then stays near it).
fn starting_tour(inst: &Instance, start: Option<&[u32]>, rng: &mut Rng) -> Vec<u32> {
    match start {
        Some(tour) => {
            let mut tour = tour.to_vec();
            let k = (inst.sets().len() * 3 / 10).max(1);
            let removed = remove(inst, &mut tour, k, Removal::Random, rng);
            insert(inst, &mut tour, removed, 0.0, rng);
            tour
        }
        None => random_insertion(inst, rng),
    }
}

/// The removal and noise arms of the adaptive search, each picked in
/// proportion to its weight; a segment's scores move the weights.
struct Arms {
    arms: Vec<Arm>,
    weight: Vec<f64>,
    score: Vec<f64>,
    uses: Vec<u32>,
}

impl Arms {
    fn new() -> Self {
        let arms: Vec<Arm> = Removal::ALL
            .iter()
            .flat_map(|&removal| {
                NOISE_LEVELS
                    .iter()
                    .map(move |&noise| Arm { removal, noise })
            })
            .collect();
        let n = arms.len();
        Self {
            arms,
            weight: vec![1.0; n],
            score: vec![0.0; n],
            uses: vec![0; n],
        }
    }

    fn pick(&self, rng: &mut Rng) -> usize {
        pick_arm(&self.weight, rng)
    }

    /// A segment's end: each used arm's weight moves toward its recent
    /// score per use.
    fn end_segment(&mut self) {
        for i in 0..self.arms.len() {
            if self.uses[i] > 0 {
                let recent = self.score[i] / self.uses[i] as f64;
                self.weight[i] = ((1.0 - REACTION) * self.weight[i] + REACTION * recent).max(0.05);
            }
            self.score[i] = 0.0;
            self.uses[i] = 0;
        }
    }
}

/// Sets whose chosen vertex or outgoing arc differs between two tours,
/// with their successors (whose incoming arc changed).
fn changed_sets(inst: &Instance, old: &[u32], new: &[u32], arcs: &mut [(u32, u32)]) -> Vec<usize> {
    let set = |v: u32| inst.set_of(v).expect("tour vertices are in sets");
    for (i, &v) in old.iter().enumerate() {
        arcs[set(v)] = (v, old[(i + 1) % old.len()]);
    }
    let mut changed = Vec::new();
    for (i, &v) in new.iter().enumerate() {
        let next = new[(i + 1) % new.len()];
        if arcs[set(v)] != (v, next) {
            changed.push(set(v));
            changed.push(set(next));
        }
    }
    changed
}

/// Roulette-wheel choice by weight.
fn pick_arm(weight: &[f64], rng: &mut Rng) -> usize {
    let total: f64 = weight.iter().sum();
    let mut x = rng.unit() * total;
    for (i, &w) in weight.iter().enumerate() {
        if x < w {
            return i;
        }
        x -= w;
    }
    weight.len() - 1
}
