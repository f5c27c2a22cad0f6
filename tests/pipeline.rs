//! End-to-end tests of `postflight demo` and `postflight run`: the demo's
//! summary.json and report.html show the simulated cracks and the simulated
//! gap (against truth.json and the stages' own files); a second run skips
//! every stage; a run killed mid-detect resumes without redoing ingest; a
//! changed setting reruns from its stage on; a failing stage says which and
//! leaves the earlier results intact; a flight recorded by ROS 1 (bags,
//! MCAP) runs to the same defects and coverage as its ROS 2 recording.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant, SystemTime};

use crate::common::*;
use serde_json::Value;

fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn modified(path: &Path) -> SystemTime {
    std::fs::metadata(path).unwrap().modified().unwrap()
}

/// Centroids of the truth cracks some recorded frame shows.
fn visible_cracks(truth: &Value) -> Vec<(i64, [f64; 3])> {
    let seen: std::collections::BTreeSet<i64> = truth["frames"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| !f["dropped"].as_bool().unwrap())
        .flat_map(|f| f["cracks"].as_array().unwrap().iter())
        .map(|c| c["id"].as_i64().unwrap())
        .collect();
    all_cracks(truth)
        .into_iter()
        .filter(|(id, _)| seen.contains(id))
        .collect()
}

/// Every simulated crack's id and centroid, seen or not (a crack the
/// truth counts too faint to see may still be found).
fn all_cracks(truth: &Value) -> Vec<(i64, [f64; 3])> {
    truth["cracks"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            let points: Vec<[f64; 3]> = c["lines"]
                .as_array()
                .unwrap()
                .iter()
                .flat_map(|l| l.as_array().unwrap().iter().map(vec3))
                .collect();
            let centroid =
                [0, 1, 2].map(|a| points.iter().map(|p| p[a]).sum::<f64>() / points.len() as f64);
            (c["id"].as_i64().unwrap(), centroid)
        })
        .collect()
}

/// Positions of the candidates the report lists ("at (x, y, z) m").
fn reported_positions(html: &str) -> Vec<[f64; 3]> {
    html.match_indices("at (")
        .filter_map(|(i, _)| {
            let rest = &html[i + 4..];
            let inner = &rest[..rest.find(") m")?];
            let v: Vec<f64> = inner
                .split(", ")
                .map(|x| x.parse().ok())
                .collect::<Option<_>>()?;
            (v.len() == 3).then(|| [v[0], v[1], v[2]])
        })
        .collect()
}

/// The number in the report's coverage table row that starts with `label`.
fn table_count(html: &str, label: &str) -> usize {
    let row = &html[html
        .find(&format!("<tr><td>{label}</td>"))
        .unwrap_or_else(|| panic!("no row {label}"))..];
    let cell = &row[row.find("<td class=\"n\">").unwrap() + 14..];
    cell[..cell.find('<').unwrap()].parse().unwrap()
}

/// SHA-256 of a file, by Python's hashlib.
fn sha256_by_python(path: &Path) -> String {
    python_run(
        "import hashlib, sys; print(hashlib.sha256(open(sys.argv[1], 'rb').read()).hexdigest())",
        &[path],
    )
}

/// Rows per "entity archetype" in `rerun rrd print`'s chunk lines
/// (`Chunk(..) with N rows (..) - /entity - data columns: [Archetype:field ..]`).
fn rrd_rows(print: &str) -> std::collections::BTreeMap<String, usize> {
    let mut rows = std::collections::BTreeMap::new();
    for line in print.lines().filter(|l| l.starts_with("Chunk(")) {
        let n: usize = line
            .split(" with ")
            .nth(1)
            .and_then(|r| r.split(' ').next())
            .unwrap()
            .parse()
            .unwrap();
        let entity = line.split(" - ").nth(1).unwrap();
        let archetype = line
            .split("data columns: [")
            .nth(1)
            .unwrap()
            .split(':')
            .next()
            .unwrap();
        *rows.entry(format!("{entity} {archetype}")).or_default() += n;
    }
    rows
}

