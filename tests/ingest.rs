//! End-to-end tests of `postflight ingest` against recordings written by the
//! official Python MCAP + ROS 2 writers (tests/fixtures/write_flight.py),
//! whose expected.json holds every value written.

use std::path::{Path, PathBuf};

use crate::common::*;
use ingest::ros::schema::ros2_name;
use polars::prelude::*;
use serde_json::Value;

fn frames_table(run: &Path) -> DataFrame {
    read_parquet(&run.join("frames.parquet"))
}

/// Every frame's time, size, status and camera pose match what was written.
fn check_frames(run: &Path, expected: &Value) {
    let df = frames_table(run);
    let frames = expected["frames"].as_array().unwrap();
    assert_eq!(df.height(), frames.len());
    let col = |n: &str| df.column(n).unwrap().clone();
    let time = col("time_ns");
    let time = time.i64().unwrap();
    let (width, height) = (col("width"), col("height"));
    let exposure = col("exposure_s");
    let exposure = exposure.f64().unwrap();
    let status = col("pose_status");
    let status = status.str().unwrap();
    let pose: Vec<Column> = ["x", "y", "z", "qx", "qy", "qz", "qw"]
        .iter()
        .map(|c| col(c))
        .collect();
    for (i, e) in frames.iter().enumerate() {
        assert_eq!(time.get(i), e["time_ns"].as_i64(), "frame {i} time");
        assert_eq!(
            width.u32().unwrap().get(i),
            e["width"].as_u64().map(|v| v as u32)
        );
        assert_eq!(
            height.u32().unwrap().get(i),
            e["height"].as_u64().map(|v| v as u32)
        );
        assert_eq!(status.get(i), e["pose_status"].as_str(), "frame {i} status");
        assert_eq!(
            exposure.get(i),
            e["exposure_s"].as_f64(),
            "frame {i} exposure"
        );
        let got: Vec<Option<f64>> = pose.iter().map(|c| c.f64().unwrap().get(i)).collect();
        match e.get("camera_pose") {
            None => assert!(
                got.iter().all(Option::is_none),
                "frame {i} should have no pose"
            ),
            Some(p) => {
                let t = vec3(&p["translation"]);
                for k in 0..3 {
                    assert_close(
                        got[k].unwrap(),
                        t[k],
                        1e-9,
                        &format!("frame {i} position {k}"),
                    );
                }
                let q = &p["rotation_xyzw"];
                let dot: f64 = (0..4).map(|k| got[3 + k].unwrap() * f(&q[k])).sum();
                assert_close(dot.abs(), 1.0, 1e-9, &format!("frame {i} rotation"));
            }
        }
    }
}

fn check_summary(summary: &Value, expected: &Value) {
    // Every topic with its type and count, whichever ROS wrote it.
    let messages = |v: &Value| -> Vec<(String, String, u64)> {
        v.as_object()
            .unwrap()
            .iter()
            .map(|(topic, m)| {
                let schema = ros2_name(m["schema"].as_str().unwrap()).into_owned();
                (topic.clone(), schema, m["count"].as_u64().unwrap())
            })
            .collect()
    };
    assert_eq!(
        messages(&summary["recordings"][0]["messages"]),
        messages(&expected["messages"])
    );
    assert_eq!(summary["poses"], expected["poses"]);
    assert_eq!(
        summary["frames"].as_u64().unwrap(),
        expected["frames"].as_array().unwrap().len() as u64
    );
    let with_pose = expected["frames"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["pose_status"] == "ok")
        .count();
    assert_eq!(
        summary["frames_with_pose"].as_u64().unwrap(),
        with_pose as u64
    );
    assert_eq!(summary["start_time_ns"], expected["start_time_ns"]);
    assert_eq!(summary["end_time_ns"], expected["end_time_ns"]);
    assert_close(
        f(&summary["duration_s"]),
        f(&expected["duration_s"]),
        1e-9,
        "duration",
    );
    assert_eq!(summary["recordings"][0]["truncated"], false);
    assert_eq!(summary["recordings"][0]["corrupt_chunks"], 0);
}

