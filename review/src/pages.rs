//! The review queue's HTML: the queue and a candidate's page, rendered on
//! the server with maud's templates, which escape every value unless told
//! it is markup (only the position pictures, SVG that escapes its own
//! text). The pages work without scripts (links and a plain form);
//! `assets/review.js` adds the keyboard.

use std::collections::HashMap;
use std::fmt::Write;

use maud::{Markup, PreEscaped, html};
use page::{
    condition_text, evidence_text, gauge_text, length_text, place_text, readable_time, state_cell,
    state_text, width_cell, width_text,
};
use postflight_core::condition::ConditionState;
use postflight_core::outputs::localise::{DefectRecord, LengthStatus};
use postflight_core::outputs::record::{ElementRecord, RecordSummary};
use postflight_core::table::Named;

use crate::queue::{Entry, Filter, Progress, Queue};
use crate::since::Since;
use crate::store::{
    Decision, MAX_NOTE_CHARS, MAX_REVIEWER_CHARS, SEVERITY_SCALE, Verdict, severity_meaning,
};

/// What the page is about, for its title and heading.
pub struct Context<'a> {
    /// The flight's recordings' file names.
    pub flight: &'a str,
    pub filter: Filter,
    /// Each candidate's place on the structure, by id.
    pub places: &'a HashMap<String, String>,
    /// Each candidate's change since an earlier inspection, by id.
    pub since: &'a HashMap<String, Since>,
    /// The recordings that saw each candidate, by id; empty for a flight
    /// of one recording.
    pub seen_in: &'a HashMap<String, String>,
}

impl Context<'_> {
    /// Where a candidate is, or its position when the structure's
    /// elements are unknown (coverage has not run).
    fn place(&self, d: &DefectRecord) -> String {
        place_text(self.places.get(&d.id).map(String::as_str), d)
    }
}

/// A review page: the pages' own style and script, and the status line
/// the script flashes messages in.
fn document(title: &str, body: Markup) -> String {
    page::document(
        title,
        html! {
            link rel="stylesheet" href="/assets/review.css";
            script src="/assets/review.js" defer {}
        },
        html! {
            (body)
            div #flash role="status" aria-live="polite" {}
        },
    )
}

fn progress_line(p: &Progress) -> Markup {
    html! {
        p.progress {
            b #reviewed { (p.reviewed) " of " (p.total) " reviewed" }
            " \u{b7} " span #count-accepted { (p.accepted) } " accepted \u{b7} "
            span #count-needs_repair { (p.needs_repair) } " needing repair \u{b7} "
            span #count-rejected { (p.rejected) } " rejected "
            progress value=(p.reviewed) max=(p.total) {}
        }
    }
}

fn reviewer_field(value: &str) -> Markup {
    html! {
        label.who {
            "Reviewer "
            input #reviewer name="reviewer" form="decision" autocomplete="name"
                maxlength=(MAX_REVIEWER_CHARS) placeholder="your name" value=(value);
        }
    }
}

/// `/candidates/ID?filter=...`
pub fn candidate_href(id: &str, filter: Filter) -> String {
    format!("/candidates/{}?filter={}", percent_encode(id), filter.key())
}

fn queue_href(filter: Filter) -> String {
    format!("/?filter={}", filter.key())
}

/// A path segment with everything but unreserved characters escaped.
pub fn percent_encode(s: &str) -> String {
    let mut out = String::new();
    for b in s.bytes() {
        if b.is_ascii_alphanumeric() || b"-_.~".contains(&b) {
            out.push(b as char);
        } else {
            let _ = write!(out, "%{b:02X}");
        }
    }
    out
}

fn verdict(d: Option<&Decision>) -> Markup {
    html! {
        @match d {
            None => span.v.pending { "pending" },
            Some(d) => {
                span class=(format!("v {}", d.verdict.as_str())) {
                    @match (d.verdict, d.severity) {
                        (Verdict::NeedsRepair, Some(s)) => {
                            "needs repair, severity " (s)
                            @if let Some(word) = severity_meaning(s).and_then(|m| m.split(':').next()) {
                                " (" (word) ")"
                            }
                        },
                        (v, _) => (v.words()),
                    }
                }
                @if let Some(state) = d.condition {
                    ", state " (condition_text(Some(state)))
                }
                " "
                span.sub { "by " (d.reviewer) }
            }
        }
    }
}

/// The severity scale, stated where severities are given.
fn severity_scale() -> Markup {
    html! {
        details.scale #severity-scale open {
            summary { "Severity of a crack that needs repair: 1 minor \u{2026} 5 urgent" }
            ol {
                @for (s, meaning) in SEVERITY_SCALE {
                    li value=(s) { b { (s) } " " (meaning) }
                }
            }
        }
    }
}

