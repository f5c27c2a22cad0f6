//! End-to-end tests of `postflight coverage` against the simulator's true
//! coverage (truth.json: true poses, the true mesh, the true blur).

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::process::Output;

use crate::common::*;
use serde_json::Value;

type Voxel = [i64; 3];

/// Simulated and ingested flight: (sim dir, run dir).
fn ingested_flight(dir: &Path, name: &str, sim_args: &[&str]) -> (PathBuf, PathBuf) {
    let sim = simulate_into(dir, name, sim_args);
    let run = dir.join(format!("{name}-run"));
    ingest_ok(&sim.join("flight.mcap"), &run, &[]);
    (sim, run)
}

fn coverage(run: &Path, args: &[&str]) -> Output {
    let mut all = vec!["coverage", "--run", run.to_str().unwrap()];
    all.extend_from_slice(args);
    postflight(&all, run.parent().unwrap())
}

fn coverage_ok(run: &Path, args: &[&str]) {
    let out = coverage(run, args);
    assert!(out.status.success(), "coverage failed: {}", stderr(&out));
}

/// One row of coverage.parquet.
#[derive(Debug)]
struct Row {
    planned: Option<bool>,
    inspected: bool,
    uninspectable: bool,
    reason: Option<String>,
}

fn rows(path: &Path) -> HashMap<Voxel, Row> {
    let df = read_parquet(path);
    let int = |c: &str| df.column(c).unwrap().i32().unwrap().clone();
    let boolean = |c: &str| df.column(c).unwrap().bool().unwrap().clone();
    let (x, y, z) = (int("voxel_x"), int("voxel_y"), int("voxel_z"));
    let (planned, inspected, uninspectable) = (
        boolean("planned"),
        boolean("inspected"),
        boolean("uninspectable"),
    );
    let reason = df.column("reason").unwrap().str().unwrap().clone();
    (0..df.height())
        .map(|i| {
            let v = [x.get(i), y.get(i), z.get(i)].map(|c| i64::from(c.unwrap()));
            let row = Row {
                planned: planned.get(i),
                inspected: inspected.get(i).unwrap(),
                uninspectable: uninspectable.get(i).unwrap(),
                reason: reason.get(i).map(str::to_owned),
            };
            (v, row)
        })
        .collect()
}

fn truth_voxels(sim: &Path) -> HashMap<Voxel, Value> {
    let truth = read_json(&sim.join("truth.json"));
    truth["coverage"]["voxels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| {
            let k = [0, 1, 2].map(|a| v["voxel"][a].as_i64().unwrap());
            (k, v.clone())
        })
        .collect()
}