/// Render `page` in headless Chromium to `png`; returns the console messages.
fn render_in_chromium(page: &Path, png: &Path, scratch: &Path) -> Vec<String> {
    let chromium = Path::new("/usr/bin/chromium");
    assert!(
        chromium.is_file(),
        "Debian's chromium is missing: run scripts/setup --test (scripts/test does)"
    );
    let out = Command::new(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--enable-logging=stderr",
            "--v=0",
            "--window-size=1100,2400",
        ])
        .arg(format!(
            "--user-data-dir={}",
            scratch.join("chromium").display()
        ))
        .arg(format!("--screenshot={}", png.display()))
        .arg(format!("file://{}", page.display()))
        .output()
        .unwrap();
    assert!(
        out.status.success() && png.is_file(),
        "chromium: {}",
        stderr(&out)
    );
    stderr(&out)
        .lines()
        .filter(|l| l.contains(":CONSOLE"))
        .map(String::from)
        .collect()
}

#[test]
fn chromium_console_messages_are_caught() {
    // The check the report passes must be able to fail.
    let dir = tempfile::tempdir().unwrap();
    let page = dir.path().join("bad.html");
    std::fs::write(&page, "<!DOCTYPE html><p>x</p><script>missing();</script>").unwrap();
    let console = render_in_chromium(&page, &dir.path().join("bad.png"), dir.path());
    assert!(
        console.iter().any(|l| l.contains("missing is not defined")),
        "{console:?}"
    );
}

