//! Shared helpers for the end-to-end tests: the project's Python (for the
//! independent MCAP writer), fixture generation and running the binary.

use std::hash::{DefaultHasher, Hash, Hasher};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use polars::prelude::*;
use serde_json::Value;

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The project virtualenv's Python; `scripts/setup` creates it.
pub fn python() -> PathBuf {
    if let Some(p) = std::env::var_os("POSTFLIGHT_PYTHON") {
        return p.into();
    }
    let p = root().join(".venv/bin/python");
    assert!(
        p.is_file(),
        "{} is missing: run scripts/setup (or scripts/test) to create the project virtualenv",
        p.display()
    );
    p
}

/// Run Python `code` (`python -c`) with `args`; returns its stdout, trimmed.
pub fn python_run<S: AsRef<std::ffi::OsStr>>(code: &str, args: &[S]) -> String {
    python_stdout(Command::new(python()).args(["-c", code]).args(args))
}

/// Run the script tests/fixtures/`script` with `args`; returns its
/// stdout, trimmed.
pub fn python_fixture<S: AsRef<std::ffi::OsStr>>(script: &str, args: &[S]) -> String {
    python_stdout(
        Command::new(python())
            .arg(root().join("tests/fixtures").join(script))
            .args(args),
    )
}

fn python_stdout(command: &mut Command) -> String {
    let out = command.output().expect("run the project's Python");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).trim().to_string()
}

