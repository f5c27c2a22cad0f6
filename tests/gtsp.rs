//! `postflight gtsp` on the shipped benchmark instances: every tour visits
//! each set once and costs what an independent reader of the file
//! (tests/fixtures/gtsp/tour_cost.py) says it costs; small instances reach
//! their published best-known costs; an asymmetric instance is solved to
//! the optimum found by brute force; bad files get line-numbered errors.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use crate::common::*;
use serde_json::Value;

/// (file, best known, time limit in seconds, largest accepted gap in %).
const INSTANCES: [(&str, i64, f64, f64); 7] = [
    ("tiny.gtsp", 9, 2.0, 0.0),
    ("11berlin52.txt", 4040, 2.0, 0.0),
    ("20kroA100.txt", 9711, 2.0, 0.0),
    ("39rat195.gtsp", 854, 2.0, 0.0),
    ("40kroa200.txt", 13406, 3.0, 0.0),
    ("89pcb442.txt", 21657, 5.0, 0.5),
    ("107si535.gtsp", 13502, 5.0, 0.5),
];

fn fixture(name: &str) -> PathBuf {
    root().join("tests/fixtures/gtsp").join(name)
}

fn solve(path: &Path, args: &[&str], home: &Path) -> Value {
    let mut all = vec!["gtsp", path.to_str().unwrap()];
    all.extend_from_slice(args);
    let out = postflight(&all, home);
    assert!(
        out.status.success(),
        "gtsp {}: {}",
        path.display(),
        stderr(&out)
    );
    serde_json::from_slice(&out.stdout).expect("gtsp prints one JSON object")
}

/// The tour's cost and visits per set, by the independent Python reader.
fn python_check(path: &Path, tour: &Value) -> (i64, Vec<i64>) {
    let mut child = Command::new(python())
        .arg(fixture("tour_cost.py"))
        .arg(path)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run tour_cost.py");
    child
        .stdin
        .take()
        .unwrap()
        .write_all(tour.to_string().as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "tour_cost.py: {}", stderr(&out));
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    let visits = v["sets_visited"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_i64().unwrap())
        .collect();
    (v["cost"].as_i64().unwrap(), visits)
}

#[test]
fn tours_on_every_shared_instance_are_valid_and_near_the_best_known() {
    let home = tempfile::tempdir().unwrap();
    for (file, best, seconds, max_gap_pct) in INSTANCES {
        let path = fixture(file);
        let limit = seconds.to_string();
        let got = solve(
            &path,
            &["--time-limit", &limit, "--threads", "2"],
            home.path(),
        );
        let cost = got["cost"].as_i64().unwrap();
        let (recomputed, visits) = python_check(&path, &got["tour"]);
        assert_eq!(recomputed, cost, "{file}: reported cost is the tour's cost");
        assert!(
            visits.iter().all(|&k| k == 1),
            "{file}: one vertex per set: {visits:?}"
        );
        assert_eq!(
            got["tour"].as_array().unwrap().len(),
            visits.len(),
            "{file}"
        );
        let gap = 100.0 * (cost - best) as f64 / best as f64;
        assert!(
            cost >= best,
            "{file}: {cost} beats the proven optimum {best}: costs are wrong"
        );
        assert!(
            gap <= max_gap_pct,
            "{file}: cost {cost}, best known {best}, gap {gap:.3}%"
        );
        let time_s = got["time_s"].as_f64().unwrap();
        assert!(
            time_s <= seconds + 0.1,
            "{file}: {time_s} s over the {seconds} s limit"
        );
        eprintln!("{file}: {cost} (best {best}, gap {gap:.3}%) in {time_s:.2} s");
    }
}

#[test]
fn the_time_limit_is_a_hard_bound_and_a_seed_repeats_its_tour() {
    let home = tempfile::tempdir().unwrap();
    let big = fixture("107si535.gtsp");
    let got = solve(
        &big,
        &["--time-limit", "0.3", "--threads", "2"],
        home.path(),
    );
    assert!(got["time_s"].as_f64().unwrap() <= 0.4, "{}", got["time_s"]);
    assert!(got["stats"]["timed_out"].as_bool().unwrap());
    let (cost, visits) = python_check(&big, &got["tour"]);
    assert_eq!(cost, got["cost"].as_i64().unwrap());
    assert!(visits.iter().all(|&k| k == 1));

    let small = fixture("40kroa200.txt");
    let args = ["--seed", "7", "--threads", "2"];
    let a = solve(&small, &args, home.path());
    let b = solve(&small, &args, home.path());
    assert_eq!(a["tour"], b["tour"], "same seed and threads, same tour");
}

