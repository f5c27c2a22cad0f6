//! `postflight compare` on a simulated repeat inspection: the earlier
//! flight, then the same structure flown again with grown and new cracks
//! and another SLAM frame (0.5 m and 10 degrees off); the registration and
//! the classification checked against the simulator's truth. The tower: a
//! silo fits many yaws, and its flights see some thirty cracks from close.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::common::*;
use nalgebra::{Point3, Vector3};
use serde_json::Value;

const REPEAT: [&str; 7] = [
    "--seed",
    "2",
    "--grow",
    "0.3",
    "--new",
    "5",
    "--frame-offset=0.5,0,0,10",
];

/// `postflight compare --before a --after b`.
fn compare(a: &Path, b: &Path) -> std::process::Output {
    compare_with(a, b, &[])
}

/// The same, with more arguments.
fn compare_with(a: &Path, b: &Path, more: &[&str]) -> std::process::Output {
    let mut args = vec![
        "compare",
        "--before",
        a.to_str().unwrap(),
        "--after",
        b.to_str().unwrap(),
    ];
    args.extend(more);
    postflight(&args, a.parent().unwrap())
}

/// The flight `simulate` makes with `sim_args` through detect (shared with
/// the other tests that fly it), localise and coverage: all that compare
/// reads of the earlier run.
fn surveyed(dir: &Path, name: &str, sim_args: &[&str]) -> PathBuf {
    let run = detected_into(dir, name, sim_args);
    let plan = simulated(sim_args).join("plan.json");
    for stage in ["localise", "coverage"] {
        let args = [
            stage,
            "--run",
            run.to_str().unwrap(),
            "--plan",
            plan.to_str().unwrap(),
        ];
        let out = postflight(&args, dir);
        assert!(out.status.success(), "{}", stderr(&out));
    }
    run
}

/// Crack ids seen whole (90% of it in view at least) from 5 m or closer,
/// as the flight's truth has it: what a flight can measure.
fn seen_close(truth: &Value) -> std::collections::BTreeSet<u64> {
    let centroids: BTreeMap<u64, Point3<f64>> = crack_points(truth)
        .into_iter()
        .map(|(id, points)| {
            let sum: Vector3<f64> = points.iter().map(|p| p.coords).sum();
            (id, Point3::from(sum / points.len() as f64))
        })
        .collect();
    let mut seen = std::collections::BTreeSet::new();
    for frame in truth["frames"].as_array().unwrap() {
        if frame["dropped"].as_bool().unwrap() {
            continue;
        }
        let camera = Point3::from(vec3(&frame["camera_pose"]["translation"]));
        for c in frame["cracks"].as_array().unwrap() {
            let id = c["id"].as_u64().unwrap();
            if f(&c["visible_fraction"]) >= 0.9 && (centroids[&id] - camera).norm() <= 5.0 {
                seen.insert(id);
            }
        }
    }
    seen
}

/// Every truth crack's points (centre lines and branches).
fn crack_points(truth: &Value) -> BTreeMap<u64, Vec<Point3<f64>>> {
    truth["cracks"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            let points = c["lines"]
                .as_array()
                .unwrap()
                .iter()
                .flat_map(|l| l.as_array().unwrap().iter().map(|p| Point3::from(vec3(p))))
                .collect();
            (c["id"].as_u64().unwrap(), points)
        })
        .collect()
}

/// The candidate of a run on each truth crack: the nearest to its centre
/// line, within 0.3 m.
fn candidates_on_cracks(truth: &Value, run: &Path) -> BTreeMap<u64, String> {
    let cracks = crack_points(truth);
    let defects = read_json(&run.join("defects.json"));
    let mut on: BTreeMap<u64, (f64, String)> = BTreeMap::new();
    for d in defects["defects"].as_array().unwrap() {
        let p = Point3::from(vec3(&d["position"]));
        let nearest = cracks
            .iter()
            .map(|(id, points)| {
                let gap = points
                    .iter()
                    .map(|q| (q - p).norm())
                    .fold(f64::INFINITY, f64::min);
                (gap, *id)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0));
        if let Some((gap, crack)) = nearest.filter(|(gap, _)| *gap <= 0.3) {
            let best = on.entry(crack).or_insert((f64::INFINITY, String::new()));
            if gap < best.0 {
                *best = (gap, d["id"].as_str().unwrap().to_string());
            }
        }
    }
    on.into_iter().map(|(crack, (_, id))| (crack, id)).collect()
}

/// The cracks a flight had in view in any frame it kept.
fn in_view(truth: &Value) -> std::collections::BTreeSet<u64> {
    truth["frames"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| !f["dropped"].as_bool().unwrap())
        .flat_map(|f| {
            f["cracks"]
                .as_array()
                .unwrap()
                .iter()
                .map(|c| c["id"].as_u64().unwrap())
        })
        .collect()
}

