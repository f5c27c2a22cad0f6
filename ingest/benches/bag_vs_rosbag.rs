//! Walking every message of a ROS 1 bag: postflight's reader (`bag::scan`)
//! against the `rosbag` crate (`RosBag::chunk_records`, then each chunk's
//! `messages()`), the obvious alternative. Both visit every message record
//! and sum its payload length; the file is in the page cache (warm).
//!
//! `cargo bench -p postflight-ingest --bench bag_vs_rosbag`
//! Environment: `POSTFLIGHT_BENCH_DIR` (default: the temp dir),
//! `POSTFLIGHT_BENCH_GB` (default 1), `POSTFLIGHT_BENCH_REPS` (default 5).
//!
//! The bag mimics an inspection flight recorded with `rosbag record`:
//! 500 KB camera frames (incompressible, like JPEG) at 10 Hz, odometry at
//! 100 Hz and IMU at 200 Hz, in 768 KiB chunks, written uncompressed and
//! with lz4 chunks by the small writer below (the reader's correctness is
//! tested against bags written by the Python `rosbags` package).

use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use ingest::recording::ScanEvent;

/// A bag record: header fields, then data.
fn record(out: &mut Vec<u8>, fields: &[(&str, &[u8])], data: &[u8]) {
    let header: Vec<u8> = fields
        .iter()
        .flat_map(|(name, value)| {
            let len = (name.len() + 1 + value.len()) as u32;
            let mut f = len.to_le_bytes().to_vec();
            f.extend(name.as_bytes());
            f.push(b'=');
            f.extend(*value);
            f
        })
        .collect();
    out.extend((header.len() as u32).to_le_bytes());
    out.extend(header);
    out.extend((data.len() as u32).to_le_bytes());
    out.extend(data);
}

/// A topic: its connection id, name, type and (short) definition.
struct Topic {
    conn: u32,
    name: &'static str,
    ty: &'static str,
    size: usize,
    hz: u32,
}

const TOPICS: [Topic; 3] = [
    Topic {
        conn: 0,
        name: "/camera/image_raw/compressed",
        ty: "sensor_msgs/CompressedImage",
        size: 500_000,
        hz: 10,
    },
    Topic {
        conn: 1,
        name: "/odom",
        ty: "nav_msgs/Odometry",
        size: 700,
        hz: 100,
    },
    Topic {
        conn: 2,
        name: "/imu",
        ty: "sensor_msgs/Imu",
        size: 320,
        hz: 200,
    },
];

fn connection(out: &mut Vec<u8>, t: &Topic) {
    let mut data = Vec::new();
    for (k, v) in [
        ("topic", t.name),
        ("type", t.ty),
        ("md5sum", "00000000000000000000000000000000"),
        ("message_definition", "uint8[] data\n"),
    ] {
        data.extend(((k.len() + 1 + v.len()) as u32).to_le_bytes());
        data.extend(format!("{k}={v}").as_bytes());
    }
    record(
        out,
        &[
            ("op", &[0x07]),
            ("conn", &t.conn.to_le_bytes()),
            ("topic", t.name.as_bytes()),
        ],
        &data,
    );
}

