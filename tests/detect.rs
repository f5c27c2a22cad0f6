//! End-to-end tests of `postflight detect` with the shipped reference
//! detectors on a simulated flight, scored against truth.json.

use std::path::{Path, PathBuf};

use crate::common::*;

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
    detection_rows(run)
        .into_iter()
        .map(|d| (d.time_ns, [d.x0, d.y0, d.x1, d.y1], d.prompt))
        .collect()
}

/// Two runs found the same boxes in the same frames.
fn assert_same_boxes(a: &[(i64, [f64; 4], String)], b: &[(i64, [f64; 4], String)]) {
    assert_eq!(a.len(), b.len());
    for ((t0, b0, _), (t1, b1, _)) in a.iter().zip(b) {
        assert_eq!(t0, t1);
        assert!(
            b0.iter().zip(b1).all(|(x, y)| (x - y).abs() < 1e-3),
            "{b0:?} vs {b1:?}"
        );
    }
}

/// A flight simulated with `sim_args` into `dir`/sim and ingested into
/// `dir`/run: (the simulated flight, the run).
fn ingested(dir: &Path, sim_args: &[&str]) -> (PathBuf, PathBuf) {
    let sim = simulate_into(dir, "sim", sim_args);
    let run = dir.join("run");
    ingest_ok(&sim.join("flight.mcap"), &run, &[]);
    (sim, run)
}

/// 20 frames of 640 x 480 with many cracks.
const SMALL_FLIGHT: [&str; 6] = ["--frames", "20", "--cracks", "80", "--seed", "4"];

/// Detections scored against truth.json at box IoU >= 0.3.
#[derive(Debug, Default, Clone, Copy)]
struct Score {
    /// Truth crack views at least 20 px long, and those found.
    views: u32,
    found: u32,
    /// Boxes, and those on a truth crack view (of any length).
    boxes: u32,
    true_boxes: u32,
}

impl Score {
    fn recall(&self) -> f64 {
        f64::from(self.found) / f64::from(self.views.max(1))
    }

    fn precision(&self) -> f64 {
        f64::from(self.true_boxes) / f64::from(self.boxes.max(1))
    }
}

fn score(truth: &serde_json::Value, found: &[(i64, [f64; 4], String)]) -> Score {
    let mut s = Score {
        boxes: found.len() as u32,
        ..Score::default()
    };
    let mut true_boxes = vec![false; found.len()];
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
            let mut hit = false;
            for (i, (ft, fb, _)) in found.iter().enumerate() {
                if *ft == t && iou(fb, &b) >= 0.3 {
                    hit = true;
                    true_boxes[i] = true;
                }
            }
            if (b[2] - b[0]).max(b[3] - b[1]) >= 20.0 {
                s.views += 1;
                s.found += u32::from(hit);
            }
        }
    }
    s.true_boxes = true_boxes.iter().filter(|t| **t).count() as u32;
    s
}

/// `model` changed by `edit` (Python with the `onnx` package, the model
/// loaded as `m`) and saved as `to`.
fn edited_model(model: &Path, to: &Path, edit: &str) {
    let code =
        format!("import onnx, sys\nm = onnx.load(sys.argv[1])\n{edit}\nonnx.save(m, sys.argv[2])");
    python_run(&code, &[model, to]);
}

