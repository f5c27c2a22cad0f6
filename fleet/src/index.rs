//! `fleet/index.html`: every flight of the fleet by structure and date,
//! how its run went and its main figures, each linking to its report.

use maud::{Markup, PreEscaped, html};
use postflight_core::outputs::report::files::REPORT;
use reports::html::{STYLE, document};

use crate::tables::{FleetRun, files};

/// The page for `runs` (as [`crate::tables::runs`] lists them).
pub fn page(runs: &[FleetRun]) -> String {
    let structures = {
        let mut s: Vec<&str> = runs.iter().map(|r| r.structure.as_str()).collect();
        s.dedup();
        s
    };
    let failed = runs.iter().filter(|r| r.state() == "failed").count();
    let body = html! {
        h1 { "Fleet" }
        p.sub {
            (structures.len()) " structures, " (runs.len()) " flights"
            @if failed > 0 { ", " span.flag { (failed) " failed" } }
            ". Tables: "
            @for (i, t) in [files::FLIGHTS, files::COVERAGE, files::DEFECTS].iter().enumerate() {
                @if i > 0 { ", " }
                code { (t) }
            }
            " (Hive-partitioned by structure)."
        }
        @for structure in &structures {
            h2 { (structure) }
            (structure_table(runs.iter().filter(|r| r.structure == *structure)))
        }
    };
    document("Fleet", html! { style { (PreEscaped(STYLE)) } }, body)
}

/// One structure's flights, oldest first.
fn structure_table<'a>(runs: impl Iterator<Item = &'a FleetRun>) -> Markup {
    html! {
        table {
            tr {
                th { "date" } th { "run" } th { "state" } th.n { "frames" }
                th.n { "inspected" } th.n { "planned inspected" } th.n { "candidates" }
                th.n { "follow-up" } th { "report" }
            }
            @for r in runs {
                @let s = r.summary.as_ref();
                @let c = s.and_then(|s| s.coverage.as_ref());
                tr {
                    td { (r.date().unwrap_or("")) }
                    td { (r.run.rsplit('/').next().unwrap_or("")) }
                    td {
                        @if r.state() == "failed" {
                            span.flag { "failed" }
                            @if let Some(e) = r.record.as_ref().and_then(|r| r.error.as_deref()) {
                                div.frames { (e) }
                            }
                        } @else { (r.state()) }
                    }
                    td.n { (s.map_or(String::new(), |s| s.frames.to_string())) }
                    td.n { (c.map_or(String::new(), |c| format!("{:.1}%", c.inspected_pct))) }
                    td.n { (c.and_then(|c| c.planned_inspected_pct).map_or(String::new(), |p| format!("{p:.1}%"))) }
                    td.n { (s.and_then(|s| s.defects).map_or(String::new(), |d| d.to_string())) }
                    td.n { (s.and_then(|s| s.replan.as_ref()).map_or(String::new(), |p| format!("{:.0} m", p.length_m))) }
                    td {
                        @if s.is_some() { a href={ "../" (r.run) "/" (REPORT) } { "report" } }
                    }
                }
            }
        }
    }
}
