//! Who may ask what: loopback names only while there is no token, the token
//! when there is one (as a bearer, a cookie, or once in the address), no
//! writes from other sites' pages; and the headers every answer carries.

use std::sync::Arc;

use axum::Router;
use axum::extract::{Request, State};
use axum::http::{HeaderMap, HeaderName, HeaderValue, Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Redirect, Response};
use axum_extra::extract::cookie::{Cookie, CookieJar, SameSite};
use subtle::ConstantTimeEq;
use tower_http::set_header::SetResponseHeaderLayer;

use super::App;
use super::errors::HttpError;
use crate::store::ReviewError;

const TOKEN_COOKIE: &str = "postflight_token";
const CSP: &str = "default-src 'none'; img-src 'self'; style-src 'self' 'unsafe-inline'; script-src 'self'; connect-src 'self'; form-action 'self'; base-uri 'none'; frame-ancestors 'none'";

/// A token must be long and plain enough to put in an address unescaped.
pub(super) fn checked_token(t: String) -> Result<String, ReviewError> {
    if t.len() >= 16
        && t.bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
    {
        Ok(t)
    } else {
        Err(ReviewError::WeakToken)
    }
}

pub(super) fn new_token() -> Result<String, ReviewError> {
    let mut bytes = [0u8; 20];
    getrandom::fill(&mut bytes).map_err(|e| ReviewError::Server(std::io::Error::other(e)))?;
    Ok(hex::encode(bytes))
}

/// Compare in time independent of where the strings differ.
fn same_secret(a: &str, b: &str) -> bool {
    a.as_bytes().ct_eq(b.as_bytes()).into()
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

/// The tokens a request presents: as a bearer, in the cookie, and for a page
/// (a GET or HEAD) in the address; a write never takes it from the address.
fn presented_tokens(headers: &HeaderMap, method: &Method, query: Option<&str>) -> Vec<String> {
    let cookie = CookieJar::from_headers(headers)
        .get(TOKEN_COOKIE)
        .map(|c| c.value().to_string());
    let in_address = query
        .filter(|_| is_read(method))
        .unwrap_or("")
        .split('&')
        .filter_map(|pair| pair.strip_prefix("token="))
        .map(str::to_string);
    bearer(headers)
        .into_iter()
        .chain(cookie)
        .chain(in_address)
        .collect()
}

fn bearer(headers: &HeaderMap) -> Option<String> {
    header_str(headers, header::AUTHORIZATION)
        .and_then(|a| a.strip_prefix("Bearer "))
        .map(|b| b.trim().to_string())
}

fn is_read(method: &Method) -> bool {
    matches!(*method, Method::GET | Method::HEAD)
}

/// Where a write comes from, as the browser says it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum WriteSource {
    /// Sent by this server's own pages.
    SameOrigin,
    /// From another site's page, or an opaque origin (a sandboxed frame).
    Foreign,
    /// Neither `Origin` nor `Sec-Fetch-Site` says.
    Unsaid,
}

/// `Sec-Fetch-Site`, and `Origin` against the `Host` asked for (`null` from
/// an opaque origin, such as a sandboxed frame, is foreign unless the
/// browser also says same-origin).
fn write_source(headers: &HeaderMap, host: &str) -> WriteSource {
    let site = header_str(headers, HeaderName::from_static("sec-fetch-site"));
    let same_site = site == Some("same-origin");
    let origin = header_str(headers, header::ORIGIN).map(|origin| match origin.split_once("://") {
        Some((_, authority)) => authority == host,
        None => same_site,
    });
    match (site, origin) {
        (Some("cross-site" | "same-site"), _) | (_, Some(false)) => WriteSource::Foreign,
        (Some("same-origin"), _) | (_, Some(true)) => WriteSource::SameOrigin,
        _ => WriteSource::Unsaid,
    }
}

