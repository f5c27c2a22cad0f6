//! The review queue's web application (`postflight review serve`): the
//! queue and candidate pages, a JSON API for the same decisions, pictures
//! served by candidate id (never by a path from the request), and the
//! exports. Bound to loopback it answers only to loopback names; bound to
//! any other address it asks every request for an access token. Writes from
//! other sites are refused, bodies are size-limited, and a malformed request
//! gets a 4xx with a message.

use std::net::SocketAddr;
use std::path::{Component, Path as FsPath, PathBuf};
use std::sync::{Arc, Mutex};

use axum::Router;
use axum::extract::rejection::{FormRejection, JsonRejection, QueryRejection};
use axum::extract::{DefaultBodyLimit, Form, Json, Path, Query, Request, State};
use axum::http::{HeaderMap, HeaderValue, Method, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{Html, IntoResponse, Redirect, Response};
use axum::routing::{get, post};
use ingest::Recording;
use postflight_core::outputs::localise::DefectRecord;
use serde::{Deserialize, Serialize};

use crate::export::{DecisionsExport, accepted_csv, accepted_defects, decisions_csv};
use crate::pages::{self, CandidateView, Context, Refused, candidate_href};
use crate::pictures::{backdrop, position_svgs, view_jpeg};
use crate::queue::{Filter, Progress, Queue};
use crate::store::{Decision, ReviewError, ReviewStore, Verdict};
use reports::results::{RunResults, TargetVoxel};
use reports::views::Side;

/// Largest request body accepted (a decision with the longest note fits).
const MAX_BODY_BYTES: usize = 64 * 1024;
const TOKEN_COOKIE: &str = "postflight_token";
const CSP: &str = "default-src 'none'; img-src 'self'; style-src 'self' 'unsafe-inline'; script-src 'self'; connect-src 'self'; form-action 'self'; base-uri 'none'; frame-ancestors 'none'";

/// How to serve.
#[derive(Debug, Clone)]
pub struct ServeOptions {
    pub run: PathBuf,
    /// The decisions' database (created if missing).
    pub db: PathBuf,
    pub addr: SocketAddr,
    /// Access token; generated when binding beyond loopback without one.
    pub token: Option<String>,
}

/// The server, once it listens.
#[derive(Debug, Clone)]
pub struct Listening {
    pub addr: SocketAddr,
    /// Address to open (with the token, if one is needed).
    pub url: String,
    pub token_generated: bool,
    pub candidates: usize,
    /// Candidates new since the database last saw this run.
    pub new: usize,
    pub decided: usize,
}

struct App {
    results: RunResults,
    /// The flight's recording, for the supporting views' frames.
    recording: Recording,
    /// Indices into `results.defects`, in review order.
    order: Vec<usize>,
    backdrop: Vec<(Side, Vec<TargetVoxel>)>,
    resolution: f64,
    store: Mutex<ReviewStore>,
    token: Option<String>,
    flight: String,
}

impl App {
    fn queue(&self, current: Vec<Decision>) -> Queue<'_> {
        let order: Vec<&DefectRecord> = self
            .order
            .iter()
            .map(|&i| &self.results.defects[i])
            .collect();
        Queue::new(&order, current)
    }

    fn defect(&self, id: &str) -> Result<&DefectRecord, HttpError> {
        self.results
            .defects
            .iter()
            .find(|d| d.id == id)
            .ok_or_else(|| ReviewError::UnknownCandidate(id.into()).into())
    }

    /// Run `f` on the store off the async workers (SQLite waits for the disk).
    async fn store<T: Send + 'static>(
        self: &Arc<Self>,
        f: impl FnOnce(&mut ReviewStore) -> Result<T, ReviewError> + Send + 'static,
    ) -> Result<T, ReviewError> {
        let app = self.clone();
        tokio::task::spawn_blocking(move || {
            let mut store = app.store.lock().unwrap_or_else(|p| p.into_inner());
            f(&mut store)
        })
        .await
        .map_err(|e| ReviewError::Server(std::io::Error::other(e.to_string())))?
    }

    fn context(&self, filter: Filter) -> Context<'_> {
        Context {
            flight: &self.flight,
            filter,
        }
    }

    fn candidate_page(
        &self,
        id: &str,
        filter: Filter,
        current: Vec<Decision>,
        history: &[Decision],
        view: Option<usize>,
        refused: Option<Refused>,
    ) -> Result<Html<String>, HttpError> {
        let queue = self.queue(current);
        let entry = queue
            .get(id)
            .ok_or_else(|| HttpError::from(ReviewError::UnknownCandidate(id.into())))?;
        let d = entry.defect;
        // The best view first, unless the address asks for another.
        let best = d.views.iter().position(|v| v.frame == d.best.frame);
        let v = CandidateView {
            view: view.or(best).unwrap_or(0),
            position: position_svgs(&self.backdrop, self.resolution, d),
            history,
            refused,
        };
        Ok(Html(pages::candidate_page(
            &self.context(filter),
            &queue,
            entry,
            &v,
        )))
    }
}