/// Coverage of a flight of `scene` (default but for `extra` simulator
/// arguments) agrees with the simulator's own account of what its frames
/// inspected, voxel for voxel.
fn coverage_matches_the_simulators_true_coverage(scene: &str, extra: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let args = [&["--scene", scene, "--seed", "1"], extra].concat();
    let (sim, run) = ingested_flight(dir.path(), scene, &args);
    let plan = sim.join("plan.json");
    coverage_ok(&run, &["--plan", plan.to_str().unwrap()]);
    let truth = truth_voxels(&sim);
    let ours = rows(&run.join("coverage.parquet"));
    assert_eq!(ours.len(), truth.len(), "{scene}: one row per target voxel");

    let mut disagree: BTreeMap<String, usize> = BTreeMap::new();
    let (mut inspected_agree, mut planned_agree) = (0, 0);
    let (mut skipped_gaps, mut skipped_found) = (0, 0);
    for (k, t) in &truth {
        let o = &ours[k];
        if o.inspected == t["inspected"].as_bool().unwrap() {
            inspected_agree += 1;
        } else {
            let why = match &o.reason {
                Some(r) => format!("we missed: {r}"),
                None => "we inspected".into(),
            };
            *disagree.entry(why).or_default() += 1;
        }
        planned_agree += usize::from(o.planned == t["planned"].as_bool());
        if t["skipped_gap"].as_bool().unwrap() {
            skipped_gaps += 1;
            skipped_found += usize::from(!o.inspected && !o.uninspectable);
        }
    }
    let n = truth.len() as f64;
    println!(
        "{scene}: inspected agrees on {inspected_agree} of {} voxels ({:.2}%), planned on {planned_agree}; disagreements {disagree:?}; skipped-segment gaps found {skipped_found} of {skipped_gaps}",
        truth.len(),
        100.0 * inspected_agree as f64 / n
    );
    assert!(inspected_agree as f64 >= 0.99 * n, "{scene}: {disagree:?}");
    assert!(planned_agree as f64 >= 0.99 * n, "{scene}: planned");
    assert!(skipped_gaps > 20, "{scene}: the skipped segment left gaps");
    assert_eq!(skipped_found, skipped_gaps, "{scene}: skipped-segment gaps");

    // The summary agrees with the table.
    let s = read_json(&run.join("coverage.json"));
    let count = |f: &dyn Fn(&Row) -> bool| ours.values().filter(|r| f(r)).count() as u64;
    assert_eq!(s["target_voxels"], truth.len());
    assert_eq!(s["inspected_voxels"], count(&|r| r.inspected));
    assert_eq!(s["planned_voxels"], count(&|r| r.planned == Some(true)));
    assert_eq!(s["uninspectable_voxels"], count(&|r| r.uninspectable));
    assert_eq!(
        s["gap_voxels"],
        count(&|r| !r.inspected && !r.uninspectable)
    );
    assert_close(
        f(&s["inspected_pct"]),
        100.0 * count(&|r| r.inspected) as f64 / n,
        1e-9,
        "inspected_pct",
    );
    let pct = f(&s["face_area_coverage_pct"]);
    assert!(pct > 0.0 && pct < 100.0, "{pct}");
    assert!(f(&s["planned_inspected_pct"]) < 100.0);
    // The fast segment blurred frames, and coverage saw it.
    assert!(s["shots_blurred"].as_u64().unwrap() > 0);
}

#[test]
fn coverage_matches_the_simulators_true_coverage_on_a_bridge_flight() {
    coverage_matches_the_simulators_true_coverage("girder-bridge", &[]);
}

#[test]
fn coverage_matches_the_simulators_true_coverage_with_a_gimballed_camera() {
    // The gimbal looks straight down over the deck's top: the frames' poses
    // come from /tf's moving camera link, the plan's from its gimbal pitch.
    // A frame at every viewpoint, so each face's verdict rests on its
    // planned views rather than on a thinned few.
    let args = [
        "--gimbal", "--frames", "700", "--width", "320", "--height", "240", "--focal", "960",
    ];
    coverage_matches_the_simulators_true_coverage("girder-bridge", &args);
    // The deck's top was seen from above, which a fixed camera never does.
    let sim = simulated(&[&["--scene", "girder-bridge", "--seed", "1"], &args[..]].concat());
    let truth = truth_voxels(&sim);
    let seen_from_above = truth
        .values()
        .filter(|v| {
            let faces = v["faces"].as_array().unwrap();
            faces
                .iter()
                .any(|f| f["face"] == "+z" && f["views"].as_u64() > Some(0))
        })
        .count();
    assert!(
        seen_from_above > 200,
        "{seen_from_above} voxels seen from above"
    );
}

#[test]
fn coverage_matches_the_simulators_true_coverage_on_a_tower_flight() {
    coverage_matches_the_simulators_true_coverage("tower", &[]);
}