#[test]
fn a_repeat_inspection_is_registered_and_its_changes_classified_against_truth() {
    let earlier_args = ["--scene", "tower"];
    let earlier = simulated(&earlier_args);
    let mut args = vec!["--scene", "tower", "--repeat-of", earlier.to_str().unwrap()];
    args.extend(REPEAT);
    let later = simulated(&args);
    let dir = tempfile::tempdir().unwrap();
    let a = surveyed(dir.path(), "a", &earlier_args);
    let b = dir.path().join("b");
    run_simulated(&later, &b);
    let out = compare(&a, &b);
    assert!(out.status.success(), "{}", stderr(&out));
    eprintln!("{}", String::from_utf8_lossy(&out.stdout));
    let changes = read_json(&b.join("changes.json"));
    let (truth_a, truth_b) = (
        read_json(&earlier.join("truth.json")),
        read_json(&later.join("truth.json")),
    );

    // Registration against the frame change the simulator applied.
    let estimated = pose(&changes["registration"]["transform"]);
    let truth = pose(&truth_b["repeat"]["earlier_to_this"]);
    let (shift, turn) = pose_error(&estimated, &truth);
    eprintln!(
        "registration error: {:.1} mm, {:.3} deg",
        shift * 1000.0,
        turn
    );
    assert!(
        shift < 0.05 && turn < 0.5,
        "registration off by {shift} m, {turn} deg"
    );

    // The later run's report says what changed, with the crack before and
    // now side by side, and lists the changes that stand out (new, first
    // seen, grown, widened) first.
    let report = std::fs::read_to_string(b.join("report.html")).unwrap();
    assert!(
        report.contains("Changes since 2025-06-15"),
        "no changes section"
    );
    let first: std::collections::BTreeSet<String> = changes["changes"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| {
            ["new", "first_seen", "grown", "widened"].contains(&c["change"].as_str().unwrap())
        })
        .map(|c| c["after"].as_str().unwrap().to_string())
        .collect();
    assert!(
        report.matches("alt=\"the crack before\"").count()
            >= changes["counts"]["grown"].as_u64().unwrap() as usize
    );
    let order = read_csv(&b.join("candidates.csv"));
    let ids: Vec<String> = order
        .column("id")
        .unwrap()
        .str()
        .unwrap()
        .iter()
        .flatten()
        .map(str::to_string)
        .collect();
    assert_eq!(
        ids[..first.len()]
            .iter()
            .cloned()
            .collect::<std::collections::BTreeSet<_>>(),
        first,
        "changes that stand out come first in the review order"
    );

    // Each truth crack's class: by the later candidate on it, or for one
    // the later flight did not see, by the earlier candidate on it.
    let class_after: BTreeMap<String, String> = changes["changes"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|c| {
            Some((
                c["after"].as_str()?.to_string(),
                c["change"].as_str()?.to_string(),
            ))
        })
        .collect();
    let class_before: BTreeMap<String, String> = changes["changes"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["after"].is_null())
        .filter_map(|c| {
            Some((
                c["before"].as_str()?.to_string(),
                c["change"].as_str()?.to_string(),
            ))
        })
        .collect();
    let (on_a, on_b) = (
        candidates_on_cracks(&truth_a, &a),
        candidates_on_cracks(&truth_b, &b),
    );
    let (close_a, close_b) = (seen_close(&truth_a), seen_close(&truth_b));
    let seen_b = in_view(&truth_b);
    // A crack the earlier flight never had in view is never called new.
    let seen_a = in_view(&truth_a);
    let unseen_old_called_new: Vec<u64> = truth_b["repeat"]["changes"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["change"] != "new")
        .map(|c| c["id"].as_u64().unwrap())
        .filter(|id| !seen_a.contains(id))
        .filter(|id| {
            on_b.get(id)
                .and_then(|c| class_after.get(c))
                .map(String::as_str)
                == Some("new")
        })
        .collect();
    assert!(
        unseen_old_called_new.is_empty(),
        "cracks the earlier flight never had in view called new: {unseen_old_called_new:?}"
    );
    let mut tally: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    for change in truth_b["repeat"]["changes"].as_array().unwrap() {
        let id = change["id"].as_u64().unwrap();
        let truth_class = change["change"].as_str().unwrap();
        let (expected, ours) = match truth_class {
            "new" if close_b.contains(&id) => {
                ("new", on_b.get(&id).and_then(|c| class_after.get(c)))
            }
            "grown" | "unchanged" if close_a.contains(&id) && close_b.contains(&id) => {
                (truth_class, on_b.get(&id).and_then(|c| class_after.get(c)))
            }
            // The later flight never had it in view (and found nothing there).
            _ if close_a.contains(&id)
                && !seen_b.contains(&id)
                && !on_b.contains_key(&id)
                && on_a.contains_key(&id) =>
            {
                (
                    "not_reinspected",
                    on_a.get(&id).and_then(|c| class_before.get(c)),
                )
            }
            _ => continue,
        };
        let t = tally.entry(expected.to_string()).or_default();
        t.1 += 1;
        // A new crack where the earlier flight did not look is first seen.
        let right = match ours.map(String::as_str) {
            Some("first_seen") => expected == "new",
            ours => ours == Some(expected),
        };
        if right {
            t.0 += 1;
        } else {
            eprintln!("crack {id}: truth {expected}, classified {ours:?}");
        }
    }
    let (right, all) = tally.values().fold((0, 0), |s, t| (s.0 + t.0, s.1 + t.1));
    eprintln!("classified right, by truth class: {tally:?}; {right} of {all}");
    assert!(all >= 20, "too few cracks to judge: {tally:?}");
    assert!(
        right as f64 >= 0.9 * all as f64,
        "{right} of {all} right: {tally:?}"
    );
    for kind in ["new", "grown", "unchanged"] {
        assert!(
            tally.get(kind).is_some_and(|t| t.1 > 0),
            "no {kind} crack judged: {tally:?}"
        );
    }
    element_records_then_and_now(&a, &b, dir.path());
}

