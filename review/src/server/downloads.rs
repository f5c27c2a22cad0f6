//! The exports (decisions as CSV and JSON, accepted defects as CSV) and
//! the pages' own script and style.

use std::sync::Arc;

use axum::extract::{Request, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};

use super::App;
use super::errors::HttpError;
use crate::export::{self, DecisionsExport, accepted_csv, accepted_defects};

fn download(content_type: &'static str, name: &str, body: String) -> Response {
    (
        [
            (header::CONTENT_TYPE, content_type.to_string()),
            (
                header::CONTENT_DISPOSITION,
                format!("attachment; filename=\"{name}\""),
            ),
        ],
        body,
    )
        .into_response()
}

pub(super) async fn decisions_csv(State(app): State<Arc<App>>) -> Result<Response, HttpError> {
    let current = app.store(|s| s.current_decisions()).await?;
    let csv = export::decisions_csv(&current)?;
    Ok(download(
        "text/csv; charset=utf-8",
        "review-decisions.csv",
        csv,
    ))
}

pub(super) async fn decisions_json(State(app): State<Arc<App>>) -> Result<Response, HttpError> {
    let export = app.store(|s| DecisionsExport::read(s)).await?;
    let body = serde_json::to_string_pretty(&export)
        .map_err(|e| HttpError::text(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?;
    Ok(download("application/json", "review-decisions.json", body))
}

pub(super) async fn accepted(State(app): State<Arc<App>>) -> Result<Response, HttpError> {
    let current = app.store(|s| s.current_decisions()).await?;
    let queue = app.queue(current);
    let csv = accepted_csv(&accepted_defects(&queue, &app.places))?;
    Ok(download(
        "text/csv; charset=utf-8",
        "accepted-defects.csv",
        csv,
    ))
}

pub(super) async fn script() -> Response {
    (
        [(header::CONTENT_TYPE, "text/javascript; charset=utf-8")],
        include_str!("../../assets/review.js"),
    )
        .into_response()
}

pub(super) async fn style() -> Response {
    (
        [(header::CONTENT_TYPE, "text/css; charset=utf-8")],
        include_str!("../../assets/review.css"),
    )
        .into_response()
}

pub(super) async fn not_found(req: Request) -> HttpError {
    HttpError::text(
        StatusCode::NOT_FOUND,
        format!("no page {}; the queue is at /", req.uri().path()),
    )
}
