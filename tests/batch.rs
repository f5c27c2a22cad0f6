//! `postflight batch` and `postflight fleet` end to end: a manifest of two
//! simulated flights and a corrupt one, run on this machine and as a job
//! array of a real Slurm cluster (`scripts/setup --slurm`), checked against
//! `postflight run` on the same flights; the fleet's tables read by DuckDB.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use crate::common::*;
use serde_json::Value;

/// The manifest's good flights: structure, date and the simulator's arguments.
const GOOD: [(&str, &str, &[&str]); 2] = [
    ("bridge-a", "2026-05-01", &["--frames", "60"]),
    ("bridge-b", "2026-05-02", &["--frames", "40"]),
];
const CORRUPT: &str = "silo-c/2026-05-03";

/// A CSV manifest in `dir`: the good flights (read from the fixture cache)
/// and a recording that is not one.
fn manifest(dir: &Path) -> PathBuf {
    let mut csv = String::from("structure,date,flight,plan\n");
    for (structure, date, args) in GOOD {
        let sim = simulated(args);
        csv += &format!(
            "{structure},{date},{},{}\n",
            sim.join("flight.mcap").display(),
            sim.join("plan.json").display()
        );
    }
    std::fs::write(
        dir.join("corrupt.mcap"),
        b"\x89MCAP0\r\nthis is not a flight",
    )
    .unwrap();
    csv += "silo-c,2026-05-03,corrupt.mcap,\n";
    let path = dir.join("fleet.csv");
    std::fs::write(&path, csv).unwrap();
    path
}

/// `postflight run` on each good flight, once per test binary: the results
/// a batch must equal.
fn reference(structure: &str) -> PathBuf {
    static RUNS: OnceLock<PathBuf> = OnceLock::new();
    let runs = RUNS.get_or_init(|| {
        let dir = locked_fixture_dir("batch-reference");
        for (structure, _, args) in GOOD {
            run_simulated(&simulated(args), &dir.join(structure));
        }
        dir
    });
    runs.join(structure)
}

/// Every table and figure of a batch's run equals `postflight run`'s. The
/// follow-up tour is the one exception: its GTSP solve is bounded in time,
/// so on a loaded machine (flights side by side, tests in parallel) it can
/// stop at another tour; it flies the same viewpoints, a tour as long to
/// within 2%.
fn assert_same_results(batch: &Path, reference: &Path) {
    for table in [
        "frames.parquet",
        "detections.parquet",
        "observations.parquet",
        "defects.parquet",
        "coverage.parquet",
        "elements.parquet",
    ] {
        let (a, b) = (
            read_parquet(&batch.join(table)),
            read_parquet(&reference.join(table)),
        );
        assert!(
            a.equals_missing(&b),
            "{table} of {} differs from postflight run's",
            batch.display()
        );
    }
    let figures = |run: &Path| {
        // Paths into the run directory and times differ; the rest may not.
        let mut s = read_json(&run.join("summary.json"));
        for varying in ["run", "timings_s"] {
            s.as_object_mut().unwrap().remove(varying);
        }
        s["versions"].as_object_mut().unwrap().remove("model");
        let tour = s["replan"].as_object_mut().unwrap();
        let length = tour.remove("length_m").unwrap().as_f64().unwrap();
        tour.remove("time_s");
        (s, length)
    };
    let ((a, a_length), (b, b_length)) = (figures(batch), figures(reference));
    assert_eq!(a, b, "summary.json of {}", batch.display());
    assert_close(
        a_length,
        b_length,
        0.02 * b_length,
        "the follow-up tour's length",
    );
}

