//! End-to-end tests of `postflight detect` with the shipped reference
//! detectors on a simulated flight, scored against truth.json.

mod common;

use std::path::{Path, PathBuf};

use common::*;
use polars::prelude::*;

fn models() -> PathBuf {
    root().join("detect/models")
}

fn detect(run: &Path, args: &[&str]) -> std::process::Output {
    let mut all = vec!["detect", "--run", run.to_str().unwrap()];
    all.extend_from_slice(args);
    postflight(&all, run.parent().unwrap())
}

/// Detections per frame time: boxes `[x0, y0, x1, y1]` and prompts.
fn detections(run: &Path) -> Vec<(i64, [f64; 4], String)> {
    let df = ParquetReader::new(std::fs::File::open(run.join("detections.parquet")).unwrap())
        .finish()
        .unwrap();
    let time = df.column("time_ns").unwrap().i64().unwrap().clone();
    let coord = |c: &str| df.column(c).unwrap().f32().unwrap().clone();
    let (x0, y0, x1, y1) = (coord("x0"), coord("y0"), coord("x1"), coord("y1"));
    let prompt = df.column("prompt").unwrap().str().unwrap().clone();
    (0..df.height())
        .map(|i| {
            let b = [x0.get(i), y0.get(i), x1.get(i), y1.get(i)].map(|v| f64::from(v.unwrap()));
            (time.get(i).unwrap(), b, prompt.get(i).unwrap().to_string())
        })
        .collect()
}

fn iou(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    let ix = (a[2].min(b[2]) - a[0].max(b[0])).max(0.0);
    let iy = (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
    let inter = ix * iy;
    let union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter;
    if union > 0.0 { inter / union } else { 0.0 }
}

/// Truth crack views at least 20 px long found by a box with IoU >= 0.3:
/// (found, views).
fn score(truth: &serde_json::Value, found: &[(i64, [f64; 4], String)]) -> (u32, u32) {
    let (mut views, mut hit) = (0, 0);
    for frame in truth["frames"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["dropped"] == false)
    {
        let t = frame["time_ns"].as_i64().unwrap();
        for c in frame["cracks"].as_array().unwrap() {
            let b: Vec<f64> = c["bbox"].as_array().unwrap().iter().map(f).collect();
            let b = [b[0], b[1], b[2], b[3]];
            if (b[2] - b[0]).max(b[3] - b[1]) < 20.0 {
                continue;
            }
            views += 1;
            if found
                .iter()
                .any(|(ft, fb, _)| *ft == t && iou(fb, &b) >= 0.3)
            {
                hit += 1;
            }
        }
    }
    (hit, views)
}

#[test]
fn reference_detectors_find_simulated_cracks_through_both_interfaces() {
    let dir = tempfile::tempdir().unwrap();
    let sim = simulate_into(dir.path(), "sim", &["--frames", "120", "--seed", "4"]);
    let run = dir.path().join("run");
    ingest_ok(&sim.join("flight.mcap"), &run, &[]);

    let baked = models().join("crack-baked.onnx");
    let out = detect(&run, &["--model", baked.to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    let summary = read_json(&run.join("detect.json"));
    let found = detections(&run);
    assert_eq!(summary["detections"].as_u64().unwrap(), found.len() as u64);
    assert_eq!(summary["frames_run"], summary["frames"]);
    assert_eq!(summary["classes"], serde_json::json!(["crack"]));

    // COCO: every annotation refers to an image and a category.
    let coco = read_json(&run.join("detections.coco.json"));
    let images = coco["images"].as_array().unwrap();
    assert_eq!(images.len() as u64, summary["frames"].as_u64().unwrap());
    for a in coco["annotations"].as_array().unwrap() {
        let id = a["image_id"].as_u64().unwrap();
        assert!(images.iter().any(|i| i["id"].as_u64() == Some(id)));
        assert_eq!(a["category_id"], 1);
    }

    // Scored against truth: crack views at least 20 px long.
    let truth = read_json(&sim.join("truth.json"));
    let (hit, views) = score(&truth, &found);
    let recall = f64::from(hit) / f64::from(views.max(1));
    eprintln!(
        "reference detector: {hit} of {views} crack views found (recall {recall:.2}), {} boxes",
        found.len()
    );
    assert!(views >= 5, "the test flight should show cracks");
    assert!(recall >= 0.5, "recall {recall:.2}");

    // The open-vocabulary export with the "crack" prompt finds the same boxes;
    // a prompt unrelated to cracks finds none.
    let open = models().join("crack-open.onnx");
    let prompts = models().join("prompts.json");
    let args = [
        "--model",
        open.to_str().unwrap(),
        "--embeddings",
        prompts.to_str().unwrap(),
    ];
    let out = detect(&run, &[&args[..], &["--prompt", "crack"]].concat());
    assert!(out.status.success(), "{}", stderr(&out));
    let via_open = detections(&run);
    assert_eq!(via_open.len(), found.len());
    for ((t0, b0, _), (t1, b1, p1)) in found.iter().zip(&via_open) {
        assert_eq!((t0, p1.as_str()), (t1, "crack"));
        assert!(b0.iter().zip(b1).all(|(a, b)| (a - b).abs() < 1e-3));
    }
    let out = detect(&run, &[&args[..], &["--prompt", "stain"]].concat());
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(detections(&run).is_empty());

    // Bad input: the open model without embeddings, a prompt with none.
    let out = detect(&run, &["--model", open.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("--embeddings"), "{}", stderr(&out));
    let out = detect(&run, &["--model", baked.to_str().unwrap(), "--tile", "8"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("--tile must be"), "{}", stderr(&out));
    let out = detect(&run, &[&args[..], &["--prompt", "pothole"]].concat());
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("\"pothole\""), "{}", stderr(&out));
}

#[test]
fn tiles_find_cracks_that_a_shrunk_frame_loses() {
    let dir = tempfile::tempdir().unwrap();
    let sim = simulate_into(
        dir.path(),
        "sim",
        &["--frames", "20", "--width", "1920", "--height", "1080"],
    );
    let run = dir.path().join("run");
    ingest_ok(&sim.join("flight.mcap"), &run, &[]);
    let truth = read_json(&sim.join("truth.json"));
    let baked = models().join("crack-baked.onnx");

    // Shrunk 3x to the 640 px input, mm-wide cracks mostly vanish.
    let out = detect(&run, &["--model", baked.to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    let (whole, views) = score(&truth, &detections(&run));

    let out = detect(&run, &["--model", baked.to_str().unwrap(), "--tile", "640"]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(read_json(&run.join("detect.json"))["tile"], 640);
    let tiled = detections(&run);
    let (with_tiles, _) = score(&truth, &tiled);
    eprintln!(
        "1920x1080: {whole} of {views} crack views found whole, {with_tiles} with 640 px tiles"
    );
    assert!(
        views >= 3 && with_tiles > whole,
        "tiles found {with_tiles}, the whole frame {whole}, of {views}"
    );
    let df = ParquetReader::new(std::fs::File::open(run.join("detections.parquet")).unwrap())
        .finish()
        .unwrap();
    let tiles = df.column("tile").unwrap().i32().unwrap().clone();
    assert!((0..tiles.len()).any(|i| tiles.get(i).is_some_and(|t| t >= 0)));
    assert!(
        tiled
            .iter()
            .all(|(_, b, _)| b[0] >= 0.0 && b[1] >= 0.0 && b[2] <= 1920.0 && b[3] <= 1080.0)
    );
}
