//! End-to-end tests of `postflight simulate`: its flights read back through
//! `postflight ingest` as any recording would, and agree with truth.json.

use std::path::PathBuf;
use std::sync::OnceLock;

use crate::common::*;
use nalgebra::{Point3, UnitQuaternion, Vector3};
use postflight_core::Flight;
use serde_json::Value;

/// One simulated bridge flight, ingested, shared by the tests of this file.
fn bridge() -> &'static (PathBuf, Value) {
    static RUN: OnceLock<(PathBuf, Value)> = OnceLock::new();
    RUN.get_or_init(|| {
        let dir = locked_fixture_dir("simulate-bridge");
        let sim = simulate_into(&dir, "sim", &["--frames", "150", "--seed", "3"]);
        ingest_ok(&sim.join("flight.mcap"), &dir.join("run"), &[]);
        (dir, read_json(&sim.join("truth.json")))
    })
}

fn rotation(pose: &Value) -> UnitQuaternion<f64> {
    let q = &pose["rotation_xyzw"];
    UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        f(&q[3]),
        f(&q[0]),
        f(&q[1]),
        f(&q[2]),
    ))
}

#[test]
fn ingest_recovers_poses_intrinsics_and_extrinsics_of_the_truth() {
    let (dir, truth) = bridge();
    let run = dir.join("run");
    let summary = read_json(&run.join("ingest.json"));
    assert_eq!(
        summary["warnings"],
        Value::Array(vec![]),
        "a simulated flight must ingest cleanly"
    );
    assert_eq!(summary["recordings"][0]["truncated"], false);

    let flight = Flight::load(&run).unwrap();
    let kept: Vec<&Value> = truth["frames"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["dropped"] == false)
        .collect();
    assert!(
        kept.len() < truth["frames"].as_array().unwrap().len(),
        "some frames are dropped"
    );
    assert_eq!(flight.frames.len(), kept.len());
    let (mut worst_position, mut worst_angle) = (0.0f64, 0.0f64);
    for (frame, t) in flight.frames.iter().zip(&kept) {
        assert_eq!(frame.time_ns, t["time_ns"].as_i64().unwrap());
        assert_eq!(frame.exposure_s, truth["exposure_s"].as_f64());
        let pose = frame.camera_pose.expect("every simulated frame has a pose");
        let p = vec3(&t["camera_pose"]["translation"]);
        worst_position = worst_position.max((pose.translation.vector - Vector3::from(p)).norm());
        worst_angle = worst_angle.max(pose.rotation.angle_to(&rotation(&t["camera_pose"])));
    }
    // The recorded poses carry 2 cm / 0.003 rad of noise (truth.json pose_noise).
    assert!(
        worst_position < 0.12,
        "camera position off by {worst_position} m"
    );
    assert!(
        worst_angle < 0.015,
        "camera rotation off by {worst_angle} rad"
    );

    let camera = &flight.cameras[0];
    let k = camera.intrinsics.as_ref().unwrap();
    let tk = &truth["camera"];
    for (got, name) in [(k.fx, "fx"), (k.fy, "fy"), (k.cx, "cx"), (k.cy, "cy")] {
        assert_close(got, f(&tk[name]), 1e-9, name);
    }
    assert_eq!(
        serde_json::to_value(&k.distortion).unwrap(),
        tk["distortion"]
    );
    let e = camera.extrinsic.unwrap();
    let te = &truth["t_body_camera"];
    assert!((e.translation.vector - Vector3::from(vec3(&te["translation"]))).norm() < 1e-9);
    assert!(e.rotation.angle_to(&rotation(te)) < 1e-9);

    // Coverage truth covers every target voxel; the skipped part of the plan
    // leaves voxels the plan would have inspected uninspected.
    let coverage = &truth["coverage"];
    let voxels = coverage["voxels"].as_array().unwrap();
    assert_eq!(
        voxels.len() as u64,
        coverage["target_voxels"].as_u64().unwrap()
    );
    let count = |key: &str| voxels.iter().filter(|v| v[key] == true).count() as u64;
    assert_eq!(
        count("inspected"),
        coverage["inspected_voxels"].as_u64().unwrap()
    );
    assert!(
        count("inspected") > 0
            && voxels
                .iter()
                .any(|v| v["planned"] == true && v["inspected"] == false)
    );

    // The plan and the map files load, and the map matches the recorded one.
    let plan = postflight_core::InspectionPlan::load(&dir.join("sim/plan.json")).unwrap();
    assert!(plan.target_voxels.len() > 100 && plan.viewpoints.len() > 50);
    let ply = postflight_core::map::PointCloud::load(&dir.join("sim/map.ply")).unwrap();
    assert_eq!(
        ply.len() as u64,
        summary["recordings"][0]["map"]["points"].as_u64().unwrap()
    );
    let recorded = ingest::Recordings::reopen(&flight)
        .unwrap()
        .recorded_map(&flight)
        .unwrap()
        .unwrap()
        .0;
    assert_eq!(recorded.points[10], ply.points[10]);
}