/// `postflight batch status`'s line for `flight`.
fn status_line(manifest: &Path, fleet: &Path, flight: &str) -> String {
    let out = postflight(
        &[
            "batch",
            "status",
            manifest.to_str().unwrap(),
            "--out",
            fleet.to_str().unwrap(),
        ],
        fleet.parent().unwrap(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    stdout(&out)
        .lines()
        .find(|l| l.starts_with(flight))
        .unwrap_or_else(|| panic!("no status line for {flight}:\n{}", stdout(&out)))
        .to_string()
}

/// The corrupt flight failed with one line naming the recording, and left
/// nothing that looks like a finished run.
fn assert_corrupt_flight_failed(manifest: &Path, fleet: &Path) {
    let line = status_line(manifest, fleet, CORRUPT);
    assert!(line.contains(" failed "), "{line}");
    assert!(
        line.contains("stage ingest failed") && line.contains("corrupt.mcap"),
        "{line}"
    );
    let record = read_json(&fleet.join(CORRUPT).join("batch.json"));
    assert_eq!(record["state"], "failed");
    assert!(!record["error"].as_str().unwrap().contains('\n'));
    assert!(!fleet.join(CORRUPT).join("summary.json").exists());
}

/// Whether the tests can submit to Slurm. Without `sbatch` the Slurm test
/// is skipped, unless `POSTFLIGHT_REQUIRE_SLURM` is set (as `scripts/test`
/// sets it, after starting a local cluster): then it fails.
fn slurm_available() -> bool {
    let found = std::process::Command::new("sbatch")
        .arg("--version")
        .output()
        .is_ok();
    if !found && std::env::var_os("POSTFLIGHT_REQUIRE_SLURM").is_some() {
        panic!("sbatch is not on PATH; run scripts/setup --slurm");
    }
    if !found {
        eprintln!("skipped: no Slurm here (scripts/setup --slurm starts a local cluster)");
    }
    found
}

#[test]
fn a_manifest_runs_as_a_slurm_job_array_with_the_results_of_postflight_run() {
    if !slurm_available() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let manifest = manifest(dir.path());
    let fleet = dir.path().join("fleet");
    let (m, f) = (manifest.to_str().unwrap(), fleet.to_str().unwrap());
    let out = postflight(
        &["batch", "run", m, "--out", f, "--engine", "slurm", "--wait"],
        dir.path(),
    );
    assert!(!out.status.success(), "the corrupt flight fails the batch");
    assert!(
        stdout(&out).contains("submitted 3 flights as Slurm job"),
        "{}",
        stdout(&out)
    );
    assert!(
        stderr(&out).contains(&format!("1 flight failed ({CORRUPT})")),
        "{}",
        stderr(&out)
    );
    for (structure, date, _) in GOOD {
        let run = fleet.join(structure).join(date);
        let record = read_json(&run.join("batch.json"));
        assert_eq!(record["state"], "finished", "{record}");
        assert_eq!(record["worker"]["engine"], "slurm", "{record}");
        assert_same_results(&run, &reference(structure));
    }
    assert_corrupt_flight_failed(&manifest, &fleet);

    // Resubmitting the failed flights sends the corrupt one alone.
    let out = postflight(
        &[
            "batch",
            "run",
            m,
            "--out",
            f,
            "--engine",
            "slurm",
            "--wait",
            "--only-failed",
        ],
        dir.path(),
    );
    assert!(
        stdout(&out).contains("submitted 1 flight as Slurm job"),
        "{}",
        stdout(&out)
    );
    assert_corrupt_flight_failed(&manifest, &fleet);

    fleet_tables_open_in_duckdb(&fleet);
}

/// A flight's detect in three shares: a share that failed here and one
/// done here, then the flight as a Slurm array, which resumes the failed
/// share, leaves the done one, merges the three and runs the later stages
/// once; the results are `postflight run`'s.
#[test]
fn a_flight_in_three_shares_as_a_slurm_array_resumes_a_failed_share_with_the_results_of_postflight_run()
 {
    if !slurm_available() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (structure, date, args) = GOOD[0];
    let sim = simulated(args);
    let manifest = dir.path().join("fleet.csv");
    std::fs::write(
        &manifest,
        format!(
            "structure,date,flight,plan,shards\n{structure},{date},{},{},3\n",
            sim.join("flight.mcap").display(),
            sim.join("plan.json").display()
        ),
    )
    .unwrap();
    let fleet = dir.path().join("fleet");
    let run = fleet.join(structure).join(date);
    let (m, f) = (manifest.to_str().unwrap(), fleet.to_str().unwrap());
    let task = |index: &str, more: &[&str]| {
        let mut args = vec!["batch", "task", m, "--out", f, "--index", index];
        args.extend_from_slice(more);
        postflight(&args, dir.path())
    };
    // Share 1 fails after ingesting (no ONNX Runtime there); share 2 runs.
    let out = task("0", &["--onnxruntime", "/no/such/libonnxruntime.so"]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("detect share 1/3 failed"),
        "{}",
        stderr(&out)
    );
    let out = task("1", &[]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stdout(&out).contains("detect: share 2/3 done; 1/3, 3/3 to go"),
        "{}",
        stdout(&out)
    );
    assert!(!run.join("detect.json").exists(), "no flight's detect yet");
    let line = status_line(&manifest, &fleet, structure);
    assert!(
        line.contains(" failed ")
            && line.contains("1 of 3 shares done; share 1/3: detect share 1/3 failed"),
        "{line}"
    );

    let out = postflight(
        &["batch", "run", m, "--out", f, "--engine", "slurm", "--wait"],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stdout(&out).contains("submitted 3 tasks (1 flight) as Slurm job"),
        "{}",
        stdout(&out)
    );
    let line = status_line(&manifest, &fleet, structure);
    assert!(
        line.contains(" finished ") && line.contains("3 of 3 shares done"),
        "{line}"
    );
    let records: Vec<Value> = (1..=3)
        .map(|k| read_json(&run.join(format!("batch-share-{k}-of-3.json"))))
        .collect();
    for r in &records {
        assert_eq!(r["state"], "finished", "{r}");
        assert_eq!(r["worker"]["engine"], "slurm", "{r}");
    }
    // Share 2 was done: its Slurm task left it; the later stages ran once.
    let ran = |r: &Value, step: &str| {
        r["stages_run"]
            .as_array()
            .unwrap()
            .iter()
            .any(|s| s == step)
    };
    assert!(!ran(&records[1], "detect share 2/3"), "{}", records[1]);
    assert!(ran(&records[0], "detect share 1/3") && ran(&records[2], "detect share 3/3"));
    assert_eq!(records.iter().filter(|r| ran(r, "localise")).count(), 1);
    let merged = read_json(&run.join("detect.json"));
    assert_eq!(merged["shard"], Value::Null, "{merged}");
    assert_same_results(&run, &reference(structure));
}

/// `postflight fleet` over a batch: every candidate in one DuckDB glob.
fn fleet_tables_open_in_duckdb(fleet: &Path) {
    let out = postflight(&["fleet", fleet.to_str().unwrap()], fleet);
    assert!(out.status.success(), "{}", stderr(&out));
    let query = r#"
import duckdb, json, sys
con = duckdb.connect()
rows = con.sql("""
    SELECT structure, date, run, count(*) AS candidates
    FROM read_parquet('fleet/defects.parquet/**/*.parquet', hive_partitioning=true)
    GROUP BY ALL ORDER BY structure
""").fetchall()
flights = con.sql("""
    SELECT structure, state FROM read_parquet('fleet/flights.parquet/**/*.parquet', hive_partitioning=true)
    ORDER BY structure
""").fetchall()
by_element = con.sql("""
    SELECT structure, coalesce(element, ''), count(*)
    FROM read_parquet('fleet/defects.parquet/**/*.parquet', hive_partitioning=true)
    GROUP BY ALL ORDER BY ALL
""").fetchall()
records = con.sql("""
    SELECT structure, run, count(*), count(parent)
    FROM read_parquet('fleet/elements.parquet/**/*.parquet', hive_partitioning=true)
    GROUP BY ALL ORDER BY structure
""").fetchall()
print(json.dumps({"defects": rows, "flights": flights, "by_element": by_element, "records": records}))
"#;
    let text = std::process::Command::new(python())
        .args(["-c", query])
        .current_dir(fleet)
        .output()
        .unwrap();
    assert!(text.status.success(), "{}", stderr(&text));
    let tables: Value = serde_json::from_slice(&text.stdout).unwrap();
    let mut expected = Vec::new();
    for (structure, date, _) in GOOD {
        let defects = read_json(&fleet.join(structure).join(date).join("defects.json"));
        let n = defects["defects"].as_array().unwrap().len();
        if n > 0 {
            expected.push(serde_json::json!([
                structure,
                date,
                format!("{structure}/{date}"),
                n
            ]));
        }
    }
    assert!(!expected.is_empty(), "the simulated flights have cracks");
    assert_eq!(tables["defects"], Value::Array(expected));
    // Cracks per element across the fleet, as each run's defects.json names them.
    let mut by_element = std::collections::BTreeMap::new();
    for (structure, date, _) in GOOD {
        let defects = read_json(&fleet.join(structure).join(date).join("defects.json"));
        for d in defects["defects"].as_array().unwrap() {
            let element = d["element"].as_str().unwrap_or_default().to_string();
            *by_element
                .entry((structure.to_string(), element))
                .or_insert(0) += 1;
        }
    }
    let by_element: Vec<Value> = by_element
        .into_iter()
        .map(|((s, e), n)| serde_json::json!([s, e, n]))
        .collect();
    assert!(
        by_element.iter().any(|row| row[1] != ""),
        "the candidates are on named elements: {by_element:?}"
    );
    assert_eq!(tables["by_element"], Value::Array(by_element));
    assert_eq!(
        tables["flights"],
        serde_json::json!([
            ["bridge-a", "finished"],
            ["bridge-b", "finished"],
            ["silo-c", "failed"]
        ])
    );
    // Each run's element record, its rows and those of defects under an
    // element, as each run's own elements.parquet holds them.
    let records: Vec<Value> = GOOD
        .iter()
        .map(|(structure, date, _)| {
            let own = read_parquet(&fleet.join(structure).join(date).join("elements.parquet"));
            let defects = own
                .column("parent")
                .unwrap()
                .is_not_null()
                .sum()
                .unwrap_or(0);
            serde_json::json!([
                structure,
                format!("{structure}/{date}"),
                own.height(),
                defects
            ])
        })
        .collect();
    assert_eq!(tables["records"], Value::Array(records));
    let index = std::fs::read_to_string(fleet.join("fleet/index.html")).unwrap();
    for (structure, date, _) in GOOD {
        assert!(
            index.contains(&format!("href=\"../{structure}/{date}/report.html\"")),
            "{index}"
        );
    }
}

#[test]
fn a_manifest_runs_here_two_at_a_time_skips_finished_flights_and_reruns_lost_ones() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = manifest(dir.path());
    let fleet = dir.path().join("fleet");
    let (m, f) = (manifest.to_str().unwrap(), fleet.to_str().unwrap());
    let out = postflight(&["batch", "run", m, "--out", f, "--jobs", "2"], dir.path());
    assert!(!out.status.success(), "the corrupt flight fails the batch");
    let lines = stdout(&out);
    for (structure, date, _) in GOOD {
        assert!(
            lines.contains(&format!("{structure}/{date}: finished in")),
            "{lines}"
        );
        let run = fleet.join(structure).join(date);
        assert_eq!(
            read_json(&run.join("batch.json"))["worker"]["engine"],
            "local"
        );
        assert_same_results(&run, &reference(structure));
    }
    assert!(
        stderr(&out).contains(&format!("{CORRUPT}: failed: stage ingest failed")),
        "{}",
        stderr(&out)
    );
    assert_corrupt_flight_failed(&manifest, &fleet);

    // A second run finds the good flights done.
    let out = postflight(&["batch", "run", m, "--out", f, "--jobs", "2"], dir.path());
    for (structure, date, _) in GOOD {
        assert!(
            stdout(&out).contains(&format!("{structure}/{date}: up to date")),
            "{}",
            stdout(&out)
        );
    }

    // A task killed mid-run leaves "running" with a process that is gone:
    // lost, and run again by --only-failed, which resumes it.
    let (structure, date, _) = GOOD[0];
    let record_path = fleet.join(structure).join(date).join("batch.json");
    let mut record = read_json(&record_path);
    record["state"] = "running".into();
    record["pid"] = (u32::MAX - 1).into();
    std::fs::write(&record_path, record.to_string()).unwrap();
    let line = status_line(&manifest, &fleet, &format!("{structure}/{date}"));
    assert!(
        line.contains(" lost ") && line.contains("is gone"),
        "{line}"
    );
    let out = postflight(
        &["batch", "run", m, "--out", f, "--only-failed"],
        dir.path(),
    );
    let lines = stdout(&out);
    assert!(
        lines.contains(&format!("[1/2] {structure}/{date}: up to date"))
            || lines.contains(&format!("[2/2] {structure}/{date}: up to date")),
        "{lines}"
    );
    assert!(
        !lines.contains(GOOD[1].0),
        "only the lost and the failed flight run: {lines}"
    );
    assert_eq!(read_json(&record_path)["state"], "finished");
}

#[test]
fn batch_k8s_writes_an_indexed_job_with_a_completion_per_flight() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = manifest(dir.path());
    let out = postflight(
        &[
            "batch",
            "k8s",
            manifest.to_str().unwrap(),
            "--out",
            "/data/fleet",
            "--image",
            "registry.example/postflight:0.1",
            "--volume-claim",
            "flights",
            "--jobs",
            "2",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let job: serde_yaml_ng::Value = serde_yaml_ng::from_slice(&out.stdout).unwrap();
    assert_eq!(job["kind"], "Job");
    assert_eq!(job["spec"]["completionMode"], "Indexed");
    assert_eq!(job["spec"]["completions"], 3);
    assert_eq!(job["spec"]["parallelism"], 2);
    let container = &job["spec"]["template"]["spec"]["containers"][0];
    let command: Vec<&str> = container["command"]
        .as_sequence()
        .unwrap()
        .iter()
        .map(|c| c.as_str().unwrap())
        .collect();
    assert_eq!(
        &command[..5],
        [
            "postflight",
            "batch",
            "task",
            manifest.to_str().unwrap(),
            "--out"
        ]
    );
    assert!(
        !command.contains(&"--index"),
        "the index comes from JOB_COMPLETION_INDEX"
    );
    // The pods read their index from JOB_COMPLETION_INDEX: the task does.
    let fleet = dir.path().join("fleet");
    let task = std::process::Command::new(env!("CARGO_BIN_EXE_postflight"))
        .args([
            "batch",
            "task",
            manifest.to_str().unwrap(),
            "--out",
            fleet.to_str().unwrap(),
        ])
        .env("JOB_COMPLETION_INDEX", "2")
        .env("XDG_CACHE_HOME", dir.path().join("cache"))
        .output()
        .unwrap();
    assert!(!task.status.success(), "flight 2 is the corrupt one");
    let record = read_json(&fleet.join(CORRUPT).join("batch.json"));
    assert_eq!(record["index"], 2);
    assert_eq!(record["worker"]["engine"], "kubernetes");
}
