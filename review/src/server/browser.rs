//! What the pages ask for: the queue, a candidate's page, the decision its
//! form sends, and the pictures (a candidate's best-view crop, its
//! supporting views' frames), served by candidate id and view number,
//! never by a path from the request.

use std::path::{Component, Path as FsPath};
use std::sync::Arc;

use axum::extract::rejection::{FormRejection, PathRejection, QueryRejection};
use axum::extract::{Form, Path, Query, State};
use axum::http::{StatusCode, header};
use axum::response::{Html, IntoResponse, Redirect, Response};
use postflight_core::condition::ConditionState;
use postflight_core::outputs::record::{ElementRecord, RecordSummary};
use postflight_core::table::Named;
use postflight_core::{RunDir, Stage};
use serde::Deserialize;

use super::App;
use super::api::DecisionRequest;
use super::errors::HttpError;
use crate::pages::{self, Refused, candidate_href};
use crate::pictures::view_jpeg;
use crate::queue::Filter;
use crate::store::{InvalidDecision, ReviewError, Verdict};

#[derive(Debug, Default, Deserialize)]
pub(super) struct PageQuery {
    filter: Option<String>,
    view: Option<usize>,
}

fn filter(name: Option<&str>) -> Result<Filter, HttpError> {
    match name {
        None | Some("") => Ok(Filter::All),
        Some(s) => Filter::parse(s).ok_or_else(|| {
            let names: Vec<&str> = Filter::ALL.iter().map(|f| f.key()).collect();
            HttpError::text(
                StatusCode::BAD_REQUEST,
                format!("unknown filter {s:?}; use one of {}", names.join(", ")),
            )
            .page()
        }),
    }
}

fn page_query(q: Result<Query<PageQuery>, QueryRejection>) -> Result<PageQuery, HttpError> {
    q.map(|Query(q)| q)
        .map_err(|r| HttpError::text(r.status(), r.body_text()).page())
}

pub(super) async fn queue_page(
    State(app): State<Arc<App>>,
    q: Result<Query<PageQuery>, QueryRejection>,
) -> Result<Html<String>, HttpError> {
    let q = page_query(q)?;
    let filter = filter(q.filter.as_deref())?;
    let current = app.store(|s| s.current_decisions()).await?;
    let queue = app.queue(current);
    Ok(Html(pages::queue_page(&app.context(filter), &queue)))
}

/// The element record as the decisions so far make it.
/// The element record as the decisions so far make it (remade from the
/// run's files on every request, off the server's threads).
pub(super) async fn record_page(State(app): State<Arc<App>>) -> Result<Html<String>, HttpError> {
    let current = app.store(|s| s.current_decisions()).await?;
    let decisions: record::Decisions = current
        .iter()
        .map(|d| (d.candidate.clone(), d.reviewer_call()))
        .collect();
    let remaking = app.clone();
    let remade = tokio::task::spawn_blocking(move || remade_record(&remaking, decisions))
        .await
        .map_err(|e| HttpError::text(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).page())?
        .map_err(|e| HttpError::text(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).page())?;
    let ctx = app.context(Filter::All);
    let shown = remade
        .as_ref()
        .map(|(summary, rows)| (summary, rows.as_slice()));
    Ok(Html(pages::record_page(&ctx, shown)))
}

/// The run's record remade with `decisions`; `None` where it has none.
fn remade_record(
    app: &App,
    decisions: record::Decisions,
) -> Result<Option<(RecordSummary, Vec<ElementRecord>)>, record::RecordError> {
    let Some((stored, _)) = &app.results.record else {
        return Ok(None);
    };
    let options = record::RecordOptions::remade(app.run_root.clone(), stored, decisions)?;
    let run = RunDir::open(&app.run_root, Stage::Record)?;
    let made = record::stage::make(&run, &options)?;
    let rows = made.rows.clone();
    Ok(Some((record::stage::summarise(&options, made, 0.0), rows)))
}

pub(super) async fn candidate_page(
    State(app): State<Arc<App>>,
    Path(id): Path<String>,
    q: Result<Query<PageQuery>, QueryRejection>,
) -> Result<Html<String>, HttpError> {
    let q = page_query(q)?;
    let filter = filter(q.filter.as_deref())?;
    let key = id.clone();
    let (current, history) = app
        .store(move |s| Ok((s.current_decisions()?, s.history(&key)?)))
        .await?;
    app.candidate_page(&id, filter, current, &history, q.view, None)
}

/// A decision as the form sends it (every field text, checked here so that
/// a bad one is named).
#[derive(Debug, Deserialize)]
pub(super) struct DecisionForm {
    #[serde(default)]
    version: String,
    #[serde(default)]
    verdict: String,
    #[serde(default)]
    severity: String,
    /// A condition state's name; empty: the measured one.
    #[serde(default)]
    condition: String,
    /// `on` where the sealed box is ticked (absent otherwise).
    #[serde(default)]
    sealed: String,
    #[serde(default)]
    note: String,
    #[serde(default)]
    reviewer: String,
    #[serde(default)]
    filter: String,
    /// `queue`: decided from a queue row, so back to the queue.
    #[serde(default)]
    back: String,
}