/// Random asymmetric costs, in TSPLIB FULL_MATRIX form.
fn asymmetric_instance(dir: &Path, sets: usize, per_set: usize) -> (PathBuf, Vec<Vec<i64>>) {
    let n = sets * per_set;
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % 1000) as i64 + 1
    };
    let cost: Vec<Vec<i64>> = (0..n).map(|_| (0..n).map(|_| next()).collect()).collect();
    let mut text = format!(
        "NAME: asym\nTYPE: AGTSP\nDIMENSION: {n}\nGTSP_SETS: {sets}\nEDGE_WEIGHT_TYPE: EXPLICIT\nEDGE_WEIGHT_FORMAT: FULL_MATRIX\nEDGE_WEIGHT_SECTION\n"
    );
    for row in &cost {
        let row: Vec<String> = row.iter().map(|c| c.to_string()).collect();
        text += &(row.join(" ") + "\n");
    }
    text += "GTSP_SET_SECTION:\n";
    for s in 0..sets {
        let members: Vec<String> = (0..per_set)
            .map(|k| (s * per_set + k + 1).to_string())
            .collect();
        text += &format!("{} {} -1\n", s + 1, members.join(" "));
    }
    text += "EOF\n";
    let path = dir.join("asym.gtsp");
    std::fs::write(&path, text).unwrap();
    (path, cost)
}

/// The optimum by brute force: every order of the sets after the first,
/// and the best vertex choice for that order by dynamic programming.
fn brute_force(cost: &[Vec<i64>], sets: usize, per_set: usize) -> i64 {
    fn permutations(items: &mut Vec<usize>, k: usize, visit: &mut dyn FnMut(&[usize])) {
        if k == items.len() {
            visit(items);
            return;
        }
        for i in k..items.len() {
            items.swap(k, i);
            permutations(items, k + 1, visit);
            items.swap(k, i);
        }
    }
    let mut best = i64::MAX;
    let mut rest: Vec<usize> = (1..sets).collect();
    permutations(&mut rest, 0, &mut |order| {
        for start in 0..per_set {
            let mut layer: Vec<i64> = (0..per_set)
                .map(|k| if k == start { 0 } else { i64::MAX / 4 })
                .collect();
            let mut prev_set = 0;
            for &s in order {
                layer = (0..per_set)
                    .map(|b| {
                        (0..per_set)
                            .map(|a| layer[a] + cost[prev_set * per_set + a][s * per_set + b])
                            .min()
                            .unwrap()
                    })
                    .collect();
                prev_set = s;
            }
            let close = (0..per_set)
                .map(|a| layer[a] + cost[prev_set * per_set + a][start])
                .min()
                .unwrap();
            best = best.min(close);
        }
    });
    best
}

#[test]
fn an_asymmetric_instance_is_solved_to_the_brute_force_optimum() {
    let dir = tempfile::tempdir().unwrap();
    let (sets, per_set) = (8, 3);
    let (path, cost) = asymmetric_instance(dir.path(), sets, per_set);
    let optimum = brute_force(&cost, sets, per_set);
    let got = solve(&path, &["--time-limit", "5"], dir.path());
    assert_eq!(got["cost"].as_i64().unwrap(), optimum);
    let tour: Vec<usize> = got["tour"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap() as usize - 1)
        .collect();
    let mut seen: Vec<usize> = tour.iter().map(|v| v / per_set).collect();
    seen.sort_unstable();
    assert_eq!(seen, (0..sets).collect::<Vec<_>>());
    // Asymmetric: the cost is that of this direction of travel.
    let walked: i64 = (0..tour.len())
        .map(|i| cost[tour[i]][tour[(i + 1) % tour.len()]])
        .sum();
    assert_eq!(walked, optimum);
}

#[test]
fn malformed_instances_get_line_numbered_errors() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "bad_number.gtsp",
            "N: 3\nM: 2\n1 1 2\n2 3\n0 4 x\n4 0 5\n6 5 0\n",
            "line 5",
        ),
        (
            "short_matrix.gtsp",
            "N: 3\nM: 2\n1 1 2\n2 3\n0 4 5\n4 0 5\n",
            "line",
        ),
        (
            "unknown_vertex.gtsp",
            "NAME: t\nTYPE: GTSP\nDIMENSION: 3\nGTSP_SETS: 2\nEDGE_WEIGHT_TYPE: EUC_2D\nNODE_COORD_SECTION\n1 0 0\n2 3 0\n3 0 4\nGTSP_SET_SECTION:\n1 1 2 -1\n2 7 -1\nEOF\n",
            "line 12",
        ),
        (
            "no_sets.gtsp",
            "NAME: t\nTYPE: GTSP\nDIMENSION: 2\nEDGE_WEIGHT_TYPE: EUC_2D\nNODE_COORD_SECTION\n1 0 0\n2 3 0\nEOF\n",
            "GTSP_SET_SECTION",
        ),
    ];
    for (name, text, expect) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        let out = postflight(&["gtsp", path.to_str().unwrap()], dir.path());
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{name}: {err}");
        assert!(out.stdout.is_empty(), "{name}: no result on stdout");
        assert!(err.contains(name) && err.contains(expect), "{name}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{name}: one line: {err}");
    }
    let missing = postflight(&["gtsp", "/nonexistent/x.gtsp"], dir.path());
    assert!(
        stderr(&missing).contains("/nonexistent/x.gtsp"),
        "{}",
        stderr(&missing)
    );
}