/// How many boxes support a candidate, in how many frames (a frame may
/// hold two boxes of one crack), and of which recordings when the flight
/// has several.
fn support_text(ctx: &Context, d: &DefectRecord) -> String {
    let boxes = d.views.len();
    let seen_in = ctx.seen_in.get(&d.id);
    format!(
        "{boxes} box{} in {} frame{}{}",
        if boxes == 1 { "" } else { "es" },
        d.frames,
        if d.frames == 1 { "" } else { "s" },
        seen_in.map_or(String::new(), |names| format!(" of {names}"))
    )
}

/// The queue: candidates in review order, filtered, with progress.
pub fn queue_page(ctx: &Context, queue: &Queue) -> String {
    let p = queue.progress();
    let shown: Vec<&Entry> = queue.shown(ctx.filter).collect();
    let body = html! {
        header {
            h1 { "Review queue " span.sub { (ctx.flight) } }
            (progress_line(&p))
            (reviewer_field(""))
        }
        nav.filters {
            @for f in Filter::ALL {
                @if f == ctx.filter {
                    a href=(queue_href(f)) class="current" aria-current="page" {
                        (f.label()) " (" (p.count(f)) ")"
                    }
                } @else {
                    a href=(queue_href(f)) { (f.label()) " (" (p.count(f)) ")" }
                }
            }
        }
        nav.exports {
            a href="/record" { "Element record" } " \u{b7} "
            "Export: "
            a href="/export/decisions.csv" { "decisions (CSV)" } " "
            a href="/export/decisions.json" { "decisions with history (JSON)" } " "
            a href="/export/accepted-defects.csv" { "accepted defects (CSV)" }
        }
        @if shown.is_empty() && ctx.filter == Filter::All {
            p.empty { "No defect candidates in this run: the detector found no cracks that could be placed on the structure." }
        } @else if shown.is_empty() {
            p.empty { "No " (ctx.filter.label()) " candidates." }
        } @else {
            table #queue {
                thead {
                    tr {
                        th.n { "#" } th { "best view" } th { "where" } th.n { "range" }
                        th.n { "GSD" } th.n { "length" } th.n { "width" } th { "state" }
                        th { "evidence" } th.n { "conf." } th { "decision" } th { "decide" }
                    }
                }
                tbody { @for e in shown { (queue_row(ctx, e)) } }
            }
        }
        (severity_scale())
        p.keys {
            "Keys: " kbd { "j" } "/" kbd { "k" } " move, " kbd { "a" } " accept, " kbd { "r" } " reject, "
            kbd { "1" } "\u{2013}" kbd { "5" } " needs repair with that severity (the row's decision, then the next row), "
            kbd { "Enter" } " open, " kbd { "i" } " reviewer name, " kbd { "Esc" } " leave a field."
        }
    };
    document(&format!("Review queue: {}", ctx.flight), body)
}

fn queue_row(ctx: &Context, e: &Entry) -> Markup {
    let d = e.defect;
    let href = candidate_href(&d.id, ctx.filter);
    html! {
        tr.row data-href=(href) data-id=(d.id) data-version=(e.version())
            data-condition=(reviewed_condition(e).map_or("", ConditionState::name)) {
            td.n { (e.rank) }
            td { (crop_img(d, "thumb")) }
            td {
                a href=(href) { (ctx.place(d)) } br;
                span.sub { (d.id) " \u{b7} " (support_text(ctx, d)) }
                @if let Some(since) = ctx.since.get(&d.id) { br; (since_line(since)) }
            }
            td.n { (format!("{:.1} m", d.best.range_m)) }
            td.n { (format!("{:.1} mm", d.best.oblique_gsd_mm)) }
            td.n { (length_text(d)) }
            td.n { (width_cell(d)) }
            td { (condition_cell(e)) }
            td {
                @if d.evidence.reshoot {
                    span.flag title=(evidence_text(d).unwrap_or_default()) { "re-shoot" }
                } @else {
                    span.ok { "good" }
                }
            }
            td.n { (format!("{:.2}", d.confidence)) }
            td.decision { (verdict(e.decision.as_ref())) }
            td {
                form.quick method="post"
                    action=(format!("/candidates/{}/decide", percent_encode(&d.id))) {
                    input type="hidden" name="version" value=(e.version());
                    input type="hidden" name="filter" value=(ctx.filter.key());
                    input type="hidden" name="back" value="queue";
                    input type="hidden" name="reviewer" value="";
                    input type="hidden" name="condition"
                        value=(reviewed_condition(e).map_or("", ConditionState::name));
                    button name="verdict" value="accepted" title="accept (a)" { "\u{2713}" }
                    button name="verdict" value="rejected" title="reject (r)" { "\u{2717}" }
                }
            }
        }
    }
}