#[test]
fn odometry_jpeg_flight_decodes_every_value() {
    let dir = tempfile::tempdir().unwrap();
    let (mcap, expected) = write_flight(dir.path(), "flight", &[]);
    let run = dir.path().join("run");
    let summary = ingest_ok(&mcap, &run, &[]);
    check_summary(&summary, &expected);
    check_frames(&run, &expected);
    assert_eq!(summary["recordings"][0]["pose_source"]["topic"], "/odom");
    assert_eq!(
        summary["recordings"][0]["pose_source"]["child_frame_id"],
        "base_link"
    );
    let warnings = summary["warnings"].to_string();
    assert!(
        warnings.contains("/imu (sensor_msgs/msg/Imu)"),
        "{warnings}"
    );

    // Intrinsics and extrinsics.
    let cameras = read_json(&run.join("cameras.json"));
    let cam = &cameras[0];
    let e = &expected["camera"];
    let i = &cam["intrinsics"];
    assert_eq!(i["width"], e["width"]);
    assert_eq!(i["height"], e["height"]);
    for (name, k) in [("fx", 0), ("cx", 2), ("fy", 4), ("cy", 5)] {
        assert_close(f(&i[name]), f(&e["k"][k]), 1e-12, name);
    }
    assert_eq!(i["distortion"]["model"], "plumb_bob");
    assert_eq!(i["distortion"]["coefficients"], e["d"]);
    let t = vec3(&cam["extrinsic"]["translation"]);
    let te = vec3(&expected["t_body_camera"]["translation"]);
    for k in 0..3 {
        assert_close(t[k], te[k], 1e-12, "extrinsic translation");
    }

    // The recorded map, read back lazily from the recording.
    let flight = postflight_core::Flight::load(&run).unwrap();
    let recording = ingest::Recordings::reopen(&flight).unwrap();
    let map = recording.recorded_map(&flight).unwrap().unwrap().0;
    let em = &expected["map"];
    assert_eq!(map.points.len() as u64, em["points"].as_u64().unwrap());
    for (p, q) in map.points.iter().zip(em["first"].as_array().unwrap()) {
        assert_eq!([p.x, p.y, p.z], vec3(q));
    }
    assert_eq!(summary["recordings"][0]["map"]["bounds"], em["bounds"]);

    // JPEG pixels decode close to the pattern written (lossy, so loosely).
    let img = recording.image(&flight.frames[0]).unwrap().to_rgb8();
    let mut total_error = 0.0;
    let pixels = expected["pixels"].as_array().unwrap();
    for p in pixels {
        let (x, y) = (p[0].as_u64().unwrap() as u32, p[1].as_u64().unwrap() as u32);
        let got = img.get_pixel(x, y).0;
        for c in 0..3 {
            total_error += (f64::from(got[c]) - f(&p[2][c])).abs();
        }
    }
    assert!(
        total_error / (pixels.len() * 3) as f64 <= 24.0,
        "JPEG too far from the pattern: {total_error}"
    );
}

#[test]
fn every_pose_message_type_gives_the_same_camera_poses() {
    let dir = tempfile::tempdir().unwrap();
    for (kind, topic) in [
        ("pose", "/slam/pose"),
        ("posecov", "/slam/pose_cov"),
        ("tf", "/tf"),
    ] {
        let (mcap, expected) = write_flight(dir.path(), kind, &["--poses", kind]);
        let run = dir.path().join(format!("run-{kind}"));
        let summary = ingest_ok(&mcap, &run, &[]);
        assert_eq!(
            summary["recordings"][0]["pose_source"]["topic"], topic,
            "{kind}"
        );
        assert_eq!(
            summary["recordings"][0]["pose_source"]["frame_id"], "map",
            "{kind}"
        );
        assert_eq!(
            summary["recordings"][0]["pose_source"]["child_frame_id"], "base_link",
            "{kind}"
        );
        check_summary(&summary, &expected);
        check_frames(&run, &expected);
    }
}