/// Mean darkness of an image along `points` shifted by `(dx, dy)`: how much
/// darker the pixels on the line are than the area around it.
fn darkness(img: &image::GrayImage, points: &[(f64, f64)], dx: i32, dy: i32) -> Option<f64> {
    let (w, h) = (img.width() as i32, img.height() as i32);
    let px: Vec<(i32, i32)> = points
        .iter()
        .map(|(x, y)| (x.floor() as i32 + dx, y.floor() as i32 + dy))
        .filter(|(x, y)| *x >= 0 && *y >= 0 && *x < w && *y < h)
        .collect();
    if px.len() < 10 {
        return None;
    }
    let luma = |x: i32, y: i32| {
        f64::from(
            img.get_pixel(x.clamp(0, w - 1) as u32, y.clamp(0, h - 1) as u32)
                .0[0],
        )
    };
    // Darkest pixel next to each line point (the line is 1-2 px wide, blurred).
    let line: f64 = px
        .iter()
        .map(|(x, y)| {
            (-1..=1)
                .flat_map(|a| (-1..=1).map(move |b| (a, b)))
                .map(|(a, b)| luma(x + a, y + b))
                .fold(f64::MAX, f64::min)
        })
        .sum::<f64>()
        / px.len() as f64;
    // Surroundings: 8 px either side.
    let around: f64 = px
        .iter()
        .map(|(x, y)| (luma(x + 8, *y) + luma(x - 8, *y) + luma(*x, y + 8) + luma(*x, y - 8)) / 4.0)
        .sum::<f64>()
        / px.len() as f64;
    Some(around - line)
}