/// Who may ask what: loopback names only while there is no token (a page
/// elsewhere cannot reach the queue through a rebound DNS name), the token
/// when there is one, and no writes from other sites' pages.
pub(super) async fn guard(State(app): State<Arc<App>>, req: Request, next: Next) -> Response {
    let headers = req.headers();
    let host = header_str(headers, header::HOST).unwrap_or("");
    if app.token.is_none() && !is_loopback_host(host) {
        return HttpError::text(
            StatusCode::FORBIDDEN,
            "this review server answers only to 127.0.0.1 or localhost; open the address it printed",
        )
        .into_response();
    }
    if !is_read(req.method()) {
        // A browser says where a write comes from; a script authenticates
        // with the bearer token, which no other site's page can send.
        let bearer_ok = app
            .token
            .as_ref()
            .is_some_and(|t| bearer(headers).is_some_and(|b| same_secret(&b, t)));
        match write_source(headers, host) {
            WriteSource::SameOrigin => {}
            WriteSource::Unsaid if bearer_ok => {}
            WriteSource::Foreign => {
                return HttpError::text(
                    StatusCode::FORBIDDEN,
                    "a decision from another site's page is refused; decide on the review pages themselves",
                )
                .into_response();
            }
            WriteSource::Unsaid => {
                return HttpError::text(
                    StatusCode::FORBIDDEN,
                    "a decision must say where it comes from: send an Origin header naming this server (browsers do), or the access token as 'Authorization: Bearer TOKEN'",
                )
                .into_response();
            }
        }
    }
    if let Some(token) = &app.token {
        let query = req.uri().query();
        let presented = presented_tokens(headers, req.method(), query);
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
            // One leading slash: `//host/` would send the browser to another site.
            let path = format!("/{}", req.uri().path().trim_start_matches('/'));
            let target = if rest.is_empty() {
                path
            } else {
                format!("{path}?{}", rest.join("&"))
            };
            let cookie = Cookie::build((TOKEN_COOKIE, token.clone()))
                .http_only(true)
                .same_site(SameSite::Strict)
                .path("/");
            return (CookieJar::new().add(cookie), Redirect::to(&target)).into_response();
        }
    }
    next.run(req).await
}

/// Headers every answer carries, refusals included: no scripts or styles
/// but the server's own, no framing, no type sniffing, no caching of pages
/// and data (pictures and assets say otherwise).
pub(super) fn secured(routes: Router<Arc<App>>) -> Router<Arc<App>> {
    let always =
        |name, value| SetResponseHeaderLayer::overriding(name, HeaderValue::from_static(value));
    routes
        .layer(always(header::CONTENT_SECURITY_POLICY, CSP))
        .layer(always(header::X_CONTENT_TYPE_OPTIONS, "nosniff"))
        .layer(always(header::REFERRER_POLICY, "same-origin"))
        .layer(SetResponseHeaderLayer::if_not_present(
            header::CACHE_CONTROL,
            HeaderValue::from_static("no-store"),
        ))
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
    fn a_write_says_where_it_comes_from() {
        let headers = |pairs: &[(&'static str, &'static str)]| {
            let mut h = HeaderMap::new();
            for (k, v) in pairs {
                h.insert(HeaderName::from_static(k), HeaderValue::from_static(v));
            }
            h
        };
        let host = "127.0.0.1:8765";
        let cases = [
            (
                &[("origin", "http://127.0.0.1:8765")][..],
                WriteSource::SameOrigin,
            ),
            (
                &[("sec-fetch-site", "same-origin")][..],
                WriteSource::SameOrigin,
            ),
            (
                &[("origin", "http://evil.example")][..],
                WriteSource::Foreign,
            ),
            (&[("origin", "null")][..], WriteSource::Foreign),
            (
                &[("origin", "null"), ("sec-fetch-site", "same-origin")][..],
                WriteSource::SameOrigin,
            ),
            (
                &[
                    ("sec-fetch-site", "same-origin"),
                    ("origin", "http://evil.example"),
                ][..],
                WriteSource::Foreign,
            ),
            (
                &[("sec-fetch-site", "cross-site")][..],
                WriteSource::Foreign,
            ),
            (&[][..], WriteSource::Unsaid),
            (&[("sec-fetch-site", "bogus")][..], WriteSource::Unsaid),
        ];
        for (pairs, expected) in cases {
            assert_eq!(write_source(&headers(pairs), host), expected, "{pairs:?}");
        }
    }

    #[test]
    fn a_token_in_the_address_counts_for_pages_only() {
        let q = Some("token=abc");
        assert_eq!(
            presented_tokens(&HeaderMap::new(), &Method::GET, q),
            ["abc"]
        );
        assert!(presented_tokens(&HeaderMap::new(), &Method::POST, q).is_empty());
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
