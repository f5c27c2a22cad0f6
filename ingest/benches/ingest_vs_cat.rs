//! Metadata-only ingest of a multi-GB flight recording against reading the
//! file once with `cat f > /dev/null`, cold (page cache dropped, when
//! permitted) and warm.
//!
//! `cargo bench -p postflight-ingest --bench ingest_vs_cat`
//! Environment: `POSTFLIGHT_BENCH_DIR` (default: the temp dir),
//! `POSTFLIGHT_BENCH_GB` (default 2), `POSTFLIGHT_BENCH_REPS` (default 3).
//!
//! The recording mimics a rosbag2 MCAP of an inspection flight: 1920x1080
//! JPEG frames at 10 Hz, CameraInfo, odometry at 100 Hz, IMU at 200 Hz,
//! /tf_static, in 768 KiB chunks (rosbag2's default), written twice:
//! uncompressed (rosbag2's default) and zstd-compressed.

use std::fs::File;
use std::io::{BufWriter, Cursor};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use ingest::ros::cdr::encode;
use ingest::ros::msg::*;

fn header(ns: i64, frame_id: &str) -> Header {
    Header {
        stamp: Time {
            sec: (ns / 1_000_000_000) as i32,
            nanosec: (ns % 1_000_000_000) as u32,
        },
        frame_id: frame_id.into(),
    }
}

fn jpeg_frame() -> Vec<u8> {
    // Concrete-like noise so the JPEG has a realistic size (~0.5 MB).
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let img = image::RgbImage::from_fn(1920, 1080, |x, y| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let n = (state & 0x3f) as u8;
        let base = 110 + ((x / 40 + y / 30) % 3) as u8 * 10;
        image::Rgb([base + n, base + n, base + n / 2])
    });
    let mut out = Cursor::new(Vec::new());
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 90)
        .encode_image(&img)
        .expect("encode JPEG");
    out.into_inner()
}

fn schema(w: &mut mcap::Writer<BufWriter<File>>, name: &str, topic: &str) -> u16 {
    let s = w.add_schema(name, "ros2msg", b"").unwrap();
    w.add_channel(s, topic, "cdr", &Default::default()).unwrap()
}

fn write_recording(
    path: &Path,
    gigabytes: f64,
    compression: Option<mcap::Compression>,
    jpeg: &[u8],
) {
    let file = BufWriter::with_capacity(1 << 20, File::create(path).unwrap());
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .compression(compression)
        .chunk_size(Some(768 * 1024))
        .create(file)
        .unwrap();
    let image = schema(
        &mut w,
        "sensor_msgs/msg/CompressedImage",
        "/camera/image_raw/compressed",
    );
    let info = schema(&mut w, "sensor_msgs/msg/CameraInfo", "/camera/camera_info");
    let odom = schema(&mut w, "nav_msgs/msg/Odometry", "/odom");
    let imu = schema(&mut w, "sensor_msgs/msg/Imu", "/imu");
    let tf = schema(&mut w, "tf2_msgs/msg/TFMessage", "/tf_static");
    let t0: i64 = 1_700_000_000_000_000_000;
    let mut seq = 0u32;
    let mut put = |w: &mut mcap::Writer<_>, channel_id: u16, ns: i64, data: &[u8]| {
        seq += 1;
        let h = mcap::records::MessageHeader {
            channel_id,
            sequence: seq,
            log_time: ns as u64,
            publish_time: ns as u64,
        };
        w.write_to_known_channel(&h, data).unwrap();
    };
    let identity = Quaternion {
        x: 0.0,
        y: 0.0,
        z: 0.0,
        w: 1.0,
    };
    let zero = Vector3 {
        x: 0.0,
        y: 0.0,
        z: 0.0,
    };
    let static_tf = TfMessage {
        transforms: vec![TransformStamped {
            header: header(t0, "base_link"),
            child_frame_id: "camera_optical".into(),
            transform: Transform {
                translation: zero,
                rotation: Quaternion {
                    x: -0.5,
                    y: 0.5,
                    z: -0.5,
                    w: 0.5,
                },
            },
        }],
    };
    put(&mut w, tf, t0, &encode(&static_tf));
    let frames = (gigabytes * 1e9 / jpeg.len() as f64) as i64;
    for i in 0..frames * 20 {
        // 200 Hz base tick: IMU every tick, odometry every 2nd, images every 20th.
        let ns = t0 + i * 5_000_000;
        let x = i as f64 * 0.01;
        let imu_msg = (
            header(ns, "imu"),
            identity,
            [0.0f64; 9],
            zero,
            [0.0f64; 9],
            zero,
            [0.0f64; 9],
        );
        put(&mut w, imu, ns, &encode(&imu_msg));
        if i % 2 == 0 {
            let o = Odometry {
                header: header(ns, "map"),
                child_frame_id: "base_link".into(),
                pose: PoseWithCovariance {
                    pose: Pose {
                        position: Vector3 { x, y: 0.0, z: 10.0 },
                        orientation: identity,
                    },
                    covariance: [[0.0; 6]; 6],
                },
                twist: TwistWithCovariance {
                    twist: Twist {
                        linear: zero,
                        angular: zero,
                    },
                    covariance: [[0.0; 6]; 6],
                },
            };
            put(&mut w, odom, ns, &encode(&o));
        }
        if i % 20 == 0 {
            let img = CompressedImage {
                header: header(ns, "camera_optical"),
                format: "jpeg".into(),
                data: jpeg.to_vec(),
            };
            put(&mut w, image, ns + 20_000_000, &encode(&img));
            let ci = CameraInfo {
                header: header(ns, "camera_optical"),
                height: 1080,
                width: 1920,
                distortion_model: "plumb_bob".into(),
                d: vec![-0.2, 0.05, 0.0, 0.0, 0.0],
                k: [1400.0, 0.0, 960.0, 0.0, 1400.0, 540.0, 0.0, 0.0, 1.0],
                r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                p: [
                    1400.0, 0.0, 960.0, 0.0, 0.0, 1400.0, 540.0, 0.0, 0.0, 0.0, 1.0, 0.0,
                ],
                binning_x: 0,
                binning_y: 0,
                roi: RegionOfInterest {
                    x_offset: 0,
                    y_offset: 0,
                    height: 0,
                    width: 0,
                    do_rectify: false,
                },
            };
            put(&mut w, info, ns + 20_000_000, &encode(&ci));
        }
    }
    w.finish().unwrap();
}

