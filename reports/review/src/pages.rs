//! The review queue's HTML: the queue and a candidate's page, rendered on
//! the server with every text escaped. The pages work without scripts
//! (links and a plain form); `assets/review.js` adds the keyboard.

use std::fmt::Write;

use postflight_core::outputs::localise::DefectRecord;

use crate::queue::{Entry, Filter, Progress, Queue};
use crate::store::{Decision, Verdict};
use reports::html::{length_html, readable_time};
use reports::svg::escape;

/// What the page is about, for its title and heading.
pub struct Context<'a> {
    /// The flight's file name.
    pub flight: &'a str,
    pub filter: Filter,
}

fn document(title: &str, body: &str) -> String {
    format!(
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><meta name=\"viewport\" content=\"width=device-width,initial-scale=1\"><title>{t}</title><link rel=\"stylesheet\" href=\"/assets/review.css\"><script src=\"/assets/review.js\" defer></script></head><body>{body}<div id=\"flash\" role=\"status\" aria-live=\"polite\"></div></body></html>\n",
        t = escape(title)
    )
}

fn progress_line(p: &Progress) -> String {
    format!(
        "<p class=\"progress\"><b id=\"reviewed\">{r} of {t} reviewed</b> &middot; {a} accepted &middot; {n} need repair &middot; {j} rejected <progress value=\"{r}\" max=\"{t}\"></progress></p>",
        r = p.reviewed,
        t = p.total,
        a = p.accepted,
        n = p.needs_repair,
        j = p.rejected,
    )
}

