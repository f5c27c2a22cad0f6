//! The report's follow-up flight: what it flies, its sorties or team
//! routes and the gaps it covers by element; and the lines the binary
//! prints about it.

use std::collections::BTreeMap;

use maud::{Markup, PreEscaped, html};
use postflight_core::outputs::replan::{
    GapChoice, ReplanSummary, Unplannable, files as replan_files,
};

use crate::results::RunResults;
use crate::views::{HEIGHT_COLOURS, Overlay, Side, view};

pub(super) fn replan_section(r: &RunResults) -> Markup {
    html! {
        h2 { "Follow-up flight for the gaps" }
        @match &r.replan {
            None => p { "No follow-up flight was planned for this run." },
            Some(p) if nothing_to_fly(p).is_some() => p {
                (nothing_to_fly(p).unwrap_or_default())
            },
            Some(p) => (follow_up(r, p)),
        }
    }
}

/// Why the follow-up flight has nothing to fly, if it has not (the
/// report's and the command line's words).
pub fn nothing_to_fly(p: &ReplanSummary) -> Option<String> {
    if p.gap_voxels > 0 {
        return None;
    }
    Some(if p.coverage_gap_voxels == 0 {
        "no gaps: coverage found nothing to replan and no candidate needs a re-shoot".into()
    } else {
        format!(
            "nothing to fly: none of the {} gaps is of the kind chosen ({}) and no candidate needs a re-shoot; --gaps all flies every gap",
            p.coverage_gap_voxels,
            p.gaps.as_str()
        )
    })
}

/// What the follow-up flight goes back for and what it is, in a sentence
/// (the report's and the command line's words).
pub fn follow_up_text(p: &ReplanSummary) -> String {
    let n = p.coverage_gap_voxels;
    let chosen = match p.gaps {
        GapChoice::Missed => format!("the planned voxels the flight missed, of {n} gaps"),
        GapChoice::All => format!("all {n} gaps"),
        GapChoice::Reshoot => format!("none of the {n} gaps"),
    };
    let plural = |n: usize, word: &str| format!("{n} {word}{}", if n == 1 { "" } else { "s" });
    let team = match p.drones.len() {
        0 | 1 => String::new(),
        n => format!(
            ", shared by {n} drones: the mission takes about {:.1} min (first take-off to last landing), the sorties {:.1} min in all",
            p.mission_time_s / 60.0,
            p.time_s / 60.0
        ),
    };
    format!(
        "{} of {} chosen voxels planned ({chosen}, plus {} to re-shoot): {} (a greedy set cover needs {}) in {} within a {:.0}-minute battery{team}: {:.0} m, about {:.1} min ({:.1} min hovering, {:.0} s a waypoint; {:.1} min flying at {:.1} m/s); at least {:.1} m from every occupied voxel.",
        p.planned_gap_voxels,
        p.gap_voxels,
        plural(p.reshoot_spots.len(), "candidate"),
        plural(p.waypoints, "waypoint"),
        p.set_cover_viewpoints,
        plural(p.sorties.len(), "sortie"),
        p.battery_minutes,
        p.length_m,
        p.time_s / 60.0,
        p.hover_time_s / 60.0,
        p.hover_s,
        p.travel_time_s / 60.0,
        p.speed_m_s,
        p.clearance_m,
    )
}

/// The airspace the follow-up keeps to, in a sentence.
fn airspace_text(p: &ReplanSummary) -> String {
    let zones: Vec<String> = p
        .keep_out
        .iter()
        .map(|z| {
            let band = match (z.bottom_m, z.top_m) {
                (None, None) => "from the ground up".to_string(),
                (Some(b), None) => format!("above {b:.1} m"),
                (None, Some(t)) => format!("below {t:.1} m"),
                (Some(b), Some(t)) => format!("{b:.1}\u{2013}{t:.1} m"),
            };
            format!("{} ({band})", z.name)
        })
        .collect();
    let mut text = String::new();
    if !zones.is_empty() {
        text += &format!(
            "No waypoint and no point of the path is in the keep-out zones: {}",
            zones.join(", ")
        );
        if p.keep_out.iter().any(|z| z.is_column()) && !p.ground_station_files.is_empty() {
            text += "; the missions' geofence holds those from the ground up";
        }
        text += ". ";
    }
    if let Some(c) = p.ceiling_z_m {
        text += &format!("Every point is below the ceiling at {c:.1} m (map z).");
    }
    text.trim_end().to_string()
}

