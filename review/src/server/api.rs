//! The JSON API over the same decisions as the pages: the queue, one
//! candidate with its history, and a decision made on a version.

use std::sync::Arc;

use axum::Json;
use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use postflight_core::condition::ConditionState;
use postflight_core::outputs::localise::DefectRecord;
use serde::{Deserialize, Serialize};

use super::App;
use super::errors::HttpError;
use crate::queue::Progress;
use crate::store::{Decision, ReviewError, ReviewStore, Ruling, Verdict};

/// A decision as the API takes it.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct DecisionRequest {
    /// The candidate's version the reviewer saw (0 before any decision).
    pub(super) version: i64,
    pub(super) verdict: Verdict,
    #[serde(default)]
    pub(super) severity: Option<u8>,
    /// The reviewer's condition state, over the measured one.
    #[serde(default)]
    pub(super) condition: Option<ConditionState>,
    /// The crack has been sealed.
    #[serde(default)]
    pub(super) sealed: bool,
    #[serde(default)]
    pub(super) note: String,
    pub(super) reviewer: String,
}

impl DecisionRequest {
    pub(super) fn apply(&self, store: &mut ReviewStore, id: &str) -> Result<Decision, ReviewError> {
        let ruling = Ruling {
            verdict: self.verdict,
            severity: self.severity,
            condition: self.condition,
            sealed: self.sealed,
            note: &self.note,
            reviewer: &self.reviewer,
        };
        store.decide(id, self.version, &ruling)
    }
}

#[derive(Serialize)]
struct QueueJson<'a> {
    progress: Progress,
    candidates: Vec<CandidateJson<'a>>,
}

#[derive(Serialize)]
struct CandidateJson<'a> {
    rank: usize,
    id: &'a str,
    priority: f64,
    confidence: f64,
    length_m: Option<f64>,
    /// The version a decision on it is made on.
    version: i64,
    decision: Option<Decision>,
}

pub(super) async fn queue(State(app): State<Arc<App>>) -> Result<Response, HttpError> {
    let current = app
        .store(|s| s.current_decisions())
        .await
        .map_err(|e| HttpError::from(e).json())?;
    let queue = app.queue(current);
    let body = QueueJson {
        progress: queue.progress(),
        candidates: queue
            .entries
            .iter()
            .map(|e| CandidateJson {
                rank: e.rank,
                id: &e.defect.id,
                priority: reports::review_priority(e.defect),
                confidence: e.defect.confidence,
                length_m: e.defect.length_m,
                version: e.version(),
                decision: e.decision.clone(),
            })
            .collect(),
    };
    Ok(Json(body).into_response())
}

#[derive(Serialize)]
struct CandidateDetail<'a> {
    candidate: &'a DefectRecord,
    version: i64,
    history: Vec<Decision>,
}

pub(super) async fn candidate(
    State(app): State<Arc<App>>,
    Path(id): Path<String>,
) -> Result<Response, HttpError> {
    let defect = app.defect(&id).map_err(HttpError::json)?;
    let key = id.clone();
    let history = app
        .store(move |s| s.history(&key))
        .await
        .map_err(|e| HttpError::from(e).json())?;
    let body = CandidateDetail {
        candidate: defect,
        version: history.last().map_or(0, |d| d.version),
        history,
    };
    Ok(Json(body).into_response())
}

pub(super) async fn decide(
    State(app): State<Arc<App>>,
    Path(id): Path<String>,
    body: Result<Json<DecisionRequest>, JsonRejection>,
) -> Result<Response, HttpError> {
    let Json(request) = body.map_err(|r| HttpError::text(r.status(), r.body_text()).json())?;
    let decision = app
        .store(move |s| request.apply(s, &id))
        .await
        .map_err(|e| HttpError::from(e).json())?;
    Ok((StatusCode::CREATED, Json(decision)).into_response())
}