fn drop_caches() -> bool {
    let _ = Command::new("sync").status();
    std::fs::write("/proc/sys/vm/drop_caches", "3").is_ok()
}

fn time_cat(path: &Path) -> f64 {
    let start = Instant::now();
    let status = Command::new("cat")
        .arg(path)
        .stdout(Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    start.elapsed().as_secs_f64()
}

fn time_ingest(path: &Path, out: &Path) -> (f64, postflight_core::outputs::ingest::IngestSummary) {
    let options = ingest::IngestOptions::new(vec![path.to_owned()], out.to_owned());
    let start = Instant::now();
    let summary = ingest::ingest(&options, &mut |_: u64, _: u64| {}).unwrap();
    (start.elapsed().as_secs_f64(), summary)
}

/// The obvious alternative: the mcap crate's own message iterator, counting
/// messages only (it copies every record and decompresses on one thread).
fn time_mcap_stream(path: &Path) -> f64 {
    let file = File::open(path).unwrap();
    let start = Instant::now();
    // SAFETY: read-only map of a file nobody modifies during the benchmark.
    let map = unsafe { memmap2::Mmap::map(&file) }.unwrap();
    let mut n = 0usize;
    for message in mcap::MessageStream::new(&map).unwrap() {
        message.unwrap();
        n += 1;
    }
    assert!(n > 0);
    start.elapsed().as_secs_f64()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    if std::env::args().any(|a| a == "--list" || a == "--test") {
        return; // `cargo test --benches` probes; nothing to list.
    }
    let dir: PathBuf = std::env::var_os("POSTFLIGHT_BENCH_DIR")
        .map(Into::into)
        .unwrap_or_else(std::env::temp_dir);
    let gigabytes: f64 = std::env::var("POSTFLIGHT_BENCH_GB")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2.0);
    let reps: usize = std::env::var("POSTFLIGHT_BENCH_REPS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3);
    std::fs::create_dir_all(&dir).unwrap();
    let jpeg = jpeg_frame();
    println!("frame: 1920x1080 JPEG of {} KB", jpeg.len() / 1000);
    let run = tempfile::tempdir().unwrap();
    for (name, compression) in [
        ("uncompressed", None),
        ("zstd", Some(mcap::Compression::Zstd)),
    ] {
        let path = dir.join(format!("postflight-bench-{gigabytes}gb-{name}.mcap"));
        if !path.exists() {
            eprintln!("writing {}", path.display());
            write_recording(&path, gigabytes, compression, &jpeg);
        }
        let size = std::fs::metadata(&path).unwrap().len() as f64;
        let cold = drop_caches();
        for (label, drop) in [("cold", true), ("warm", false)] {
            if drop && !cold {
                println!("{name}: cannot drop the page cache here (not root?); cold runs skipped");
                continue;
            }
            let (mut cat, mut ing, mut stream) = (Vec::new(), Vec::new(), Vec::new());
            let mut frames = 0;
            if !drop {
                time_cat(&path); // warm the cache
            }
            for _ in 0..reps {
                if drop {
                    drop_caches();
                }
                cat.push(time_cat(&path));
                if drop {
                    drop_caches();
                }
                let (t, s) = time_ingest(&path, run.path());
                frames = s.frames;
                ing.push(t);
                if drop {
                    drop_caches();
                }
                stream.push(time_mcap_stream(&path));
            }
            let (c, i, m) = (median(cat), median(ing), median(stream));
            println!(
                "{name:>12} {label}: {:.2} GB, {frames} frames | cat {c:.3} s ({:.0} MB/s) | ingest {i:.3} s ({:.0} MB/s) | ingest/cat = {:.2}x | mcap::MessageStream {m:.3} s = {:.1}x ingest",
                size / 1e9,
                size / c / 1e6,
                size / i / 1e6,
                i / c,
                m / i
            );
        }
    }
}