#[test]
fn reference_detectors_find_simulated_cracks_through_both_interfaces() {
    let dir = tempfile::tempdir().unwrap();
    let (sim, run) = ingested(
        dir.path(),
        &["--frames", "60", "--cracks", "80", "--seed", "4"],
    );

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
    let s = score(&truth, &found);
    assert!(s.views >= 5, "the test flight should show cracks");
    assert!(s.recall() >= 0.5, "{s:?}");

    // The same model exported with a fixed batch of 3: views are sent three
    // at a time, the last call padded, and the boxes are the same.
    let fixed = dir.path().join("crack-batch3.onnx");
    edited_model(
        &baked,
        &fixed,
        "for t in (m.graph.input[0], m.graph.output[0]):\n    t.type.tensor_type.shape.dim[0].dim_value = 3",
    );
    let out = detect(&run, &["--model", fixed.to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(read_json(&run.join("detect.json"))["batch"], 3);
    assert_same_boxes(&found, &detections(&run));

    // The semantic model as PyTorch's exporter often leaves one: no
    // dimension of its output known. Its channels are read from each result.
    let semantic = models().join("crack-semantic.onnx");
    let out = detect(&run, &["--model", semantic.to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    let via_semantic = detections(&run);
    assert!(!via_semantic.is_empty());
    let unknown = dir.path().join("crack-semantic-unknown.onnx");
    edited_model(
        &semantic,
        &unknown,
        "for d in m.graph.output[0].type.tensor_type.shape.dim:\n    d.Clear()",
    );
    let out = detect(&run, &["--model", unknown.to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_same_boxes(&via_semantic, &detections(&run));

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
    assert_same_boxes(&found, &via_open);
    assert!(via_open.iter().all(|(_, _, prompt)| prompt == "crack"));
    // The same embeddings as NumPy writes them (float64 here), names beside.
    let npy = dir.path().join("text.npy");
    let out = std::process::Command::new(python())
        .args(["-c", "import json, sys, numpy as np\nt = json.load(open(sys.argv[1]))\nnp.save(sys.argv[2], np.array(list(t.values()), dtype=np.float64))\nopen(sys.argv[3], 'w').write('\\n'.join(t) + '\\n')"])
        .args([prompts.as_path(), npy.as_path(), dir.path().join("text.txt").as_path()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let npy_args = [
        "--model",
        open.to_str().unwrap(),
        "--embeddings",
        npy.to_str().unwrap(),
    ];
    // Asked for CUDA, the CPU-only wheel warns and runs on the CPU.
    let out = detect(&run, &[&npy_args[..], &["--device", "cuda"]].concat());
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("no CUDA execution provider; running on the CPU"),
        "{}",
        stderr(&out)
    );
    assert_eq!(read_json(&run.join("detect.json"))["device"], "cpu");
    assert_same_boxes(&found, &detections(&run));
    std::fs::remove_file(dir.path().join("text.txt")).unwrap();
    let out = detect(&run, &npy_args);
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("text.txt"), "{}", stderr(&out));

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
    let (sim, run) = ingested(
        dir.path(),
        &["--frames", "20", "--width", "1920", "--height", "1080"],
    );
    let truth = read_json(&sim.join("truth.json"));
    let baked = models().join("crack-baked.onnx");

    // Shrunk 3x to the 640 px input, mm-wide cracks mostly vanish.
    let out = detect(&run, &["--model", baked.to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    let Score {
        found: whole,
        views,
        ..
    } = score(&truth, &detections(&run));

    let out = detect(&run, &["--model", baked.to_str().unwrap(), "--tile", "640"]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(read_json(&run.join("detect.json"))["tile"], 640);
    let tiled = detections(&run);
    let with_tiles = score(&truth, &tiled).found;
    eprintln!(
        "1920x1080: {whole} of {views} crack views found whole, {with_tiles} with 640 px tiles"
    );
    assert!(
        views >= 3 && with_tiles > whole,
        "tiles found {with_tiles}, the whole frame {whole}, of {views}"
    );
    assert!(detection_rows(&run).iter().any(|d| d.tile >= 0));
    assert!(
        tiled
            .iter()
            .all(|(_, b, _)| b[0] >= 0.0 && b[1] >= 0.0 && b[2] <= 1920.0 && b[3] <= 1080.0)
    );
}

/// The semantic reference detector wrapped by tests/fixtures/wrap_model.py
/// (the `onnx` package) with another input convention, saved in `dir`.
fn wrapped_semantic(dir: &Path, front: &str, fixed: Option<u32>) -> PathBuf {
    let to = dir.join(format!("semantic-{front}-{}.onnx", fixed.unwrap_or(0)));
    let fixed = fixed.map(|n| n.to_string());
    let mut args = vec![
        models()
            .join("crack-semantic.onnx")
            .to_str()
            .unwrap()
            .to_string(),
        to.to_str().unwrap().to_string(),
        "--front".into(),
        front.into(),
    ];
    if let Some(n) = fixed {
        args.extend(["--fixed".into(), n]);
    }
    python_fixture("wrap_model.py", &args);
    to
}

/// Two runs found the same regions with the same scores: the wrapped
/// models recompute the network's input to float rounding.
fn assert_same_detections(a: &[(i64, [f64; 5], i64)], b: &[(i64, [f64; 5], i64)], what: &str) {
    assert!(a.len() >= 3, "{what}: too few detections to compare");
    assert_eq!(a.len(), b.len(), "{what}");
    for (x, y) in a.iter().zip(b) {
        assert_eq!((x.0, x.2), (y.0, y.2), "{what}");
        assert!(
            x.1.iter().zip(&y.1).all(|(p, q)| (p - q).abs() < 1e-3),
            "{what}: {x:?} vs {y:?}"
        );
    }
}

/// A model published with ImageNet's normalisation, or taking raw BGR on
/// 0..255 (declared in its ONNX image metadata), detects what the
/// reference network does when its convention is declared or read; fed
/// postflight's default instead, the ImageNet one finds other regions.
#[test]
fn models_with_their_own_input_convention_detect_as_the_network_does() {
    let dir = tempfile::tempdir().unwrap();
    let (_, run) = ingested(dir.path(), &SMALL_FLIGHT);
    let run_model = |model: &Path, args: &[&str]| {
        let all = [&["--model", model.to_str().unwrap()], args].concat();
        let out = detect(&run, &all);
        assert!(out.status.success(), "{}", stderr(&out));
        let mut found = detections_with_scores(&run);
        found.sort_by(|a, b| {
            (a.0, a.1[0], a.1[1])
                .partial_cmp(&(b.0, b.1[0], b.1[1]))
                .unwrap()
        });
        (found, read_json(&run.join("detect.json"))["input"].clone())
    };
    let (reference, input) = run_model(&models().join("crack-semantic.onnx"), &[]);
    assert_eq!(input["source"], "default");

    let imagenet = wrapped_semantic(dir.path(), "imagenet", None);
    let declared = ["--mean", "0.485,0.456,0.406", "--std", "0.229,0.224,0.225"];
    let (found, input) = run_model(&imagenet, &declared);
    assert_same_detections(&reference, &found, "ImageNet mean and std declared");
    assert_eq!(input["source"], "settings");
    let (undeclared, _) = run_model(&imagenet, &[]);
    assert_ne!(
        undeclared, reference,
        "fed RGB on 0..1, the normalised model should differ"
    );

    let bgr = wrapped_semantic(dir.path(), "bgr255", None);
    let (found, input) = run_model(&bgr, &[]);
    assert_same_detections(&reference, &found, "BGR 0..255 from the metadata");
    assert_eq!(
        (
            &input["source"],
            &input["channel_order"],
            &input["pixel_scale"]
        ),
        (
            &serde_json::json!("metadata"),
            &serde_json::json!("bgr"),
            &serde_json::json!(255.0)
        )
    );
}

/// A model with a fixed 256 x 256 input runs on 640 x 480 frames as 256 px
/// tiles at full resolution without being told, and finds crack views the
/// frame shrunk 2.5 times to its input loses (`--tile off`, which warns).
#[test]
fn a_fixed_size_model_runs_on_tiles_without_a_flag() {
    let dir = tempfile::tempdir().unwrap();
    let (sim, run) = ingested(dir.path(), &SMALL_FLIGHT);
    let truth = read_json(&sim.join("truth.json"));
    let fixed = wrapped_semantic(dir.path(), "none", Some(256));
    let model = fixed.to_str().unwrap();

    let out = detect(&run, &["--model", model]);
    assert!(out.status.success(), "{}", stderr(&out));
    let summary = read_json(&run.join("detect.json"));
    assert_eq!(summary["tile"], 256);
    assert_eq!(summary["input_size"], serde_json::json!([256, 256]));
    assert!(detection_rows(&run).iter().any(|d| d.tile >= 0));
    let tiled = score(&truth, &detections(&run));

    let out = detect(&run, &["--model", model, "--tile", "off"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let summary = read_json(&run.join("detect.json"));
    assert!(summary["tile"].is_null());
    let warning = summary["warnings"].to_string();
    assert!(warning.contains("shrunk 2.5 times"), "{warning}");
    let shrunk = score(&truth, &detections(&run));
    eprintln!("fixed 256 x 256 model on 640 x 480 frames: tiles {tiled:?}, shrunk {shrunk:?}");
    assert!(
        tiled.found > shrunk.found && tiled.found >= 2,
        "tiles found {tiled:?}, the shrunk frame {shrunk:?}"
    );
}

/// Issue 4's bar: on a default flight of `scene` the reference detector
/// finds >= 90% of the crack views at least 20 px long, with precision
/// >= 0.8, at box IoU 0.3.
fn reference_detector_meets_recall_and_precision(scene: &str) {
    let dir = tempfile::tempdir().unwrap();
    let sim_args = ["--scene", scene, "--seed", "1"];
    let run = detected_into(dir.path(), &format!("{scene}-run"), &sim_args);
    let truth = read_json(&simulated(&sim_args).join("truth.json"));
    let s = score(&truth, &detections(&run));
    eprintln!(
        "{scene}: recall {:.3} ({} of {} views), precision {:.3} ({} of {} boxes)",
        s.recall(),
        s.found,
        s.views,
        s.precision(),
        s.true_boxes,
        s.boxes
    );
    assert!(s.views >= 30, "{scene} flight shows too few cracks: {s:?}");
    assert!(s.recall() >= 0.9 && s.precision() >= 0.8, "{scene}: {s:?}");
}

#[test]
fn reference_detector_meets_recall_and_precision_on_a_bridge_flight() {
    reference_detector_meets_recall_and_precision("girder-bridge");
}

#[test]
fn reference_detector_meets_recall_and_precision_on_a_tower_flight() {
    reference_detector_meets_recall_and_precision("tower");
}

/// The same model, frames and settings through Python onnxruntime + NumPy +
/// Pillow (detect/python/pipeline.py) give the same boxes and scores, to
/// 1e-4: resized whole frames, tiles, merging off, and the open-vocabulary
/// interface.
/// PNG frames, so both sides decode the same pixels.
#[test]
fn rust_matches_python_onnxruntime_on_the_same_frames() {
    let dir = tempfile::tempdir().unwrap();
    let (sim, run) = ingested(
        dir.path(),
        &[
            "--frames",
            "20",
            "--cracks",
            "80",
            "--seed",
            "4",
            "--width",
            "800",
            "--height",
            "600",
            "--image-format",
            "png",
        ],
    );
    let baked = models().join("crack-baked.onnx");
    let open = models().join("crack-open.onnx");
    let prompts = models().join("prompts.json");
    let open_args = [
        "--embeddings",
        prompts.to_str().unwrap(),
        "--prompt",
        "crack",
        "--prompt",
        "stain",
    ];
    let semantic = models().join("crack-semantic.onnx");
    let cases: [(&Path, &[&str]); 6] = [
        (&baked, &[]),
        // A semantic segmentation model: its connected crack regions.
        (&semantic, &[]),
        (&semantic, &["--tile", "640"]),
        (&baked, &["--tile", "640"]),
        // GATSBI's confidence, with and without merging (which keeps faint boxes apart).
        (&baked, &["--confidence", "0.008", "--merge-gap", "off"]),
        (&open, &open_args),
    ];
    for (model, args) in cases {
        // Every tile, as the Python pipeline runs them.
        let every: &[&str] = &["--model", model.to_str().unwrap(), "--views-per-patch", "0"];
        let rust_args = [every, args].concat();
        let out = detect(&run, &rust_args);
        assert!(out.status.success(), "{}", stderr(&out));
        let mut rust = detections_with_scores(&run);

        let json = dir.path().join("python.json");
        let out = std::process::Command::new(python())
            .arg(root().join("detect/python/pipeline.py"))
            .args([sim.join("flight.mcap").as_path(), model, json.as_path()])
            .args(args)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
        let mut python: Vec<(i64, [f64; 5], i64)> = read_json(&json)["detections"]
            .as_array()
            .unwrap()
            .iter()
            .map(|d| {
                let v = ["x0", "y0", "x1", "y1", "score"].map(|k| f(&d[k]));
                (
                    d["time_ns"].as_i64().unwrap(),
                    v,
                    d["tile"].as_i64().unwrap(),
                )
            })
            .collect();
        let order = |a: &(i64, [f64; 5], i64), b: &(i64, [f64; 5], i64)| {
            (a.0, a.1[0], a.1[1])
                .partial_cmp(&(b.0, b.1[0], b.1[1]))
                .unwrap()
        };
        rust.sort_by(order);
        python.sort_by(order);
        assert!(rust.len() >= 3, "{args:?}: too few detections to compare");
        assert_eq!(rust.len(), python.len(), "{args:?}");
        let mut worst = 0.0f64;
        for (r, p) in rust.iter().zip(&python) {
            assert_eq!((r.0, r.2), (p.0, p.2), "{args:?}: frame or tile differs");
            for (a, b) in r.1.iter().zip(&p.1) {
                worst = worst.max((a - b).abs());
            }
        }
        eprintln!(
            "{} {args:?}: {} detections, largest difference {worst:e}",
            model.file_name().unwrap().to_string_lossy(),
            rust.len()
        );
        assert!(worst <= 1e-4, "{args:?}: differs by {worst}");
    }
}

/// Detections with scores and tiles: (time, [x0, y0, x1, y1, score], tile).
fn detections_with_scores(run: &Path) -> Vec<(i64, [f64; 5], i64)> {
    detection_rows(run)
        .into_iter()
        .map(|d| (d.time_ns, [d.x0, d.y0, d.x1, d.y1, d.score], d.tile))
        .collect()
}

/// Frames whose image cannot be decoded are counted, listed and skipped; the
/// rest are still run.
#[test]
fn undecodable_frames_are_listed_and_skipped() {
    let dir = tempfile::tempdir().unwrap();
    let (mcap, expected) = write_flight(
        dir.path(),
        "cut",
        &["--width", "160", "--height", "120", "--cut-images", "5"],
    );
    let run = dir.path().join("run");
    ingest_ok(&mcap, &run, &[]);
    let baked = models().join("crack-baked.onnx");
    // Every frame run: a frame no patch needs is not decoded at all.
    let every = ["--model", baked.to_str().unwrap(), "--views-per-patch", "0"];
    let out = detect(&run, &every);
    assert!(out.status.success(), "{}", stderr(&out));
    let frames = expected["frames"].as_array().unwrap();
    let cut: Vec<u64> = (0..frames.len() as u64)
        .filter(|i| frames[*i as usize]["cut"] == true)
        .collect();
    assert!(cut.len() >= 5);
    let summary = read_json(&run.join("detect.json"));
    let failed: Vec<u64> = summary["failed_frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["frame"].as_u64().unwrap())
        .collect();
    assert_eq!(failed, cut);
    assert_eq!(
        summary["frames_run"].as_u64().unwrap(),
        frames.len() as u64 - cut.len() as u64
    );
    assert!(
        stderr(&out).contains(&format!("frame {} skipped", cut[0])),
        "{}",
        stderr(&out)
    );

    // Not one frame decodes: an error, not an empty result.
    let (mcap, _) = write_flight(
        dir.path(),
        "all-cut",
        &["--width", "160", "--height", "120", "--cut-images", "1"],
    );
    let run = dir.path().join("all-cut-run");
    ingest_ok(&mcap, &run, &[]);
    let out = detect(&run, &every);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("none of the") && stderr(&out).contains("cut off"),
        "{}",
        stderr(&out)
    );
    assert!(!run.join("detect.json").exists());
}

/// A flight's detect as four shares, merged, is what one process finds;
/// a share missing is named; and localise merges a complete split itself.
#[test]
fn four_shares_merged_are_one_process_and_localise_merges_them() {
    let dir = tempfile::tempdir().unwrap();
    let (_, run) = ingested(
        dir.path(),
        &["--frames", "40", "--cracks", "80", "--seed", "4"],
    );
    let model = models().join("crack-baked.onnx");
    let model = model.to_str().unwrap();
    let out = detect(&run, &["--model", model]);
    assert!(out.status.success(), "{}", stderr(&out));
    let sorted = |run: &Path| {
        let df = read_parquet(&run.join("detections.parquet"));
        let by: Vec<String> = ["frame", "x0", "y0", "x1", "y1", "score"]
            .map(String::from)
            .into();
        df.sort(by, Default::default()).unwrap()
    };
    let whole = sorted(&run);
    let whole_summary = read_json(&run.join("detect.json"));
    assert!(whole.height() >= 8, "{}", whole.height());

    let mut shares = Vec::new();
    for k in 1..=4 {
        if k == 4 {
            // Three of four done: the merge names the one missing.
            let out = detect(&run, &["--merge"]);
            assert_fails_in_one_line(&out, "share 4/4 not done");
        }
        let out = detect(&run, &["--model", model, "--shard", &format!("{k}/4")]);
        assert!(out.status.success(), "{}", stderr(&out));
        assert!(
            stdout(&out).contains(&format!("share {k}/4")),
            "{}",
            stdout(&out)
        );
        // A share remakes the flight's detections: the whole's are gone.
        assert!(!run.join("detect.json").exists());
        shares.push(read_json(&run.join(format!("detect-shard-{k}-of-4.json"))));
    }
    // The shares hold the tiles to run evenly, give or take a frame's.
    let tiles: Vec<u64> = shares
        .iter()
        .map(|s| s["tiles_run"].as_u64().unwrap())
        .collect();
    assert_eq!(
        tiles.iter().sum::<u64>(),
        whole_summary["tiles_run"].as_u64().unwrap()
    );
    let per_frame = tiles.iter().sum::<u64>() / whole_summary["frames_run"].as_u64().unwrap();
    assert!(
        tiles.iter().all(|t| t.abs_diff(tiles[0]) <= 2 * per_frame),
        "{tiles:?}"
    );

    let out = detect(&run, &["--merge"]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(
        sorted(&run),
        whole,
        "four shares merged differ from one process"
    );
    let merged = read_json(&run.join("detect.json"));
    for key in [
        "frames",
        "frames_run",
        "tiles_run",
        "tiles_skipped",
        "detections",
        "failed_frames",
    ] {
        assert_eq!(merged[key], whole_summary[key], "{key}");
    }
    let coco = read_json(&run.join("detections.coco.json"));
    assert_eq!(
        coco["annotations"].as_array().unwrap().len(),
        whole.height()
    );

    // Unmerged, the next stage merges a complete split before it starts.
    std::fs::remove_file(run.join("detect.json")).unwrap();
    std::fs::remove_file(run.join("detections.parquet")).unwrap();
    let out = postflight(&["localise", "--run", run.to_str().unwrap()], dir.path());
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stdout(&out).contains("merged"), "{}", stdout(&out));
    assert_eq!(sorted(&run), whole);
}

/// Per COCO file (read by pycocotools): each annotation's image, category
/// name, box and mask, and the mask IoU of each of the first file's
/// `first` annotations with the second's `second` in the same image.
const COCO_KINDS: &str = r#"
import json, sys
from pycocotools.coco import COCO
from pycocotools import mask as mu
a, b = COCO(sys.argv[1]), COCO(sys.argv[2])
def of(c, name):
    cat = c.getCatIds(catNms=[name])
    return [x for x in c.loadAnns(c.getAnnIds(catIds=cat))] if cat else []
mine, theirs = of(a, sys.argv[3]), of(b, sys.argv[4])
ious = []
for m in mine:
    same = [t for t in theirs if t["image_id"] == m["image_id"]]
    best = max((mu.iou([m["segmentation"]], [t["segmentation"]], [0])[0][0] for t in same), default=0.0)
    ious.append(float(best))
print(json.dumps({
    "categories": [c["name"] for c in a.loadCats(a.getCatIds())],
    "mine": len(mine), "theirs": len(theirs),
    "min_iou": min(ious, default=0.0),
    "mask_area": sum(int(mu.area(m["segmentation"])) for m in mine),
}))
"#;

#[test]
fn an_area_model_runs_at_its_own_scale_beside_the_crack_model_and_names_its_kinds() {
    let dir = tempfile::tempdir().unwrap();
    let (_, run) = ingested(dir.path(), &SMALL_FLIGHT);
    // The crack segmenter renamed: its crack is this model's "spalling".
    let semantic = models().join("crack-semantic.onnx");
    let area = dir.path().join("area.onnx");
    python_fixture(
        "area_model.py",
        &[
            semantic.as_os_str(),
            area.as_os_str(),
            "--train-px".as_ref(),
            "320".as_ref(),
        ],
    );
    let alone = dir.path().join("alone");
    copy_dir(&run, &alone);
    let semantic = semantic.to_str().unwrap();
    let out = detect(
        &alone,
        &["--model", semantic, "--tile", "off", "--imgsz", "320"],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stdout(&out).contains("not looked for"), "{}", stdout(&out));

    let baked = models().join("crack-baked.onnx");
    let args = [
        "--model",
        baked.to_str().unwrap(),
        "--area-model",
        area.to_str().unwrap(),
    ];
    let out = detect(&run, &args);
    assert!(out.status.success(), "{}", stderr(&out));
    let said = "of which the area model (spall, exposed_rebar)";
    assert!(stdout(&out).contains(said), "{}", stdout(&out));
    let summary = read_json(&run.join("detect.json"));
    assert_eq!(
        summary["kinds"],
        serde_json::json!(["crack", "spall", "exposed_rebar"])
    );
    assert_eq!(
        summary["classes"],
        serde_json::json!(["crack", "background", "exposed_rebar", "spalling"])
    );
    let pass = &summary["area_model"];
    // 640 x 480 frames at 320 px, padded to the stride.
    assert_eq!(pass["input_size"], serde_json::json!([320, 256]), "{pass}");
    assert!(pass["seconds"].as_f64().unwrap() > 0.0);

    // The rows: cracks from the crack model, spalls from the area model's
    // class 2 (numbered after the crack model's one class).
    let df = read_parquet(&run.join("detections.parquet"));
    let kinds = df.column("kind").unwrap().str().unwrap().clone();
    let classes = df.column("class").unwrap().u32().unwrap().clone();
    let spalls: Vec<u32> = (0..df.height())
        .filter(|&i| kinds.get(i) == Some("spall"))
        .map(|i| classes.get(i).unwrap())
        .collect();
    assert!(spalls.iter().all(|c| *c == 3), "{spalls:?}");
    assert_eq!(pass["detections"].as_u64().unwrap(), spalls.len() as u64);

    // What the area model found as spall is what the segmenter finds as
    // crack at that scale: the same regions, the same pixels.
    let found = python_run(
        COCO_KINDS,
        &[
            run.join("detections.coco.json").to_str().unwrap(),
            alone.join("detections.coco.json").to_str().unwrap(),
            "spall",
            "crack",
        ],
    );
    // pycocotools talks as it loads: the figures are the last line.
    let found: serde_json::Value = serde_json::from_str(found.lines().last().unwrap()).unwrap();
    assert_eq!(
        found["categories"],
        serde_json::json!([
            "crack",
            "spall",
            "exposed_rebar",
            "efflorescence",
            "rust_stain",
            "corrosion"
        ])
    );
    assert!(found["mine"].as_u64().unwrap() >= 2, "{found}");
    assert_eq!(found["mine"], found["theirs"], "{found}");
    assert!(found["min_iou"].as_f64().unwrap() > 0.95, "{found}");
    assert!(found["mask_area"].as_u64().unwrap() > 0, "{found}");
}
