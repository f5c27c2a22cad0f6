//! The report's coverage section: target voxels inspected against
//! planned, the View model's rules they were judged by, coverage and
//! cracks by structural element, the structure seen from each side, and
//! why voxels were missed.

use maud::{Markup, PreEscaped, html};
use postflight_core::ViewModel;
use postflight_core::outputs::coverage::CoverageSummary;
use postflight_core::table::Named;

use page::condition_text;
use postflight_core::condition::ConditionState;

use crate::results::{ElementCracks, RunResults, VoxelStatus};
use crate::svg::bar_chart;
use crate::views::{Marker, Overlay, Side, colour, view, width_m};

pub(super) fn coverage_section(r: &RunResults) -> Markup {
    html! {
        h2 { "Coverage: achieved against planned" }
        @match &r.coverage {
            None => p {
                "Coverage was not computed for this run (it needs an inspection plan: "
                code { "--plan" } ")."
            },
            Some(c) => {
                (view_model(c))
                (coverage_table(c))
                (element_table(r))
                (legend())
                (coverage_views(r, c))
                (miss_reasons(c))
            }
        }
    }
}

fn legend() -> Markup {
    html! {
        p.legend {
            @for s in VoxelStatus::ALL {
                span { i style=(format!("background:{}", colour(s))) {} (s.label()) }
            }
            span { "\u{25CF} defect candidate (number = review order)" }
        }
    }
}

fn view_model(c: &CoverageSummary) -> Markup {
    html! {
        p {
            "Under the View model: " (view_rules(&c.view))
            (format!("; {:.2} m voxels, targets from ", c.figures.resolution_m))
            (c.targets) "."
        }
        @if !c.focus.is_empty() {
            p { "Focus regions, judged under a stricter View model:" }
            ul {
                @for f in &c.focus {
                    li {
                        b { (f.model.region.name) } ": " (view_rules(&f.model.view))
                        (format!(
                            "; {} of its {} target voxels inspected.",
                            f.inspected_voxels, f.target_voxels
                        ))
                    }
                }
            }
        }
    }
}

/// A View model's rules in a line.
fn view_rules(v: &ViewModel) -> String {
    format!(
        "cone apex {:.0}\u{b0}, distance {:.1}\u{2013}{:.1} m, incidence up to {:.0}\u{b0}, blur up to {:.1} px, GSD up to {:.1} mm/px, {} view(s) per face",
        v.cone_apex_deg,
        v.min_distance_m,
        v.max_distance_m,
        v.max_incidence_deg,
        v.max_blur_px,
        v.max_gsd_mm,
        v.views_required,
    )
}

fn coverage_table(c: &CoverageSummary) -> Markup {
    let pct = |n: usize, of: usize| {
        if of == 0 {
            "\u{2013}".to_string()
        } else {
            format!("{:.1}%", 100.0 * n as f64 / of as f64)
        }
    };
    let t = c.figures.target_voxels;
    // Each column one denominator: the targets, then the planned voxels.
    let row = |what: &str, n: usize, of_planned: Option<usize>| {
        html! {
            tr {
                td { (what) } td.n { (n) } td.n { (pct(n, t)) }
                @if let Some(p) = c.figures.planned_voxels {
                    td.n { (of_planned.map_or("\u{2013}".into(), |n| pct(n, p))) }
                }
            }
        }
    };
    html! {
        table {
            tr {
                th { "voxels" } th.n { "count" } th.n { "of target" }
                @if c.figures.planned_voxels.is_some() { th.n { "of planned" } }
            }
            (row("target", t, None))
            @if let Some(p) = c.figures.planned_voxels { (row("planned", p, Some(p))) }
            (row("inspected", c.figures.inspected_voxels, None))
            @if let (Some(p), Some(missed)) = (c.figures.planned_voxels, c.figures.planned_missed_voxels) {
                (row("planned and inspected", p - missed, Some(p - missed)))
                (row("planned but missed", missed, Some(missed)))
            }
            (row("gaps (a follow-up flight can inspect them)", c.figures.gap_voxels, None))
            (row("uninspectable (no free viewpoint satisfies the View)", c.figures.uninspectable_voxels, None))
        }
        p.sub {
            (format!("{:.1}% of the exposed face area was inspected.", c.figures.face_area_coverage_pct))
        }
    }
}