fn reviewer_field(value: &str) -> String {
    format!(
        "<label class=\"who\">Reviewer <input id=\"reviewer\" name=\"reviewer\" form=\"decision\" autocomplete=\"name\" maxlength=\"{max}\" placeholder=\"your name\" value=\"{v}\"></label>",
        max = crate::store::MAX_REVIEWER_CHARS,
        v = escape(value)
    )
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

fn verdict_html(d: Option<&Decision>) -> String {
    match d {
        None => "<span class=\"v pending\">pending</span>".into(),
        Some(d) => {
            let what = match (d.verdict, d.severity) {
                (Verdict::NeedsRepair, Some(s)) => format!("needs repair, severity {s}"),
                (v, _) => v.as_str().to_string(),
            };
            format!(
                "<span class=\"v {k}\">{what}</span> <span class=\"sub\">by {who}</span>",
                k = d.verdict.as_str(),
                who = escape(&d.reviewer)
            )
        }
    }
}

/// The queue: candidates in review order, filtered, with progress.
pub fn queue_page(ctx: &Context, queue: &Queue) -> String {
    let p = queue.progress();
    let mut h = String::new();
    let _ = write!(
        h,
        "<header><h1>Review queue <span class=\"sub\">{flight}</span></h1>{progress}{who}</header><nav class=\"filters\">",
        flight = escape(ctx.flight),
        progress = progress_line(&p),
        who = reviewer_field(""),
    );
    for f in Filter::ALL {
        let _ = write!(
            h,
            "<a href=\"{href}\"{cur}>{label} ({n})</a>",
            href = queue_href(f),
            cur = if f == ctx.filter {
                " class=\"current\" aria-current=\"page\""
            } else {
                ""
            },
            label = f.label(),
            n = p.count(f),
        );
    }
    h.push_str("</nav><nav class=\"exports\">Export: <a href=\"/export/decisions.csv\">decisions (CSV)</a> <a href=\"/export/decisions.json\">decisions with history (JSON)</a> <a href=\"/export/accepted-defects.csv\">accepted defects (CSV)</a></nav>");
    let shown: Vec<&Entry> = queue.shown(ctx.filter).collect();
    if shown.is_empty() && ctx.filter == Filter::All {
        h.push_str("<p class=\"empty\">No defect candidates in this run: the detector found no cracks that could be placed on the structure.</p>");
    } else if shown.is_empty() {
        let _ = write!(
            h,
            "<p class=\"empty\">No {} candidates.</p>",
            ctx.filter.label()
        );
    } else {
        h.push_str("<table id=\"queue\"><thead><tr><th class=\"n\">#</th><th>best view</th><th>candidate</th><th class=\"n\">length</th><th class=\"n\">confidence</th><th>decision</th></tr></thead><tbody>");
        for e in shown {
            let d = e.defect;
            let href = candidate_href(&d.id, ctx.filter);
            let _ = write!(
                h,
                "<tr class=\"row\" data-href=\"{href}\"><td class=\"n\">{rank}</td><td>{thumb}</td><td><a href=\"{href}\">{id}</a><br><span class=\"sub\">{frames} view{s}, face {face}</span></td><td class=\"n\">{len}</td><td class=\"n\">{conf:.2}</td><td>{verdict}</td></tr>",
                rank = e.rank,
                thumb = crop_img(d, "thumb"),
                id = escape(&d.id),
                frames = d.views.len(),
                s = if d.views.len() == 1 { "" } else { "s" },
                face = d.face,
                len = length_html(d),
                conf = d.confidence,
                verdict = verdict_html(e.decision.as_ref()),
            );
        }
        h.push_str("</tbody></table>");
    }
    h.push_str("<p class=\"keys\">Keys: <kbd>j</kbd>/<kbd>k</kbd> move, <kbd>Enter</kbd> open, <kbd>i</kbd> reviewer name, <kbd>Esc</kbd> leave a field.</p>");
    document(&format!("Review queue: {}", ctx.flight), &h)
}

fn crop_img(d: &DefectRecord, class: &str) -> String {
    if d.crop.is_some() {
        format!(
            "<img class=\"{class}\" loading=\"lazy\" alt=\"best view of {id}\" src=\"/candidates/{href}/crop\">",
            id = escape(&d.id),
            href = percent_encode(&d.id)
        )
    } else {
        "<span class=\"sub\">(no image)</span>".into()
    }
}

/// What the candidate page shows besides the candidate itself.
pub struct CandidateView<'a> {
    /// Supporting view shown first (index into `defect.views`).
    pub view: usize,
    /// Its pictures of place on the structure (SVG).
    pub position: Vec<String>,
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
    let id_href = percent_encode(&d.id);
    let prev = queue
        .neighbour(&d.id, ctx.filter, false)
        .map(|e| candidate_href(&e.defect.id, ctx.filter));
    let next = queue
        .neighbour(&d.id, ctx.filter, true)
        .map(|e| candidate_href(&e.defect.id, ctx.filter));
    let link = |href: &Option<String>, text: &str, rel: &str| match href {
        Some(h) => format!("<a href=\"{h}\" rel=\"{rel}\">{text}</a>"),
        None => format!("<span class=\"sub\">{text}</span>"),
    };
    let mut h = String::new();
    let _ = write!(
        h,
        "<header><p class=\"crumbs\"><a href=\"{queue}\" id=\"to-queue\">&larr; queue ({filter})</a> &middot; {prev} &middot; {next}</p><h1>Candidate {rank} of {total} <span class=\"sub\" id=\"candidate-id\">{id}</span></h1>{progress}{who}</header>",
        queue = queue_href(ctx.filter),
        filter = ctx.filter.label(),
        prev = link(&prev, "&larr; previous (k)", "prev"),
        next = link(&next, "next (j) &rarr;", "next"),
        rank = entry.rank,
        total = p.total,
        id = escape(&d.id),
        progress = progress_line(&p),
        who = reviewer_field(v.refused.as_ref().map_or("", |r| r.reviewer)),
    );
    let _ = write!(
        h,
        "<main class=\"candidate\" data-id=\"{id}\" data-prev=\"{prev}\" data-next=\"{next}\" data-queue=\"{queue}\">",
        id = escape(&d.id),
        prev = prev.as_deref().unwrap_or(""),
        next = next.as_deref().unwrap_or(""),
        queue = queue_href(ctx.filter),
    );
    views_section(&mut h, d, &id_href, v.view, ctx.filter);
    h.push_str("<aside>");
    let _ = write!(
        h,
        "<figure class=\"best\">{}<figcaption>best view (closest, most frontal), frame {}</figcaption></figure>",
        crop_img(d, "crop"),
        d.best.frame
    );
    facts(&mut h, d);
    if !v.position.is_empty() {
        h.push_str("<div class=\"position\">");
        for svg in &v.position {
            h.push_str(svg);
        }
        h.push_str("</div>");
    }
    decision_form(&mut h, ctx, entry, v);
    history(&mut h, v.history);
    h.push_str("</aside></main>");
    h.push_str("<p class=\"keys\" id=\"help\">Keys: <kbd>a</kbd> accept, <kbd>r</kbd> reject, <kbd>1</kbd>&ndash;<kbd>5</kbd> needs repair with that severity, <kbd>n</kbd> write a note, <kbd>j</kbd>/<kbd>k</kbd> next/previous candidate, <kbd>]</kbd>/<kbd>[</kbd> next/previous view, <kbd>q</kbd> queue, <kbd>i</kbd> reviewer name, <kbd>Esc</kbd> leave a field.</p>");
    document(&format!("Candidate {}: {}", entry.rank, d.id), &h)
}

fn views_section(h: &mut String, d: &DefectRecord, id_href: &str, shown: usize, filter: Filter) {
    let n = d.views.len();
    let shown = shown.min(n.saturating_sub(1));
    h.push_str("<section class=\"views\">");
    if n == 0 {
        h.push_str("<p>No supporting views.</p></section>");
        return;
    }
    let caption = |k: usize| {
        let v = &d.views[k];
        format!(
            "view {k1} of {n}: frame {f}, score {s:.2}, {r:.1} m away, {i:.0}&deg; incidence, {g:.1} mm/px{clip}",
            k1 = k + 1,
            f = v.frame,
            s = v.score,
            r = v.range_m,
            i = v.incidence_deg,
            g = v.oblique_gsd_mm,
            clip = if v.clipped {
                ", cut by the image border"
            } else {
                ""
            },
        )
    };
    let _ = write!(
        h,
        "<figure><img id=\"view\" alt=\"supporting view with the detection box\" src=\"/candidates/{id_href}/views/{shown}\"><figcaption id=\"view-caption\">{c}</figcaption></figure><p class=\"stepper\"><a id=\"view-prev\" href=\"?filter={f}&amp;view={p}\">&larr; view ([)</a> <a id=\"view-next\" href=\"?filter={f}&amp;view={nx}\">view (]) &rarr;</a></p><ol id=\"view-list\" hidden>",
        c = caption(shown),
        f = filter.key(),
        p = shown.saturating_sub(1),
        nx = (shown + 1).min(n - 1),
    );
    for k in 0..n {
        let _ = write!(
            h,
            "<li data-src=\"/candidates/{id_href}/views/{k}\" data-caption=\"{c}\"></li>",
            c = escape(&caption(k))
        );
    }
    h.push_str("</ol></section>");
}

