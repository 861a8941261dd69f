//! Bearer-token authentication with roles.
//!
//! A token is 32 random bytes from the OS, written as 64 hex digits. The configuration
//! holds only a salted digest of it, `sha256$<salt hex>$<digest hex>` with
//! digest = SHA-256(salt ‖ token) and a random 16-byte salt per token. A slow password
//! hash (argon2) would add nothing: the token has 256 bits of entropy, nothing to
//! brute-force, and every request is checked: argon2 with its default parameters took
//! 35 ms per verification here (per request and configured token, on a companion's CPU
//! a denial of service of its own). Build cost is no argument either way: sha2 + subtle
//! build in 4.4 s from clean, argon2 in 5.6 s (2 jobs). Digests are compared in constant
//! time (`subtle`).
//!
//! Every route has one [`Access`]: the role router it is registered in
//! ([`crate::openapi::routes`]), whose gate ([`require`], one `route_layer` per role)
//! checks it. The contract states it on each operation (`x-skein-role`), and
//! [`crate::openapi::route_access`] reads the table back from there. Any other `/api/…` path needs a viewer token (and answers 404);
//! a handler cannot be routed without a role. Without tokens configured
//! ([`Auth::disabled`]) everything is allowed, as before; the binary refuses that on a
//! non-loopback address unless told `--insecure-no-auth`.
//!
//! Failed attempts are counted per client IP: after [`MAX_FAILURES`] within
//! [`FAILURE_WINDOW`], that IP is answered 429 for [`LOCKOUT`].

use crate::ApiState;
use crate::roles::{Access, Role};
use axum::Json;
use axum::extract::{ConnectInfo, Request, State};
use axum::http::{HeaderValue, Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use rand::TryRngCore;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};
use subtle::ConstantTimeEq;
use utoipa::ToSchema;

/// The gate of one role's routes: the API's state and the access they need.
#[derive(Clone)]
pub struct Gate {
    state: ApiState,
    access: Access,
}

impl Gate {
    /// A gate letting through what `access` allows.
    pub fn new(state: ApiState, access: Access) -> Self {
        Gate { state, access }
    }
}

/// Failed attempts from one IP before it is locked out.
pub const MAX_FAILURES: u32 = 10;
/// The window the failures are counted in.
pub const FAILURE_WINDOW: Duration = Duration::from_secs(60);
/// How long a locked-out IP is answered 429.
pub const LOCKOUT: Duration = Duration::from_secs(60);
/// Client IPs remembered at most (older entries are pruned first).
const MAX_TRACKED: usize = 4096;

/// A token as configured: a name for humans, its role and the salted digest.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TokenConfig {
    /// Who holds it (shown by `whoami` and in the dashboard).
    pub name: String,
    /// What it may do.
    pub role: Role,
    /// `sha256$<salt hex>$<digest hex>`, from `skein token create`.
    pub hash: String,
}

struct Token {
    name: String,
    role: Role,
    salt: Vec<u8>,
    digest: [u8; 32],
}

#[derive(Default)]
struct Attempts {
    failures: u32,
    since: Option<Instant>,
    locked_until: Option<Instant>,
}

/// The tokens and the failed-attempt counters.
pub struct Auth {
    tokens: Vec<Token>,
    attempts: Mutex<HashMap<IpAddr, Attempts>>,
}

/// Who made a request (an extension of authenticated requests).
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct Identity {
    /// Whether tokens are required at all.
    pub auth: bool,
    /// The token's name (none without auth).
    pub name: Option<String>,
    /// The token's role (admin without auth).
    pub role: Role,
}

impl Auth {
    /// No tokens: every request allowed.
    pub fn disabled() -> Self {
        Auth {
            tokens: Vec::new(),
            attempts: Mutex::default(),
        }
    }

    /// These tokens (none: [`Auth::disabled`]).
    ///
    /// # Errors
    /// A malformed hash or a duplicate name, naming the token.
    pub fn new(tokens: &[TokenConfig]) -> Result<Self, String> {
        let mut out: Vec<Token> = Vec::new();
        for t in tokens {
            if out.iter().any(|o| o.name == t.name) {
                return Err(format!(
                    "[[http.tokens]]: the name `{}` is used twice",
                    t.name
                ));
            }
            let (salt, digest) = parse_hash(&t.hash)
                .ok_or_else(|| format!("[[http.tokens]] `{}`: hash is not `sha256$<salt hex>$<64 hex digits>` (make one with `skein token create`)", t.name))?;
            out.push(Token {
                name: t.name.clone(),
                role: t.role,
                salt,
                digest,
            });
        }
        Ok(Auth {
            tokens: out,
            attempts: Mutex::default(),
        })
    }