fn follow_up(r: &RunResults, p: &ReplanSummary) -> Markup {
    let count = |reason| {
        p.uninspectable_gaps
            .iter()
            .filter(|u| u.reason == reason)
            .count()
    };
    let team = p.drones.len() > 1;
    let overlay = Overlay {
        paths: p.sorties.iter().map(|s| s.path.as_slice()).collect(),
        points: p
            .sorties
            .iter()
            .flat_map(|s| s.waypoints.iter().map(|w| [w.x, w.y, w.z]))
            .collect(),
        home: Some(p.home),
        grey: true,
        ..Overlay::default()
    };
    html! {
        p {
            (follow_up_text(p)) " "
            "Flyable files: " code { "replan.json" } " (waypoints with yaw and gimbal pitch), "
            code { "replan.csv" } " (X,Y,Z,Yaw with gimbal pitch, sortie and kind of point)"
            @if let (Some(o), false) = (&p.geo_origin, p.ground_station_files.is_empty()) {
                ", and for ground stations "
                @for (i, file) in p.ground_station_files.iter().enumerate() {
                    @if i > 0 { ", " }
                    code { (file) }
                }
                (format!(
                    " (the map's origin at {:.6}, {:.6}, {:.1} m, its x axis {:.1}° from east; from {}).",
                    o.position.latitude_deg,
                    o.position.longitude_deg,
                    o.position.altitude_m,
                    o.yaw_deg,
                    p.geo_origin_from.as_deref().unwrap_or("settings"),
                ))
            } @else {
                ". Given where the map is on the Earth ("
                code { "postflight replan --geo-origin LAT,LON,ALT[,YAW_DEG]" }
                ", or GPS fixes or geotagged photos in the flight), replan also writes QGroundControl and DJI missions, KML and GeoJSON."
            }
        }
        @if !p.keep_out.is_empty() || p.ceiling_z_m.is_some() {
            p { (airspace_text(p)) }
        }
        @if !p.uninspectable_gaps.is_empty() {
            p.warn {
                (format!(
                    "{} gap voxels cannot be planned: {} with no viewpoint that keeps the clearance{}, {} with fewer such viewpoints than the views they need, {} unreachable from home.",
                    p.uninspectable_gaps.len(),
                    count(Unplannable::NoClearViewpoint),
                    if p.keep_out.is_empty() && p.ceiling_z_m.is_none() { "" } else { " and the airspace" },
                    count(Unplannable::TooFewViewpoints),
                    count(Unplannable::Unreachable)
                ))
            }
        }
        div.views {
            @for side in [Side::Top, Side::South] {
                figure {
                    (PreEscaped(view(&r.voxels, p.resolution, side, &overlay, 500.0)))
                    figcaption {
                        "Follow-up flight, " (side.title())
                        ": waypoints numbered in flight order (numbers that would overlap left out), coloured by height (ramp, "
                        (HEIGHT_COLOURS.len()) " steps, low to high)"
                    }
                }
            }
        }
        (gaps_by_element(r, p))
        (team_plan(p))
        table {
            tr {
                @if team { th { "drone" } }
                th { "sortie" } th.n { "waypoints" } th.n { "gap voxels" }
                th.n { "length" } th.n { "time" }
            }
            @for (i, s) in p.sorties.iter().enumerate() {
                tr {
                    @if team { td { (s.drone + 1) } }
                    // A team's sorties are numbered within their drone.
                    td { (p.sorties[..i].iter().filter(|o| o.drone == s.drone).count() + 1) }
                    td.n { (s.waypoints.len()) }
                    td.n { (s.waypoints.iter().map(|w| w.gap_voxels.len()).sum::<usize>()) }
                    td.n { (format!("{:.0} m", s.length_m)) }
                    td.n { (format!("{:.1} min", s.time_s / 60.0)) }
                }
            }
        }
    }
}

