//! Local-only by design: which requests the server answers at all.
//!
//! Three checks, each against a different attack:
//! - **Host allowlist** (DNS rebinding): a page on `evil.example` whose name the attacker
//!   re-points at 127.0.0.1 reaches the server with `Host: evil.example`. Only `localhost`,
//!   `*.localhost`, loopback addresses, the address the server listens on (any address when it
//!   listens on all of them: an IP literal cannot be rebound) and the names given with
//!   `--allow-host` are answered; any other `Host` gets `403`, as Jupyter Server and Vite do.
//! - **Origin** (cross-site requests): browsers send `POST`s with a `text/plain` body to any
//!   address without asking first. A request that changes state (every method but `GET` and
//!   `HEAD`) is refused when its `Origin` is not this page's own, and any request is refused when
//!   the browser says it comes from another site (`Sec-Fetch-Site` other than `same-origin` or
//!   `none`) and asks for the API; a page of another site may still link to the page itself.
//! - **Token** (other people on the network): when the server listens beyond loopback, every
//!   request must carry the run's random token, as a `token=` parameter (the printed address
//!   `/?token=...` has it, and the page adds it to each request it makes) or an
//!   `Authorization: token ...` header. It is never set as a cookie: a browser sends a host's
//!   cookies to every port of it, so any other server on the machine would receive it. The
//!   page's script and style ([`PUBLIC_FILES`]) load without it: they are the same in every copy
//!   of uwnr and say nothing of this server. On loopback no token is asked: the Host and Origin
//!   checks already keep other sites out, and other users of the machine are outside this model.

use std::net::IpAddr;

use rand::RngCore;

use crate::error::{Result, ServeError};
use crate::http::Request;

/// Bytes of randomness in a token (printed as hex).
const TOKEN_BYTES: usize = 24;

/// Paths served without the token (still only to allowed hosts): the files the page loads
/// before its script can add the token to requests, the same in every copy of uwnr.
pub const PUBLIC_FILES: [&str; 2] = ["app.js", "style.css"];

/// The checks of the module docs.
#[derive(Clone, Debug)]
pub struct Access {
    bound: IpAddr,
    names: Vec<String>,
    token: Option<String>,
}