#[test]
fn truth_cracks_are_drawn_where_the_recovered_camera_projects_them() {
    let (dir, truth) = bridge();
    let flight = Flight::load(&dir.join("run")).unwrap();
    let recording = ingest::Recordings::reopen(&flight).unwrap();
    let cracks = truth["cracks"].as_array().unwrap();
    let mut checked = 0;
    for t in truth["frames"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["dropped"] == false)
    {
        let Some(frame) = flight
            .frames
            .iter()
            .find(|fr| fr.time_ns == t["time_ns"].as_i64().unwrap())
        else {
            panic!("frame at {} not ingested", t["time_ns"]);
        };
        // Clearly drawn, mostly visible views: faint pieces near the
        // visibility limit are checked by the detector's scores instead.
        for seen in t["cracks"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|c| f(&c["contrast"]) >= 0.3 && f(&c["visible_fraction"]) >= 0.5)
        {
            let crack = &cracks[seen["id"].as_u64().unwrap() as usize];
            // Project the 3D crack through the recovered camera model.
            let camera = flight.camera(frame).unwrap();
            let k = camera.intrinsics.as_ref().unwrap();
            let world_to_camera = frame.camera_pose.unwrap().inverse();
            let mut points = Vec::new();
            for line in crack["lines"].as_array().unwrap() {
                let line: Vec<Point3<f64>> = line
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|p| Point3::from(vec3(p)))
                    .collect();
                for w in line.windows(2) {
                    for s in 0..5 {
                        let p = w[0] + (w[1] - w[0]) * (f64::from(s) / 5.0);
                        if let Some(px) = k.project(&(world_to_camera * p).coords) {
                            points.push((px.x, px.y));
                        }
                    }
                }
            }
            let img = recording.image(frame).unwrap().to_luma8();
            // Pose noise moves the projection by a few pixels: search nearby.
            let best = |ox: i32, oy: i32| {
                (-12..=12)
                    .flat_map(|dx| (-12..=12).map(move |dy| (dx, dy)))
                    .filter_map(|(dx, dy)| darkness(&img, &points, ox + dx, oy + dy))
                    .fold(f64::MIN, f64::max)
            };
            let on_crack = best(0, 0);
            // The same shape elsewhere on the image: no crack there.
            let control = [(60, 0), (-60, 0), (0, 60), (0, -60)]
                .map(|(x, y)| best(x, y))
                .into_iter()
                .fold(f64::MIN, f64::max);
            assert!(
                on_crack > 15.0 && on_crack > control + 5.0,
                "frame {} crack {}: darkness {on_crack:.1} on the projected crack, {control:.1} off it",
                t["index"],
                seen["id"]
            );
            checked += 1;
        }
    }
    assert!(checked >= 10, "only {checked} crack views checked");
}

#[test]
fn the_same_seed_gives_byte_identical_files() {
    let dir = tempfile::tempdir().unwrap();
    let small = [
        "--frames", "12", "--width", "160", "--height", "120", "--scene", "tower",
    ];
    // Fresh flights: the fixture cache would hand both runs the same files.
    let (a, b, c) = (
        dir.path().join("a"),
        dir.path().join("b"),
        dir.path().join("c"),
    );
    simulate_fresh(&a, &[&small[..], &["--seed", "5"]].concat());
    simulate_fresh(&b, &[&small[..], &["--seed", "5"]].concat());
    simulate_fresh(&c, &[&small[..], &["--seed", "6"]].concat());
    for file in ["flight.mcap", "map.ply", "plan.json", "truth.json"] {
        let (x, y) = (
            std::fs::read(a.join(file)).unwrap(),
            std::fs::read(b.join(file)).unwrap(),
        );
        assert!(x == y, "{file} differs between two runs with one seed");
    }
    assert_ne!(
        std::fs::read(a.join("flight.mcap")).unwrap(),
        std::fs::read(c.join("flight.mcap")).unwrap()
    );

    // The tower flight ingests cleanly too.
    let run = dir.path().join("run");
    let summary = ingest_ok(&a.join("flight.mcap"), &run, &[]);
    assert_eq!(summary["warnings"], Value::Array(vec![]));
}

