//! End-to-end detection speed: postflight's detect stage against the plain
//! Python onnxruntime + NumPy + Pillow pipeline (`detect/python/pipeline.py`,
//! the same pre- and post-processing) on the same simulated frames, in the
//! same run, with the shipped reference model.
//!
//! `cargo bench -p postflight-detect --bench detect_vs_python`
//! Environment: `POSTFLIGHT_BENCH_DIR` (default: the temp dir),
//! `POSTFLIGHT_BENCH_REPS` (default 3), `POSTFLIGHT_PYTHON` (default: the
//! project's `.venv/bin/python`).
//!
//! Flights: the default bridge flight (300 frames of 640x480 JPEG, the model
//! input size: no resizing), and 40 frames of 1920x1080 JPEG with 640 px
//! tiles (the whole frame resized, plus 6 full-resolution tiles per frame).
//! Frames/s count every frame, from opening the flight to writing the
//! outputs, session creation included.

use std::path::{Path, PathBuf};
use std::process::Command;

use detect::settings::{Off, Tile};
use detect::{DetectConfig, DetectOptions};
use postflight_core::outputs::detect::TileChoice;

/// A simulated, ingested flight to detect on.
struct Flight {
    name: &'static str,
    run: PathBuf,
    mcap: PathBuf,
    tile: Option<u32>,
}

impl Flight {
    fn simulate(
        dir: &Path,
        name: &'static str,
        frames: u32,
        (width, height): (u32, u32),
        tile: Option<u32>,
    ) -> Self {
        let sim_dir = dir.join(format!("{width}x{height}-sim"));
        let run = dir.join(format!("{width}x{height}-run"));
        let options = sim::SimOptions {
            frames,
            width,
            height,
            ..sim::SimOptions::new(sim_dir.clone())
        };
        sim::simulate(&options, &mut |_, _| {}).expect("simulate");
        let mcap = sim_dir.join("flight.mcap");
        let ingest = ingest::IngestOptions::new(vec![mcap.clone()], run.clone());
        ingest::ingest(&ingest, &mut |_, _| {}).expect("ingest");
        Self {
            name,
            run,
            mcap,
            tile,
        }
    }
}

/// Frames/s and share of the time inside `run`.
struct Speed {
    frames_per_s: f64,
    share: f64,
}

/// The median run by frames/s.
fn median(mut runs: Vec<Speed>) -> Speed {
    runs.sort_by(|a, b| a.frames_per_s.total_cmp(&b.frames_per_s));
    runs.swap_remove(runs.len() / 2)
}

fn python_pipeline(python: &Path, root: &Path, model: &Path, flight: &Flight, out: &Path) -> Speed {
    let mut cmd = Command::new(python);
    cmd.arg(root.join("detect/python/pipeline.py"))
        .args([&flight.mcap, model, out]);
    if let Some(t) = flight.tile {
        cmd.args(["--tile", &t.to_string()]);
    }
    assert!(
        cmd.status().expect("run python").success(),
        "pipeline.py failed"
    );
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(out).unwrap()).unwrap();
    let seconds = r["seconds"].as_f64().unwrap();
    Speed {
        frames_per_s: r["frames"].as_f64().unwrap() / seconds,
        share: r["run_seconds"].as_f64().unwrap() / seconds,
    }
}

fn main() {
    if std::env::args().any(|a| a == "--list" || a == "--test") {
        return; // `cargo test --benches` probes; nothing to list.
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
    let dir = tempfile::tempdir_in(
        std::env::var_os("POSTFLIGHT_BENCH_DIR")
            .map(PathBuf::from)
            .unwrap_or_else(std::env::temp_dir),
    )
    .expect("bench dir");
    let reps: usize = std::env::var("POSTFLIGHT_BENCH_REPS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3);
    let python = std::env::var_os("POSTFLIGHT_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join(".venv/bin/python"));
    let model = root.join("detect/models/crack-baked.onnx");

    eprintln!("simulating the flights ...");
    let flights = [
        Flight::simulate(dir.path(), "640x480", 300, (640, 480), None),
        Flight::simulate(
            dir.path(),
            "1920x1080, 640 px tiles",
            40,
            (1920, 1080),
            Some(640),
        ),
    ];
    println!("| flight | pipeline | frames/s | time in `run` | vs Python |");
    println!("|---|---|---|---|---|");
    for flight in &flights {
        let out = dir.path().join("python.json");
        let baseline = median(
            (0..reps)
                .map(|_| python_pipeline(&python, root, &model, flight, &out))
                .collect(),
        );
        for batch in [DetectConfig::default().batch, 1] {
            let mut options = DetectOptions::new(flight.run.clone(), model.clone());
            options.settings.tile = flight.tile.map_or(Tile::Off(Off::Off), Tile::Pixels);
            options.settings.batch = batch;
            let speed = median(
                (0..reps)
                    .map(|_| {
                        let s = detect::detect(
                            &options,
                            detect::TilesToRun::every(TileChoice::Every),
                            &mut |_| {},
                        )
                        .expect("detect");
                        Speed {
                            frames_per_s: s.frames_per_s,
                            share: s.inference_share,
                        }
                    })
                    .collect(),
            );
            println!(
                "| {} | postflight, batch {batch} | {:.1} | {:.0}% | {:.2}x |",
                flight.name,
                speed.frames_per_s,
                100.0 * speed.share,
                speed.frames_per_s / baseline.frames_per_s
            );
        }
        println!(
            "| {} | Python onnxruntime + NumPy + Pillow | {:.1} | {:.0}% | 1.00x |",
            flight.name,
            baseline.frames_per_s,
            100.0 * baseline.share
        );
    }
}
