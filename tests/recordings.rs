//! One flight recorded as several recordings (a recording per battery
//! sortie) and run as one: `postflight run --flight DIR` gives the frames,
//! coverage and candidates of the same flight recorded once; each frame,
//! pose and camera names its recording; the report and the review queue
//! say which recordings saw each candidate. Sorties in SLAM frames of
//! their own (a SLAM system started afresh after each landing) are
//! registered onto the first sortie's map, as the simulator's truth puts
//! them. Recordings given twice, or a
//! directory without any, are refused in one line before anything is
//! written.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use crate::common::*;
use polars::prelude::*;

const WHOLE: [&str; 2] = ["--frames", "60"];
const SORTIES: [&str; 4] = ["--frames", "60", "--sorties", "3"];

fn run(flights: &[&Path], plan: &Path, out: &Path) -> std::process::Output {
    let mut args = vec!["run"];
    for f in flights {
        args.extend(["--flight", f.to_str().unwrap()]);
    }
    args.extend([
        "--plan",
        plan.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    postflight(&args, out.parent().unwrap())
}

/// A column of a run's table, as integers.
fn column(run: &Path, table: &str, name: &str) -> Vec<i64> {
    let frame = read_parquet(&run.join(table));
    let values = frame.column(name).unwrap().cast(&DataType::Int64).unwrap();
    values.i64().unwrap().into_no_null_iter().collect()
}

/// Candidates' positions.
fn candidates(run: &Path) -> Vec<[f64; 3]> {
    let frame = read_parquet(&run.join("defects.parquet"));
    let get = |c: &str| -> Vec<f64> {
        let column = frame.column(c).unwrap().f64().unwrap();
        column.into_no_null_iter().collect()
    };
    let (x, y, z) = (get("x"), get("y"), get("z"));
    (0..x.len()).map(|i| [x[i], y[i], z[i]]).collect()
}

/// The simulated flight `flags` and the same flight recorded once, each
/// run into `dir` against the whole flight's plan: (whole, recordings).
fn run_against_whole(dir: &Path, flags: &[&str]) -> (PathBuf, PathBuf, PathBuf) {
    let recorded = simulated(flags);
    let whole = simulated(&WHOLE);
    let (one, several) = (dir.join("whole"), dir.join("several"));
    let plan = whole.join("plan.json");
    let out = run(&[&whole.join("flight.mcap")], &plan, &one);
    assert!(out.status.success(), "{}", stderr(&out));
    let out = run(&[&recorded], &plan, &several);
    assert!(out.status.success(), "{}", stderr(&out));
    (recorded, one, several)
}

/// Where the simulator put recording `k`'s frame in the first's: T_first_k
/// = slam_1 * slam_k^-1 (a point of k's frame in the first's).
fn true_frame(simulated: &Path, k: usize) -> nalgebra::Isometry3<f64> {
    let truth = read_json(&simulated.join("truth.json"));
    let told = &truth["sorties"];
    pose(&told[0]["slam_from_world"]) * pose(&told[k]["slam_from_world"]).inverse()
}

/// Each later recording's placement `kind` in `run`, checked against the
/// truth within `metres` and `degrees`.
fn placed_as_truth(run: &Path, simulated: &Path, kind: &str, (metres, degrees): (f64, f64)) {
    let summary = read_json(&run.join("ingest.json"));
    for (k, r) in summary["recordings"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
        .skip(1)
    {
        let placement = &r["placement"];
        let (m, d) = pose_error(&true_frame(simulated, k), &pose(&placement["transform"]));
        eprintln!("{} {kind}: off by {m:.4} m, {d:.3} deg", r["path"]);
        assert_eq!(placement["by"]["kind"], kind, "{placement}");
        assert!(m < metres && d < degrees, "{}: {m} m, {d} deg", r["path"]);
    }
}

/// Inspected voxels within 1% of the whole flight's, and candidates
/// within one.
fn same_results(one: &Path, several: &Path, what: &str) {
    let inspected = |run: &Path| f(&read_json(&run.join("coverage.json"))["inspected_voxels"]);
    let (a, b) = (inspected(one), inspected(several));
    let (ca, cb) = (candidates(one).len(), candidates(several).len());
    eprintln!(
        "{what}: inspected voxels {a} recorded once, {b} as recorded; candidates {ca} and {cb}"
    );
    assert!((a - b).abs() <= 0.01 * a, "{a} against {b}");
    assert!(ca.abs_diff(cb) <= 1, "{ca} against {cb}");
}

#[test]
fn three_sorties_run_as_one_give_the_results_of_the_flight_recorded_once() {
    let dir = tempfile::tempdir().unwrap();
    let sorties = simulated(&SORTIES);
    let whole = simulated(&WHOLE);
    let (one, three) = (dir.path().join("whole"), dir.path().join("sorties"));
    // The plan is the same flight's either way.
    let plan = whole.join("plan.json");
    let out = run(&[&whole.join("flight.mcap")], &plan, &one);
    assert!(out.status.success(), "{}", stderr(&out));
    // The first two sorties ingested as they come back, then the third
    // added: only the third is read.
    let first_two = [1, 2].map(|k| sorties.join(format!("sortie-{k}.mcap")));
    let two = ingest_ok(
        &first_two[0],
        &three,
        &["--flight", first_two[1].to_str().unwrap()],
    );
    assert_eq!(two["recordings"].as_array().unwrap().len(), 2);
    let out = run(&[&sorties], &plan, &three);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stdout(&out).contains("from 3 recordings (2 read by an earlier ingest"),
        "{}",
        stdout(&out)
    );

    // Every recording, in name order, with its own frames, poses and map.
    let summary = read_json(&three.join("ingest.json"));
    let recordings = summary["recordings"].as_array().unwrap();
    let names: Vec<&str> = recordings
        .iter()
        .map(|r| {
            Path::new(r["path"].as_str().unwrap())
                .file_name()
                .unwrap()
                .to_str()
                .unwrap()
        })
        .collect();
    assert_eq!(names, ["sortie-1.mcap", "sortie-2.mcap", "sortie-3.mcap"]);

    // The sortie of each frame the simulator recorded (it drops some).
    let truth = read_json(&sorties.join("truth.json"));
    let told = truth["sorties"].as_array().unwrap();
    let sortie_of = |frame: u64| {
        let ends = told
            .iter()
            .map(|s| s["first_frame"].as_u64().unwrap() + s["frames"].as_u64().unwrap());
        ends.take_while(|end| *end <= frame).count() as i64
    };
    let recorded = truth["frames"].as_array().unwrap().iter();
    let recorded = recorded.filter(|f| f["dropped"] == false);
    let expected: Vec<i64> = recorded
        .map(|f| sortie_of(f["index"].as_u64().unwrap()))
        .collect();
    for (i, (r, s)) in recordings.iter().zip(told).enumerate() {
        assert_eq!(r["reused"], i < 2, "{r}");
        let frames = expected.iter().filter(|e| **e == i as i64).count();
        assert_eq!(r["frames"], frames, "{r}");
        // The simulator records the map in the last sortie only.
        assert_eq!(r["map"].is_object(), s["map"].as_bool().unwrap(), "{r}");
    }

    // The same frames, each in the recording the truth says, with a pose.
    let times = |run: &Path| column(run, "frames.parquet", "time_ns");
    assert_eq!(times(&three), times(&one));
    assert_eq!(column(&three, "frames.parquet", "recording"), expected);
    assert_eq!(
        summary["frames_with_pose"],
        read_json(&one.join("ingest.json"))["frames_with_pose"]
    );
    // Each recording's poses are its own.
    let posed: BTreeSet<i64> = column(&three, "trajectory.parquet", "recording")
        .into_iter()
        .collect();
    assert_eq!(posed, BTreeSet::from([0, 1, 2]));
    let cameras = read_json(&three.join("cameras.json"));
    let camera_recordings: Vec<u64> = cameras
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["recording"].as_u64().unwrap())
        .collect();
    assert_eq!(camera_recordings, [0, 1, 2]);

    // Coverage over every frame of every recording: the flight's.
    let inspected = |run: &Path| f(&read_json(&run.join("coverage.json"))["inspected_voxels"]);
    let (a, b) = (inspected(&one), inspected(&three));
    eprintln!("inspected voxels: {a} recorded once, {b} as three sorties");
    assert!(a > 50.0 && (a - b).abs() <= 0.005 * a, "{a} against {b}");

    // The same candidates: as many, each within 5 cm of one of the other run's.
    let (a, b) = (candidates(&one), candidates(&three));
    eprintln!(
        "candidates: {} recorded once, {} as three sorties",
        a.len(),
        b.len()
    );
    assert!(
        a.len() >= 3 && a.len().abs_diff(b.len()) <= 1,
        "{} against {}",
        a.len(),
        b.len()
    );
    let near = |p: &[f64; 3], all: &[[f64; 3]]| {
        all.iter()
            .any(|q| (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>().sqrt() < 0.05)
    };
    let matched = a.iter().filter(|p| near(p, &b)).count();
    assert!(matched + 1 >= a.len(), "{matched} of {} matched", a.len());

    // The report lists the recordings and which saw each candidate.
    let report = std::fs::read_to_string(three.join("report.html")).unwrap();
    assert!(
        report.contains("<h2>Recordings</h2>"),
        "no recordings section"
    );
    assert!(
        report.contains("seen in sortie-"),
        "no candidate says where it was seen"
    );
    let report = std::fs::read_to_string(one.join("report.html")).unwrap();
    assert!(!report.contains("<h2>Recordings</h2>"));
}

#[test]
fn a_recording_given_twice_or_a_directory_without_any_is_refused_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let whole = simulated(&WHOLE);
    let flight = whole.join("flight.mcap");
    let plan = whole.join("plan.json");

    let out_dir = dir.path().join("twice");
    let out = run(&[&flight, &flight], &plan, &out_dir);
    assert_eq!(out.status.code(), Some(1));
    let err = stderr(&out);
    assert!(err.contains("given twice"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(!out_dir.join("ingest.json").exists());

    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    std::fs::write(empty.join("notes.txt"), "no recordings here").unwrap();
    let out_dir = dir.path().join("none");
    let out = run(&[&empty], &plan, &out_dir);
    assert_eq!(out.status.code(), Some(1));
    let err = stderr(&out);
    assert!(
        err.contains("no flight recordings in") && err.contains("empty"),
        "{err}"
    );
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(!out_dir.exists(), "a refused run made its directory");
}

#[test]
fn sorties_in_slam_frames_of_their_own_are_registered_onto_the_first() {
    let dir = tempfile::tempdir().unwrap();
    let offset = [&SORTIES[..], &["--sortie-offset=0.6,-0.4,0.1,12"]].concat();
    let (sorties, one, three) = run_against_whole(dir.path(), &offset);
    placed_as_truth(&three, &sorties, "registered", (0.05, 0.5));

    // The same results as the flight recorded once, the candidates at the
    // same places.
    same_results(&one, &three, "three sorties in three frames");
    let (a, b) = (candidates(&one), candidates(&three));
    eprintln!(
        "candidates: {} recorded once, {} as three sorties in three frames",
        a.len(),
        b.len()
    );
    assert_eq!(a.len(), b.len());
    for p in &a {
        let nearest = b
            .iter()
            .map(|q| (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>().sqrt());
        let nearest = nearest.fold(f64::INFINITY, f64::min);
        assert!(
            nearest < 0.05,
            "a candidate at {p:?} is {nearest:.3} m from the nearest"
        );
    }
}

#[test]
fn camera_only_sorties_are_placed_by_their_gps_or_by_the_settings() {
    let dir = tempfile::tempdir().unwrap();
    // The later two sorties flown by a drone with a camera and odometry
    // only, 7 m and 40 degrees off; every sortie with GPS.
    let gps = "--gps=47.397742,8.545594,488.0,23.5";
    let flags = [
        &SORTIES[..],
        &["--sortie-offset=6,-4,0.2,40", "--camera-only", gps],
    ]
    .concat();
    let (sorties, one, three) = run_against_whole(dir.path(), &flags);
    // By GPS: each later sortie's frame near where the truth puts it.
    placed_as_truth(&three, &sorties, "gps", (0.1, 0.2));
    same_results(&one, &three, "placed by GPS");

    // Given in the settings (the truth's frames): exactly there.
    let mut args = Vec::new();
    for k in 1..3 {
        let t = true_frame(&sorties, k);
        let yaw = t.rotation.euler_angles().2.to_degrees();
        let v = t.translation.vector;
        args.push("--recording-frame".to_string());
        args.push(format!(
            "{{recording = \"sortie-{}.mcap\", origin = [{}, {}, {}, {yaw}]}}",
            k + 1,
            v.x,
            v.y,
            v.z
        ));
    }
    let given_run = dir.path().join("given");
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    ingest_ok(&sorties, &given_run, &args);
    placed_as_truth(&given_run, &sorties, "given", (1e-9, 1e-9));
    // A frame for a recording the flight does not have is refused.
    let out = postflight(
        &[
            "ingest",
            "--flight",
            sorties.to_str().unwrap(),
            "--out",
            dir.path().join("typo").to_str().unwrap(),
            "--recording-frame",
            "{recording = \"sortie-9.mcap\", origin = [0, 0, 0, 0]}",
        ],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("--recording-frame must be a recording of the flight (sortie-1.mcap, sortie-2.mcap, sortie-3.mcap) (it is sortie-9.mcap)"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn a_team_flying_at_once_in_slam_frames_of_their_own_is_one_inspection() {
    let dir = tempfile::tempdir().unwrap();
    // Three drones, each a stretch of the plan, all from the same start;
    // the second 0.73 m and 12 degrees from the first's frame, the third
    // twice that, each with its own map.
    let flags = [
        "--frames",
        "60",
        "--drones",
        "3",
        "--sortie-offset=0.6,-0.4,0.1,12",
    ];
    let (team, one, three) = run_against_whole(dir.path(), &flags);
    let summary = read_json(&three.join("ingest.json"));
    let recordings = summary["recordings"].as_array().unwrap();
    let names: Vec<&str> = recordings
        .iter()
        .map(|r| r["path"].as_str().unwrap().rsplit('/').next().unwrap())
        .collect();
    assert_eq!(names, ["drone-1.mcap", "drone-2.mcap", "drone-3.mcap"]);
    // At once: every recording starts within a second of the others.
    let starts: Vec<i64> = recordings
        .iter()
        .map(|r| r["start_time_ns"].as_i64().unwrap())
        .collect();
    assert!(starts.iter().max().unwrap() - starts.iter().min().unwrap() < 1_000_000_000);
    placed_as_truth(&three, &team, "registered", (0.05, 0.5));
    // Frames of the three interleaved in time, each on its own trajectory.
    let recording = column(&three, "frames.parquet", "recording");
    assert!(
        recording.windows(2).any(|w| w[0] != w[1] && w[1] < w[0]),
        "interleaved"
    );

    same_results(&one, &three, "a team at once");
}