/// The condition state a reviewer set on the candidate, over the measured one.
fn reviewed_condition(e: &Entry) -> Option<ConditionState> {
    e.decision.as_ref().and_then(|d| d.condition)
}

/// The state that stands: the reviewer's (marked so), else the measured.
fn condition_cell(e: &Entry) -> Markup {
    html! {
        @match reviewed_condition(e) {
            Some(state) => {
                (condition_text(Some(state))) " "
                span.sub title=(format!("measured: {}", state_text(e.defect.condition))) { "(reviewer)" }
            },
            None => (state_cell(e.defect.condition)),
        }
    }
}

fn crop_img(d: &DefectRecord, class: &str) -> Markup {
    html! {
        @if d.crop.is_some() {
            img class=(class) loading="lazy" alt=(format!("best view of {}", d.id))
                src=(format!("/candidates/{}/crop", percent_encode(&d.id)));
        } @else {
            span.sub { "(no image)" }
        }
    }
}

/// What the candidate page shows besides the candidate itself.
pub struct CandidateView<'a> {
    /// Supporting view shown first (index into `defect.views`).
    pub view: usize,
    /// Its pictures of place on the structure: (title, SVG).
    pub position: Vec<(String, String)>,
    /// Every decision on it, oldest first.
    pub history: &'a [Decision],
    /// The decision just sent, if it was refused.
    pub refused: Option<Refused<'a>>,
}

/// A decision the form sent and the store refused: shown again with why,
/// keeping what the reviewer typed.
pub struct Refused<'a> {
    pub why: String,
    pub note: &'a str,
    pub reviewer: &'a str,
}

/// One candidate: its views, facts, place, decision form and history.
pub fn candidate_page(ctx: &Context, queue: &Queue, entry: &Entry, v: &CandidateView) -> String {
    let d = entry.defect;
    let p = queue.progress();
    let neighbour = |forward: bool| {
        queue
            .neighbour(&d.id, ctx.filter, forward)
            .map(|e| candidate_href(&e.defect.id, ctx.filter))
    };
    let (prev, next) = (neighbour(false), neighbour(true));
    let link = |href: &Option<String>, text: &str, rel: &str| {
        html! {
            @match href {
                Some(h) => a href=(h) rel=(rel) { (text) },
                None => span.sub { (text) },
            }
        }
    };
    let body = html! {
        header {
            p.crumbs {
                a href=(queue_href(ctx.filter)) #to-queue { "\u{2190} queue (" (ctx.filter.label()) ")" }
                " \u{b7} " (link(&prev, "\u{2190} previous (k)", "prev"))
                " \u{b7} " (link(&next, "next (j) \u{2192}", "next"))
            }
            h1 {
                "Candidate " (entry.rank) " of " (p.total) ": " span #place { (ctx.place(d)) } " "
                span.sub #candidate-id { (d.id) }
            }
            (progress_line(&p))
            (reviewer_field(v.refused.as_ref().map_or("", |r| r.reviewer)))
        }
        main.candidate data-id=(d.id) data-prev=(prev.as_deref().unwrap_or(""))
            data-next=(next.as_deref().unwrap_or("")) data-queue=(queue_href(ctx.filter)) {
            (views_section(d, v.view, ctx.filter))
            aside {
                figure.best {
                    (crop_img(d, "crop"))
                    figcaption { "best view (meeting the View model if one does, then the finest), frame " (d.best.frame) }
                }
                (facts(ctx, d))
                @if !v.position.is_empty() {
                    div.position {
                        @for (title, svg) in &v.position {
                            figure { figcaption { (title) } (PreEscaped(svg)) }
                        }
                    }
                    p.sub { "The spot: solid where it is in front, hollow where nearer parts hide it." }
                }
                (decision_form(ctx, entry, v))
                (history(v.history))
            }
        }
        p.keys #help {
            "Keys: " kbd { "a" } " accept, " kbd { "r" } " reject, " kbd { "1" } "\u{2013}" kbd { "5" }
            " needs repair with that severity, " kbd { "n" } " write a note, " kbd { "j" } "/" kbd { "k" }
            " next/previous candidate, " kbd { "]" } "/" kbd { "[" } " next/previous view, "
            kbd { "z" } " zoom the frame, " kbd { "b" } " hide or show the box, "
            kbd { "q" } " queue, " kbd { "i" } " reviewer name, " kbd { "Esc" } " leave a field."
        }
    };
    document(&format!("Candidate {}: {}", entry.rank, d.id), body)
}