/// Write a flight with tests/fixtures/write_flight.py; returns (mcap, expected).
pub fn write_flight(dir: &Path, name: &str, args: &[&str]) -> (PathBuf, Value) {
    let mcap = dir.join(format!("{name}.mcap"));
    let expected = dir.join(format!("{name}.expected.json"));
    let out = Command::new(python())
        .arg(root().join("tests/fixtures/write_flight.py"))
        .arg(&mcap)
        .arg("--expected")
        .arg(&expected)
        .args(args)
        .output()
        .expect("run the fixture writer");
    assert!(
        out.status.success(),
        "fixture writer failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let expected = serde_json::from_str(&std::fs::read_to_string(&expected).unwrap()).unwrap();
    (mcap, expected)
}

/// Run `postflight` with isolated cache/config dirs.
pub fn postflight(args: &[&str], home: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_postflight"))
        .args(args)
        .env("XDG_CACHE_HOME", home.join("cache"))
        .env("XDG_CONFIG_HOME", home.join("config"))
        .env("XDG_DATA_HOME", home.join("data"))
        .env_remove("POSTFLIGHT_LOG")
        .output()
        .expect("run postflight")
}

pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The command failed (exit 1) with one line of error that says `says`.
pub fn assert_fails_in_one_line(out: &Output, says: &str) {
    let err = stderr(out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains(says), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
}

pub fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

pub fn read_json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

pub fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

pub fn vec3(v: &Value) -> [f64; 3] {
    [f(&v[0]), f(&v[1]), f(&v[2])]
}

/// A `{translation, rotation_xyzw}` object (truth.json, ingest.json,
/// changes.json) as a pose.
pub fn pose(v: &Value) -> nalgebra::Isometry3<f64> {
    let t = vec3(&v["translation"]);
    let q = v["rotation_xyzw"].as_array().unwrap();
    let q = nalgebra::Quaternion::new(f(&q[3]), f(&q[0]), f(&q[1]), f(&q[2]));
    nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::new(t[0], t[1], t[2]),
        nalgebra::UnitQuaternion::from_quaternion(q),
    )
}

/// How far `found` is from `expected`: metres, and degrees of rotation.
pub fn pose_error(
    expected: &nalgebra::Isometry3<f64>,
    found: &nalgebra::Isometry3<f64>,
) -> (f64, f64) {
    let error = expected.inverse() * found;
    (
        error.translation.vector.norm(),
        error.rotation.angle().to_degrees(),
    )
}

pub fn assert_close(a: f64, b: f64, tol: f64, what: &str) {
    assert!(
        (a - b).abs() <= tol,
        "{what}: {a} vs expected {b} (tolerance {tol})"
    );
}

/// Rewrite the ROS 2 recording `src` as ROS 1 at `out` with
/// tests/fixtures/to_ros1.py (`rosbags` for bags, `mcap-ros1-support` for
/// MCAP); `args` as the script takes them (`--container`, `--compression`).
pub fn to_ros1(src: &Path, out: &Path, args: &[&str]) {
    let run = Command::new(python())
        .arg(root().join("tests/fixtures/to_ros1.py"))
        .arg(src)
        .arg(out)
        .args(args)
        .output()
        .expect("run the ROS 1 writer");
    assert!(
        run.status.success(),
        "ROS 1 writer failed: {}",
        String::from_utf8_lossy(&run.stderr)
    );
}

/// Run `postflight ingest` (XDG dirs beside the run directory).
pub fn run_ingest(flight: &Path, run: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "ingest",
        "--flight",
        flight.to_str().unwrap(),
        "--out",
        run.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    postflight(&args, run.parent().unwrap())
}

/// Run `postflight ingest`, which must succeed; returns its ingest.json.
pub fn ingest_ok(flight: &Path, run: &Path, extra: &[&str]) -> Value {
    let out = run_ingest(flight, run, extra);
    assert!(out.status.success(), "ingest failed: {}", stderr(&out));
    read_json(&run.join("ingest.json"))
}

/// An empty scratch directory `name` under Cargo's `CARGO_TARGET_TMPDIR`
/// (reused, not leaked, across runs), locked for the rest of this process:
/// two test runs that share a target directory (two clones, one cache) take
/// turns at the fixture instead of writing into each other's.
pub fn locked_fixture_dir(name: &str) -> PathBuf {
    let scratch = Path::new(env!("CARGO_TARGET_TMPDIR"));
    let lock = std::fs::File::create(scratch.join(format!("{name}.lock"))).unwrap();
    lock.lock().unwrap();
    // Held until the process exits, whatever the tests do meanwhile.
    std::mem::forget(lock);
    let dir = scratch.join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The flight `postflight simulate` makes with `args`, in `dir/name` (a
/// copy from the fixture cache).
pub fn simulate_into(dir: &Path, name: &str, args: &[&str]) -> PathBuf {
    let out = dir.join(name);
    copy_dir(&simulated(args), &out);
    out
}

/// Simulate a flight into `out` with `args`, now (not from the fixture cache).
pub fn simulate_fresh(out: &Path, args: &[&str]) {
    let mut all = vec!["simulate", "--out", out.to_str().unwrap()];
    all.extend_from_slice(args);
    let result = postflight(&all, out.parent().unwrap());
    assert!(result.status.success(), "{}", stderr(&result));
}

/// The flight `postflight simulate` makes with `args`, made once per
/// version of the simulator's sources (it is deterministic) and shared by
/// every test and test binary that flies it: read only. A test that changes
/// its flight takes a copy ([`simulate_into`]).
pub fn simulated(args: &[&str]) -> PathBuf {
    made_once("simulated", simulator_sources(), &flight_key(args), |out| {
        simulate_fresh(out, args)
    })
}

/// `simulate`'s arguments without those that give a default, in order: a
/// flight asked for with its defaults spelled out is the same flight.
fn flight_key<'a>(args: &[&'a str]) -> Vec<&'a str> {
    let defaults = [
        // The default scene (`sim::BuiltIn`'s first).
        ("--scene", "girder-bridge".to_string()),
        ("--seed", sim::SimOptions::DEFAULT_SEED.to_string()),
        ("--frames", sim::SimOptions::DEFAULT_FRAMES.to_string()),
    ];
    let is_default =
        |flag: &str, value: &str| defaults.iter().any(|(f, v)| *f == flag && v == value);
    let mut key = Vec::new();
    let mut i = 0;
    while i < args.len() {
        if args.get(i + 1).is_some_and(|v| is_default(args[i], v)) {
            i += 2;
        } else {
            key.push(args[i]);
            i += 1;
        }
    }
    key
}

/// A hash of every file the simulator is built from (the flight model and
/// the simulator's crates, the commands that call it, the locked
/// dependencies): a flight made by any build of the same sources is the
/// same flight, so a fresh clone reuses what an earlier clone simulated
/// into the same target directory, whatever else changed.
fn simulator_sources() -> u64 {
    static HASH: std::sync::OnceLock<u64> = std::sync::OnceLock::new();
    *HASH.get_or_init(|| {
        let mut files = Vec::new();
        for dir in ["core", "sim"] {
            files_under(&root().join(dir), &mut files);
        }
        let files_too = ["src/main.rs", "src/stages.rs", "Cargo.toml", "Cargo.lock"];
        files.extend(files_too.map(|f| root().join(f)));
        files.sort();
        let mut h = DefaultHasher::new();
        for f in &files {
            f.strip_prefix(root()).unwrap().hash(&mut h);
            std::fs::read(f).unwrap().hash(&mut h);
        }
        h.finish()
    })
}

