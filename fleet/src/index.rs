//! `fleet/index.html`: every flight of the fleet by structure and date,
//! how its run went and its main figures, each linking to its report.

use maud::{Markup, PreEscaped, html};
use page::{STYLE, document};
use postflight_core::outputs::report::files::REPORT;

use crate::tables::{FleetRun, RunState, files};

/// The page for `runs` (as [`crate::tables::runs`] lists them: by
/// structure, then date).
pub fn page(runs: &[FleetRun]) -> String {
    let structures = {
        let mut s: Vec<&str> = runs.iter().map(|r| r.structure.as_str()).collect();
        s.dedup();
        s.len()
    };
    let failed = runs
        .iter()
        .filter(|r| r.state() == RunState::Failed)
        .count();
    let body = html! {
        h1 { "Fleet" }
        p.sub {
            (structures) " structures, " (runs.len()) " flights"
            @if failed > 0 { ", " span.flag { (failed) " failed" } }
            ". Tables: "
            @for (i, t) in [files::FLIGHTS, files::COVERAGE, files::DEFECTS].iter().enumerate() {
                @if i > 0 { ", " }
                code { (t) }
            }
            " (Hive-partitioned by structure)."
        }
        (flights_table(runs))
    };
    document("Fleet", html! { style { (PreEscaped(STYLE)) } }, body)
}

const COLUMNS: usize = 10;

/// Every flight, a structure's name on its first; a failed flight's error
/// on a line of its own below it.
fn flights_table(runs: &[FleetRun]) -> Markup {
    html! {
        table {
            tr {
                th { "structure" } th { "date" } th { "run" } th { "state" } th.n { "frames" }
                th.n { "inspected" } th.n { "of planned" } th.n { "candidates" }
                th.n { "follow-up" } th { "report" }
            }
            @for (i, r) in runs.iter().enumerate() {
                @let first = i == 0 || runs[i - 1].structure != r.structure;
                (flight_row(r, first))
                @if let Some(e) = r.record.as_ref().and_then(|t| t.error.as_deref()) {
                    tr { td {} td.frames colspan=(COLUMNS - 1) { (e) } }
                }
            }
        }
    }
}

fn flight_row(r: &FleetRun, first_of_structure: bool) -> Markup {
    let s = r.summary.as_ref();
    let c = s.and_then(|s| s.coverage.as_ref());
    let blank = String::new;
    html! {
        tr style=[first_of_structure.then_some("border-top:2px solid #d1d5db")] {
            td { @if first_of_structure { b { (r.structure) } } }
            td { (r.date().unwrap_or("")) }
            td { (r.run.rsplit('/').next().unwrap_or("")) }
            td {
                @if r.state() == RunState::Failed { span.flag { (r.state().as_str()) } } @else { (r.state().as_str()) }
            }
            td.n { (s.map_or_else(blank, |s| s.frames.to_string())) }
            td.n { (c.map_or_else(blank, |c| format!("{:.1}%", c.inspected_pct))) }
            td.n { (c.and_then(|c| c.planned_inspected_pct).map_or_else(blank, |p| format!("{p:.1}%"))) }
            td.n { (s.and_then(|s| s.defects).map_or_else(blank, |d| d.to_string())) }
            td.n { (s.and_then(|s| s.replan.as_ref()).map_or_else(blank, |p| format!("{:.0} m", p.length_m))) }
            td {
                @if s.is_some() { a href={ "../" (r.run) "/" (REPORT) } { "report" } }
            }
        }
    }
}