#[test]
fn raw_and_png_images_decode_exactly() {
    let dir = tempfile::tempdir().unwrap();
    for (kind, extra) in [
        ("png", &[][..]),
        ("rgb8", &[][..]),
        ("bgr8", &[][..]),
        ("mono8", &[][..]),
        ("mono16", &[][..]),
        ("mono16", &["--big-endian-images"][..]),
    ] {
        let mut args = vec![
            "--images",
            kind,
            "--width",
            "33",
            "--height",
            "17",
            "--duration",
            "2",
        ];
        args.extend_from_slice(extra);
        let (mcap, expected) = write_flight(dir.path(), kind, &args);
        let run = dir.path().join(format!("run-{kind}-{}", extra.len()));
        let summary = ingest_ok(&mcap, &run, &[]);
        check_summary(&summary, &expected);
        check_frames(&run, &expected);
        check_pixels(&run, &expected, kind);
    }
}

/// Frame 3's pixels, read back through the recording, are the ones written
/// (for JPEG, lossy, its size).
fn check_pixels(run: &Path, expected: &Value, kind: &str) {
    let flight = postflight_core::Flight::load(run).unwrap();
    let frame = &flight.frames[3];
    assert_eq!(frame.encoding, kind);
    let img = ingest::Recordings::reopen(&flight)
        .unwrap()
        .image(frame)
        .unwrap();
    assert_eq!(Some(img.width()), frame.width);
    if kind == "jpeg" {
        return;
    }
    for p in expected["pixels"].as_array().unwrap() {
        let (x, y) = (p[0].as_u64().unwrap() as u32, p[1].as_u64().unwrap() as u32);
        let want: Vec<u64> = p[2]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap())
            .collect();
        let got: Vec<u64> = match kind {
            "mono8" => vec![u64::from(img.to_luma8().get_pixel(x, y).0[0])],
            "mono16" => vec![u64::from(img.to_luma16().get_pixel(x, y).0[0])],
            _ => img
                .to_rgb8()
                .get_pixel(x, y)
                .0
                .iter()
                .map(|v| u64::from(*v))
                .collect(),
        };
        assert_eq!(got, want, "{kind} pixel ({x}, {y})");
    }
}

#[test]
fn equidistant_lz4_uncompressed_and_big_endian_float64_clouds() {
    let dir = tempfile::tempdir().unwrap();
    for (name, args) in [
        (
            "fisheye-lz4",
            vec!["--distortion", "equidistant", "--compression", "lz4"],
        ),
        (
            "f64be-none",
            vec!["--cloud", "f64be", "--compression", "none"],
        ),
    ] {
        let (mcap, expected) = write_flight(dir.path(), name, &args);
        let run = dir.path().join(format!("run-{name}"));
        let summary = ingest_ok(&mcap, &run, &[]);
        check_summary(&summary, &expected);
        check_frames(&run, &expected);
        let cam = &read_json(&run.join("cameras.json"))[0]["intrinsics"];
        assert_eq!(
            cam["distortion"]["model"],
            expected["camera"]["distortion_model"].as_str().unwrap()
        );
        assert_eq!(cam["distortion"]["coefficients"], expected["camera"]["d"]);
        let flight = postflight_core::Flight::load(&run).unwrap();
        let map = ingest::Recordings::reopen(&flight)
            .unwrap()
            .recorded_map(&flight)
            .unwrap()
            .unwrap()
            .0;
        for (p, q) in map
            .points
            .iter()
            .zip(expected["map"]["first"].as_array().unwrap())
        {
            assert_eq!([p.x, p.y, p.z], vec3(q), "{name}");
        }
    }
}