fn files_under(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        let path = entry.path();
        if path.is_dir() {
            files_under(&path, out);
        } else {
            out.push(path);
        }
    }
}

/// The reference detector's run (`ingest`, then `detect` with
/// crack-baked.onnx) over the flight `postflight simulate` makes with
/// `sim_args`, in `dir/name` (a copy from the fixture cache, like
/// [`simulate_into`]): detection is the slowest stage, and the detect,
/// localise and other truth tests fly the same default flights.
pub fn detected_into(dir: &Path, name: &str, sim_args: &[&str]) -> PathBuf {
    let model = root().join("detect/models/crack-baked.onnx");
    let meta = std::fs::metadata(&model).unwrap();
    let key = (flight_key(sim_args), meta.len(), meta.modified().unwrap());
    let cached = made_once("detected", this_build(), &key, |out| {
        ingest_ok(&simulated(sim_args).join("flight.mcap"), out, &[]);
        let run = out.to_str().unwrap();
        let model = model.to_str().unwrap();
        let result = postflight(
            &["detect", "--run", run, "--model", model],
            out.parent().unwrap(),
        );
        assert!(result.status.success(), "{}", stderr(&result));
    });
    let out = dir.join(name);
    copy_dir(&cached, &out);
    out
}

/// A hash of this build of postflight (the binary's size and time).
fn this_build() -> u64 {
    let exe = std::fs::metadata(env!("CARGO_BIN_EXE_postflight")).unwrap();
    let mut h = DefaultHasher::new();
    (exe.len(), exe.modified().unwrap()).hash(&mut h);
    h.finish()
}