#[test]
fn a_mesh_from_an_obj_file_flies_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = root().join("tests/fixtures/footbridge.obj");
    let sim = simulate_into(
        dir.path(),
        "sim",
        &[
            "--mesh",
            mesh.to_str().unwrap(),
            "--frames",
            "40",
            "--cracks",
            "6",
        ],
    );
    let truth = read_json(&sim.join("truth.json"));
    assert_eq!(truth["scene"], "footbridge");
    assert_eq!(truth["cracks"].as_array().unwrap().len(), 6);
    assert!(
        truth["cracks"]
            .as_array()
            .unwrap()
            .iter()
            .all(|c| c["part"] == "structure")
    );
    let run = dir.path().join("run");
    let summary = ingest_ok(&sim.join("flight.mcap"), &run, &[]);
    assert_eq!(summary["warnings"], Value::Array(vec![]));
    assert_eq!(summary["frames_with_pose"], summary["frames"]);
    let plan = postflight_core::InspectionPlan::load(&sim.join("plan.json")).unwrap();
    // The footbridge's surface fits in a 13 x 2.5 x 4 m box: at most that many 0.5 m voxels.
    assert!(!plan.target_voxels.is_empty() && plan.target_voxels.len() <= 26 * 5 * 8);

    // The mesh itself as the map, OBJ or PLY with faces (written by
    // Python), sampled over its surface: the coverage the recorded map
    // gives.
    let ply = dir.path().join("footbridge.ply");
    python_fixture(
        "obj_to_ply.py",
        &[mesh.to_str().unwrap(), ply.to_str().unwrap()],
    );
    let plan = sim.join("plan.json");
    let inspected = |map: Option<&std::path::Path>| {
        let mut args = vec![
            "coverage",
            "--run",
            run.to_str().unwrap(),
            "--plan",
            plan.to_str().unwrap(),
        ];
        if let Some(m) = map {
            args.extend(["--map", m.to_str().unwrap()]);
        }
        let out = postflight(&args, dir.path());
        assert!(out.status.success(), "{}", stderr(&out));
        read_json(&run.join("coverage.json"))["inspected_voxels"]
            .as_u64()
            .unwrap()
    };
    let recorded = inspected(None);
    for map in [&mesh, &ply] {
        let from_mesh = inspected(Some(map));
        let differ = from_mesh.abs_diff(recorded) as f64;
        eprintln!(
            "{}: {from_mesh} inspected voxels, the recorded map {recorded}",
            map.display()
        );
        assert!(
            differ <= 0.05 * recorded as f64,
            "{}: {from_mesh} inspected voxels, the recorded map {recorded}",
            map.display()
        );
    }

    let missing = postflight(
        &[
            "simulate",
            "--out",
            dir.path().join("x").to_str().unwrap(),
            "--mesh",
            "/nonexistent.obj",
        ],
        dir.path(),
    );
    assert_eq!(missing.status.code(), Some(1));
    let err = stderr(&missing);
    assert!(
        err.starts_with("error: ") && err.contains("--mesh") && err.trim().lines().count() == 1,
        "{err}"
    );
}