/// Serve the review queue of the run until interrupted (Ctrl-C or SIGTERM);
/// `on_ready` is called once it listens.
pub fn serve(options: ServeOptions, on_ready: impl FnOnce(&Listening)) -> Result<(), ReviewError> {
    let results = RunResults::read(&options.run)?;
    if results.localise.is_none() {
        return Err(ReviewError::NotLocalised(options.run.clone()));
    }
    let mut store = ReviewStore::open(&options.db)?;
    let new = store.sync_candidates(&results.defects)?;
    let decided = store.current_decisions()?.len();
    let (token, token_generated) = match options.token {
        Some(t) => (Some(checked_token(t)?), false),
        None if options.addr.ip().is_loopback() => (None, false),
        None => (Some(new_token()?), true),
    };
    let order = results.review_order();
    let resolution = results.coverage.as_ref().map_or(0.1, |c| c.resolution_m);
    let flight = results
        .flight
        .summary
        .flight
        .path
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let app = Arc::new(App {
        recording: Recording::reopen(&results.flight)?,
        backdrop: backdrop(&results.voxels, resolution),
        resolution,
        order,
        store: Mutex::new(store),
        token,
        flight,
        results,
    });
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .map_err(ReviewError::Server)?;
    runtime.block_on(async move {
        let listener = tokio::net::TcpListener::bind(options.addr)
            .await
            .map_err(|cause| ReviewError::Bind {
                addr: options.addr,
                cause,
            })?;
        let addr = listener.local_addr().map_err(ReviewError::Server)?;
        let url = match &app.token {
            Some(t) => format!("http://{addr}/?token={t}"),
            None => format!("http://{addr}/"),
        };
        on_ready(&Listening {
            addr,
            url,
            token_generated,
            candidates: app.results.defects.len(),
            new,
            decided,
        });
        axum::serve(listener, router(app))
            .with_graceful_shutdown(shutdown())
            .await
            .map_err(ReviewError::Server)
    })
}

fn router(app: Arc<App>) -> Router {
    Router::new()
        .route("/", get(queue_page))
        .route("/candidates/{id}", get(candidate_page))
        .route("/candidates/{id}/decide", post(decide_form))
        .route("/candidates/{id}/crop", get(crop))
        .route("/candidates/{id}/views/{k}", get(view_image))
        .route("/api/candidates", get(api_queue))
        .route("/api/candidates/{id}", get(api_candidate))
        .route("/api/candidates/{id}/decisions", post(api_decide))
        .route("/export/decisions.csv", get(export_csv))
        .route("/export/decisions.json", get(export_json))
        .route("/export/accepted-defects.csv", get(export_accepted))
        .route("/assets/review.js", get(script))
        .route("/assets/review.css", get(style))
        .fallback(not_found)
        .layer(middleware::from_fn_with_state(app.clone(), guard))
        .layer(DefaultBodyLimit::max(MAX_BODY_BYTES))
        .with_state(app)
}

async fn shutdown() {
    let term = async {
        #[cfg(unix)]
        if let Ok(mut s) = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
        {
            s.recv().await;
            return;
        }
        std::future::pending::<()>().await
    };
    tokio::select! {
        _ = tokio::signal::ctrl_c() => {}
        _ = term => {}
    }
}

// ---- access ----------------------------------------------------------------

/// A token must be long and plain enough to put in an address unescaped.
fn checked_token(t: String) -> Result<String, ReviewError> {
    if t.len() >= 16
        && t.bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
    {
        Ok(t)
    } else {
        Err(ReviewError::Invalid(
            "an access token needs at least 16 characters of letters, digits, '-' or '_'; or leave --token out to have one generated".into(),
        ))
    }
}