#[test]
fn a_plan_is_checked_before_anyone_flies_it() {
    let dir = tempfile::tempdir().unwrap();
    let (sim, run) = ingested_flight(dir.path(), "tower", &["--scene", "tower", "--frames", "80"]);
    let plan_path = sim.join("plan.json");
    let plan = plan_path.to_str().unwrap();
    // Only the viewpoints the flight skipped: a follow-up for that segment.
    let truth = read_json(&sim.join("truth.json"));
    let mut follow_up = read_json(&plan_path);
    let skipped: Vec<usize> = truth["skipped_viewpoints"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| i.as_u64().unwrap() as usize)
        .collect();
    let all = follow_up["viewpoints"].as_array().unwrap().clone();
    follow_up["viewpoints"] = skipped.iter().map(|i| all[*i].clone()).collect();
    let follow_up_path = dir.path().join("follow-up.json");
    std::fs::write(&follow_up_path, follow_up.to_string()).unwrap();
    coverage_ok(
        &run,
        &[
            "--plan",
            plan,
            "--viewpoints",
            follow_up_path.to_str().unwrap(),
        ],
    );
    // The flight's own coverage is untouched by a plan check.
    assert!(!run.join("coverage.json").exists());
    let checked = rows(&run.join("coverage-viewpoints.parquet"));
    let truth = truth_voxels(&sim);
    // Every voxel the skipped viewpoints truly inspect (whatever the
    // flight did) is inspected by the check, give or take the cone edges.
    let (mut seen, mut agree) = (0, 0);
    for (k, t) in &truth {
        let by_skipped = t["faces"]
            .as_array()
            .unwrap()
            .iter()
            .any(|f| f["skipped_views"].as_u64().unwrap() > 0);
        seen += usize::from(by_skipped);
        agree += usize::from(by_skipped && checked[k].inspected);
    }
    assert!(seen > 20);
    assert!(agree as f64 >= 0.98 * seen as f64, "{agree} of {seen}");
    let s = read_json(&run.join("coverage-viewpoints.json"));
    assert_eq!(s["shots_total"], skipped.len());
}

#[test]
fn settings_come_from_the_config_file_and_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let (sim, run) = ingested_flight(dir.path(), "tower", &["--scene", "tower", "--frames", "40"]);
    let plan = sim.join("plan.json");
    let config = dir.path().join("postflight.toml");
    std::fs::write(
        &config,
        "[view]\nmax_distance_m = 4.0\ncone_apex_deg = 30.0\n[coverage]\nexposure_s = 0.01\n",
    )
    .unwrap();
    let args = |extra: &[&'static str]| {
        let mut a = vec![
            "--plan".to_string(),
            plan.to_str().unwrap().into(),
            "--config".into(),
            config.to_str().unwrap().into(),
        ];
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    };
    let run_with = |extra: &[&'static str]| {
        let a = args(extra);
        let refs: Vec<&str> = a.iter().map(String::as_str).collect();
        coverage_ok(&run, &refs);
        read_json(&run.join("coverage.json"))["view"].clone()
    };
    let view = run_with(&[]);
    assert_eq!(view["max_distance_m"], 4.0);
    assert_eq!(view["cone_apex_deg"], 30.0);
    // Unset ones keep the plan's (GATSBI's defaults).
    assert_eq!(view["min_distance_m"], 2.0);
    let view = run_with(&["--max-distance", "4.5", "--views", "2"]);
    assert_eq!(view["max_distance_m"], 4.5);
    assert_eq!(view["views_required"], 2);

    // A typo in the config is named, not ignored.
    std::fs::write(&config, "[view]\nmax_distnce_m = 4.0\n").unwrap();
    let out = coverage(
        &run,
        &[
            "--plan",
            plan.to_str().unwrap(),
            "--config",
            config.to_str().unwrap(),
        ],
    );
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("max_distnce_m"), "{}", stderr(&out));
}