#[test]
fn a_repeat_flight_keeps_the_cracks_grows_some_adds_new_ones_and_records_in_its_own_frame() {
    let earlier = simulated(&["--frames", "40"]);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("repeat");
    simulate_fresh(
        &out,
        &[
            "--frames",
            "40",
            "--seed",
            "2",
            "--repeat-of",
            earlier.to_str().unwrap(),
            "--grow",
            "0.3",
            "--new",
            "4",
            "--frame-offset",
            "0.5,-0.2,0.1,10",
        ],
    );
    let (before, after) = (
        read_json(&earlier.join("truth.json")),
        read_json(&out.join("truth.json")),
    );
    let repeat = &after["repeat"];
    // The earlier frame to this one: 10 degrees about z, then the shift.
    let to_this = |p: &Value| {
        let r = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 10f64.to_radians());
        r * Point3::from(vec3(p)) + Vector3::new(0.5, -0.2, 0.1)
    };
    let before_cracks = before["cracks"].as_array().unwrap();
    let after_cracks = after["cracks"].as_array().unwrap();
    assert_eq!(after_cracks.len(), before_cracks.len() + 4);
    let changes = repeat["changes"].as_array().unwrap();
    let count = |c: &str| changes.iter().filter(|x| x["change"] == c).count();
    assert_eq!(count("new"), 4);
    assert!(
        count("grown") >= 5,
        "about 30% of {} cracks grow",
        before_cracks.len()
    );
    for (was, change) in before_cracks.iter().zip(changes) {
        let now = &after_cracks[was["id"].as_u64().unwrap() as usize];
        let was_line: Vec<Point3<f64>> = was["lines"][0]
            .as_array()
            .unwrap()
            .iter()
            .map(to_this)
            .collect();
        let now_line: Vec<Point3<f64>> = now["lines"][0]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| Point3::from(vec3(p)))
            .collect();
        // Every earlier point is still on the crack, where the frame puts it.
        for p in &was_line {
            let nearest = now_line
                .iter()
                .map(|q| (q - p).norm())
                .fold(f64::INFINITY, f64::min);
            assert!(nearest < 1e-9, "crack {} moved by {nearest} m", was["id"]);
        }
        let (length_before, length) = (f(&was["length_m"]), f(&now["length_m"]));
        assert_close(
            f(&change["length_before_m"]),
            length_before,
            1e-9,
            "length before",
        );
        assert_close(f(&change["length_m"]), length, 1e-9, "length now");
        match change["change"].as_str().unwrap() {
            "grown" => assert!(
                length > 1.1 * length_before,
                "crack {} grew {length_before} -> {length}",
                was["id"]
            ),
            "unchanged" => assert!(length < 1.1 * length_before),
            other => panic!("an earlier crack cannot be {other}"),
        }
    }
    // The map is recorded in the new frame too: the earlier map's points
    // moved by the offset lie on this flight's map.
    use postflight_core::map::{PointCloud, SlamMap};
    let cloud = |dir: &std::path::Path| PointCloud::load(&dir.join("map.ply")).unwrap();
    let new_map = SlamMap::new(cloud(&out), 0.5).unwrap();
    // (Each flight samples its map afresh: compare where they are dense.)
    let mut gaps: Vec<f64> = cloud(&earlier)
        .points
        .iter()
        .step_by(97)
        .map(|p| {
            new_map
                .nearest(&to_this(&serde_json::json!([p.x, p.y, p.z])))
                .distance
        })
        .collect();
    gaps.sort_by(f64::total_cmp);
    let (median, p90) = (gaps[gaps.len() / 2], gaps[gaps.len() * 9 / 10]);
    eprintln!("earlier map to the repeat's: median {median:.3} m, 90th percentile {p90:.3} m");
    assert!(
        median < 0.1 && p90 < 0.3,
        "median {median} m, 90th percentile {p90} m"
    );
}

/// A recording as tests/fixtures/read_recording.py reads it (the `mcap`
/// and `mcap-ros2-support` packages, not postflight's reader).
fn recording(path: &std::path::Path) -> Value {
    serde_json::from_str(&python_fixture("read_recording.py", &[path])).unwrap()
}

/// The sorties' recordings of the 20-frame flight cut with `args`, read
/// back, with truth.json's account of them.
fn sorties(args: &[&str]) -> (Vec<Value>, Vec<Value>) {
    let out = simulated(&[&["--frames", "20"], args].concat());
    let truth = read_json(&out.join("truth.json"));
    let told = truth["sorties"].as_array().unwrap().clone();
    let read = told
        .iter()
        .map(|s| recording(&out.join(s["recording"].as_str().unwrap())))
        .collect();
    (told, read)
}