/// The directory `make` fills for `key`, made once per `generation` (a
/// hash of what makes it: a build, or the sources of one) under
/// `CARGO_TARGET_TMPDIR/kind` and shared by every test and test binary
/// that asks for it; what other generations made is removed.
fn made_once<K: Hash>(kind: &str, generation: u64, key: &K, make: impl FnOnce(&Path)) -> PathBuf {
    let mut made = DefaultHasher::new();
    key.hash(&mut made);
    let (generation, made) = (format!("{generation:016x}"), made.finish());
    let cache = Path::new(env!("CARGO_TARGET_TMPDIR")).join(kind);
    let done = cache.join(format!("{generation}-{made:016x}"));
    if done.is_dir() {
        return done;
    }
    std::fs::create_dir_all(&cache).unwrap();
    for entry in std::fs::read_dir(&cache).unwrap().flatten() {
        if !entry.file_name().to_string_lossy().starts_with(&generation) {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
    let making = tempfile::Builder::new()
        .prefix(&format!("{generation}-making-"))
        .tempdir_in(&cache)
        .unwrap()
        .keep();
    make(&making.join("made"));
    // Another test may have made it meanwhile: either copy will do.
    if std::fs::rename(making.join("made"), &done).is_err() {
        assert!(done.is_dir(), "{} was not made", done.display());
    }
    let _ = std::fs::remove_dir_all(&making);
    done
}

/// Copy directory `from`, with its folders, into a new directory `to`.
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap().flatten() {
        let (path, into) = (entry.path(), to.join(entry.file_name()));
        if path.is_dir() {
            copy_dir(&path, &into);
        } else {
            std::fs::copy(&path, &into).unwrap();
        }
    }
}

/// A row of detections.parquet.
pub struct DetectionRow {
    pub time_ns: i64,
    pub x0: f64,
    pub y0: f64,
    pub x1: f64,
    pub y1: f64,
    pub score: f64,
    pub tile: i64,
    pub prompt: String,
}

/// `postflight run` on a simulated flight (`simulate`'s directory) with
/// its plan, into `out`.
pub fn run_simulated(sim: &Path, out: &Path) {
    run_simulated_with(sim, out, &[]);
}

/// [`run_simulated`] with more of `run`'s arguments (`--config FILE`).
pub fn run_simulated_with(sim: &Path, out: &Path, more: &[&str]) {
    let (flight, plan) = (sim.join("flight.mcap"), sim.join("plan.json"));
    let mut args = vec![
        "run",
        "--flight",
        flight.to_str().unwrap(),
        "--plan",
        plan.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(more);
    let result = postflight(&args, out.parent().unwrap());
    assert!(result.status.success(), "{}", stderr(&result));
}

/// A truth crack's lines (`truth.json`'s `lines`: main line, then
/// branches), world frame, metres.
pub fn truth_lines(crack: &Value) -> Vec<Vec<[f64; 3]>> {
    crack["lines"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l.as_array().unwrap().iter().map(vec3).collect())
        .collect()
}

/// A Parquet table, whole.
pub fn read_parquet(path: &Path) -> DataFrame {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    ParquetReader::new(file).finish().unwrap()
}

/// A CSV table with a header line, whole.
pub fn read_csv(path: &Path) -> DataFrame {
    CsvReadOptions::default()
        .with_has_header(true)
        .try_into_reader_with_file_path(Some(path.to_owned()))
        .unwrap()
        .finish()
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

pub fn detection_rows(run: &Path) -> Vec<DetectionRow> {
    let df = read_parquet(&run.join("detections.parquet"));
    let time = df.column("time_ns").unwrap().i64().unwrap().clone();
    let tile = df.column("tile").unwrap().i32().unwrap().clone();
    let prompt = df.column("prompt").unwrap().str().unwrap().clone();
    let col = |c: &str| df.column(c).unwrap().f32().unwrap().clone();
    let [x0, y0, x1, y1, score] = ["x0", "y0", "x1", "y1", "score"].map(col);
    let at = |c: &Float32Chunked, i: usize| f64::from(c.get(i).unwrap());
    (0..df.height())
        .map(|i| DetectionRow {
            time_ns: time.get(i).unwrap(),
            x0: at(&x0, i),
            y0: at(&y0, i),
            x1: at(&x1, i),
            y1: at(&y1, i),
            score: at(&score, i),
            tile: i64::from(tile.get(i).unwrap()),
            prompt: prompt.get(i).unwrap().to_string(),
        })
        .collect()
}

/// Intersection over union of two `[x0, y0, x1, y1]` boxes.
pub fn iou(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    let ix = (a[2].min(b[2]) - a[0].max(b[0])).max(0.0);
    let iy = (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
    let inter = ix * iy;
    let union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter;
    if union > 0.0 { inter / union } else { 0.0 }
}

fn octomap_tool(name: &str, args: &[&str]) {
    let out = Command::new(name).args(args).output().unwrap_or_else(|e| {
        panic!("{name}: {e}; install Debian's octomap-tools (scripts/setup --test does)")
    });
    assert!(
        out.status.success(),
        "{name} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Build `.bt` and `.ot` trees of `points` at `resolution` with
/// octomap-tools. Each point is a scan node of its own with the point at
/// the sensor, so no ray crosses (and frees) another point's voxel.
pub fn octomap_of(
    dir: &Path,
    name: &str,
    points: &[nalgebra::Point3<f64>],
    resolution: f64,
) -> [PathBuf; 2] {
    let log = dir.join(format!("{name}.log"));
    let mut text = String::new();
    for p in points {
        text.push_str(&format!("NODE {} {} {} 0 0 0\n0 0 0\n", p.x, p.y, p.z));
    }
    std::fs::write(&log, text).unwrap();
    let graph = dir.join(format!("{name}.graph"));
    let bt = dir.join(format!("{name}.bt"));
    let ot = dir.join(format!("{name}.ot"));
    let s = |p: &Path| p.to_str().unwrap().to_string();
    octomap_tool("log2graph", &[&s(&log), &s(&graph)]);
    octomap_tool(
        "graph2tree",
        &[
            "-i",
            &s(&graph),
            "-o",
            &s(&bt),
            "-res",
            &resolution.to_string(),
        ],
    );
    octomap_tool("convert_octree", &[&s(&bt), &s(&ot)]);
    [bt, ot]
}

/// Write `points` as an ASCII PLY (doubles, as written by `{}`: exact).
pub fn write_ply(path: &Path, points: &[nalgebra::Point3<f64>]) {
    let mut text = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nend_header\n",
        points.len()
    );
    for p in points {
        text.push_str(&format!("{} {} {}\n", p.x, p.y, p.z));
    }
    std::fs::write(path, text).unwrap();
}