#[test]
fn targets_from_boxes_or_a_segmented_cloud() {
    let dir = tempfile::tempdir().unwrap();
    let (sim, run) = ingested_flight(dir.path(), "tower", &["--scene", "tower", "--frames", "40"]);
    let plan = read_json(&sim.join("plan.json"));
    let targets: Vec<Voxel> = plan["target_voxels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| [0, 1, 2].map(|a| v[a].as_i64().unwrap()))
        .collect();
    let res = f(&plan["resolution"]);
    // A segmented cloud: one point at each target voxel's centre.
    let cloud = dir.path().join("structure.ply");
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
        targets.len()
    );
    for v in &targets {
        let c = v.map(|i| (i as f64 + 0.5) * res);
        ply.push_str(&format!("{} {} {}\n", c[0], c[1], c[2]));
    }
    std::fs::write(&cloud, ply).unwrap();
    coverage_ok(&run, &["--target-cloud", cloud.to_str().unwrap()]);
    let from_cloud = rows(&run.join("coverage.parquet"));
    assert_eq!(from_cloud.len(), targets.len());
    assert!(targets.iter().all(|v| from_cloud.contains_key(v)));
    // Without a plan nothing is planned.
    assert!(from_cloud.values().all(|r| r.planned.is_none()));
    let s = read_json(&run.join("coverage.json"));
    assert!(s["planned_voxels"].is_null());

    // A box filter around the tower (its targets' extent, and a margin).
    let lo = [0, 1, 2].map(|a| targets.iter().map(|v| v[a]).min().unwrap() as f64 * res - 0.3);
    let hi =
        [0, 1, 2].map(|a| (targets.iter().map(|v| v[a]).max().unwrap() + 1) as f64 * res + 0.3);
    let boxes = dir.path().join("boxes.json");
    std::fs::write(
        &boxes,
        serde_json::json!([{ "min": lo, "max": hi }]).to_string(),
    )
    .unwrap();
    coverage_ok(&run, &["--target-boxes", boxes.to_str().unwrap()]);
    let from_boxes = rows(&run.join("coverage.parquet"));
    let shared = targets
        .iter()
        .filter(|v| from_boxes.contains_key(*v))
        .count();
    assert!(
        shared as f64 >= 0.95 * targets.len() as f64,
        "{shared} of {} plan targets are occupied map voxels in the box",
        targets.len()
    );

    // Boxes nowhere near the map: said so, nothing written.
    std::fs::write(&boxes, r#"[{"min": [500, 500, 0], "max": [510, 510, 10]}]"#).unwrap();
    let out = coverage(&run, &["--target-boxes", boxes.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("hold no voxel"), "{}", stderr(&out));
    assert!(!run.join("coverage.json").exists());
    // No targets at all.
    let out = coverage(&run, &[]);
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("--target-boxes"), "{}", stderr(&out));
}

#[test]
fn bad_inputs_fail_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let (sim, run) = ingested_flight(dir.path(), "tower", &["--scene", "tower", "--frames", "40"]);
    let plan = sim.join("plan.json");
    let plan = plan.to_str().unwrap();
    // The map moved 100 m (another frame): said so, nothing written.
    let bytes = std::fs::read(sim.join("map.ply")).unwrap();
    let header_end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let mut shifted = bytes[..header_end].to_vec();
    for point in bytes[header_end..].chunks_exact(12) {
        let x = f32::from_le_bytes(point[..4].try_into().unwrap()) + 100.0;
        shifted.extend_from_slice(&x.to_le_bytes());
        shifted.extend_from_slice(&point[4..]);
    }
    let moved = dir.path().join("moved.ply");
    std::fs::write(&moved, shifted).unwrap();
    let out = coverage(&run, &["--plan", plan, "--map", moved.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let err = stderr(&out);
    assert!(err.contains("do not overlap the map"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(!run.join("coverage.json").exists());
    // A distance band upside down.
    let out = coverage(
        &run,
        &["--plan", plan, "--min-distance", "5", "--max-distance", "2"],
    );
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("distance band"), "{}", stderr(&out));
    // The same map file as recorded gives the recorded map's result.
    coverage_ok(&run, &["--plan", plan]);
    let recorded = read_json(&run.join("coverage.json"));
    coverage_ok(
        &run,
        &[
            "--plan",
            plan,
            "--map",
            sim.join("map.ply").to_str().unwrap(),
        ],
    );
    let from_file = read_json(&run.join("coverage.json"));
    assert_eq!(recorded["inspected_voxels"], from_file["inspected_voxels"]);
    assert_eq!(recorded["gap_voxels"], from_file["gap_voxels"]);
}
