//! `postflight demo`: the whole pipeline on the default simulated flight,
//! with the reference crack detector that ships inside postflight.

use std::path::Path;

use postflight_core::Stage;
use postflight_core::outputs::report::files;

use crate::config::RunConfig;
use crate::pipeline::{RunInputs, run};
use crate::stages;

/// The reference detector (`detect/models/crack-baked.onnx`, built by
/// `detect/models/build_reference.py` for the simulator's cracks).
const REFERENCE_MODEL: &[u8] = include_bytes!("../detect/models/crack-baked.onnx");

/// Write the reference detector to `path` (unless it is already there, so
/// its content hash and the run's fingerprints stay put).
pub fn write_reference_model(path: &Path) -> anyhow::Result<()> {
    if std::fs::read(path).ok().as_deref() == Some(REFERENCE_MODEL) {
        return Ok(());
    }
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)
            .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", dir.display()))?;
    }
    std::fs::write(path, REFERENCE_MODEL)
        .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))
}

pub fn demo(out: &Path, force: Option<Stage>, quiet: bool) -> anyhow::Result<()> {
    let flight = out.join("flight");
    // truth.json is the simulator's last file: with it, the flight is whole.
    if flight.join("truth.json").is_file() {
        if !quiet {
            println!(
                "simulate: reusing the simulated flight in {}",
                flight.display()
            );
        }
    } else {
        stages::simulate(&sim::SimOptions::new(flight.clone()), quiet)?;
    }
    let model = out.join("model").join("crack-baked.onnx");
    write_reference_model(&model)?;
    let run_dir = out.join("run");
    run(
        &RunInputs {
            flights: vec![flight.join("flight.mcap")],
            map: None,
            plan: Some(postflight_core::PlanFile::new(flight.join("plan.json"))),
            targets: coverage::Targets::Plan,
            model: Some(model),
            onnxruntime: None,
            config: RunConfig::default(),
            out: run_dir.clone(),
            force,
            previous: None,
        },
        quiet,
    )?;
    println!(
        "\nThe demo flight's results:\n  report:       {}\n  3D recording: rerun {}\n  summary:      {}\n  tables:       {} (*.parquet: polars, pandas, DuckDB)\n  ground truth: {}\n  review:       postflight review serve --run {}",
        run_dir.join(files::REPORT).display(),
        run_dir.join(files::RECORDING).display(),
        run_dir.join(files::SUMMARY).display(),
        run_dir.display(),
        flight.join("truth.json").display(),
        run_dir.display()
    );
    Ok(())
}