#[test]
fn a_flight_recorded_as_sorties_is_the_whole_flight_cut_at_battery_changes() {
    // The 20-frame flight the parser tests fly too.
    let whole = recording(&simulated(&["--frames", "20"]).join("flight.mcap"));
    let (told, read) = sorties(&["--sorties", "3"]);
    assert_eq!(told.len(), 3);
    let names: Vec<&str> = told
        .iter()
        .map(|s| s["recording"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["sortie-1.mcap", "sortie-2.mcap", "sortie-3.mcap"]);
    assert!(
        !simulated(&["--frames", "20", "--sorties", "3"])
            .join("flight.mcap")
            .exists()
    );
    // The frames shared out evenly, each sortie's stretch starting where
    // the last one ended.
    let shot: Vec<u64> = told.iter().map(|s| s["frames"].as_u64().unwrap()).collect();
    assert_eq!(shot, [7, 7, 6]);
    for pair in told.windows(2) {
        assert_eq!(pair[0]["end_ns"], pair[1]["start_ns"]);
    }
    // Read independently, the sorties hold the whole flight's images and
    // poses, each within its stretch, and the map only in the last.
    let all = |key: &str| -> Vec<Value> {
        read.iter()
            .flat_map(|r| r[key].as_array().unwrap().clone())
            .collect()
    };
    assert_eq!(all("images"), *whole["images"].as_array().unwrap());
    assert_eq!(all("poses"), *whole["poses"].as_array().unwrap());
    for (s, r) in told.iter().zip(&read) {
        let (start, end) = (
            s["start_ns"].as_i64().unwrap(),
            s["end_ns"].as_i64().unwrap(),
        );
        for stamped in r["images"]
            .as_array()
            .unwrap()
            .iter()
            .chain(r["poses"].as_array().unwrap())
        {
            let t = stamped[0].as_i64().unwrap();
            assert!(start <= t && t <= end, "{t} outside {start}..{end}");
        }
        assert_eq!(r["topics"]["/tf_static"], 1);
        assert!(r["topics"]["/camera/camera_info"].as_u64().unwrap() > 0);
        assert_eq!(s["map"], s["recording"] == "sortie-3.mcap");
    }
    let maps: Vec<Value> = all("maps");
    assert_eq!(maps, *whole["maps"].as_array().unwrap());

    // In another SLAM frame from the second sortie on: its poses and its
    // own map are the whole flight's, moved 15 degrees and (0.8, -0.3, 0).
    let (told, read) = sorties(&["--sorties", "3", "--sortie-offset=0.8,-0.3,0,15"]);
    let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 15f64.to_radians());
    let moved = |p: [f64; 3], s: usize| {
        let p = Vector3::from(p);
        if s == 0 {
            p
        } else {
            turn * p + Vector3::new(0.8, -0.3, 0.0)
        }
    };
    let xyz = |v: &Value, from: usize| [f(&v[from]), f(&v[from + 1]), f(&v[from + 2])];
    let whole_poses = whole["poses"].as_array().unwrap();
    let mut at = 0;
    for (s, r) in read.iter().enumerate() {
        assert!(
            told[s]["map"].as_bool().unwrap(),
            "sortie {s} records its own map"
        );
        for pose in r["poses"].as_array().unwrap() {
            let expected = &whole_poses[at];
            at += 1;
            assert_eq!(pose[0], expected[0]);
            let gap = (Vector3::from(xyz(pose, 1)) - moved(xyz(expected, 1), s)).norm();
            assert!(gap < 1e-9, "sortie {s}: pose {gap} m off");
            let q = |v: &Value| {
                UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                    f(&v[7]),
                    f(&v[4]),
                    f(&v[5]),
                    f(&v[6]),
                ))
            };
            let want = if s == 0 {
                q(expected)
            } else {
                turn * q(expected)
            };
            assert!(q(pose).angle_to(&want) < 1e-9);
        }
        let map = &r["maps"][0];
        let first = xyz(&whole["maps"][0]["first"], 0);
        let gap = (Vector3::from(xyz(&map["first"], 0)) - moved(first, s)).norm();
        assert!(gap < 1e-4, "sortie {s}: map {gap} m off");
        assert_eq!(map["points"], whole["maps"][0]["points"]);
    }
    assert_eq!(at, whole_poses.len());
}

#[test]
fn more_sorties_than_frames_is_refused_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sim");
    let args = [
        "simulate",
        "--out",
        out.to_str().unwrap(),
        "--frames",
        "4",
        "--sorties",
        "5",
    ];
    let result = postflight(&args, dir.path());
    assert!(!result.status.success());
    let err = stderr(&result);
    assert!(
        err.contains("--sorties from 1 to 4") && err.trim().lines().count() == 1,
        "{err}"
    );
    assert!(!out.exists(), "nothing is written");
}