fn facts(h: &mut String, d: &DefectRecord) {
    let p = d.position;
    let scores: Vec<String> = d.views.iter().map(|v| format!("{:.2}", v.score)).collect();
    let _ = write!(
        h,
        "<table class=\"facts\"><tr><th>length</th><td>{len}{partial}</td></tr><tr><th>GSD (best view)</th><td>{gsd:.1} mm/px at {range:.1} m</td></tr><tr><th>position</th><td>({x:.2}, {y:.2}, {z:.2}) m, face {face}</td></tr><tr><th>fused confidence</th><td>{conf:.2} (best score {max:.2})</td></tr><tr><th>detector scores</th><td>{scores}</td></tr><tr><th>supporting frames</th><td>{frames}</td></tr></table>",
        len = length_html(d),
        partial = if d.length_partial {
            " <span class=\"sub\">(every view cut by the image border)</span>"
        } else {
            ""
        },
        gsd = d.best.oblique_gsd_mm,
        range = d.best.range_m,
        x = p[0],
        y = p[1],
        z = p[2],
        face = d.face,
        conf = d.confidence,
        max = d.max_score,
        scores = scores.join(", "),
        frames = d.frames,
    );
}

fn decision_form(h: &mut String, ctx: &Context, entry: &Entry, v: &CandidateView) {
    h.push_str("<section class=\"decide\"><h2>Decision</h2>");
    let _ = write!(
        h,
        "<p>Current: {}</p>",
        verdict_html(entry.decision.as_ref())
    );
    if let Some(r) = &v.refused {
        let _ = write!(
            h,
            "<p class=\"error\" role=\"alert\">{}</p>",
            escape(&r.why)
        );
    }
    let _ = write!(
        h,
        "<form id=\"decision\" method=\"post\" action=\"/candidates/{id}/decide\"><input type=\"hidden\" name=\"version\" value=\"{version}\"><input type=\"hidden\" name=\"filter\" value=\"{filter}\"><label>Severity (needs repair) <select name=\"severity\"><option value=\"\">&ndash;</option>{options}</select></label><label>Note <textarea name=\"note\" rows=\"2\" maxlength=\"{max}\">{note}</textarea></label><p class=\"buttons\"><button name=\"verdict\" value=\"accepted\">Accept (a)</button> <button name=\"verdict\" value=\"needs_repair\">Needs repair (1&ndash;5)</button> <button name=\"verdict\" value=\"rejected\">Reject (r)</button></p></form></section>",
        id = percent_encode(&entry.defect.id),
        version = entry.version(),
        filter = ctx.filter.key(),
        options = (1..=5)
            .map(|s| format!("<option value=\"{s}\">{s}</option>"))
            .collect::<String>(),
        max = crate::store::MAX_NOTE_CHARS,
        note = escape(v.refused.as_ref().map_or("", |r| r.note)),
    );
}

fn history(h: &mut String, history: &[Decision]) {
    h.push_str("<section class=\"history\"><h2>History</h2>");
    if history.is_empty() {
        h.push_str("<p class=\"sub\">No decisions yet.</p></section>");
        return;
    }
    h.push_str("<table id=\"history\"><tr><th>v</th><th>decision</th><th>note</th><th>when</th><th>replaced</th></tr>");
    for (i, d) in history.iter().enumerate().rev() {
        let replaced = match i.checked_sub(1).map(|j| &history[j]) {
            Some(old) => format!(
                "v{} ({} by {})",
                old.version,
                old.verdict.as_str(),
                escape(&old.reviewer)
            ),
            None => "&ndash;".into(),
        };
        let _ = write!(
            h,
            "<tr><td>{v}</td><td>{what}</td><td>{note}</td><td>{when}</td><td>{replaced}</td></tr>",
            v = d.version,
            what = verdict_html(Some(d)),
            note = escape(&d.note),
            when = escape(&readable_time(&d.decided_at)),
        );
    }
    h.push_str("</table></section>");
}

/// A page for errors met while browsing (unknown candidate, bad address).
pub fn error_page(message: &str) -> String {
    document(
        "Review queue: error",
        &format!(
            "<p class=\"error\" role=\"alert\">{}</p><p><a href=\"/\">Back to the queue</a></p>",
            escape(message)
        ),
    )
}