#[test]
fn the_demo_reports_the_simulated_cracks_and_the_simulated_gap() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    let result = postflight(&["demo", "--out", out.to_str().unwrap()], dir.path());
    assert!(result.status.success(), "demo failed: {}", stderr(&result));
    let run = out.join("run");
    let text = stdout(&result);
    assert!(
        text.contains(&run.join("report.html").display().to_string()),
        "{text}"
    );

    let truth = read_json(&out.join("flight/truth.json"));
    let summary = read_json(&run.join("summary.json"));
    let html = std::fs::read_to_string(run.join("report.html")).unwrap();

    // The run weighs its time against the flight's.
    let flown = read_json(&run.join("ingest.json"))["duration_s"]
        .as_f64()
        .unwrap();
    let line = text
        .lines()
        .find(|l| l.starts_with("processed "))
        .unwrap_or_else(|| panic!("no closing line:\n{text}"));
    let numbers: Vec<f64> = line
        .split(|c: char| !c.is_ascii_digit())
        .filter(|w| !w.is_empty())
        .map(|w| w.parse().unwrap())
        .collect();
    assert!(line.ends_with("% of its flying time"), "{line}");
    assert_eq!(numbers[0], flown.round(), "{line}");
    assert!(
        (numbers[2] - 100.0 * numbers[1] / flown).abs() <= 1.0,
        "{line}"
    );

    // Frames: what the simulator recorded (its dropped frames are not in the file).
    let recorded = truth["frames"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| !f["dropped"].as_bool().unwrap())
        .count();
    assert_eq!(summary["frames"].as_u64().unwrap() as usize, recorded);

    // The cracks: every crack a frame shows is a candidate in the report,
    // and the report shows nothing that is not a crack.
    let defects = read_json(&run.join("defects.json"))["defects"]
        .as_array()
        .unwrap()
        .len();
    assert_eq!(summary["defects"].as_u64().unwrap() as usize, defects);
    let reported = reported_positions(&html);
    assert_eq!(reported.len(), defects, "one report row per candidate");
    let visible = visible_cracks(&truth);
    let found = visible
        .iter()
        .filter(|(_, c)| reported.iter().any(|p| dist(p, c) <= 0.3))
        .count();
    assert!(
        found as f64 >= 0.9 * visible.len() as f64 && found > 0,
        "report shows {found} of {} visible cracks",
        visible.len()
    );
    let cracks = all_cracks(&truth);
    for p in &reported {
        assert!(
            cracks.iter().any(|(_, c)| dist(p, c) <= 0.5),
            "reported candidate at {p:?} is no simulated crack"
        );
    }
    assert!(
        html.contains("data:image/jpeg;base64,"),
        "thumbnails are inline"
    );

    // The gap: the simulator skipped viewpoints; the voxels only they would
    // have inspected are planned-but-missed, in the summary and the report.
    let skipped_gap = truth["coverage"]["voxels"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|v| v["skipped_gap"].as_bool().unwrap())
        .count();
    assert!(skipped_gap > 20, "the simulated flight has a gap");
    let coverage = read_json(&run.join("coverage.json"));
    let c = &summary["coverage"];
    for key in [
        "target_voxels",
        "gap_voxels",
        "uninspectable_voxels",
        "inspected_pct",
        "planned_inspected_pct",
    ] {
        assert_eq!(c[key], coverage[key], "summary coverage.{key}");
    }
    let missed = table_count(&html, "planned but missed");
    assert_eq!(
        missed as u64,
        coverage["planned_missed_voxels"].as_u64().unwrap()
    );
    assert!(
        missed >= skipped_gap,
        "{missed} planned-missed voxels, {skipped_gap} in the skipped segment"
    );
    assert!(f(&c["planned_inspected_pct"]) < 100.0);
    assert!(html.contains("#d7301f"), "planned-missed voxels are drawn");

    // The follow-up flight for the gaps.
    let replan = read_json(&run.join("replan.json"));
    let r = &summary["replan"];
    assert_eq!(r["waypoints"], replan["waypoints"]);
    assert_eq!(
        r["sorties"].as_u64().unwrap() as usize,
        replan["sorties"].as_array().unwrap().len()
    );
    assert!(f(&r["length_m"]) > 0.0);
    assert!(html.contains("<polyline"), "the follow-up flight is drawn");

    // Timings of every stage, and versions checked by Python.
    for stage in [
        "ingest", "detect", "localise", "coverage", "replan", "record", "report",
    ] {
        assert!(f(&summary["timings_s"][stage]) >= 0.0, "timing of {stage}");
    }
    let v = &summary["versions"];
    let model = out.join("model/crack-baked.onnx");
    assert_eq!(
        v["model_sha256"].as_str().unwrap(),
        sha256_by_python(&model)
    );
    assert_eq!(
        v["onnxruntime"].as_str().unwrap(),
        python_run::<&str>("import onnxruntime; print(onnxruntime.__version__)", &[])
    );

    // Looked at as a person would: Chromium renders it, with nothing said
    // on its console, and it needs nothing from the network.
    let png = dir.path().join("report.png");
    let console = render_in_chromium(&run.join("report.html"), &png, dir.path());
    assert!(console.is_empty(), "console messages: {console:?}");
    let picture = image::open(&png).unwrap().to_rgb8();
    assert_eq!(picture.width(), 1100);
    let colours: std::collections::HashSet<[u8; 3]> = picture.pixels().map(|p| p.0).collect();
    assert!(colours.len() > 50, "the rendered report is blank");
    // What a browser would load by itself (links the reader may follow,
    // such as the review queue's address, are not fetched).
    let fetched: Vec<&str> = [
        "src=\"http",
        "src='http",
        "url(http",
        "url(\"http",
        "@import",
        "<link",
        "<script",
    ]
    .into_iter()
    .filter(|pattern| html.contains(pattern))
    .collect();
    assert!(fetched.is_empty(), "the report fetches by {fetched:?}");

    // The 3D recording: Rerun's own tools load it and find the run in it.
    let rrd = run.join("flight.rrd");
    let rerun = |args: &[&str]| {
        let out = Command::new(python().with_file_name("rerun"))
            .args(args)
            .arg(&rrd)
            .env("XDG_CONFIG_HOME", dir.path().join("config"))
            .env("XDG_DATA_HOME", dir.path().join("data"))
            .output()
            .unwrap();
        assert!(out.status.success(), "rerun {args:?}: {}", stderr(&out));
        stdout(&out)
    };
    rerun(&["rrd", "verify"]);
    let rows = rrd_rows(&rerun(&["rrd", "print"]));
    let posed = summary["frames_with_pose"].as_u64().unwrap() as usize;
    let camera = "/world/cameras/camera_image_raw_compressed";
    assert_eq!(
        rows.get(&format!("{camera} Transform3D")),
        Some(&posed),
        "{rows:?}"
    );
    assert_eq!(
        rows.get(&format!("{camera}/image EncodedImage")),
        Some(&posed)
    );
    assert_eq!(rows.get(&format!("{camera}/image Pinhole")), Some(&posed));
    assert_eq!(
        rows.get(&format!("{camera}/image/detections Boxes2D")),
        Some(&posed)
    );
    for static_entity in [
        "/world/map Points3D",
        "/world/trajectory LineStrips3D",
        "/world/defects Points3D",
        "/world/coverage/inspected Boxes3D",
        "/world/coverage/planned_missed Boxes3D",
        "/world/replan/path LineStrips3D",
    ] {
        assert_eq!(
            rows.get(static_entity),
            Some(&1),
            "{static_entity} in {rows:?}"
        );
    }

    // Again: nothing to do.
    let ingest_time = modified(&run.join("ingest.json"));
    let again = postflight(&["demo", "--out", out.to_str().unwrap()], dir.path());
    assert!(again.status.success(), "{}", stderr(&again));
    let text = stdout(&again);
    for stage in [
        "ingest", "detect", "localise", "coverage", "replan", "record", "report",
    ] {
        assert!(
            text.contains(&format!("{stage}: up to date, skipped")),
            "{stage} was redone:\n{text}"
        );
    }
    assert!(text.contains("reusing the simulated flight"), "{text}");
    assert_eq!(modified(&run.join("ingest.json")), ingest_time);
}