    /// Whether tokens are required.
    pub fn enabled(&self) -> bool {
        !self.tokens.is_empty()
    }

    /// The token's holder, checking every configured token in constant time each.
    fn check(&self, presented: &str) -> Option<&Token> {
        let mut found = None;
        for t in &self.tokens {
            if bool::from(digest(&t.salt, presented).ct_eq(&t.digest)) && found.is_none() {
                found = Some(t);
            }
        }
        found
    }

    /// Time left of the IP's lockout, if locked out.
    fn locked(&self, ip: IpAddr, now: Instant) -> Option<Duration> {
        let map = self.attempts.lock().unwrap_or_else(PoisonError::into_inner);
        let until = map.get(&ip)?.locked_until?;
        (until > now).then(|| until - now)
    }

    fn fail(&self, ip: IpAddr, now: Instant) {
        let mut map = self.attempts.lock().unwrap_or_else(PoisonError::into_inner);
        if map.len() >= MAX_TRACKED && !map.contains_key(&ip) {
            map.retain(|_, a| {
                a.locked_until.is_some_and(|u| u > now)
                    || a.since.is_some_and(|s| now - s < FAILURE_WINDOW)
            });
            if map.len() >= MAX_TRACKED {
                map.clear();
            }
        }
        let a = map.entry(ip).or_default();
        if a.since.is_none_or(|s| now - s >= FAILURE_WINDOW) {
            a.since = Some(now);
            a.failures = 0;
        }
        a.failures += 1;
        if a.failures >= MAX_FAILURES {
            tracing::warn!(
                "api auth: {MAX_FAILURES} failed attempts from {ip}: locked out for {} s",
                LOCKOUT.as_secs()
            );
            a.locked_until = Some(now + LOCKOUT);
            a.failures = 0;
            a.since = None;
        }
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn unhex(s: &str) -> Option<Vec<u8>> {
    if !s.len().is_multiple_of(2) || !s.is_ascii() {
        return None;
    }
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).ok())
        .collect()
}

fn digest(salt: &[u8], token: &str) -> [u8; 32] {
    let mut h = Sha256::new();
    h.update(salt);
    h.update(token.as_bytes());
    h.finalize().into()
}

fn parse_hash(s: &str) -> Option<(Vec<u8>, [u8; 32])> {
    let mut parts = s.split('$');
    if parts.next()? != "sha256" {
        return None;
    }
    let salt = unhex(parts.next()?)?;
    let d: [u8; 32] = unhex(parts.next()?)?.try_into().ok()?;
    if parts.next().is_some() || salt.len() < 8 {
        return None;
    }
    Some((salt, d))
}

fn os_random<const N: usize>() -> Result<[u8; N], String> {
    let mut b = [0u8; N];
    rand::rngs::OsRng
        .try_fill_bytes(&mut b)
        .map_err(|e| format!("the OS random number generator failed: {e}"))?;
    Ok(b)
}

/// A new token: 32 random bytes from the OS as 64 hex digits.
///
/// # Errors
/// The OS random number generator failed.
pub fn new_token() -> Result<String, String> {
    Ok(hex(&os_random::<32>()?))
}

/// The salted digest of `token` to put in the configuration (a new random salt each call).
///
/// # Errors
/// The OS random number generator failed.
pub fn hash_token(token: &str) -> Result<String, String> {
    let salt = os_random::<16>()?;
    Ok(format!(
        "sha256${}${}",
        hex(&salt),
        hex(&digest(&salt, token))
    ))
}

/// Whether `token` matches `hash` (constant-time comparison of the digests).
pub fn verify(token: &str, hash: &str) -> bool {
    parse_hash(hash).is_some_and(|(salt, d)| bool::from(digest(&salt, token).ct_eq(&d)))
}

fn auth_error(status: StatusCode, error: String, required_role: Option<Role>) -> Response {
    let body = crate::responses::ErrorBody {
        error,
        field: Some("authorization".into()),
        required_role: required_role.map(|r| r.as_str().to_string()),
    };
    let mut r = (status, Json(body)).into_response();
    if status == StatusCode::UNAUTHORIZED {
        r.headers_mut().insert(
            header::WWW_AUTHENTICATE,
            HeaderValue::from_static("Bearer realm=\"skein\""),
        );
    }
    r
}