#[test]
fn calibration_file_stands_in_for_missing_camera_info() {
    let dir = tempfile::tempdir().unwrap();
    let (mcap, expected) = write_flight(dir.path(), "nocaminfo", &["--no-camera-info"]);
    let run = dir.path().join("run");
    let out = run_ingest(&mcap, &run, &[]);
    assert_eq!(out.status.code(), Some(1));
    let err = stderr(&out);
    assert!(err.contains("--camera-info"), "{err}");
    assert!(!run.join("ingest.json").exists());

    let yaml = dir.path().join("camera.yaml");
    std::fs::write(
        &yaml,
        "image_width: 64\nimage_height: 48\ncamera_name: narrow_stereo\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [57.6, 0, 31.5, 0, 58.6, 24.25, 0, 0, 1]\ndistortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [-0.21, 0.045, 0.0012, -0.0007, 0]\nrectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\nprojection_matrix:\n  rows: 3\n  cols: 4\n  data: [57.6, 0, 31.5, 0, 0, 58.6, 24.25, 0, 0, 0, 1, 0]\n",
    )
    .unwrap();
    let summary = ingest_ok(&mcap, &run, &["--camera-info", yaml.to_str().unwrap()]);
    check_summary(&summary, &expected);
    let cam = &read_json(&run.join("cameras.json"))[0];
    assert_close(f(&cam["intrinsics"]["fy"]), 58.6, 1e-12, "fy");
    assert!(
        cam["intrinsics_source"]
            .as_str()
            .unwrap()
            .contains("camera.yaml")
    );

    let bad = dir.path().join("bad.yaml");
    std::fs::write(&bad, "image_width: 64\n").unwrap();
    let out = run_ingest(&mcap, &run, &["--camera-info", bad.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("camera calibration file"),
        "{}",
        stderr(&out)
    );
}

/// Cut `recording` at 60% of its size and ingest it, which must succeed
/// with a warning and flag it truncated (and, when the cut falls in one
/// big uncompressed chunk, recover messages from its front); returns the
/// run directory.
fn cut_and_ingest(recording: &Path, dir: &Path, name: &str, cut_chunk_salvaged: bool) -> PathBuf {
    let bytes = std::fs::read(recording).unwrap();
    let ext = recording.extension().unwrap().to_str().unwrap();
    let cut = dir.join(format!("{name}-cut.{ext}"));
    std::fs::write(&cut, &bytes[..bytes.len() * 6 / 10]).unwrap();
    let run = dir.join(format!("run-{name}"));
    let out = run_ingest(&cut, &run, &[]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("truncated"),
        "no warning printed: {}",
        stderr(&out)
    );
    let summary = read_json(&run.join("ingest.json"));
    assert_eq!(summary["recordings"][0]["truncated"], true, "{name}");
    if cut_chunk_salvaged {
        assert!(
            summary["warnings"]
                .to_string()
                .contains("complete messages recovered from it"),
            "{}",
            summary["warnings"]
        );
    }
    // --strict refuses it in one line and writes nothing that looks complete.
    let strict_run = dir.join(format!("strict-{name}"));
    let strict = run_ingest(&cut, &strict_run, &["--strict"]);
    assert_eq!(strict.status.code(), Some(1));
    let err = stderr(&strict);
    assert!(
        err.contains("truncated") && err.contains("drop --strict"),
        "{err}"
    );
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(!strict_run.join("ingest.json").exists());
    run
}

#[test]
fn truncated_flight_is_salvaged_and_flagged() {
    let dir = tempfile::tempdir().unwrap();
    // zstd chunks of 64 KiB (the cut loses the chunk it falls in), and one
    // large uncompressed chunk (rosbag2's default storage) whose front is salvaged.
    for (name, args) in [
        ("zstd", vec!["--duration", "20"]),
        (
            "uncompressed",
            vec![
                "--duration",
                "20",
                "--compression",
                "none",
                "--chunk-size",
                "1000000",
            ],
        ),
    ] {
        let (mcap, expected) = write_flight(dir.path(), name, &args);
        let run = cut_and_ingest(&mcap, dir.path(), name, name == "uncompressed");
        let summary = read_json(&run.join("ingest.json"));

        // The salvaged frames are exactly the first ones written, with their values.
        let df = frames_table(&run);
        let all = expected["frames"].as_array().unwrap();
        let n = df.height();
        assert!(
            n >= all.len() / 2 && n < all.len(),
            "{name}: salvaged {n} of {} frames",
            all.len()
        );
        let mut prefix = expected.clone();
        prefix["frames"] = Value::Array(all[..n].to_vec());
        check_frames(&run, &prefix);
        // Poses: the complete ones up to the cut, reaching past the last salvaged frame.
        let poses = summary["poses"].as_u64().unwrap();
        assert!(poses > 0 && poses < expected["poses"].as_u64().unwrap());
        let last_frame_ns = all[n - 1]["time_ns"].as_i64().unwrap();
        assert!(last_pose_ns(&run) + 100_000_000 >= last_frame_ns);
    }
}

/// The time of the last pose of a run's trajectory.
fn last_pose_ns(run: &Path) -> i64 {
    read_parquet(&run.join("trajectory.parquet"))
        .column("time_ns")
        .unwrap()
        .i64()
        .unwrap()
        .max()
        .unwrap()
}

#[test]
fn corrupt_chunk_is_skipped_and_counted() {
    let dir = tempfile::tempdir().unwrap();
    let (mcap, expected) = write_flight(dir.path(), "flight", &[]);
    let chunks = expected["chunks"].as_array().unwrap();
    let victim = &chunks[chunks.len() / 2];
    let (offset, len, lost) = (
        victim[0].as_u64().unwrap() as usize,
        victim[1].as_u64().unwrap() as usize,
        victim[2].as_u64().unwrap(),
    );
    let mut bytes = std::fs::read(&mcap).unwrap();
    for b in &mut bytes[offset + len / 2..offset + len / 2 + 64] {
        *b ^= 0x5a;
    }
    let bad = dir.path().join("corrupt.mcap");
    std::fs::write(&bad, &bytes).unwrap();
    let run = dir.path().join("run");
    let summary = ingest_ok(&bad, &run, &[]);
    assert_eq!(summary["recordings"][0]["corrupt_chunks"], 1);
    assert_eq!(summary["recordings"][0]["truncated"], false);
    let total = |v: &Value| -> u64 {
        v.as_object()
            .unwrap()
            .values()
            .map(|t| t["count"].as_u64().unwrap())
            .sum()
    };
    assert_eq!(
        total(&summary["recordings"][0]["messages"]),
        total(&expected["messages"]) - lost
    );
}

#[test]
fn bad_input_fails_with_one_line_and_no_run_dir() {
    let dir = tempfile::tempdir().unwrap();
    let text = dir.path().join("notes.txt");
    std::fs::write(&text, "this is not a flight\n").unwrap();
    let empty = dir.path().join("empty.mcap");
    std::fs::write(&empty, "").unwrap();
    let (no_poses, _) = write_flight(
        dir.path(),
        "noposes",
        &["--poses", "none", "--duration", "2"],
    );
    // A named pipe: opening it would wait for a writer for ever.
    let pipe = dir.path().join("pipe.mcap");
    assert!(
        std::process::Command::new("mkfifo")
            .arg(&pipe)
            .status()
            .unwrap()
            .success()
    );
    let cases = [
        (text.clone(), "not a flight recording"),
        (empty, "it is empty"),
        (dir.path().join("missing.mcap"), "cannot open"),
        (no_poses.clone(), "no usable pose topic"),
        (
            pipe,
            "it is not a regular file but a pipe, socket or device",
        ),
    ];
    for (i, (flight, message)) in cases.iter().enumerate() {
        let run = dir.path().join(format!("run{i}"));
        let out = run_ingest(&no_poses, &dir.path().join("gap"), &["--max-pose-gap=0"]);
        assert_eq!(out.status.code(), Some(1));
        assert!(
            stderr(&out).contains("--max-pose-gap must be"),
            "{}",
            stderr(&out)
        );
        let out = run_ingest(flight, &run, &[]);
        assert_eq!(out.status.code(), Some(1), "{message}");
        let err = stderr(&out);
        assert!(err.starts_with("error: ") && err.contains(message), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(!run.join("ingest.json").exists());
    }
    let out = run_ingest(
        &no_poses,
        &dir.path().join("r"),
        &["--image-topic", "/nope"],
    );
    let err = stderr(&out);
    assert!(
        err.contains("\"/nope\" is not in the recording")
            && err.contains("/camera/image_raw/compressed"),
        "{err}"
    );
}

/// The ingest tables without the columns that say where each message sits
/// in its file, which differ by container; everything else must not.
fn tables_without_locations(run: &Path) -> (DataFrame, DataFrame, Value) {
    let frames = frames_table(run)
        .drop_many(["chunk_offset", "record_offset"])
        .clone();
    let trajectory = read_parquet(&run.join("trajectory.parquet"));
    (frames, trajectory, read_json(&run.join("cameras.json")))
}

/// The same flight as ROS 1: bags by `rosbags` with each chunk compression,
/// and an MCAP of the `ros1` profile by `mcap-ros1-support`.
const ROS1_WRITES: [(&str, &[&str]); 4] = [
    (
        "bag-none.bag",
        &["--container", "bag", "--compression", "none"],
    ),
    (
        "bag-bz2.bag",
        &["--container", "bag", "--compression", "bz2"],
    ),
    (
        "bag-lz4.bag",
        &["--container", "bag", "--compression", "lz4"],
    ),
    ("ros1.mcap", &["--container", "mcap"]),
];

#[test]
fn ros1_bags_of_every_compression_and_ros1_mcap_ingest_to_the_ros2_tables() {
    let dir = tempfile::tempdir().unwrap();
    // Topics named explicitly too: ROS 1 types must pass the flags' checks.
    for (poses, images, flags) in [
        ("odometry", "jpeg", &["--pose-topic", "/odom"][..]),
        ("tf", "rgb8", &["--image-topic", "/camera/image_raw"][..]),
    ] {
        let name = format!("{poses}-{images}");
        let (mcap, expected) =
            write_flight(dir.path(), &name, &["--poses", poses, "--images", images]);
        let ros2 = dir.path().join(format!("run-{name}"));
        ingest_ok(&mcap, &ros2, &[]);
        let reference = tables_without_locations(&ros2);
        for (file, args) in ROS1_WRITES {
            let ros1 = dir.path().join(format!("{name}-{file}"));
            to_ros1(&mcap, &ros1, args);
            let run = dir.path().join(format!("run-{name}-{file}"));
            let summary = ingest_ok(&ros1, &run, flags);
            check_summary(&summary, &expected);
            check_frames(&run, &expected);
            check_pixels(&run, &expected, images);
            let (frames, trajectory, cameras) = tables_without_locations(&run);
            assert!(frames.equals_missing(&reference.0), "{name} {file}: frames");
            assert!(
                trajectory.equals_missing(&reference.1),
                "{name} {file}: trajectory"
            );
            assert_eq!(cameras, reference.2, "{name} {file}: cameras");
        }
    }
}

#[test]
fn a_bag_cut_at_60_percent_is_salvaged_and_flagged() {
    let dir = tempfile::tempdir().unwrap();
    let (mcap, expected) = write_flight(dir.path(), "flight", &["--duration", "20"]);
    // Compressed chunks of 64 KiB (the cut loses the chunk it falls in), and
    // one large uncompressed chunk whose front is salvaged.
    for (compression, chunk) in [("bz2", "65536"), ("lz4", "65536"), ("none", "1000000")] {
        let bag = dir.path().join(format!("{compression}.bag"));
        to_ros1(
            &mcap,
            &bag,
            &["--compression", compression, "--chunk-size", chunk],
        );
        let run = cut_and_ingest(&bag, dir.path(), compression, compression == "none");
        // The salvaged frames are exactly the first ones written.
        let all = expected["frames"].as_array().unwrap();
        let n = frames_table(&run).height();
        assert!(
            n >= all.len() / 2 && n < all.len(),
            "{compression}: salvaged {n} of {} frames",
            all.len()
        );
        // A frame after the last salvaged pose has none.
        let last_pose_ns = last_pose_ns(&run);
        let salvaged = all[..n].iter().map(|frame| {
            let mut frame = frame.clone();
            if frame["time_ns"].as_i64().unwrap() > last_pose_ns && frame["pose_status"] == "ok" {
                frame["pose_status"] = "after_trajectory".into();
                frame.as_object_mut().unwrap().remove("camera_pose");
            }
            frame
        });
        let mut salvaged: Vec<Value> = salvaged.collect();
        // The cut may fall between the last image and its exposure message.
        let exposures = frames_table(&run).column("exposure_s").unwrap().clone();
        if exposures.f64().unwrap().get(n - 1).is_none() {
            salvaged[n - 1]["exposure_s"] = Value::Null;
        }
        let mut prefix = expected.clone();
        prefix["frames"] = Value::Array(salvaged);
        check_frames(&run, &prefix);
    }
}

#[test]
fn an_unindexed_bag_reads_the_same_as_the_indexed_one() {
    let dir = tempfile::tempdir().unwrap();
    let (mcap, expected) = write_flight(dir.path(), "flight", &[]);
    for compression in ["none", "lz4"] {
        let indexed = dir.path().join(format!("{compression}.bag"));
        to_ros1(&mcap, &indexed, &["--compression", compression]);
        let unindexed = dir.path().join(format!("{compression}-unindexed.bag"));
        to_ros1(
            &mcap,
            &unindexed,
            &["--compression", compression, "--unindexed"],
        );
        assert!(
            std::fs::metadata(&unindexed).unwrap().len()
                < std::fs::metadata(&indexed).unwrap().len()
        );
        let runs = [indexed, unindexed].map(|bag| {
            let run = dir
                .path()
                .join(format!("run-{}", bag.file_stem().unwrap().display()));
            let summary = ingest_ok(&bag, &run, &[]);
            check_summary(&summary, &expected);
            (run, summary)
        });
        assert!(
            runs[1].1["warnings"].to_string().contains("no index"),
            "{}",
            runs[1].1["warnings"]
        );
        // Message locations too: the same chunks at the same offsets.
        assert!(frames_table(&runs[0].0).equals_missing(&frames_table(&runs[1].0)));
        assert!(
            read_parquet(&runs[0].0.join("trajectory.parquet"))
                .equals_missing(&read_parquet(&runs[1].0.join("trajectory.parquet")))
        );
    }
}

#[test]
fn gps_fixes_are_kept_as_recorded_by_ros2_and_ros1_and_place_the_map_on_the_earth() {
    let dir = tempfile::tempdir().unwrap();
    let (mcap, expected) = write_flight(dir.path(), "gps", &["--gps"]);
    let bag = dir.path().join("gps.bag");
    to_ros1(&mcap, &bag, &["--compression", "lz4"]);
    let want = expected["gnss"].as_array().unwrap();
    for flight in [mcap, bag] {
        let run = dir
            .path()
            .join(format!("run-{}", flight.display()).replace('/', "_"));
        ingest_ok(&flight, &run, &[]);
        let fixes = postflight_core::outputs::ingest::read_gnss(
            &postflight_core::RunDir::open(&run, postflight_core::Stage::Ingest).unwrap(),
        )
        .unwrap();
        assert_eq!(fixes.len(), want.len(), "{}", flight.display());
        for (got, want) in fixes.iter().zip(want) {
            assert_eq!(got.topic, "/dji_sdk/gps_position");
            assert_eq!(Some(got.time_ns), want["time_ns"].as_i64());
            assert_eq!(got.position.latitude_deg, f(&want["latitude_deg"]));
            assert_eq!(got.position.longitude_deg, f(&want["longitude_deg"]));
            assert_eq!(got.position.altitude_m, f(&want["altitude_m"]));
            assert_eq!(Some(i64::from(got.status)), want["status"].as_i64());
        }
        // The writer put the map's origin at 38.6916 N, 9.1770 W, 80 m,
        // east-north-up (on a sphere, a few centimetres off WGS 84 here).
        let geo = &read_json(&run.join("ingest.json"))["geo_origin"];
        let origin = &geo["origin"];
        let north_m = (f(&origin["latitude_deg"]) - 38.6916) * 111_000.0;
        let east_m = (f(&origin["longitude_deg"]) + 9.1770) * 111_000.0 * 0.78;
        assert!(north_m.hypot(east_m) < 0.2, "{geo}");
        assert!((f(&origin["altitude_m"]) - 80.0).abs() < 0.01, "{geo}");
        assert!(f(&origin["yaw_deg"]).abs() < 0.2, "{geo}");
        assert!(f(&geo["rms_m"]) < 0.05, "{geo}");
        // Fixes without a fix (every 10th), or without a pose at their
        // time, are left out.
        let fixed = want
            .iter()
            .filter(|w| w["status"].as_i64() >= Some(0))
            .count();
        let aligned = geo["fixes"].as_u64().unwrap() as usize;
        assert!(aligned <= fixed && aligned > fixed * 4 / 5, "{geo}");
    }
}

/// A named pipe given where postflight reads a file (settings, a map, a
/// plan, a model, a calibration) is refused in one line at once, not
/// waited on for ever (issue 57, item 5).
#[test]
fn named_pipes_given_as_inputs_are_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let (flight, _) = write_flight(dir.path(), "flight", &["--duration", "2"]);
    let run = dir.path().join("run");
    let ingested = run_ingest(&flight, &run, &[]);
    assert!(ingested.status.success(), "{}", stderr(&ingested));
    let pipe = dir.path().join("pipe");
    let made = std::process::Command::new("mkfifo")
        .arg(&pipe)
        .status()
        .unwrap();
    assert!(made.success());
    let (f, r, p) = (
        flight.to_str().unwrap(),
        run.to_str().unwrap(),
        pipe.to_str().unwrap(),
    );
    let out = dir.path().join("out");
    let o = out.to_str().unwrap();
    for (args, says) in [
        (
            &["run", "--flight", f, "--config", p, "--out", o][..],
            "pipe, socket or device",
        ),
        (
            &["run", "--flight", f, "--map", p, "--out", o],
            "is not a file",
        ),
        (
            &["ingest", "--flight", f, "--camera-info", p, "--out", o],
            "pipe, socket or device",
        ),
        (
            &["coverage", "--run", r, "--plan", p],
            "pipe, socket or device",
        ),
        (
            &["detect", "--run", r, "--model", p],
            "pipe, socket or device",
        ),
    ] {
        // Spawned and waited on with a deadline: a regression hangs here.
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_postflight"))
            .args(args)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let start = std::time::Instant::now();
        while child.try_wait().unwrap().is_none() {
            if start.elapsed().as_secs() > 60 {
                child.kill().unwrap();
                panic!("{args:?} waited on the pipe");
            }
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        assert_fails_in_one_line(&child.wait_with_output().unwrap(), says);
        assert!(!out.exists(), "{args:?} wrote {o}");
    }
}
