//! Every parser under attack: recordings, maps, plans and GTSP instances
//! cut at every byte, bits flipped, lengths made absurd. A parser may refuse, salvage or skip, and must say
//! so; it must never panic or allocate what the input only claims to hold.
//! The damage is deterministic (seeded), so a failure reproduces.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::common::*;
use ingest::recording::{RecordedMessage, ScanEvent, ScanReport};
use ingest::ros::{Wire, msg, schema};
use sim::rng::Rng;

/// A small flight (tests/fixtures/write_flight.py's options): 45 messages.
const SMALL_FLIGHT: [&str; 10] = [
    "--duration",
    "0.3",
    "--width",
    "8",
    "--height",
    "6",
    "--cloud-points",
    "20",
    "--pose-hz",
    "20",
];

/// A small flight as ROS 1 bags of each compression, by `rosbags`.
fn small_bags(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let (mcap, _) = write_flight(dir, "small", &SMALL_FLIGHT);
    ["none", "bz2", "lz4"]
        .iter()
        .map(|compression| {
            let bag: PathBuf = dir.join(format!("small-{compression}.bag"));
            to_ros1(
                &mcap,
                &bag,
                &["--compression", compression, "--chunk-size", "4000"],
            );
            (compression.to_string(), std::fs::read(&bag).unwrap())
        })
        .collect()
}

/// One message as a scan met it: topic, log time and payload.
type Met = (String, u64, Vec<u8>);

/// Scan a recording held in memory (a bag, else MCAP), decoding every
/// message it meets by its channel's wire into the struct postflight reads
/// it as.
fn scan_and_decode(bytes: &[u8]) -> (Vec<Met>, ScanReport) {
    let mut channels: HashMap<u16, (String, String, Option<Wire>)> = HashMap::new();
    let mut met = Vec::new();
    let mut visit = |event: ScanEvent<'_>| match event {
        ScanEvent::Channel(c) => {
            let wire = Wire::of(&c.message_encoding, &c.schema, &c.definition).ok();
            channels.insert(c.id, (c.topic.clone(), c.schema.clone(), wire));
        }
        ScanEvent::Message(m) => {
            // A damaged file may hold messages of channels it never defines.
            let topic = match channels.get(&m.channel_id) {
                Some((topic, schema, Some(wire))) => {
                    decode_as_postflight_does(wire, schema, &m);
                    topic.clone()
                }
                Some((topic, _, None)) => topic.clone(),
                None => format!("(channel {})", m.channel_id),
            };
            met.push((topic, m.log_time, m.data.to_vec()));
        }
        ScanEvent::Progress { .. } => {}
    };
    let report = if bytes.starts_with(ingest::bag::MAGIC) {
        ingest::bag::scan(bytes, &mut visit)
    } else {
        ingest::recording::scan_mcap(bytes, &mut visit)
    };
    (met, report)
}

/// Decode a message as ingest and the later stages do; errors are fine.
fn decode_as_postflight_does(wire: &Wire, schema_name: &str, m: &RecordedMessage<'_>) {
    let data = m.data;
    match schema::ros2_name(schema_name).as_ref() {
        schema::IMAGE => drop(wire.image(data)),
        schema::COMPRESSED_IMAGE => drop(wire.compressed_image(data)),
        schema::CAMERA_INFO => drop(wire.decode::<msg::CameraInfo>(data)),
        schema::POSE_STAMPED => drop(wire.decode::<msg::PoseStamped>(data)),
        schema::ODOMETRY => drop(wire.decode::<msg::Odometry>(data)),
        schema::TF_MESSAGE => drop(wire.decode::<msg::TfMessage>(data)),
        schema::POINT_CLOUD2 => drop(wire.decode::<msg::PointCloud2>(data)),
        schema::FLOAT64 => drop(wire.decode::<msg::Float64>(data)),
        _ => {}
    }
}