/// The files each stage after ingest writes, in the run's order (replan's
/// missions and per-drone paths too: every name starting with "replan").
const STAGE_FILES: [(&str, &[&str]); 5] = [
    (
        "detect",
        &["detections.parquet", "detections.coco.json", "detect.json"],
    ),
    (
        "localise",
        &[
            "defects.json",
            "observations.parquet",
            "defects.parquet",
            "defects",
            "localise.json",
        ],
    ),
    ("coverage", &["coverage.parquet", "coverage.json"]),
    (
        "replan",
        &["replan.csv", "replan.kml", "replan.geojson", "replan.json"],
    ),
    (
        "report",
        &[
            "report.html",
            "candidates.csv",
            "flight.rrd",
            "summary.json",
        ],
    ),
];

/// After `failed` failed in `run`: no file of it or of a later stage is
/// left to be taken for their results (`users`, the user's own, stays);
/// each stage before it kept its summary; every JSON file left reads as a
/// value, none as null (issue 57, items 12 and 13).
fn assert_honest_after_failure(run: &Path, failed: &str, users: Option<&Path>) {
    let left: Vec<String> = std::fs::read_dir(run)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| users.is_none_or(|u| u != run.join(name)))
        .collect();
    let at = STAGE_FILES.iter().position(|(s, _)| *s == failed).unwrap();
    for (stage, files) in &STAGE_FILES[at..] {
        for name in &left {
            assert!(
                !(files.contains(&name.as_str()) || name.starts_with(stage) && *stage == "replan"),
                "{name} of {stage} is left after {failed} failed: {left:?}"
            );
        }
    }
    for (stage, files) in
        std::iter::once(&("ingest", &["ingest.json"][..])).chain(&STAGE_FILES[..at])
    {
        let summary = files.last().unwrap();
        assert!(
            left.contains(&summary.to_string()),
            "{stage}'s {summary} gone after {failed} failed: {left:?}"
        );
    }
    for name in left.iter().filter(|n| n.ends_with(".json")) {
        let text = std::fs::read_to_string(run.join(name)).unwrap();
        let value: Value = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(!value.is_null(), "{name} is null");
    }
}

