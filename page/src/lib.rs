//! What every page postflight writes shares (the report, the review queue,
//! the fleet's index): the styles, the document shell, and how times,
//! lengths, widths, condition states, places and a candidate's evidence
//! are worded for people.

pub mod record;

use maud::{DOCTYPE, Markup, html};
use postflight_core::condition::{ConditionState, StateCall};
use postflight_core::outputs::localise::{
    ContrastSource, DefectRecord, LengthStatus, WidthFit, WidthMethod, WidthRecord,
};
use postflight_core::table::Named;

/// The pages' styles.
pub const STYLE: &str = r#"
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;color:#1f2937;margin:0 auto;max-width:1060px;padding:24px}
h1{font-size:24px;margin:0 0 4px}h2{font-size:19px;margin:32px 0 10px;border-bottom:2px solid #e5e7eb;padding-bottom:4px}
.sub{color:#6b7280}.flag{color:#b45309;font-weight:600}.warn{background:#fef3c7;border-left:4px solid #f59e0b;padding:8px 12px;margin:10px 0}
.cards{display:flex;flex-wrap:wrap;gap:10px;margin:16px 0}.card{border:1px solid #e5e7eb;border-radius:6px;padding:8px 14px;min-width:120px}
.card b{display:block;font-size:22px}.card span{color:#6b7280;font-size:12px}
table{border-collapse:collapse;width:100%;margin:8px 0}th,td{text-align:left;padding:4px 8px;border-bottom:1px solid #e5e7eb;vertical-align:top}
th{background:#f9fafb;font-weight:600}td.n,th.n{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}
.views{display:grid;grid-template-columns:1fr 1fr;gap:12px}.views figure{margin:0}figcaption{color:#6b7280;font-size:12px}
svg{max-width:100%;height:auto}.legend span{display:inline-block;margin-right:14px}.legend i{display:inline-block;width:12px;height:12px;margin-right:4px;vertical-align:-1px}
img.thumb{width:160px;border:1px solid #d1d5db}.frames{font-size:12px;color:#4b5563}
@media print{body{max-width:none;padding:0}h2{break-after:avoid}tr,figure,.card{break-inside:avoid}.views{grid-template-columns:1fr 1fr}}
"#;

/// An HTML page: its title, what the head adds (styles, scripts) and its body.
pub fn document(title: &str, head: Markup, body: Markup) -> String {
    let page = html! {
        (DOCTYPE)
        html lang="en" {
            head {
                meta charset="utf-8";
                meta name="viewport" content="width=device-width,initial-scale=1";
                title { (title) }
                (head)
            }
            body { (body) }
        }
    };
    page.into_string() + "\n"
}

/// An RFC 3339 time (`2025-06-15T12:00:00.000000000Z`) as people read it
/// in UTC (`2025-06-15 12:00:00 UTC`); text that is not one, as it is.
pub fn readable_time(rfc3339: &str) -> String {
    match rfc3339.parse::<jiff::Timestamp>() {
        Ok(t) => t.strftime("%Y-%m-%d %H:%M:%S UTC").to_string(),
        Err(_) => rfc3339.to_string(),
    }
}

/// A candidate's estimated length: "≥" marks a lower bound (its views were
/// cut by the image border), a dash an unknown length ([`evidence_text`]
/// says why).
pub fn length_text(d: &DefectRecord) -> String {
    match (d.length_m, d.evidence.length) {
        (Some(l), LengthStatus::Partial) => format!("\u{2265} {l:.2} m"),
        (Some(l), _) => format!("{l:.2} m"),
        (None, _) => "\u{2013}".into(),
    }
}

/// A candidate's width, for people: its widest (and where along the crack
/// that stretch is) and median with their uncertainty, how they were read,
/// the bound it is below, or why it is unknown.
pub fn width_text(d: &DefectRecord) -> String {
    let Some(w) = d.width else {
        return "not measured: no view traced the crack's line".into();
    };
    let scale = format!("at {:.2} mm/px across it", w.mm_per_px);
    match (w.max_mm, w.median_mm, w.narrower_than_mm) {
        (Some(max), median, _) => {
            let median = median.map_or(String::new(), |m| format!(", median {m:.2} mm"));
            let spread = w
                .uncertainty_mm
                .map_or(String::new(), |u| format!(" \u{b1} {u:.2} mm"));
            let widest = match w.widest {
                Some(s) => match s.along_m {
                    Some(along) => format!("at its widest, {along:.2} m along its trace"),
                    None => "at its widest".into(),
                },
                None => "along its length".into(),
            };
            let how = method_text(&w);
            let fit = fit_text(w.fit);
            format!("{max:.2} mm {widest}{spread}{median} ({how}{fit}; {scale})")
        }
        (None, _, Some(below)) => {
            format!("below resolution: narrower than {below:.2} mm ({scale})")
        }
        (None, _, None) => format!("not measured ({scale})"),
    }
}

/// Where a crack's crossings do not fit the model its width is read by,
/// for people (after the method, or nothing).
fn fit_text(fit: Option<WidthFit>) -> &'static str {
    match fit {
        Some(WidthFit::SlopingWalls) => {
            "; its walls spread wider than the camera's blur (sloping walls, a shoulder or a blurrier photo): its opening may be wider, as the uncertainty says"
        }
        Some(WidthFit::WallsAndDarknessDisagree) => {
            "; its walls and its darkness read different widths (a lighter inside, a stain beside it): the uncertainty covers both"
        }
        Some(WidthFit::Slot) | None => "",
    }
}

/// How a width was read, for people.
fn method_text(w: &WidthRecord) -> String {
    let interior = match w.contrast_from {
        Some(ContrastSource::Crack) => "its own wider stretches show",
        Some(ContrastSource::Photo) => "this photo's wider cracks show",
        Some(ContrastSource::Flight) => "the flight's wider cracks show",
        Some(ContrastSource::Setting) | None => {
            "the crack_darkness setting says (no crack of the flight is wide enough to show it)"
        }
    };
    let darkness =
        format!("from the light it takes away, a crack's interior as dark as {interior}");
    match w.method {
        Some(WidthMethod::Walls) | None => "across its walls".into(),
        Some(WidthMethod::Darkness) => darkness,
        Some(WidthMethod::WallsAndDarkness) => format!("across its walls and {darkness}"),
    }
}

/// A candidate's width in a table cell: its widest, `< bound` below
/// resolution, a dash when unknown.
pub fn width_cell(d: &DefectRecord) -> String {
    match d.width.map(|w| (w.max_mm, w.narrower_than_mm)) {
        Some((Some(max), _)) => format!("{max:.2} mm"),
        Some((None, Some(below))) => format!("< {below:.2} mm"),
        _ => "\u{2013}".into(),
    }
}

/// A measured condition state as inspectors write it, and where its
/// width's interval straddles a limit, the state across it and how likely
/// each is: `2 fair (62%) or 1 good (38%)`; a dash for none.
pub fn state_text(call: Option<StateCall>) -> String {
    match call {
        None => "\u{2013}".into(),
        Some(c) => match (c.other, c.other_probability) {
            (Some(other), Some(p)) => format!(
                "{} ({:.0}%) or {} ({:.0}%)",
                condition_text(Some(c.state)),
                100.0 * c.probability,
                condition_text(Some(other)),
                100.0 * p,
            ),
            _ => condition_text(Some(c.state)),
        },
    }
}

/// A table cell's condition state: [`state_text`], flagged "gauge on
/// site" (its reason on hover) where the state is unsure.
pub fn state_cell(call: Option<StateCall>) -> Markup {
    html! {
        (state_text(call))
        @if let Some(why) = gauge_text(call) { br; span.flag title=(why) { "gauge on site" } }
    }
}

/// Why an inspector should gauge a candidate on site, where its state is
/// unsure; `None` where it is sure.
pub fn gauge_text(call: Option<StateCall>) -> Option<String> {
    let c = call?;
    let other = c.other?;
    Some(format!(
        "gauge on site: its width is within its uncertainty of the limit between {} and {}",
        condition_text(Some(c.state.min(other))),
        condition_text(Some(c.state.max(other)))
    ))
}

/// A condition state as inspectors write it: `2 fair`; a dash for none.
pub fn condition_text(state: Option<ConditionState>) -> String {
    state.map_or("\u{2013}".into(), |s| {
        format!("{} {}", s.number(), s.name())
    })
}

/// Where a candidate is, for people: its place on the structure, else
/// (before coverage has found the elements, or off them) its position.
pub fn place_text(place: Option<&str>, d: &DefectRecord) -> String {
    match place {
        Some(p) => p.to_string(),
        None => {
            let p = d.position;
            format!("at ({:.1}, {:.1}, {:.1}) m", p[0], p[1], p[2])
        }
    }
}

/// Why a candidate must be shot again, for people: the View model's rules
/// its best view breaks and why its length is missing; `None` when its
/// evidence is sound.
pub fn evidence_text(d: &DefectRecord) -> Option<String> {
    let e = &d.evidence;
    let mut weak = Vec::new();
    if !e.view_faults.is_empty() {
        let faults: Vec<String> = e
            .view_faults
            .iter()
            .map(|f| f.as_str().replace('_', " "))
            .collect();
        weak.push(format!("best view {}", faults.join(", ")));
    }
    if let Some(why) = e.length.missing_reason() {
        weak.push(format!("no length: {why}"));
    }
    e.reshoot.then(|| format!("re-shoot: {}", weak.join("; ")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_state_near_a_limit_names_both_states_and_asks_for_a_gauge() {
        use postflight_core::condition::Material;
        let limits = Material::ReinforcedConcrete.limits();
        let near = limits.call(0.28, 0.05);
        assert_eq!(state_text(Some(near)), "1 good (69%) or 2 fair (31%)");
        assert!(
            gauge_text(Some(near))
                .unwrap()
                .contains("between 1 good and 2 fair")
        );
        let sure = limits.call(0.8, 0.05);
        assert_eq!(state_text(Some(sure)), "2 fair");
        assert_eq!(gauge_text(Some(sure)), None);
        assert_eq!(state_text(None), "\u{2013}");
    }

    #[test]
    fn times_read_in_utc_and_other_text_stays() {
        assert_eq!(
            readable_time("2025-06-15T12:00:00.000000000Z"),
            "2025-06-15 12:00:00 UTC"
        );
        assert_eq!(
            readable_time("2025-06-15T14:00:00+02:00"),
            "2025-06-15 12:00:00 UTC"
        );
        assert_eq!(readable_time("yesterday"), "yesterday");
    }
}
