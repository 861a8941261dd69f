//! What the router tests share: [`skein_api::app`] over a coordinator stand-in, requests
//! as a client at a given address would send them, and their answers as JSON. Shared by
//! `core/api/tests/router.rs` and `tests/api_auth.rs`.
#![allow(dead_code)] // each test binary uses a different subset

use axum::body::Body;
use axum::extract::ConnectInfo;
use axum::http::{Method, Request, StatusCode};
use ractor::{Actor, ActorProcessingErr, ActorRef};
use skein_api::auth::{self, Auth, TokenConfig};
use skein_api::roles::Role;
use skein_swarm::CoordinatorMsg;
use std::net::SocketAddr;
use tokio::sync::broadcast;
use tower::ServiceExt;

/// A coordinator that drops every request: handlers that ask it answer 503 at once, so
/// what is under test is what the router does before (routing, auth, body parsing).
struct Mute;

impl Actor for Mute {
    type Msg = CoordinatorMsg;
    type State = ();
    type Arguments = ();
    async fn pre_start(
        &self,
        _: ActorRef<CoordinatorMsg>,
        _: (),
    ) -> Result<(), ActorProcessingErr> {
        Ok(())
    }
    async fn handle(
        &self,
        _: ActorRef<CoordinatorMsg>,
        _msg: CoordinatorMsg,
        _: &mut (),
    ) -> Result<(), ActorProcessingErr> {
        Ok(()) // the reply port is dropped: the caller learns at once
    }
}

/// A token of each role: (name, role, token).
pub const TOKENS: [(&str, Role, &str); 3] = [
    ("watch", Role::Viewer, "v1ewer-token-0123456789abcdef"),
    ("ops", Role::Operator, "0perator-token-0123456789abcdef"),
    ("root", Role::Admin, "adm1n-token-0123456789abcdef"),
];

/// [`TOKENS`], configured.
pub fn configured() -> Auth {
    let cfg: Vec<TokenConfig> = TOKENS
        .iter()
        .map(|(name, role, token)| TokenConfig {
            name: (*name).into(),
            role: *role,
            hash: auth::hash_token(token).unwrap(),
        })
        .collect();
    Auth::new(&cfg).unwrap()
}

/// The router with these tokens.
pub async fn router(auth: Auth) -> axum::Router {
    router_of(auth, None).await
}

/// The router, as a coordinator candidate's with `election`.
pub async fn router_of(
    auth: Auth,
    election: Option<tokio::sync::watch::Receiver<skein_swarm::election::ElectionStatus>>,
) -> axum::Router {
    let (coordinator, _) = Actor::spawn(None, Mute, ()).await.unwrap();
    let (events, _) = broadcast::channel(4);
    let state = skein_api::ApiState::new(coordinator, skein_swarm::SwarmReads::idle(), events)
        .with_auth(auth);
    skein_api::app(match election {
        Some(e) => state.with_election(e),
        None => state,
    })
}

/// A route of the contract with its parameters filled in as a `skein up --sim 3` has
/// them.
pub fn concrete(path: &str) -> String {
    path.replace("{id}", "uav-1")
        .replace("{name}", "MPC_XY_VEL_MAX")
        .replace("{slot}", "cam")
}

/// `method path` from `ip`, with `token`; a body of `{}` but for GET.
pub fn request(method: &str, path: &str, token: Option<&str>, ip: [u8; 4]) -> Request<Body> {
    let body = if method == "GET" { None } else { Some("{}") };
    request_with(method, path, token, ip, body)
}

/// `method path` from `ip`, with `token` and `body` (JSON).
pub fn request_with(
    method: &str,
    path: &str,
    token: Option<&str>,
    ip: [u8; 4],
    body: Option<&str>,
) -> Request<Body> {
    let mut b = Request::builder()
        .method(Method::from_bytes(method.as_bytes()).unwrap())
        .uri(path)
        .header("content-type", "application/json");
    if let Some(t) = token {
        b = b.header("authorization", format!("Bearer {t}"));
    }
    let body = body.map_or_else(Body::empty, |b| Body::from(b.to_string()));
    let mut req = b.body(body).unwrap();
    req.extensions_mut()
        .insert(ConnectInfo(SocketAddr::from((ip, 40000))));
    req
}

/// The answer to `req`: status and body as JSON (null when it is not JSON).
pub async fn call(app: &axum::Router, req: Request<Body>) -> (StatusCode, serde_json::Value) {
    let res = app.clone().oneshot(req).await.unwrap();
    let status = res.status();
    let bytes = axum::body::to_bytes(res.into_body(), 1 << 20)
        .await
        .unwrap();
    let json = serde_json::from_slice(&bytes).unwrap_or(serde_json::Value::Null);
    (status, json)
}