#[test]
fn a_bag_cut_anywhere_gives_a_prefix_of_its_messages_and_says_it_is_truncated() {
    let dir = tempfile::tempdir().unwrap();
    for (compression, bytes) in small_bags(dir.path()) {
        // Every byte of the uncompressed bag; every 7th of the others
        // (decompressing each cut makes every byte slow in a debug build).
        let step = if compression == "none" { 1 } else { 7 };
        check_cuts(&compression, &bytes, 0, step);
    }
}

/// Cut `bytes` at every `step`th byte from `start`: each cut recording is
/// flagged truncated and gives a prefix of the whole one's messages.
fn check_cuts(label: &str, bytes: &[u8], start: usize, step: usize) {
    let (all, report) = scan_and_decode(bytes);
    assert!(!report.truncated && all.len() > 40, "{label}");
    for cut in (start..bytes.len()).step_by(step) {
        let (met, report) = scan_and_decode(&bytes[..cut]);
        assert!(report.truncated, "{label} cut at {cut}: not flagged");
        assert!(
            met.len() <= all.len() && met[..] == all[..met.len()],
            "{label} cut at {cut}: {} messages, not a prefix of the {}",
            met.len(),
            all.len()
        );
    }
}

#[test]
fn flipped_bits_and_absurd_lengths_in_a_bag_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = Rng::new(22);
    for (compression, bytes) in small_bags(dir.path()) {
        for _ in 0..3000 {
            let mut damaged = bytes.clone();
            let at = rng.next_u64() as usize % damaged.len();
            damaged[at] ^= 1 << (rng.next_u64() % 8);
            scan_and_decode(&damaged);
        }
        // Every u32 that could be a length, made 4 GB (one at a time).
        for at in (0..bytes.len() - 4).step_by(if compression == "none" { 1 } else { 5 }) {
            let mut damaged = bytes.clone();
            damaged[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
            scan_and_decode(&damaged);
        }
    }
}

#[test]
fn ros1_definitions_cut_or_flipped_parse_or_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let bags = small_bags(dir.path());
    let mut definitions = Vec::new();
    ingest::bag::scan(&bags[0].1, |event: ScanEvent<'_>| {
        if let ScanEvent::Channel(c) = event {
            definitions.push((c.schema.clone(), c.definition.clone()));
        }
    });
    assert!(definitions.len() >= 6);
    let mut rng = Rng::new(7);
    for (name, text) in definitions {
        for cut in (0..text.len()).filter(|&c| text.is_char_boundary(c)) {
            let _ = Wire::of("ros1", &name, &text[..cut]);
        }
        for _ in 0..500 {
            let mut bytes = text.clone().into_bytes();
            let at = rng.next_u64() as usize % bytes.len();
            bytes[at] = b"[]=#/ \nMSG:0123456789abc"[rng.next_u64() as usize % 23];
            let _ = Wire::of("ros1", &name, &String::from_utf8_lossy(&bytes));
        }
    }
}

#[test]
fn octomap_trees_cut_or_flipped_read_or_fail_cleanly() {
    use nalgebra::Point3;
    use postflight_core::map::octomap::{Format, parse};
    let dir = tempfile::tempdir().unwrap();
    let points: Vec<Point3<f64>> = (0..200)
        .map(|i| {
            Point3::new(
                f64::from(i % 7),
                f64::from(i % 11) * 0.3,
                f64::from(i / 20) * 0.2,
            )
        })
        .collect();
    let trees = octomap_of(dir.path(), "small", &points, 0.1);
    let mut rng = Rng::new(3);
    for (tree, format) in trees.iter().zip([Format::Binary, Format::Full]) {
        let bytes = std::fs::read(tree).unwrap();
        let whole = parse(&bytes, format).unwrap();
        assert!(whole.points.len() >= 100);
        for cut in 0..bytes.len() {
            // A cut tree is an error, or (cut inside the header's comments)
            // nothing at all; never a panic.
            if let Ok(map) = parse(&bytes[..cut], format) {
                assert!(map.points.len() <= whole.points.len());
            }
        }
        for _ in 0..3000 {
            let mut damaged = bytes.clone();
            let at = rng.next_u64() as usize % damaged.len();
            damaged[at] ^= 1 << (rng.next_u64() % 8);
            let _ = parse(&damaged, format);
        }
    }
}