/// A new random token (hex).
#[must_use]
pub fn new_token() -> String {
    let mut bytes = [0_u8; TOKEN_BYTES];
    rand::rng().fill_bytes(&mut bytes);
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

impl Access {
    /// Checks for a server listening on `bound`, also answering to the host `names`
    /// (`--allow-host`), asking for `token` when given.
    #[must_use]
    pub fn new(bound: IpAddr, names: &[String], token: Option<String>) -> Self {
        Self {
            bound,
            names: names.iter().map(|n| normalise(n)).collect(),
            token,
        }
    }

    /// The token requests must carry, if any.
    #[must_use]
    pub fn token(&self) -> Option<&str> {
        self.token.as_deref()
    }

    /// Whether a `Host` name (port and brackets removed, lower case) may be answered.
    #[must_use]
    pub fn allows_host(&self, name: &str) -> bool {
        if name == "localhost" || name.ends_with(".localhost") {
            return true;
        }
        if let Ok(ip) = name.parse::<IpAddr>() {
            return ip.is_loopback() || ip == self.bound || self.bound.is_unspecified();
        }
        self.names.iter().any(|n| n == name)
    }

    /// Checks `req` (its head: the body is never needed).
    pub fn check(&self, req: &Request) -> Result<()> {
        let host = req
            .header("host")
            .ok_or_else(|| ServeError::Forbidden("the request has no Host header".into()))?;
        let name = host_name(host);
        if !self.allows_host(&name) {
            return Err(ServeError::Forbidden(format!(
                "this server answers to localhost and its own address, not to host {name:?} \
                 (name it with --allow-host if it is yours)"
            )));
        }
        let changes_state = !matches!(req.method.as_str(), "GET" | "HEAD");
        if changes_state
            && let Some(origin) = req.header("origin")
            && !origin.eq_ignore_ascii_case(&format!("http://{host}"))
        {
            return Err(ServeError::Forbidden(format!(
                "a request from another page ({origin}) was refused: only this page may change \
                 anything"
            )));
        }
        if let Some(site) = req.header("sec-fetch-site")
            && !matches!(site, "same-origin" | "none")
            && (changes_state || req.segments().first() == Some(&"api"))
        {
            return Err(ServeError::Forbidden(format!(
                "a {site} request to the API was refused: only this page may use it"
            )));
        }
        let Some(token) = &self.token else {
            return Ok(());
        };
        if let [file] = req.segments().as_slice()
            && PUBLIC_FILES.contains(file)
        {
            return Ok(());
        }
        let from_header = req.header("authorization").and_then(|a| {
            a.strip_prefix("token ")
                .or_else(|| a.strip_prefix("Bearer "))
        });
        let from_query = req.param("token");
        if [from_header, from_query]
            .into_iter()
            .any(|t| t.is_some_and(|t| same(t, token)))
        {
            return Ok(());
        }
        Err(ServeError::Forbidden(
            "this server asks for the token it printed at start: open the address `uwnr serve` \
             printed (…/?token=…)"
                .into(),
        ))
    }
}

/// Compares in time independent of where the strings differ.
fn same(a: &str, b: &str) -> bool {
    a.len() == b.len()
        && a.bytes()
            .zip(b.bytes())
            .fold(0_u8, |acc, (x, y)| acc | (x ^ y))
            == 0
}

fn normalise(name: &str) -> String {
    name.trim().trim_end_matches('.').to_ascii_lowercase()
}

/// The name of a `Host` header value: the port removed, an IPv6 address without brackets, lower
/// case, no trailing dot.
#[must_use]
pub fn host_name(host: &str) -> String {
    let host = host.trim();
    let name = if let Some(rest) = host.strip_prefix('[') {
        rest.split(']').next().unwrap_or(rest)
    } else {
        host.rsplit_once(':')
            .filter(|(_, port)| port.bytes().all(|b| b.is_ascii_digit()))
            .map_or(host, |(name, _)| name)
    };
    normalise(name)
}

#[cfg(test)]
mod tests {
    use std::net::Ipv4Addr;

    use super::*;

    fn req(method: &str, target: &str, headers: &[(&'static str, &str)]) -> Request {
        let mut r = Request::new(method, target);
        for (k, v) in headers {
            r.headers.insert(*k, v.parse().unwrap());
        }
        r
    }

    fn loopback() -> Access {
        Access::new(IpAddr::V4(Ipv4Addr::LOCALHOST), &[], None)
    }

    #[test]
    fn host_names_lose_port_brackets_case_and_trailing_dot() {
        assert_eq!(host_name("LocalHost.:8787"), "localhost");
        assert_eq!(host_name("[::1]:80"), "::1");
        assert_eq!(host_name("127.0.0.1"), "127.0.0.1");
        assert_eq!(host_name("evil.example:1"), "evil.example");
    }

    #[test]
    fn only_local_names_and_own_addresses_are_answered() {
        let a = loopback();
        for ok in [
            "localhost:8787",
            "127.0.0.1:8787",
            "[::1]:8787",
            "app.localhost",
            "127.1.2.3",
        ] {
            assert!(a.check(&req("GET", "/", &[("host", ok)])).is_ok(), "{ok}");
        }
        for bad in [
            "evil.example",
            "evil.example:8787",
            "localhost.evil.example",
            "10.0.0.5:8787",
        ] {
            let e = a.check(&req("GET", "/", &[("host", bad)])).unwrap_err();
            assert_eq!(e.status(), 403, "{bad}");
        }
        assert!(a.check(&req("GET", "/", &[])).is_err(), "no Host");
        let named = Access::new(IpAddr::V4(Ipv4Addr::UNSPECIFIED), &["Lab-Box".into()], None);
        assert!(named.allows_host("lab-box"));
        assert!(named.allows_host("10.0.0.5"));
        assert!(!named.allows_host("evil.example"));
    }

    #[test]
    fn state_changes_need_this_pages_origin() {
        let a = loopback();
        let h = ("host", "127.0.0.1:8787");
        assert!(
            a.check(&req("POST", "/api/render", &[h])).is_ok(),
            "no Origin: a script"
        );
        assert!(
            a.check(&req(
                "POST",
                "/api/render",
                &[h, ("origin", "http://127.0.0.1:8787")]
            ))
            .is_ok()
        );
        for bad in [
            "http://evil.example",
            "null",
            "http://127.0.0.1:9999",
            "https://127.0.0.1:8787",
        ] {
            let e = a
                .check(&req("POST", "/api/upload", &[h, ("origin", bad)]))
                .unwrap_err();
            assert_eq!(e.status(), 403, "{bad}");
        }
        // A GET with another page's Origin (an <img> on another site) reads nothing: allowed
        // unless the browser says it is cross-site and asks for the API.
        assert!(
            a.check(&req("GET", "/", &[h, ("sec-fetch-site", "cross-site")]))
                .is_ok()
        );
        for site in ["cross-site", "same-site"] {
            let e = a
                .check(&req("GET", "/api/info", &[h, ("sec-fetch-site", site)]))
                .unwrap_err();
            assert_eq!(e.status(), 403, "{site}");
        }
        assert!(
            a.check(&req(
                "GET",
                "/api/info",
                &[h, ("sec-fetch-site", "same-origin")]
            ))
            .is_ok()
        );
    }

    #[test]
    fn the_api_is_the_same_path_for_the_guard_as_for_the_router() {
        let a = loopback();
        let h = ("host", "127.0.0.1:8787");
        for path in ["/api/info", "//api/info", "///api//info/", "/%2Fapi/info"] {
            let e = a
                .check(&req("GET", path, &[h, ("sec-fetch-site", "cross-site")]))
                .unwrap_err();
            assert_eq!(e.status(), 403, "{path}");
        }
    }

    #[test]
    fn a_token_is_asked_and_never_set_as_a_cookie() {
        let a = Access::new(
            IpAddr::V4(Ipv4Addr::UNSPECIFIED),
            &[],
            Some("abc123".into()),
        );
        let h = ("host", "10.0.0.5:8787");
        assert_eq!(a.check(&req("GET", "/", &[h])).unwrap_err().status(), 403);
        assert!(a.check(&req("GET", "/?token=abc124", &[h])).is_err());
        assert!(a.check(&req("GET", "/?token=abc123", &[h])).is_ok());
        assert!(a.check(&req("GET", "/api/info?token=abc123", &[h])).is_ok());
        let header = ("authorization", "token abc123");
        assert!(a.check(&req("GET", "/api/info", &[h, header])).is_ok());
        // A cookie is not a way in: a browser would send it to every port of the host.
        let cookie = ("cookie", "uwnr-token-8787=abc123; token=abc123");
        assert!(a.check(&req("GET", "/api/info", &[h, cookie])).is_err());
        // The page's own script and style load without it, only from allowed hosts.
        assert!(a.check(&req("GET", "/app.js", &[h])).is_ok());
        assert!(a.check(&req("GET", "//style.css", &[h])).is_ok());
        assert!(a.check(&req("GET", "/api/app.js", &[h])).is_err());
        assert!(
            a.check(&req("GET", "/app.js", &[("host", "evil.example")]))
                .is_err()
        );
        assert!(new_token().len() == 2 * TOKEN_BYTES && new_token() != new_token());
    }
}