/// Per element: surface area by coverage status (where the gaps are) and
/// crack length by condition state (what element-level records keep).
fn element_table(r: &RunResults) -> Markup {
    let m2 = |a: f64| format!("{a:.1}");
    let cracks = r.element_cracks();
    html! {
        @if !r.element_areas.is_empty() || !cracks.is_empty() {
            h3 { "By element" }
        }
        @if !r.element_areas.is_empty() {
            p.sub {
                "Exposed surface of the target voxels, m\u{b2}. Elements are found from the map's geometry: piers numbered from the west (south) end, girders from the south (east) side."
            }
            table #element-areas {
                tr {
                    th { "element" } th.n { "surface" } th.n { "inspected" }
                    th.n { "planned, missed" } th.n { "not planned" } th.n { "uninspectable" }
                }
                @for a in &r.element_areas {
                    tr {
                        td { (a.element) }
                        td.n { (m2(a.target_m2)) }
                        td.n {
                            (m2(a.inspected_m2))
                            span.sub { (format!(" ({:.0}%)", 100.0 * a.inspected_m2 / a.target_m2.max(1e-9))) }
                        }
                        td.n { (m2(a.planned_missed_m2)) }
                        td.n { (m2(a.not_planned_m2)) }
                        td.n { (m2(a.uninspectable_m2)) }
                    }
                }
            }
        }
        @if !cracks.is_empty() {
            (crack_states_table(&cracks))
        }
    }
}

/// Crack length per element in each condition state.
fn crack_states_table(cracks: &[ElementCracks]) -> Markup {
    let m = |l: f64| {
        if l > 0.0 {
            format!("{l:.2}")
        } else {
            "\u{2013}".into()
        }
    };
    html! {
        p.sub {
            "Crack length, m, in each condition state its widest point puts it in (AASHTO MBEI cracking defect; docs/condition.md), before review: the review queue's exports carry each inspector's corrections."
        }
        table #crack-states {
            tr {
                th { "element" } th.n { "cracks" }
                @for state in ConditionState::ALL {
                    th.n { (condition_text(Some(*state))) }
                }
                th.n { "no state" } th.n { "length unknown" }
            }
            @for e in cracks {
                tr {
                    td { (e.element.as_deref().unwrap_or("on no element")) }
                    td.n { (e.cracks) }
                    @for l in e.state_m { td.n { (m(l)) } }
                    td.n { (m(e.no_state_m)) }
                    td.n { @if e.unmeasured > 0 { (e.unmeasured) } @else { "\u{2013}" } }
                }
            }
        }
    }
}

fn coverage_views(r: &RunResults, c: &CoverageSummary) -> Markup {
    let markers: Vec<Marker> = r
        .defects_for_review()
        .iter()
        .enumerate()
        .map(|(i, d)| Marker {
            label: (i + 1).to_string(),
            position: d.position,
            normal: d.normal,
            trace: &d.trace,
            condition: d.state(),
        })
        .collect();
    let overlay = Overlay {
        markers,
        ..Overlay::default()
    };
    // Every side at one scale: the widest 500 px.
    let widths = Side::ALL.map(|side| width_m(&r.voxels, c.figures.resolution_m, side));
    let widest = widths.iter().copied().fold(1e-9, f64::max);
    html! {
        div.views {
            @for (side, w) in Side::ALL.into_iter().zip(widths) {
                figure {
                    (PreEscaped(view(&r.voxels, c.figures.resolution_m, side, &overlay, (500.0 * w / widest).max(160.0))))
                    figcaption { "Target voxels " (side.title()) }
                }
            }
        }
        p.sub { "Candidates are marked in the views that face their surface: solid where the spot is in front, hollow where nearer parts hide it; the line over it is the crack's trace, coloured by its condition state (green 1, amber 2, red 3, purple 4, grey none)." }
    }
}

fn miss_reasons(c: &CoverageSummary) -> Markup {
    let mut bars: Vec<(String, f64)> = c
        .reasons
        .iter()
        .map(|(k, n)| (k.name().replace('_', " "), *n as f64))
        .collect();
    bars.sort_by(|a, b| b.1.total_cmp(&a.1));
    html! {
        @if !bars.is_empty() {
            h3 { "Why voxels were not inspected" }
            p.sub { "Each not-inspected voxel counted once, by the furthest View rule any frame reached." }
            (PreEscaped(bar_chart(&bars, "#d7301f", "Reasons voxels were not inspected")))
        }
    }
}
