//! The GTSP solver on benchmark instances: one JSON line per (instance,
//! seed) with the cost, the time and when the best tour was found. With
//! `--export DIR` it also writes each instance as JSON (`n`, 0-based `sets`,
//! row-major `cost`) so that `benches/gtsp/compare.py` hands OR-Tools and
//! PyVRP exactly the costs this parser read.
//!
//! Run: `cargo bench -p postflight-gtsp --bench gtsp -- [--seeds N]
//! [--threads N] [--export DIR] INSTANCE=SECONDS ...` (or `scripts/bench-gtsp`
//! for the whole comparison).

use std::path::{Path, PathBuf};
use std::time::Duration;

use gtsp::{Instance, SolveOptions, solve};

fn main() {
    let mut seeds = 10u64;
    let mut threads = 0usize;
    let mut export: Option<PathBuf> = None;
    let mut runs: Vec<(PathBuf, f64)> = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = |name: &str| {
            args.next()
                .unwrap_or_else(|| fail(&format!("{name} needs a value")))
        };
        match arg.as_str() {
            "--seeds" => {
                seeds = value("--seeds")
                    .parse()
                    .unwrap_or_else(|_| fail("--seeds takes a count"))
            }
            "--threads" => {
                threads = value("--threads")
                    .parse()
                    .unwrap_or_else(|_| fail("--threads takes a count"))
            }
            "--export" => export = Some(value("--export").into()),
            // cargo bench passes --bench to every bench binary.
            "--bench" => {}
            run => {
                let Some((path, seconds)) = run.rsplit_once('=') else {
                    fail(&format!("expected INSTANCE=SECONDS, got {run}"))
                };
                let seconds = seconds
                    .parse()
                    .unwrap_or_else(|_| fail(&format!("{run}: SECONDS is not a number")));
                runs.push((path.into(), seconds));
            }
        }
    }
    if runs.is_empty() {
        fail("no instances: give INSTANCE=SECONDS ...");
    }
    for (path, seconds) in runs {
        let inst =
            Instance::read(&path).unwrap_or_else(|e| fail(&format!("{}: {e}", path.display())));
        if let Some(dir) = &export {
            write_instance(&inst, dir);
        }
        for seed in 1..=seeds {
            let options = SolveOptions {
                time_limit: Some(Duration::from_secs_f64(seconds)),
                seed,
                threads,
                ..SolveOptions::default()
            };
            let solution = solve(&inst, &options);
            inst.check_tour(&solution.tour)
                .unwrap_or_else(|e| fail(&format!("{}: invalid tour: {e}", inst.name)));
            assert_eq!(
                inst.tour_cost(&solution.tour),
                solution.cost,
                "reported cost is the tour's cost"
            );
            let line = serde_json::json!({
                "instance": inst.name,
                "solver": "postflight",
                "seed": seed,
                "time_limit_s": seconds,
                "cost": solution.cost,
                "time_s": solution.stats.time_s,
                "best_found_s": solution.stats.best_found_s,
                "threads": solution.stats.threads,
            });
            println!("{line}");
        }
    }
}

fn write_instance(inst: &Instance, dir: &Path) {
    let n = inst.vertices();
    let cost: Vec<i64> = (0..n as u32)
        .flat_map(|a| (0..n as u32).map(move |b| inst.cost(a, b)))
        .collect();
    let json = serde_json::json!({
        "name": inst.name,
        "n": n,
        "sets": inst.sets(),
        "cost": cost,
    });
    std::fs::create_dir_all(dir).unwrap_or_else(|e| fail(&format!("{}: {e}", dir.display())));
    let path = dir.join(format!("{}.json", inst.name));
    std::fs::write(&path, json.to_string())
        .unwrap_or_else(|e| fail(&format!("{}: {e}", path.display())));
}

fn fail(message: &str) -> ! {
    eprintln!("gtsp bench: {message}");
    std::process::exit(2);
}