/// A small ROS 2 flight as MCAP, by the Python `mcap` writer, with each
/// chunk compression.
fn small_mcaps(dir: &Path) -> Vec<(String, Vec<u8>)> {
    ["zstd", "lz4", "none"]
        .iter()
        .map(|compression| {
            let mut args = SMALL_FLIGHT.to_vec();
            args.extend(["--compression", compression, "--chunk-size", "2000"]);
            let (mcap, _) = write_flight(dir, &format!("small-{compression}"), &args);
            (compression.to_string(), std::fs::read(mcap).unwrap())
        })
        .collect()
}

#[test]
fn an_mcap_cut_anywhere_gives_a_prefix_of_its_messages_and_damage_never_panics() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = Rng::new(9);
    for (compression, bytes) in small_mcaps(dir.path()) {
        // From past the magic bytes (a shorter file is not an MCAP file).
        check_cuts(
            &compression,
            &bytes,
            8,
            if compression == "none" { 1 } else { 3 },
        );
        for _ in 0..3000 {
            let mut damaged = bytes.clone();
            let at = rng.next_u64() as usize % damaged.len();
            damaged[at] ^= 1 << (rng.next_u64() % 8);
            scan_and_decode(&damaged);
        }
        for at in (8..bytes.len() - 8).step_by(3) {
            let mut damaged = bytes.clone();
            let absurd: &[u8] = if at % 2 == 0 {
                &u32::MAX.to_le_bytes()
            } else {
                &u64::MAX.to_le_bytes()
            };
            damaged[at..at + absurd.len()].copy_from_slice(absurd);
            scan_and_decode(&damaged);
        }
    }
}

/// Every prefix and a few thousand single-bit flips of `bytes`, through `parse`.
fn attack(bytes: &[u8], step: usize, rng: &mut Rng, mut parse: impl FnMut(&[u8])) {
    for cut in (0..bytes.len()).step_by(step) {
        parse(&bytes[..cut]);
    }
    for _ in 0..2000 {
        let mut damaged = bytes.to_vec();
        let at = rng.next_u64() as usize % damaged.len();
        damaged[at] ^= 1 << (rng.next_u64() % 8);
        parse(&damaged);
    }
}

#[test]
fn ply_and_pcd_maps_cut_or_flipped_read_or_fail_cleanly() {
    use postflight_core::map::PointCloud;
    let points: Vec<[f32; 3]> = (0..40)
        .map(|i| [i as f32, (i % 7) as f32 * 0.5, 1.25])
        .collect();
    let ascii: String = points
        .iter()
        .map(|p| format!("{} {} {}\n", p[0], p[1], p[2]))
        .collect();
    let binary: Vec<u8> = points
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let ply = |format: &str| {
        format!("ply\nformat {format} 1.0\nelement vertex 40\nproperty float x\nproperty float y\nproperty float z\nend_header\n").into_bytes()
    };
    let pcd = |data: &str| {
        format!("# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 40\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 40\nDATA {data}\n").into_bytes()
    };
    let files = [
        ("ply", [ply("ascii"), ascii.clone().into_bytes()].concat()),
        (
            "ply",
            [ply("binary_little_endian"), binary.clone()].concat(),
        ),
        ("pcd", [pcd("ascii"), ascii.into_bytes()].concat()),
        ("pcd", [pcd("binary"), binary].concat()),
    ];
    let mut rng = Rng::new(11);
    for (ext, bytes) in files {
        assert_eq!(
            PointCloud::parse(&bytes, ext).unwrap().points.len(),
            40,
            "{ext}"
        );
        attack(&bytes, 1, &mut rng, |b| drop(PointCloud::parse(b, ext)));
        // Absurd counts: a header claiming 4 billion points in a few bytes.
        let text = String::from_utf8_lossy(&bytes).replace(" 40\n", " 4294967295\n");
        let _ = PointCloud::parse(text.as_bytes(), ext);
    }
}