fn views_section(d: &DefectRecord, shown: usize, filter: Filter) -> Markup {
    let n = d.views.len();
    let shown = shown.min(n.saturating_sub(1));
    let id = percent_encode(&d.id);
    let caption = |k: usize| {
        let v = &d.views[k];
        format!(
            "view {} of {n}: frame {}, score {:.2}, {:.1} m away, {:.0}\u{b0} incidence, {:.1} mm/px{}",
            k + 1,
            v.frame,
            v.score,
            v.range_m,
            v.incidence_deg,
            v.oblique_gsd_mm,
            if v.clipped {
                ", cut by the image border"
            } else {
                ""
            },
        )
    };
    let step = |k: usize| format!("?filter={}&view={k}", filter.key());
    html! {
        section.views {
            @if n == 0 {
                p { "No supporting views." }
            } @else {
                figure {
                    div.frame #frame {
                        img #view alt="supporting view with the detection box"
                            src=(format!("/candidates/{id}/views/{shown}"));
                    }
                    figcaption #view-caption { (caption(shown)) }
                }
                p.stepper {
                    a #view-prev href=(step(shown.saturating_sub(1))) { "\u{2190} view ([)" } " "
                    a #view-next href=(step((shown + 1).min(n - 1))) { "view (]) \u{2192}" } " \u{b7} "
                    button #zoom type="button" { "zoom (z)" } " "
                    button #box-toggle type="button" { "hide box (b)" }
                }
                ol #view-list hidden {
                    @for k in 0..n {
                        li data-src=(format!("/candidates/{id}/views/{k}")) data-caption=(caption(k)) {}
                    }
                }
            }
        }
    }
}

/// A candidate's change since the earlier inspection; new, first seen,
/// grown and widened ones stand out.
fn since_line(since: &Since) -> Markup {
    html! {
        @if since.change.change.stands_out() {
            span.flag.since { (since.text()) }
        } @else {
            span.sub.since { (since.text()) }
        }
    }
}

fn facts(ctx: &Context, d: &DefectRecord) -> Markup {
    let p = d.position;
    let scores: Vec<String> = d.views.iter().map(|v| format!("{:.2}", v.score)).collect();
    html! {
        table.facts {
            tr { th { "where" } td { (ctx.place(d)) } }
            @if let Some(since) = ctx.since.get(&d.id) {
                tr {
                    th { "since " (since.date) }
                    td {
                        (since_line(since))
                        @if let Some(before) = since.change.length_before_m {
                            br; span.sub { (format!("{before:.2} m long then")) }
                        }
                    }
                }
            }
            tr {
                th { "length" }
                td {
                    (length_text(d))
                    @if d.evidence.length == LengthStatus::Partial {
                        " " span.sub { "(every view cut by the image border)" }
                    }
                }
            }
            tr {
                th { "evidence" }
                td {
                    @match evidence_text(d) {
                        Some(weak) => b { (weak) },
                        None => "the best view meets the View model (range, incidence, GSD, blur)",
                    }
                }
            }
            tr { th { "width" } td { (width_text(d)) } }
            tr {
                th { "condition state" }
                td {
                    (state_text(d.condition))
                    @if d.condition.is_some() { " " span.sub { "(from its widest)" } }
                    @if let Some(why) = gauge_text(d.condition) { br; b.flag { (why) } }
                }
            }
            tr {
                th { "GSD (best view)" }
                td { (format!("{:.1} mm/px at {:.1} m", d.best.oblique_gsd_mm, d.best.range_m)) }
            }
            tr {
                th { "position" }
                td { (format!("({:.2}, {:.2}, {:.2}) m, face {}", p[0], p[1], p[2], d.face)) }
            }
            tr {
                th { "fused confidence" }
                td { (format!("{:.2} (best score {:.2})", d.confidence, d.max_score)) }
            }
            tr { th { "detector scores" } td { (scores.join(", ")) } }
            tr { th { "support" } td { (support_text(ctx, d)) } }
        }
    }
}