fn new_token() -> Result<String, ReviewError> {
    let mut bytes = [0u8; 20];
    getrandom::fill(&mut bytes).map_err(|e| ReviewError::Server(std::io::Error::other(e)))?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// Compare in time independent of where the strings differ.
fn same_secret(a: &str, b: &str) -> bool {
    a.len() == b.len()
        && a.bytes()
            .zip(b.bytes())
            .fold(0, |acc, (x, y)| acc | (x ^ y))
            == 0
}

fn is_loopback_host(host: &str) -> bool {
    let name = if let Some(rest) = host.strip_prefix('[') {
        rest.split(']').next().unwrap_or("")
    } else {
        host.rsplit_once(':').map_or(host, |(n, _)| n)
    };
    name.eq_ignore_ascii_case("localhost")
        || name
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_loopback())
}

fn header_str(headers: &HeaderMap, name: header::HeaderName) -> Option<&str> {
    headers.get(name).and_then(|v| v.to_str().ok())
}

fn presented_token<'a>(headers: &'a HeaderMap, query: Option<&'a str>) -> Vec<&'a str> {
    let mut found = Vec::new();
    if let Some(b) =
        header_str(headers, header::AUTHORIZATION).and_then(|a| a.strip_prefix("Bearer "))
    {
        found.push(b.trim());
    }
    for c in headers
        .get_all(header::COOKIE)
        .iter()
        .filter_map(|v| v.to_str().ok())
    {
        for pair in c.split(';') {
            if let Some(v) = pair
                .trim()
                .strip_prefix(TOKEN_COOKIE)
                .and_then(|r| r.strip_prefix('='))
            {
                found.push(v);
            }
        }
    }
    for pair in query.unwrap_or("").split('&') {
        if let Some(v) = pair.strip_prefix("token=") {
            found.push(v);
        }
    }
    found
}

/// Who may ask what: loopback names only while there is no token (a page
/// elsewhere cannot reach the queue through a rebound DNS name), the token
/// when there is one, and no writes from other sites' pages.
async fn guard(State(app): State<Arc<App>>, req: Request, next: Next) -> Response {
    secured(admit(&app, req, next).await)
}

async fn admit(app: &App, req: Request, next: Next) -> Response {
    let headers = req.headers();
    let host = header_str(headers, header::HOST).unwrap_or("");
    if app.token.is_none() && !is_loopback_host(host) {
        return HttpError::text(
            StatusCode::FORBIDDEN,
            "this review server answers only to 127.0.0.1 or localhost; open the address it printed",
        )
        .into_response();
    }
    if !matches!(*req.method(), Method::GET | Method::HEAD) {
        // Browsers say where a request comes from: Sec-Fetch-Site, and Origin
        // ("null" from opaque origins such as sandboxed frames).
        let site = headers.get("sec-fetch-site").and_then(|v| v.to_str().ok());
        let same_origin = site == Some("same-origin");
        let foreign_site = matches!(site, Some("cross-site" | "same-site"));
        let foreign_origin = header_str(headers, header::ORIGIN).is_some_and(|origin| match origin
            .split_once("://")
        {
            Some((_, authority)) => authority != host,
            None => !same_origin,
        });
        if foreign_site || foreign_origin {
            return HttpError::text(
                StatusCode::FORBIDDEN,
                "a decision from another site's page is refused; decide on the review pages themselves",
            )
            .into_response();
        }
    }
    if let Some(token) = &app.token {
        let query = req.uri().query();
        let presented = presented_token(headers, query);
        if !presented.iter().any(|t| same_secret(t, token)) {
            return HttpError::text(
                StatusCode::UNAUTHORIZED,
                "this review server needs its access token: open the address with ?token= that it printed, or send 'Authorization: Bearer TOKEN'",
            )
            .into_response();
        }
        // A token in the address becomes a cookie, and the address loses it
        // (so it is not left in history or shown over a shoulder).
        if query.is_some_and(|q| q.split('&').any(|p| p.starts_with("token=")))
            && *req.method() == Method::GET
        {
            let rest: Vec<&str> = query
                .unwrap_or("")
                .split('&')
                .filter(|p| !p.starts_with("token=") && !p.is_empty())
                .collect();
            let target = if rest.is_empty() {
                req.uri().path().to_string()
            } else {
                format!("{}?{}", req.uri().path(), rest.join("&"))
            };
            let mut resp = Redirect::to(&target).into_response();
            if let Ok(v) = HeaderValue::from_str(&format!(
                "{TOKEN_COOKIE}={token}; HttpOnly; SameSite=Strict; Path=/"
            )) {
                resp.headers_mut().insert(header::SET_COOKIE, v);
            }
            return resp;
        }
    }
    next.run(req).await
}

