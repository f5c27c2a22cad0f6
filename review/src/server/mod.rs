//! The review queue's web application (`postflight review serve`): the
//! queue and candidate pages, a JSON API for the same decisions, pictures
//! served by candidate id (never by a path from the request), and the
//! exports. Bound to loopback it answers only to loopback names; bound to
//! any other address it asks every request for an access token. Writes from
//! other sites are refused, bodies are size-limited, and a malformed request
//! gets a 4xx with a message.

//!
//! [`access`] decides who may ask what and adds the security headers;
//! [`browser`] answers the pages and their pictures, [`api`] the JSON API,
//! [`downloads`] the exports and the page assets; [`errors`] words every
//! refusal for the kind of client that asked.

mod access;
mod api;
mod browser;
mod downloads;
mod errors;

use std::collections::HashMap;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use axum::Router;
use axum::extract::DefaultBodyLimit;
use axum::middleware;
use axum::response::Html;
use axum::routing::{get, post};
use ingest::Recordings;
use postflight_core::outputs::localise::DefectRecord;
use reports::results::{RunResults, TargetVoxel};
use reports::views::Side;

use crate::pages::{self, CandidateView, Context, Refused};
use crate::pictures::{backdrop, position_svgs};
use crate::queue::{Filter, Queue};
use crate::store::{Decision, ReviewError, ReviewStore};
use errors::HttpError;

/// Largest request body accepted (a decision with the longest note fits).
const MAX_BODY_BYTES: usize = 64 * 1024;

/// Connections answered at once: a review team's browsers (six each) with
/// room to spare; more wait to be accepted.
pub const MAX_CONNECTIONS: usize = 128;

/// How long a request's headers may take to arrive, and a connection may
/// idle between requests, before it is closed.
pub const HEADER_READ_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(10);

/// How long requests under way may take to finish at shutdown.
const SHUTDOWN_GRACE: std::time::Duration = std::time::Duration::from_secs(5);

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
    /// The run directory, links resolved: what the server reads from it
    /// stays inside.
    run_root: PathBuf,
    /// The flight's recording, for the supporting views' frames.
    recording: Recordings,
    /// Indices into `results.defects`, in review order.
    order: Vec<usize>,
    backdrop: Vec<(Side, Vec<TargetVoxel>)>,
    resolution: f64,
    store: Mutex<ReviewStore>,
    token: Option<String>,
    flight: String,
    /// Each candidate's place on the structure, by id.
    places: HashMap<String, String>,
    seen_in: HashMap<String, String>,
    /// Each candidate's change since an earlier inspection, by id.
    since: HashMap<String, crate::since::Since>,
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
            places: &self.places,
            seen_in: &self.seen_in,
            since: &self.since,
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
        Some(t) => (Some(access::checked_token(t)?), false),
        None if options.addr.ip().is_loopback() => (None, false),
        None => (Some(access::new_token()?), true),
    };
    let order = results.review_order();
    let resolution = results
        .coverage
        .as_ref()
        .map_or(0.1, |c| c.figures.resolution_m);
    let flight = results.flight.summary.recording_names();
    let run_root = std::fs::canonicalize(&options.run).map_err(ReviewError::Server)?;
    let app = Arc::new(App {
        run_root,
        recording: Recordings::reopen(&results.flight)?,
        backdrop: backdrop(&results.voxels, resolution),
        resolution,
        order,
        places: results.places(),
        seen_in: results.seen_in(),
        since: crate::since::pasts(results.changes.as_ref())?,
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
        serve_connections(listener, router(app)).await;
        Ok(())
    })
}

/// Answer connections until shut down: at most [`MAX_CONNECTIONS`] at once
/// (more wait to be accepted), each closed when a request's headers take
/// longer than [`HEADER_READ_TIMEOUT`] to arrive or it idles that long
/// between requests. On shutdown, requests under way get
/// [`SHUTDOWN_GRACE`] to finish.
async fn serve_connections(listener: tokio::net::TcpListener, router: Router) {
    use hyper_util::rt::{TokioIo, TokioTimer};
    use hyper_util::service::TowerToHyperService;

    let slots = Arc::new(tokio::sync::Semaphore::new(MAX_CONNECTIONS));
    let graceful = hyper_util::server::graceful::GracefulShutdown::new();
    let mut http = hyper::server::conn::http1::Builder::new();
    http.timer(TokioTimer::new())
        .header_read_timeout(HEADER_READ_TIMEOUT);
    let stop = shutdown();
    tokio::pin!(stop);
    loop {
        let slot = tokio::select! {
            slot = slots.clone().acquire_owned() => slot.expect("the semaphore is never closed"),
            () = &mut stop => break,
        };
        let stream = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok((stream, _)) => stream,
                // Out of file descriptors, or a connection reset before it
                // was accepted: try again shortly.
                Err(_) => {
                    tokio::time::sleep(std::time::Duration::from_millis(50)).await;
                    continue;
                }
            },
            () = &mut stop => break,
        };
        let service = TowerToHyperService::new(router.clone());
        let connection = graceful.watch(http.serve_connection(TokioIo::new(stream), service));
        tokio::spawn(async move {
            // A connection ends in an error when the client goes away or
            // times out; there is no one to tell.
            let _ = connection.await;
            drop(slot);
        });
    }
    let _ = tokio::time::timeout(SHUTDOWN_GRACE, graceful.shutdown()).await;
}

fn router(app: Arc<App>) -> Router {
    let routes = Router::new()
        .route("/", get(browser::queue_page))
        .route("/candidates/{id}", get(browser::candidate_page))
        .route("/record", get(browser::record_page))
        .route("/candidates/{id}/decide", post(browser::decide_form))
        .route("/candidates/{id}/crop", get(browser::crop))
        .route("/candidates/{id}/views/{k}", get(browser::view_image))
        .route("/api/candidates", get(api::queue))
        .route("/api/candidates/{id}", get(api::candidate))
        .route("/api/candidates/{id}/decisions", post(api::decide))
        .route("/export/decisions.csv", get(downloads::decisions_csv))
        .route("/export/decisions.json", get(downloads::decisions_json))
        .route("/export/accepted-defects.csv", get(downloads::accepted))
        .route("/assets/review.js", get(downloads::script))
        .route("/assets/review.css", get(downloads::style))
        .fallback(downloads::not_found)
        .layer(middleware::from_fn_with_state(app.clone(), access::guard))
        .layer(DefaultBodyLimit::max(MAX_BODY_BYTES));
    access::secured(routes).with_state(app)
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