/// With an element record in both runs (the silo recorded as a wall, its
/// quantity the metres around it), compare pairs their rows and says what
/// moved between states, as both runs' elements.parquet hold them.
fn element_records_then_and_now(a: &Path, b: &Path, dir: &Path) {
    for run in [a, b] {
        let r = run.to_str().unwrap();
        let args = [
            "record",
            "--run",
            r,
            "--element",
            "{pattern = \"*\", number = 210}",
        ];
        let out = postflight(&args, dir);
        assert!(out.status.success(), "{}", stderr(&out));
    }
    let out = compare(a, b);
    assert!(out.status.success(), "{}", stderr(&out));
    let said = stdout(&out);
    let changes = read_json(&b.join("changes.json"));
    let pairs = changes["elements"].as_array().unwrap();
    let states = |run: &Path| {
        let t = read_parquet(&run.join("elements.parquet"));
        let col = |name: &str| -> Vec<f64> {
            t.column(name)
                .unwrap()
                .f64()
                .unwrap()
                .into_no_null_iter()
                .collect()
        };
        let (cs1, cs2, cs3, cs4) = (col("cs1"), col("cs2"), col("cs3"), col("cs4"));
        (0..t.height())
            .map(|i| serde_json::json!([cs1[i], cs2[i], cs3[i], cs4[i]]))
            .collect::<Vec<Value>>()
    };
    let (before, after) = (states(a), states(b));
    assert_eq!(pairs.len(), after.len(), "{pairs:?}");
    let now: Vec<Value> = pairs.iter().map(|p| p["after"].clone()).collect();
    assert_eq!(now, after);
    let then: Vec<Value> = pairs.iter().map(|p| p["before"].clone()).collect();
    assert_eq!(
        then[..before.len().min(then.len())],
        before[..before.len().min(then.len())]
    );
    // The cracks grew and new ones opened: more of the silo is in a state
    // above 1 now, and compare says so.
    let above_one = |s: &Value| 1.0 - f(&s[0]) / s.as_array().unwrap().iter().map(f).sum::<f64>();
    assert!(
        above_one(&after[0]) > above_one(&before[0]),
        "{before:?} -> {after:?}"
    );
    assert!(
        said.contains("tower, Reinforced Concrete Pier Wall: condition state"),
        "{said}"
    );
    let report = std::fs::read_to_string(b.join("report.html")).unwrap();
    assert!(report.contains("Element record, then and now"));
}

/// Compare refuses maps of different structures, leaving nothing behind.
#[test]
fn runs_of_different_structures_are_refused_with_the_overlap_they_have() {
    let bridge = simulated(&["--frames", "40"]);
    let tower = simulated(&["--frames", "40", "--scene", "tower"]);
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    run_simulated(&bridge, &a);
    run_simulated(&tower, &b);
    let out = compare(&a, &b);
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(
        e.contains("overlap in only") && e.contains("same structure"),
        "{e}"
    );
    assert_eq!(e.trim().lines().count(), 1, "{e}");
    assert!(!b.join("changes.json").exists());
}

#[test]
fn a_link_distance_that_cannot_match_is_refused_as_given() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("postflight.toml");
    std::fs::write(&config, "[compare]\nlink_distance_m = inf\n").unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let out = compare_with(&a, &b, &["--config", config.to_str().unwrap()]);
    assert_fails_in_one_line(&out, "[compare] link_distance_m");
    let out = compare_with(&a, &b, &["--link-distance=-0.5"]);
    assert_fails_in_one_line(&out, "--link-distance must be 0 or more metres");
}