/// A team's plan, drone by drone: its share of the flight and its files.
/// Nothing for one drone.
fn team_plan(p: &ReplanSummary) -> Markup {
    if p.drones.len() < 2 {
        return html! {};
    }
    let files_of = |drone: usize| -> Vec<String> {
        let prefix = format!("replan-drone-{}", drone + 1);
        let own = p.ground_station_files.iter().filter(|f| {
            f.strip_prefix(&prefix)
                .is_some_and(|rest| rest.starts_with('.') || rest.starts_with('-'))
        });
        std::iter::once(replan_files::drone_path_csv(drone))
            .chain(own.cloned())
            .collect()
    };
    html! {
        h3 { "Team plan" }
        p {
            (p.drones.len()) " drones take off one after another, each flying its share of the gaps in its own battery sorties from its home. "
            (format!("The mission takes about {:.1} min from the first take-off to the last landing", p.mission_time_s / 60.0))
            @if let Some(m) = p.closest_drones_m {
                (format!("; the take-offs are spaced so that no two drones come closer than {m:.1} m (clearance {:.1} m)", p.clearance_m))
            }
            "."
        }
        table {
            tr {
                th { "drone" } th { "camera" } th { "home" } th.n { "speed" } th.n { "takes off" } th.n { "sorties" }
                th.n { "waypoints" } th.n { "length" } th.n { "time" } th { "files" }
            }
            @for d in &p.drones {
                tr {
                    td { (d.drone + 1) @if !d.name.is_empty() { " " (d.name) } }
                    td {
                        (format!("{} x {} px, f {:.0} px", d.image_size[0], d.image_size[1], d.focal_px))
                        @match &d.camera {
                            Some(file) => { ", " code { (file.file_name().map_or_else(|| file.display().to_string(), |n| n.to_string_lossy().into_owned())) } }
                            None => { ", the flight's" }
                        }
                    }
                    td { (format!("{:.1}, {:.1}, {:.1}", d.home[0], d.home[1], d.home[2])) }
                    td.n { (format!("{:.1} m/s", d.speed_m_s)) }
                    td.n { (format!("+{:.0} s", d.takeoff_s)) }
                    td.n { (d.sorties) }
                    td.n { (d.waypoints) }
                    td.n { (format!("{:.0} m", d.length_m)) }
                    td.n { (format!("{:.1} min", d.time_s / 60.0)) }
                    td {
                        @for (i, f) in files_of(d.drone as usize).iter().enumerate() {
                            @if i > 0 { ", " }
                            code { (f) }
                        }
                    }
                }
            }
        }
    }
}

/// Which elements the follow-up flight goes back to, and at which of its
/// waypoints (numbered in flight order, as in the pictures).
fn gaps_by_element(r: &RunResults, p: &ReplanSummary) -> Markup {
    let mut by_element: BTreeMap<&str, (usize, Vec<usize>)> = BTreeMap::new();
    let waypoints = p.sorties.iter().flat_map(|s| &s.waypoints);
    for (i, w) in waypoints.enumerate() {
        for v in &w.gap_voxels {
            let element = r
                .elements
                .as_ref()
                .and_then(|m| m.element_of(*v))
                .map_or("off the targets", |e| e.name.as_str());
            let entry = by_element.entry(element).or_default();
            entry.0 += 1;
            if entry.1.last() != Some(&(i + 1)) {
                entry.1.push(i + 1);
            }
        }
    }
    html! {
        @if !by_element.is_empty() {
            table {
                tr { th { "element" } th.n { "gap voxels" } th { "at waypoints" } }
                @for (element, (voxels, at)) in &by_element {
                    tr { td { (element) } td.n { (voxels) } td { (number_ranges(at)) } }
                }
            }
        }
    }
}

/// Increasing numbers as ranges: `1–4, 7, 9–10`.
fn number_ranges(numbers: &[usize]) -> String {
    use postflight_core::runs;
    runs::write(&runs::consecutive(numbers), "\u{2013}", ", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn waypoint_numbers_read_as_ranges() {
        assert_eq!(
            number_ranges(&[1, 2, 3, 4, 7, 9, 10]),
            "1\u{2013}4, 7, 9\u{2013}10"
        );
        assert_eq!(number_ranges(&[5]), "5");
        assert_eq!(number_ranges(&[]), "");
    }
}