#[test]
fn gtsp_instances_and_plans_cut_or_flipped_read_or_fail_cleanly() {
    let mut rng = Rng::new(5);
    let gtsp = std::fs::read(root().join("tests/fixtures/gtsp/tiny.gtsp")).unwrap();
    assert!(gtsp::Instance::parse("tiny", &String::from_utf8_lossy(&gtsp)).is_ok());
    attack(&gtsp, 1, &mut rng, |b| {
        let _ = gtsp::Instance::parse("tiny", &String::from_utf8_lossy(b));
    });
    let huge = String::from_utf8_lossy(&gtsp).replace("DIMENSION", "DIMENSION : 4294967295\nX");
    let _ = gtsp::Instance::parse("huge", &huge);

    let dir = tempfile::tempdir().unwrap();
    let sim = simulate_into(dir.path(), "sim", &["--frames", "20"]);
    let plan = std::fs::read(sim.join("plan.json")).unwrap();
    let path = dir.path().join("damaged.json");
    attack(&plan, plan.len() / 400 + 1, &mut rng, |b| {
        std::fs::write(&path, b).unwrap();
        let _ = postflight_core::InspectionPlan::load(&path);
    });
}

#[test]
fn waypoint_paths_and_target_boxes_cut_or_flipped_read_or_fail_in_one_line() {
    use postflight_core::{FlownPlan, PlanFile};
    let dir = tempfile::tempdir().unwrap();
    let mut rng = Rng::new(17);
    let rows: String = (0..30)
        .map(|i| format!("{}.5,{},{}.25,{}\n", i, -i, i % 4, f64::from(i) * 0.1))
        .collect();
    let csv = format!("X,Y,Z,Yaw\n{rows}").into_bytes();
    let file = PlanFile::new(dir.path().join("path.csv"));
    let load = |bytes: &[u8]| {
        std::fs::write(&file.path, bytes).unwrap();
        match file.load() {
            Ok(FlownPlan::Path(points)) => assert!(points.len() <= 30),
            Ok(other) => panic!("a CSV read as {other:?}"),
            Err(e) => assert!(!e.to_string().contains('\n'), "{e}"),
        }
    };
    load(&csv);
    attack(&csv, 1, &mut rng, load);
    // Absurd rows: a million columns, a megabyte number; each refused by line.
    let wide = format!("1,2,3,0\n{}\n", "1,".repeat(1_000_000));
    let long = format!("1,2,3,0\n1,2,{},0\n", "9".repeat(1_000_000));
    for text in [wide, long] {
        std::fs::write(&file.path, &text).unwrap();
        let err = file.load().unwrap_err().to_string();
        assert!(
            err.contains("line 2") && !err.contains('\n'),
            "{}",
            &err[..200.min(err.len())]
        );
    }

    let boxes =
        br#"[{"min": [0, 0, 0], "max": [1, 2, 3]}, {"min": [-5, -5, 0], "max": [5, 5, 10]}]"#;
    let path = dir.path().join("boxes.json");
    attack(boxes, 1, &mut rng, |b| {
        std::fs::write(&path, b).unwrap();
        if let Err(e) = targets::source::load_boxes(&path) {
            assert!(!e.to_string().contains('\n'), "{e}");
        }
    });
    std::fs::write(&path, "[{\"min\": [0, 0, 0],\n \"max\": [1, 2]}]").unwrap();
    let err = targets::source::load_boxes(&path).unwrap_err().to_string();
    assert!(err.contains("line 2 column"), "{err}");
}