#[test]
fn a_run_killed_mid_detect_resumes_without_redoing_ingest() {
    let dir = tempfile::tempdir().unwrap();
    let sim = simulate_into(dir.path(), "sim", &["--frames", "150", "--seed", "3"]);
    let run = dir.path().join("run");
    let config = dir.path().join("postflight.toml");
    std::fs::write(&config, "[replan]\nsolver_time_limit_s = 2.0\n").unwrap();
    let model = root().join("detect/models/crack-baked.onnx");
    let flight = sim.join("flight.mcap");
    let plan = sim.join("plan.json");
    let args = |config: &Path, plan: &Path| -> Vec<String> {
        [
            "run",
            "--flight",
            flight.to_str().unwrap(),
            "--plan",
            plan.to_str().unwrap(),
            "--model",
            model.to_str().unwrap(),
            "--config",
            config.to_str().unwrap(),
            "--out",
            run.to_str().unwrap(),
        ]
        .map(String::from)
        .to_vec()
    };
    let run_with = |args: &[String]| {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        postflight(&args, dir.path())
    };

    // Start, and kill -9 once detect has been running for a moment.
    let mut child = Command::new(env!("CARGO_BIN_EXE_postflight"))
        .args(args(&config, &plan))
        .arg("-q")
        .env("XDG_CACHE_HOME", dir.path().join("cache"))
        .env("XDG_CONFIG_HOME", dir.path().join("config"))
        .env("XDG_DATA_HOME", dir.path().join("data"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let log = run.join("pipeline.json");
    let start = Instant::now();
    loop {
        let running = std::fs::read_to_string(&log)
            .ok()
            .and_then(|t| serde_json::from_str::<Value>(&t).ok())
            .and_then(|v| v["running"].as_str().map(String::from));
        if running.as_deref() == Some("detect") {
            break;
        }
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended before detect"
        );
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "detect never started"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(1500));
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(
        !run.join("detect.json").exists(),
        "detect finished before the kill; the flight is too short for this test"
    );
    let ingest_time = modified(&run.join("ingest.json"));

    let resumed = run_with(&args(&config, &plan));
    assert!(resumed.status.success(), "{}", stderr(&resumed));
    let text = stdout(&resumed);
    assert!(text.contains("ingest: up to date, skipped"), "{text}");
    assert!(!text.contains("ingested"), "ingest was redone:\n{text}");
    assert!(text.contains("detections in"), "detect ran:\n{text}");
    assert_eq!(modified(&run.join("ingest.json")), ingest_time);
    let logged = read_json(&log);
    let stages: Vec<&str> = logged["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["stage"].as_str().unwrap())
        .collect();
    assert_eq!(
        stages,
        [
            "ingest", "detect", "localise", "coverage", "replan", "record", "report"
        ]
    );
    assert!(logged["running"].is_null());
    assert_eq!(
        logged["stages"][0]["inputs"]["flight"]["sha256"]
            .as_str()
            .unwrap(),
        sha256_by_python(&flight)
    );

    // A changed localise setting reruns localise and what follows it, only.
    std::fs::write(
        &config,
        "[replan]\nsolver_time_limit_s = 2.0\n[localise]\nmax_range_m = 25.0\n",
    )
    .unwrap();
    let detect_time = modified(&run.join("detect.json"));
    let changed = run_with(&args(&config, &plan));
    assert!(changed.status.success(), "{}", stderr(&changed));
    let text = stdout(&changed);
    for stage in ["ingest", "detect"] {
        assert!(
            text.contains(&format!("{stage}: up to date, skipped")),
            "{text}"
        );
    }
    assert!(
        text.contains("defect candidates from"),
        "localise reran:\n{text}"
    );
    assert!(text.contains("target voxels"), "coverage reran:\n{text}");
    assert_eq!(modified(&run.join("detect.json")), detect_time);

    // A changed View model reruns detect (its tiles are chosen by it) and
    // localise (which judges each view by it).
    std::fs::write(
        &config,
        "[replan]\nsolver_time_limit_s = 2.0\n[localise]\nmax_range_m = 25.0\n[view]\nmax_distance_m = 3.0\n",
    )
    .unwrap();
    let text = stdout(&run_with(&args(&config, &plan)));
    assert!(text.contains("detections in"), "detect reran:\n{text}");
    assert!(
        text.contains("defect candidates from"),
        "localise reran:\n{text}"
    );
    let defects = read_json(&run.join("defects.json"));
    let far: Vec<&Value> = defects["defects"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|d| d["best"]["range_m"].as_f64().unwrap() > 3.0)
        .collect();
    assert!(!far.is_empty(), "no candidate's best view is beyond 3 m");
    for d in far {
        assert!(
            d["evidence"]["view_faults"]
                .as_array()
                .unwrap()
                .contains(&Value::from("too_far")),
            "{} seen from {} m has no too_far fault",
            d["id"],
            d["best"]["range_m"]
        );
    }

    // --force detect reruns detect.
    let mut forced = args(&config, &plan);
    forced.extend(["--force".to_string(), "detect".to_string()]);
    let text = stdout(&run_with(&forced));
    assert!(
        text.contains("ingest: up to date, skipped") && text.contains("detections in"),
        "{text}"
    );

    // A rerun whose replan fails (a battery of three seconds): nothing left
    // claims the old follow-up, neither replan's files nor the report and
    // summary built on them; the stages before keep their results, and no
    // JSON left holds null where a number was (issue 57, item 13).
    let flat = dir.path().join("flat-battery.toml");
    std::fs::write(
        &flat,
        "[replan]\nsolver_time_limit_s = 2.0\nbattery_minutes = 0.05\n[localise]\nmax_range_m = 25.0\n[view]\nmax_distance_m = 3.0\n",
    )
    .unwrap();
    assert!(run.join("report.html").is_file() && run.join("replan.csv").is_file());
    let failed = run_with(&args(&flat, &plan));
    assert_eq!(failed.status.code(), Some(1), "{}", stderr(&failed));
    assert!(
        stderr(&failed).contains("stage replan failed"),
        "{}",
        stderr(&failed)
    );
    assert_honest_after_failure(&run, "replan", None);

    // Each stage failing in turn, from the last to the first, with the
    // user's own folder where it writes a file: the folder is named and
    // kept, and the run directory is as honest as above.
    let done = run_with(&args(&config, &plan));
    assert!(done.status.success(), "{}", stderr(&done));
    for (stage, files) in STAGE_FILES.iter().rev() {
        // The user's folder is there before the run: so is not the file.
        let mine = run.join(files[0]);
        std::fs::remove_file(&mine).unwrap();
        std::fs::create_dir(&mine).unwrap();
        std::fs::write(mine.join("notes.txt"), "the user's").unwrap();
        let mut forced = args(&config, &plan);
        forced.extend(["--force".to_string(), stage.to_string()]);
        let failed = run_with(&forced);
        assert_eq!(
            failed.status.code(),
            Some(1),
            "{stage}: {}",
            stderr(&failed)
        );
        let err = stderr(&failed);
        assert!(
            err.contains(&format!("stage {stage} failed"))
                && err.contains(&format!("{} is in the way", mine.display())),
            "{err}"
        );
        assert_honest_after_failure(&run, stage, Some(&mine));
        assert_eq!(
            std::fs::read_to_string(mine.join("notes.txt")).unwrap(),
            "the user's"
        );
        std::fs::remove_dir_all(&mine).unwrap();
    }
    // What the failures left is what the stages before them wrote: a rerun
    // takes it as current.
    let resumed = run_with(&args(&config, &plan));
    assert!(resumed.status.success(), "{}", stderr(&resumed));
    let text = stdout(&resumed);
    assert!(text.contains("ingest: up to date, skipped"), "{text}");
    assert!(text.contains("detections in"), "detect reran:\n{text}");

    // A malformed plan is refused before anything runs, by line and column.
    let bad_plan = dir.path().join("bad-plan.json");
    std::fs::write(&bad_plan, "{\"resolution\": \"half a metre\"}").unwrap();
    let before = std::fs::read(&log).unwrap();
    let refused = run_with(&args(&config, &bad_plan));
    assert_eq!(refused.status.code(), Some(1));
    let err = stderr(&refused);
    assert!(err.contains("line 1 column 29"), "{err}");
    assert_eq!(std::fs::read(&log).unwrap(), before);

    // A stage that fails says which, and earlier results stay. (Detect
    // reads the map first: it chooses the tiles to run by it.)
    let bad_map = dir.path().join("bad-map.ply");
    std::fs::write(&bad_map, "ply\nformat ascii 1.0\nelement vertex 3\n").unwrap();
    let mut with_bad_map = args(&config, &plan);
    with_bad_map.extend(["--map".to_string(), bad_map.display().to_string()]);
    let failed = run_with(&with_bad_map);
    assert_eq!(failed.status.code(), Some(1));
    let err = stderr(&failed);
    assert!(
        err.contains("stage detect failed") && err.contains("resume from detect"),
        "{err}"
    );
    assert!(run.join("ingest.json").is_file() && !run.join("detect.json").exists());
    let logged = read_json(&log);
    assert_eq!(logged["running"], "detect");
    assert_eq!(logged["stages"].as_array().unwrap().len(), 1);

    // A config with a misspelt key is refused before anything runs.
    let typo = dir.path().join("typo.toml");
    std::fs::write(&typo, "[detect]\nconfidense = 0.3\n").unwrap();
    let refused = run_with(&args(&typo, &plan));
    assert_eq!(refused.status.code(), Some(1));
    let err = stderr(&refused);
    assert!(
        err.contains("confidense") && err.contains("[detect]"),
        "{err}"
    );
}

#[test]
fn a_simulated_flight_as_ros1_bags_and_ros1_mcap_runs_to_the_same_defects_and_coverage() {
    let dir = tempfile::tempdir().unwrap();
    // The 60-frame flight the batch tests fly too.
    let sim = simulate_into(dir.path(), "sim", &["--frames", "60"]);
    let ros2 = sim.join("flight.mcap");
    let config = dir.path().join("postflight.toml");
    std::fs::write(&config, "[replan]\nsolver_time_limit_s = 0.5\n").unwrap();
    let model = root().join("detect/models/crack-baked.onnx");
    let run = |flight: &Path, name: &str| {
        let out_dir = dir.path().join(name);
        let out = postflight(
            &[
                "run",
                "--flight",
                flight.to_str().unwrap(),
                "--plan",
                sim.join("plan.json").to_str().unwrap(),
                "--model",
                model.to_str().unwrap(),
                "--config",
                config.to_str().unwrap(),
                "--out",
                out_dir.to_str().unwrap(),
                "-q",
            ],
            dir.path(),
        );
        assert!(out.status.success(), "{name}: {}", stderr(&out));
        let table = |file: &str| read_parquet(&out_dir.join(file));
        (table("defects.parquet"), table("coverage.parquet"))
    };
    let (defects, coverage) = run(&ros2, "run-ros2");
    assert!(defects.height() > 0, "the flight shows no defects");
    for (file, args) in [
        ("none.bag", &["--compression", "none"][..]),
        ("bz2.bag", &["--compression", "bz2"][..]),
        ("lz4.bag", &["--compression", "lz4"][..]),
        ("ros1.mcap", &["--container", "mcap"][..]),
    ] {
        let flight = dir.path().join(file);
        to_ros1(&ros2, &flight, args);
        let (ros1_defects, ros1_coverage) = run(&flight, &format!("run-{file}"));
        assert!(ros1_defects.equals_missing(&defects), "{file}: defects");
        assert!(ros1_coverage.equals_missing(&coverage), "{file}: coverage");
    }
}

#[test]
fn a_missing_path_is_named_once_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing");
    let m = missing.to_str().unwrap();
    for command in [
        &["review", "serve", "--run", m][..],
        &["review", "export", "--run", m],
        &["report", "--run", m],
        &["coverage", "--run", m],
        &["replan", "--run", m],
        &["localise", "--run", m],
    ] {
        let out = postflight(command, dir.path());
        assert_eq!(out.status.code(), Some(1), "{command:?}");
        let err = stderr(&out);
        assert!(
            err.contains("no such directory")
                && err.contains("--run")
                && err.trim().lines().count() == 1,
            "{command:?}: {err}"
        );
    }
    let flight = dir.path().join("missing.mcap");
    let out_dir = dir.path().join("out");
    let (f, o) = (flight.to_str().unwrap(), out_dir.to_str().unwrap());
    for command in [
        &["ingest", "--flight", f, "--out", o][..],
        &["run", "--flight", f, "--out", o],
    ] {
        let out = postflight(command, dir.path());
        assert_eq!(out.status.code(), Some(1), "{command:?}");
        let err = stderr(&out);
        assert!(err.contains("missing.mcap"), "{command:?}: {err}");
        assert_eq!(
            err.matches("No such file").count().max(1),
            1,
            "{command:?}: {err}"
        );
        assert!(!out_dir.exists(), "{command:?} wrote {o}");
    }
    // A photo folder that is not there is named as such, not as a
    // recording that could not be read.
    let photos = dir.path().join("photos");
    let out = postflight(
        &["ingest", "--photos", photos.to_str().unwrap(), "--out", o],
        dir.path(),
    );
    assert_fails_in_one_line(&out, "cannot open");
    assert!(
        !stderr(&out).contains("not a flight recording"),
        "{}",
        stderr(&out)
    );
    assert!(!out_dir.exists());
}