fn write_bag(path: &Path, gigabytes: f64, lz4: bool) {
    let mut file = BufWriter::new(File::create(path).unwrap());
    file.write_all(ingest::bag::MAGIC).unwrap();
    // The bag header is rewritten at the end with the index position.
    let header_at = file.stream_position().unwrap();
    // Padded to 4096 bytes, as rosbag writes it, so it can be rewritten in place.
    let bag_header = |index_pos: u64, chunks: u32| {
        let fields: [(&str, &[u8]); 4] = [
            ("op", &[0x03]),
            ("index_pos", &index_pos.to_le_bytes()),
            ("conn_count", &3u32.to_le_bytes()),
            ("chunk_count", &chunks.to_le_bytes()),
        ];
        let mut out = Vec::new();
        record(&mut out, &fields, &[]);
        let padding = vec![b' '; 4096 - out.len()];
        out.clear();
        record(&mut out, &fields, &padding);
        out
    };
    file.write_all(&bag_header(0, 0)).unwrap();
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut noise = |n: usize| -> Vec<u8> {
        (0..n)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                state as u8
            })
            .collect()
    };
    let frame = noise(TOPICS[0].size);
    let (odom, imu) = (noise(TOPICS[1].size), noise(TOPICS[2].size));
    let target = (gigabytes * 1e9) as u64;
    let (mut chunk, mut chunk_infos, mut written) = (Vec::new(), Vec::new(), 0u64);
    let mut flush = |chunk: &mut Vec<u8>, file: &mut BufWriter<File>, last: bool| {
        let full = chunk.len() >= 768 * 1024;
        if !full && (!last || chunk.is_empty()) {
            return;
        }
        let pos = file.stream_position().unwrap();
        let (compression, data): (&str, Vec<u8>) = if lz4 {
            let mut enc = lz4::EncoderBuilder::new().build(Vec::new()).unwrap();
            enc.write_all(chunk).unwrap();
            ("lz4", enc.finish().0)
        } else {
            ("none", chunk.clone())
        };
        let mut out = Vec::new();
        record(
            &mut out,
            &[
                ("op", &[0x05]),
                ("compression", compression.as_bytes()),
                ("size", &(chunk.len() as u32).to_le_bytes()),
            ],
            &data,
        );
        file.write_all(&out).unwrap();
        chunk_infos.push(pos);
        chunk.clear();
    };
    for t in &TOPICS {
        connection(&mut chunk, t);
    }
    let mut tick = 0u64; // 200 Hz
    while written < target {
        let time = 1_700_000_000u64 * 1_000_000_000 + tick * 5_000_000;
        let stamp = [
            ((time / 1_000_000_000) as u32).to_le_bytes(),
            ((time % 1_000_000_000) as u32).to_le_bytes(),
        ]
        .concat();
        for (t, payload) in TOPICS.iter().zip([&frame, &odom, &imu]) {
            if tick.is_multiple_of(u64::from(200 / t.hz)) {
                record(
                    &mut chunk,
                    &[
                        ("op", &[0x02]),
                        ("conn", &t.conn.to_le_bytes()),
                        ("time", &stamp),
                    ],
                    payload,
                );
                written += payload.len() as u64;
            }
        }
        flush(&mut chunk, &mut file, false);
        tick += 1;
    }
    flush(&mut chunk, &mut file, true);
    let index_pos = file.stream_position().unwrap();
    let mut index = Vec::new();
    for t in &TOPICS {
        connection(&mut index, t);
    }
    for pos in &chunk_infos {
        record(
            &mut index,
            &[
                ("op", &[0x06]),
                ("ver", &1u32.to_le_bytes()),
                ("chunk_pos", &pos.to_le_bytes()),
                ("start_time", &[0; 8]),
                ("end_time", &[0; 8]),
                ("count", &3u32.to_le_bytes()),
            ],
            &[0; 24],
        );
    }
    file.write_all(&index).unwrap();
    file.seek(std::io::SeekFrom::Start(header_at)).unwrap();
    file.write_all(&bag_header(index_pos, chunk_infos.len() as u32))
        .unwrap();
    file.flush().unwrap();
}

fn postflight(path: &Path) -> (u64, u64) {
    let file = File::open(path).unwrap();
    // SAFETY: a read-only map of a file this benchmark wrote.
    let map = unsafe { memmap2::Mmap::map(&file) }.unwrap();
    let (mut messages, mut bytes) = (0, 0);
    let report = ingest::bag::scan(&map, |event: ScanEvent<'_>| {
        if let ScanEvent::Message(m) = event {
            messages += 1;
            bytes += m.data.len() as u64;
        }
    });
    assert!(!report.truncated && report.corrupt_chunks == 0);
    (messages, bytes)
}

fn rosbag_crate(path: &Path) -> (u64, u64) {
    use rosbag::{ChunkRecord, MessageRecord, RosBag};
    let bag = RosBag::new(path).unwrap();
    let (mut messages, mut bytes) = (0, 0);
    for record in bag.chunk_records() {
        if let ChunkRecord::Chunk(chunk) = record.unwrap() {
            for m in chunk.messages() {
                if let MessageRecord::MessageData(m) = m.unwrap() {
                    messages += 1;
                    bytes += m.data.len() as u64;
                }
            }
        }
    }
    (messages, bytes)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let dir: PathBuf = std::env::var_os("POSTFLIGHT_BENCH_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(std::env::temp_dir);
    let env = |k: &str, d: f64| {
        std::env::var(k)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(d)
    };
    let gigabytes = env("POSTFLIGHT_BENCH_GB", 1.0);
    let reps = env("POSTFLIGHT_BENCH_REPS", 5.0) as usize;
    println!("| chunks | size | postflight | rosbag crate | rosbag / postflight |");
    println!("|---|---|---|---|---|");
    for lz4 in [false, true] {
        let path = dir.join(format!("bench-{}.bag", if lz4 { "lz4" } else { "none" }));
        write_bag(&path, gigabytes, lz4);
        let size = std::fs::metadata(&path).unwrap().len() as f64;
        // Warm the cache and check both readers see the same messages.
        let (ours, theirs) = (postflight(&path), rosbag_crate(&path));
        assert_eq!(ours, theirs, "the readers disagree");
        let time = |f: fn(&Path) -> (u64, u64)| {
            median(
                (0..reps)
                    .map(|_| {
                        let start = Instant::now();
                        std::hint::black_box(f(&path));
                        start.elapsed().as_secs_f64()
                    })
                    .collect(),
            )
        };
        let (a, b) = (time(postflight), time(rosbag_crate));
        println!(
            "| {} | {:.2} GB, {} messages | {a:.3} s ({:.1} GB/s) | {b:.3} s ({:.1} GB/s) | {:.2}x |",
            if lz4 { "lz4" } else { "uncompressed" },
            size / 1e9,
            ours.0,
            size / a / 1e9,
            size / b / 1e9,
            b / a
        );
        std::fs::remove_file(&path).ok();
    }
}
