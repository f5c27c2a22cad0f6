//! Refusals and failures as answers: an HTML page for the pages, JSON for
//! the API, text for the rest; each with its status and its reason.

use axum::Json;
use axum::http::StatusCode;
use axum::response::{Html, IntoResponse, Response};
use serde::Serialize;

use crate::pages;
use crate::store::ReviewError;

/// An error answer: an HTML page for the pages, JSON for the API, text for
/// the rest.
#[derive(Debug)]
pub(super) struct HttpError {
    status: StatusCode,
    message: String,
    shape: Shape,
    /// For a conflict: the candidate's version now.
    current_version: Option<i64>,
}

#[derive(Debug, Clone, Copy)]
enum Shape {
    Page,
    Json,
    Text,
}

impl HttpError {
    pub(super) fn text(status: StatusCode, message: impl Into<String>) -> Self {
        Self {
            status,
            message: message.into(),
            shape: Shape::Text,
            current_version: None,
        }
    }

    pub(super) fn json(mut self) -> Self {
        self.shape = Shape::Json;
        self
    }

    pub(super) fn page(mut self) -> Self {
        self.shape = Shape::Page;
        self
    }
}

impl From<ReviewError> for HttpError {
    fn from(e: ReviewError) -> Self {
        let status = match &e {
            ReviewError::UnknownCandidate(_) => StatusCode::NOT_FOUND,
            ReviewError::Conflict { .. } => StatusCode::CONFLICT,
            ReviewError::Decision(_) => StatusCode::UNPROCESSABLE_ENTITY,
            _ => StatusCode::INTERNAL_SERVER_ERROR,
        };
        let current_version = match &e {
            ReviewError::Conflict { current, .. } => Some(*current),
            _ => None,
        };
        Self {
            current_version,
            ..Self::text(status, e.to_string()).page()
        }
    }
}

impl IntoResponse for HttpError {
    fn into_response(self) -> Response {
        #[derive(Serialize)]
        struct Body<'a> {
            error: &'a str,
            #[serde(skip_serializing_if = "Option::is_none")]
            current_version: Option<i64>,
        }
        match self.shape {
            Shape::Page => (self.status, Html(pages::error_page(&self.message))).into_response(),
            Shape::Json => (
                self.status,
                Json(Body {
                    error: &self.message,
                    current_version: self.current_version,
                }),
            )
                .into_response(),
            Shape::Text => (self.status, format!("{}\n", self.message)).into_response(),
        }
    }
}