/// Headers every answer carries: no scripts or styles but the server's own,
/// no framing, no type sniffing, no caching of pages and data.
fn secured(mut resp: Response) -> Response {
    let h = resp.headers_mut();
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(CSP),
    );
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    h.insert(
        header::REFERRER_POLICY,
        HeaderValue::from_static("same-origin"),
    );
    h.entry(header::CACHE_CONTROL)
        .or_insert(HeaderValue::from_static("no-store"));
    resp
}

// ---- errors ----------------------------------------------------------------

/// An error answer: an HTML page for the pages, JSON for the API, text for
/// the rest.
#[derive(Debug)]
struct HttpError {
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
    fn text(status: StatusCode, message: impl Into<String>) -> Self {
        Self {
            status,
            message: message.into(),
            shape: Shape::Text,
            current_version: None,
        }
    }

    fn json(mut self) -> Self {
        self.shape = Shape::Json;
        self
    }

    fn page(mut self) -> Self {
        self.shape = Shape::Page;
        self
    }
}

impl From<ReviewError> for HttpError {
    fn from(e: ReviewError) -> Self {
        let status = match &e {
            ReviewError::UnknownCandidate(_) => StatusCode::NOT_FOUND,
            ReviewError::Conflict { .. } => StatusCode::CONFLICT,
            ReviewError::Invalid(_) => StatusCode::UNPROCESSABLE_ENTITY,
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

// ---- pages -----------------------------------------------------------------

#[derive(Debug, Default, Deserialize)]
struct PageQuery {
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

async fn queue_page(
    State(app): State<Arc<App>>,
    q: Result<Query<PageQuery>, QueryRejection>,
) -> Result<Html<String>, HttpError> {
    let q = page_query(q)?;
    let filter = filter(q.filter.as_deref())?;
    let current = app.store(|s| s.current_decisions()).await?;
    let queue = app.queue(current);
    Ok(Html(pages::queue_page(&app.context(filter), &queue)))
}

async fn candidate_page(
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
struct DecisionForm {
    #[serde(default)]
    version: String,
    #[serde(default)]
    verdict: String,
    #[serde(default)]
    severity: String,
    #[serde(default)]
    note: String,
    #[serde(default)]
    reviewer: String,
    #[serde(default)]
    filter: String,
}

/// A decision as the API takes it.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DecisionRequest {
    /// The candidate's version the reviewer saw (0 before any decision).
    version: i64,
    verdict: Verdict,
    #[serde(default)]
    severity: Option<u8>,
    #[serde(default)]
    note: String,
    reviewer: String,
}

impl DecisionForm {
    fn request(&self) -> Result<DecisionRequest, String> {
        let version = self.version.parse().map_err(|_| {
            format!(
                "version {:?} is not a number; reload the page",
                self.version
            )
        })?;
        let verdict = Verdict::parse(&self.verdict).ok_or_else(|| {
            format!(
                "unknown decision {:?}; use accepted, rejected or needs_repair",
                self.verdict
            )
        })?;
        let severity = match self.severity.trim() {
            "" => None,
            s => Some(
                s.parse()
                    .map_err(|_| format!("severity {s:?} is not a number from 1 to 5"))?,
            ),
        };
        Ok(DecisionRequest {
            version,
            verdict,
            severity,
            note: self.note.clone(),
            reviewer: self.reviewer.clone(),
        })
    }
}

impl DecisionRequest {
    fn apply(&self, store: &mut ReviewStore, id: &str) -> Result<Decision, ReviewError> {
        store.decide(
            id,
            self.version,
            self.verdict,
            self.severity,
            &self.note,
            &self.reviewer,
        )
    }
}

/// The form's decision: on success, on to the next candidate the filter
/// shows; refused (a conflict, a bad field), the page again with the reason
/// and what the reviewer typed.
async fn decide_form(
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
                Err(why) => Err(ReviewError::Invalid(why.clone())),
            };
            Ok((outcome, s.current_decisions()?, s.history(&key)?))
        })
        .await?;
    match outcome {
        Ok(_) => {
            let queue = app.queue(current);
            let next = match queue.neighbour(&id, filter, true) {
                Some(e) => candidate_href(&e.defect.id, filter),
                None => format!("/?filter={}", filter.key()),
            };
            Ok(Redirect::to(&next).into_response())
        }
        Err(e @ (ReviewError::Conflict { .. } | ReviewError::Invalid(_))) => {
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

// ---- pictures --------------------------------------------------------------

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

async fn crop(State(app): State<Arc<App>>, Path(id): Path<String>) -> Result<Response, HttpError> {
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
    let bytes = tokio::fs::read(app.results.file(name))
        .await
        .map_err(|_| missing())?;
    Ok(jpeg(bytes))
}

async fn view_image(
    State(app): State<Arc<App>>,
    path: Result<Path<(String, usize)>, axum::extract::rejection::PathRejection>,
) -> Result<Response, HttpError> {
    let Path((id, k)) = path.map_err(|r| HttpError::text(r.status(), r.body_text()))?;
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
        view_jpeg(&worker.results.flight, &worker.recording, &view)
    })
    .await
    .map_err(|e| HttpError::text(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?
    .map_err(|why| HttpError::text(StatusCode::INTERNAL_SERVER_ERROR, why))?;
    Ok(jpeg(bytes))
}

// ---- API -------------------------------------------------------------------

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

async fn api_queue(State(app): State<Arc<App>>) -> Result<Response, HttpError> {
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

async fn api_candidate(
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

async fn api_decide(
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

// ---- exports and assets ----------------------------------------------------

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

async fn export_csv(State(app): State<Arc<App>>) -> Result<Response, HttpError> {
    let current = app.store(|s| s.current_decisions()).await?;
    let csv = decisions_csv(&current)?;
    Ok(download(
        "text/csv; charset=utf-8",
        "review-decisions.csv",
        csv,
    ))
}

async fn export_json(State(app): State<Arc<App>>) -> Result<Response, HttpError> {
    let export = app.store(|s| DecisionsExport::read(s)).await?;
    let body = serde_json::to_string_pretty(&export)
        .map_err(|e| HttpError::text(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?;
    Ok(download("application/json", "review-decisions.json", body))
}

async fn export_accepted(State(app): State<Arc<App>>) -> Result<Response, HttpError> {
    let current = app.store(|s| s.current_decisions()).await?;
    let queue = app.queue(current);
    let csv = accepted_csv(&accepted_defects(&queue))?;
    Ok(download(
        "text/csv; charset=utf-8",
        "accepted-defects.csv",
        csv,
    ))
}

async fn script() -> Response {
    (
        [(header::CONTENT_TYPE, "text/javascript; charset=utf-8")],
        include_str!("../assets/review.js"),
    )
        .into_response()
}

async fn style() -> Response {
    (
        [(header::CONTENT_TYPE, "text/css; charset=utf-8")],
        include_str!("../assets/review.css"),
    )
        .into_response()
}

async fn not_found(req: Request) -> HttpError {
    HttpError::text(
        StatusCode::NOT_FOUND,
        format!("no page {}; the queue is at /", req.uri().path()),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loopback_names_are_told_apart_from_others() {
        for host in [
            "127.0.0.1:8765",
            "localhost:8765",
            "[::1]:8765",
            "LOCALHOST",
            "127.0.0.2:80",
        ] {
            assert!(is_loopback_host(host), "{host}");
        }
        for host in [
            "evil.example:8765",
            "192.168.1.5:8765",
            "",
            "localhost.evil.example",
            "[fe80::1]:1",
        ] {
            assert!(!is_loopback_host(host), "{host}");
        }
    }

    #[test]
    fn tokens_are_checked_and_generated_long() {
        assert!(checked_token("short".into()).is_err());
        assert!(checked_token("has spaces in it, too many".into()).is_err());
        assert!(checked_token("a-good_token-0123456789".into()).is_ok());
        let t = new_token().unwrap();
        assert_eq!(t.len(), 40);
        assert_ne!(t, new_token().unwrap());
        assert!(same_secret(&t, &t.clone()));
        assert!(!same_secret(&t, &t[1..]));
    }
}