impl DecisionForm {
    fn request(&self) -> Result<DecisionRequest, InvalidDecision> {
        let version = self
            .version
            .parse()
            .map_err(|_| InvalidDecision::Version(self.version.clone()))?;
        let verdict = Verdict::parse(&self.verdict)
            .ok_or_else(|| InvalidDecision::Verdict(self.verdict.clone()))?;
        let severity = match self.severity.trim() {
            "" => None,
            s => Some(
                s.parse()
                    .map_err(|_| InvalidDecision::SeverityNotANumber(s.into()))?,
            ),
        };
        let condition = match self.condition.trim() {
            "" => None,
            c => {
                Some(ConditionState::named(c).ok_or_else(|| InvalidDecision::Condition(c.into()))?)
            }
        };
        Ok(DecisionRequest {
            version,
            verdict,
            severity,
            condition,
            sealed: !self.sealed.is_empty(),
            note: self.note.clone(),
            reviewer: self.reviewer.clone(),
        })
    }
}

/// The form's decision: on success, on to the next candidate the filter
/// shows; refused (a conflict, a bad field), the page again with the reason
/// and what the reviewer typed.
pub(super) async fn decide_form(
    State(app): State<Arc<App>>,
    Path(id): Path<String>,
    form: Result<Form<DecisionForm>, FormRejection>,
) -> Result<Response, HttpError> {
    let Form(form) = form.map_err(|r| HttpError::text(r.status(), r.body_text()).page())?;
    let filter = filter(Some(&form.filter))?;
    app.defect(&id)?;
    let request = form.request();
    let key = id.clone();
    let (outcome, current, history) = app
        .store(move |s| {
            let outcome = match &request {
                Ok(r) => r.apply(s, &key),
                Err(why) => Err(why.clone().into()),
            };
            Ok((outcome, s.current_decisions()?, s.history(&key)?))
        })
        .await?;
    match outcome {
        Ok(_) => {
            let queue = app.queue(current);
            let next = match queue.neighbour(&id, filter, true) {
                Some(_) if form.back == "queue" => format!("/?filter={}", filter.key()),
                Some(e) => candidate_href(&e.defect.id, filter),
                None => format!("/?filter={}", filter.key()),
            };
            Ok(Redirect::to(&next).into_response())
        }
        Err(e @ (ReviewError::Conflict { .. } | ReviewError::Decision(_))) => {
            let status = match e {
                ReviewError::Conflict { .. } => StatusCode::CONFLICT,
                _ => StatusCode::UNPROCESSABLE_ENTITY,
            };
            let page = app.candidate_page(
                &id,
                filter,
                current,
                &history,
                None,
                Some(Refused {
                    why: e.to_string(),
                    note: &form.note,
                    reviewer: &form.reviewer,
                }),
            )?;
            Ok((status, page).into_response())
        }
        Err(e) => Err(HttpError::from(e)),
    }
}

fn jpeg(bytes: Vec<u8>) -> Response {
    (
        [
            (header::CONTENT_TYPE, "image/jpeg"),
            (header::CACHE_CONTROL, "private, max-age=3600"),
        ],
        bytes,
    )
        .into_response()
}

pub(super) async fn crop(
    State(app): State<Arc<App>>,
    Path(id): Path<String>,
) -> Result<Response, HttpError> {
    let d = app.defect(&id)?;
    let missing = || {
        HttpError::text(
            StatusCode::NOT_FOUND,
            format!(
                "candidate {id} has no best-view image; rerun `postflight localise` to make it"
            ),
        )
    };
    let name = d.crop.as_deref().ok_or_else(missing)?;
    // The name comes from defects.json; still, only files inside the run.
    if FsPath::new(name)
        .components()
        .any(|c| !matches!(c, Component::Normal(_)))
    {
        return Err(missing());
    }
    let bytes = read_inside(&app.run_root, &app.results.file(name))
        .await
        .ok_or_else(missing)?;
    Ok(jpeg(bytes))
}

/// The file at `path` if it lies in `root` (canonical) once links are
/// followed: a crop linked to a file elsewhere is not served.
async fn read_inside(root: &FsPath, path: &FsPath) -> Option<Vec<u8>> {
    let real = tokio::fs::canonicalize(path).await.ok()?;
    if !real.starts_with(root) {
        return None;
    }
    tokio::fs::read(real).await.ok()
}

/// `?box=0`: the frame without its detection box (it can hide the crack).
#[derive(Debug, Default, Deserialize)]
pub(super) struct ViewQuery {
    #[serde(rename = "box")]
    draw_box: Option<u8>,
}

pub(super) async fn view_image(
    State(app): State<Arc<App>>,
    path: Result<Path<(String, usize)>, PathRejection>,
    q: Result<Query<ViewQuery>, QueryRejection>,
) -> Result<Response, HttpError> {
    let Path((id, k)) = path.map_err(|r| HttpError::text(r.status(), r.body_text()))?;
    let Query(q) = q.map_err(|r| HttpError::text(r.status(), r.body_text()))?;
    let draw_box = q.draw_box != Some(0);
    let d = app.defect(&id)?;
    let view = d.views.get(k).cloned().ok_or_else(|| {
        HttpError::text(
            StatusCode::NOT_FOUND,
            format!(
                "candidate {id} has {} supporting views, numbered from 0",
                d.views.len()
            ),
        )
    })?;
    let worker = app.clone();
    let bytes = tokio::task::spawn_blocking(move || {
        view_jpeg(&worker.results.flight, &worker.recording, &view, draw_box)
    })
    .await
    .map_err(|e| HttpError::text(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?
    .map_err(|why| HttpError::text(StatusCode::INTERNAL_SERVER_ERROR, why))?;
    Ok(jpeg(bytes))
}
