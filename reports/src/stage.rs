//! The report stage: reads what the other stages wrote into a run directory
//! and writes `flight.rrd`, `candidates.csv`, `report.html`, then
//! `summary.json` (last: the stage is complete exactly when it exists).

use std::path::PathBuf;
use std::time::Instant;

use postflight_core::outputs::report::{self, RunSummary, files};

use crate::error::ReportError;
use crate::html;
use crate::recording::write_recording;
use crate::results::RunResults;
use crate::summary::run_summary;

#[derive(Debug, Clone)]
pub struct ReportOptions {
    pub run: PathBuf,
}

/// Write the report of the run directory `options.run`.
pub fn report(
    options: &ReportOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<RunSummary, ReportError> {
    let start = Instant::now();
    let results = RunResults::read(&options.run)?;
    results.dir().remove(files::SUMMARY)?;
    // Timings of the stages `postflight run` ran, else what each stage
    // recorded of itself.
    let mut timings = results.log.timings();
    timings.remove("report");
    if timings.is_empty() {
        if let Some(d) = &results.detect {
            timings.insert("detect".into(), d.seconds);
        }
        if let Some(l) = &results.localise {
            timings.insert("localise".into(), l.seconds);
        }
        if let Some(c) = &results.coverage {
            timings.insert("coverage".into(), c.seconds);
        }
        if let Some(r) = &results.replan {
            timings.insert("replan".into(), r.seconds);
        }
    }
    // Rerun writes as it goes: to a temporary name, renamed when complete.
    let partial = results.file(&format!(".{}.tmp", files::RECORDING));
    write_recording(&results, &partial, progress)?;
    std::fs::rename(&partial, results.file(files::RECORDING)).map_err(|cause| {
        postflight_core::Error::Write {
            path: results.file(files::RECORDING),
            cause,
        }
    })?;
    report::write_candidates(results.dir(), &results.candidate_rows())?;
    let mut summary = run_summary(&results, timings);
    let page = html::page(&results, &summary);
    results.dir().write_text(files::REPORT, &page)?;
    summary
        .timings_s
        .insert("report".into(), start.elapsed().as_secs_f64());
    results.dir().write_json(files::SUMMARY, &summary)?;
    Ok(summary)
}