fn decision_form(ctx: &Context, entry: &Entry, v: &CandidateView) -> Markup {
    let current = entry.decision.as_ref();
    let severity = current.and_then(|d| d.severity);
    let condition = current.and_then(|d| d.condition);
    let sealed = current.is_some_and(|d| d.sealed);
    let measured = entry.defect.condition;
    // After a refusal the form keeps what was typed; otherwise it shows
    // the current decision's note.
    let note = match &v.refused {
        Some(r) => r.note,
        None => current.map_or("", |d| d.note.as_str()),
    };
    let button = |value: Verdict, text: &str| {
        let on = current.is_some_and(|d| d.verdict == value);
        html! {
            button name="verdict" value=(value.as_str()) class=[on.then_some("current")]
                aria-pressed=(on) { (text) }
        }
    };
    html! {
        section.decide {
            h2 { "Decision" }
            p #current { "Current: " (verdict(current)) }
            @if let Some(r) = &v.refused {
                p.error role="alert" { (r.why) }
            }
            form #decision method="post"
                action=(format!("/candidates/{}/decide", percent_encode(&entry.defect.id))) {
                input type="hidden" name="version" value=(entry.version());
                input type="hidden" name="filter" value=(ctx.filter.key());
                label {
                    "Severity (needs repair) "
                    select name="severity" #severity {
                        option value="" selected[severity.is_none()] { "\u{2013}" }
                        @for (s, meaning) in SEVERITY_SCALE {
                            option value=(s) selected[severity == Some(s)] { (s) " \u{2013} " (meaning) }
                        }
                    }
                }
                label {
                    "Condition state "
                    select name="condition" #condition {
                        option value="" selected[condition.is_none()] {
                            "as measured (" (state_text(measured)) ")"
                        }
                        @for state in ConditionState::ALL {
                            option value=(state.name()) selected[condition == Some(*state)] {
                                (condition_text(Some(*state)))
                            }
                        }
                    }
                }
                label {
                    input type="checkbox" name="sealed" value="on" checked[sealed];
                    " Sealed (the element record counts a sealed moderate crack in state 1)"
                }
                label {
                    "Note "
                    textarea name="note" rows="2" maxlength=(MAX_NOTE_CHARS) { (note) }
                }
                p.buttons {
                    (button(Verdict::Accepted, "Accept (a)")) " "
                    (button(Verdict::NeedsRepair, "Needs repair (1\u{2013}5)")) " "
                    (button(Verdict::Rejected, "Reject (r)"))
                }
            }
            (severity_scale())
        }
    }
}

fn history(history: &[Decision]) -> Markup {
    html! {
        section.history {
            h2 { "History" }
            @if history.is_empty() {
                p.sub { "No decisions yet." }
            } @else {
                table #history {
                    tr { th { "v" } th { "decision" } th { "note" } th { "when" } th { "replaced" } }
                    @for (i, d) in history.iter().enumerate().rev() {
                        tr {
                            td { (d.version) }
                            td { (verdict(Some(d))) }
                            td { (d.note) }
                            td { (readable_time(&d.decided_at)) }
                            td {
                                @match i.checked_sub(1).map(|j| &history[j]) {
                                    Some(old) => {
                                        "v" (old.version) " (" (old.verdict.as_str()) " by " (old.reviewer) ")"
                                    },
                                    None => "\u{2013}",
                                }
                            }
                        }
                    }
                }
            }
        }
    }
}

/// A page for errors met while browsing (unknown candidate, bad address).
pub fn error_page(message: &str) -> String {
    document(
        "Review queue: error",
        html! {
            p.error role="alert" { (message) }
            p { a href="/" { "Back to the queue" } }
        },
    )
}

/// The element record as the decisions so far make it: remade on every
/// request, so that it follows the queue; `None`, where the run has no
/// record yet.
pub fn record_page(ctx: &Context, record: Option<(&RecordSummary, &[ElementRecord])>) -> String {
    let link = |id: &str| Some(candidate_href(id, ctx.filter));
    let body = html! {
        style { (PreEscaped(page::record::RECORD_STYLE)) }
        header {
            h1 { "Element record " span.sub { (ctx.flight) } }
            p { a href="/" { "\u{2190} review queue" } }
        }
        @match record {
            Some((summary, rows)) => {
                p.sub {
                    "As the decisions so far make it: rejected candidates do not count, accepted and needs-repair ones do, in the state a reviewer set. "
                    "The files in the run directory are rebuilt by " code { "postflight record --run RUN" } "."
                }
                (page::record::record_section(summary, rows, false, &link))
            }
            None => p.empty {
                "This run has no element record yet: run " code { "postflight record --run RUN" } " (or " code { "postflight run" } " with a structure to inspect), then reload."
            },
        }
    };
    document(&format!("Element record: {}", ctx.flight), body)
}