/// The token of a request: `Authorization: Bearer <token>`, or for a `GET` the `token`
/// query parameter (browsers cannot set headers on a WebSocket or an `<img>`).
fn presented(req: &Request) -> Option<String> {
    if let Some(v) = req.headers().get(header::AUTHORIZATION) {
        let v = v.to_str().ok()?;
        let (scheme, token) = v.split_once(' ')?;
        return scheme
            .eq_ignore_ascii_case("bearer")
            .then(|| token.trim().to_string());
    }
    if req.method() != Method::GET {
        return None;
    }
    req.uri().query()?.split('&').find_map(|kv| {
        let (k, v) = kv.split_once('=')?;
        (k == "token").then(|| v.to_string())
    })
}

/// The middleware of one role's routes ([`Gate`]): authenticates and authorises every
/// request they get (see the module).
pub async fn require(State(gate): State<Gate>, mut req: Request, next: Next) -> Response {
    let auth = gate.state.auth.clone();
    if !auth.enabled() {
        req.extensions_mut().insert(Identity {
            auth: false,
            name: None,
            role: Role::Admin,
        });
        return next.run(req).await;
    }
    let needed = match gate.access {
        Access::Public => return next.run(req).await,
        Access::Role(r) => r,
    };
    let ip = req
        .extensions()
        .get::<ConnectInfo<SocketAddr>>()
        .map_or(IpAddr::V4(Ipv4Addr::UNSPECIFIED), |c| c.0.ip());
    let now = Instant::now();
    if let Some(left) = auth.locked(ip, now) {
        let mut r = auth_error(
            StatusCode::TOO_MANY_REQUESTS,
            format!(
                "too many failed authentication attempts from {ip}: retry in {} s",
                left.as_secs() + 1
            ),
            None,
        );
        if let Ok(v) = HeaderValue::from_str(&(left.as_secs() + 1).to_string()) {
            r.headers_mut().insert(header::RETRY_AFTER, v);
        }
        return r;
    }
    let Some(token) = presented(&req) else {
        return auth_error(
            StatusCode::UNAUTHORIZED,
            "authentication required: send `Authorization: Bearer <token>`".into(),
            None,
        );
    };
    let Some(t) = auth.check(&token) else {
        auth.fail(ip, now);
        return auth_error(StatusCode::UNAUTHORIZED, "invalid token".into(), None);
    };
    if t.role < needed {
        return auth_error(
            StatusCode::FORBIDDEN,
            format!(
                "this needs the {needed} role; the token `{}` is {}",
                t.name, t.role
            ),
            Some(needed),
        );
    }
    req.extensions_mut().insert(Identity {
        auth: true,
        name: Some(t.name.clone()),
        role: t.role,
    });
    next.run(req).await
}

/// The caller's token: name and role
#[utoipa::path(get, path = "/api/v1/auth/whoami",
    responses((status = 200, body = Identity)))]
pub(crate) async fn whoami(identity: Option<axum::Extension<Identity>>) -> Response {
    match identity {
        Some(axum::Extension(i)) => Json(i).into_response(),
        None => Json(Identity {
            auth: false,
            name: None,
            role: Role::Admin,
        })
        .into_response(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_created_token_verifies_and_a_wrong_one_does_not() {
        let t = new_token().unwrap();
        assert_eq!(t.len(), 64);
        let h = hash_token(&t).unwrap();
        assert!(verify(&t, &h));
        assert!(!verify(&new_token().unwrap(), &h));
        assert!(!verify("", &h));
        assert!(!verify(&t, "sha256$00$00"));
    }

    #[test]
    fn every_hash_has_its_own_salt() {
        let t = new_token().unwrap();
        let (a, b) = (hash_token(&t).unwrap(), hash_token(&t).unwrap());
        assert_ne!(a, b);
        assert_ne!(a.split('$').nth(1), b.split('$').nth(1));
        assert!(verify(&t, &a) && verify(&t, &b));
        assert_ne!(new_token().unwrap(), t);
    }

    #[test]
    fn malformed_hashes_and_duplicate_names_are_refused() {
        let ok = hash_token("x").unwrap();
        let tc = |name: &str, hash: &str| TokenConfig {
            name: name.into(),
            role: Role::Viewer,
            hash: hash.into(),
        };
        assert!(Auth::new(&[tc("a", "plain")]).is_err());
        assert!(Auth::new(&[tc("a", &ok), tc("a", &ok)]).is_err());
        assert!(Auth::new(&[tc("a", &ok)]).unwrap().enabled());
        assert!(!Auth::new(&[]).unwrap().enabled());
    }
}
