//! The web face of skein: the v1 HTTP API, the WebSocket stream and the embedded
//! dashboard.
//!
//! [`app`] builds the axum router (tests call it without a socket); [`serve`] runs it on a
//! listener. Handlers reach the swarm only by messages to the coordinator (`call` with a
//! timeout). Errors are JSON, `{"error": "...", "field": "..."}`, with a 4xx status naming
//! the problem (see [`error::ApiError`]). With tokens configured every route but health
//! needs `Authorization: Bearer <token>` with a role (see [`auth::ROUTES`]).
//!
//! Routes (all JSON):
//! - `GET /api/v1/health`, `GET /api/v1/openapi.json` (the contract, OpenAPI 3.1, see
//!   [`openapi`]): the routes that never need a token
//! - `GET /api/v1/auth/whoami`: `{"auth", "name", "role"}` of the caller's token
//! - `GET /api/v1/vehicles`, `GET /api/v1/vehicles/{id}`
//! - `POST /api/v1/vehicles/{id}/commands`, `POST /api/v1/swarm/commands`: `202` with
//!   `{"command_id", "accepted", "refused"}`; the outcome follows on the stream
//! - `GET /api/v1/vehicles/{id}/params`, `GET` / `PUT /api/v1/vehicles/{id}/params/{name}`:
//!   PX4 parameters through the vehicle's link (`{"name", "value", "type"}`)
//! - `GET` / `PUT /api/v1/formation`
//! - `DELETE /api/v1/formation`: stop flying the formation (vehicles hold)
//! - `POST /api/v1/formation/leader/{goto,waypoints,orbit,hold}`: move the formation's
//!   reference point; `GET /api/v1/formation/shapes`
//! - `GET /api/v1/vehicles/{id}/payloads`, `POST /api/v1/vehicles/{id}/payloads/{slot}`
//!   (the payload's JSON command), `POST …/payloads` and `DELETE …/payloads/{slot}`
//!   (attach and detach at run time, see [`payloads`]), `GET …/payloads/{slot}/snapshot` (JPEG),
//!   `GET …/payloads/{slot}/stream` (MJPEG)
//! - `GET /api/v1/plugins`, `POST /api/v1/plugins/{load,unload,reload}`: payload plugin
//!   libraries at run time (see [`plugins`])
//! - `GET /api/v1/supervision`: the actor tree with status, restarts, last failures
//! - `POST /api/v1/faults`: `{"target": "<actor path>", "kind": "panic" | "hang" |
//!   "stop" | "error"}`, only with `--enable-fault-injection` (403 otherwise)
//! - `GET /metrics`: Prometheus (OpenMetrics text)
//! - `GET /api/v1/links`: per-endpoint MAVLink counters (malformed input)
//! - `GET /api/v1/geofence`: the geofence every setpoint is clamped into (for the plan view)
//! - `GET /api/v1/tracks`, `GET /api/v1/sim/truth`: counter-UAS tracks and the embedded
//!   simulator's ground truth (see [`tracks`])
//! - `GET /api/v1/stream`: WebSocket, `{"type": "vehicles", "vehicles": [...]}` at
//!   [`TELEMETRY_HZ`] plus every [`skein_swarm::SwarmEvent`]
//! - `/`: the dashboard (`web-ui/`, embedded at build time)
#![warn(missing_docs)]

pub mod auth;
pub mod election;
pub mod error;
pub mod openapi;
pub mod payloads;
pub mod plugins;
pub mod px4_params;
pub mod recording;
pub mod replay_server;
pub mod requests;
pub mod responses;
pub mod server;
mod static_files;
mod stream;
pub mod tls;
pub mod tracks;
mod video;

pub use server::ApiServer;

use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use error::ApiError;
use ractor::ActorRef;
use skein_swarm::{CommandOutcome, CoordinatorMsg, SwarmEvent, VehicleCommand};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::broadcast;

/// Rate of the `vehicles` frames on the stream, Hz.
pub const TELEMETRY_HZ: f64 = 10.0;
/// How long a handler waits for the coordinator.
pub const COORDINATOR_TIMEOUT: Duration = Duration::from_secs(5);

/// What the handlers share.
#[derive(Clone)]
pub struct ApiState {
    coordinator: ActorRef<CoordinatorMsg>,
    events: broadcast::Sender<SwarmEvent>,
    telemetry: broadcast::Sender<Arc<str>>,
    plugins: Option<Arc<plugins::PluginsApi>>,
    geofence: Option<Arc<skein_model::safety::Geofence>>,
    auth: Arc<auth::Auth>,
    tls: Option<Arc<rustls::ServerConfig>>,
    recorder: Option<Arc<skein_record::Recorder>>,
    election: Option<tokio::sync::watch::Receiver<skein_swarm::election::ElectionStatus>>,
}

impl ApiState {
    /// State for a running swarm. Starts the task that publishes the `vehicles` frames of
    /// the stream (it ends when the coordinator stops).
    pub fn new(
        coordinator: ActorRef<CoordinatorMsg>,
        events: broadcast::Sender<SwarmEvent>,
    ) -> Self {
        let (telemetry, _) = broadcast::channel(16);
        tokio::spawn(stream::publish_telemetry(
            coordinator.clone(),
            telemetry.clone(),
        ));
        ApiState {
            coordinator,
            events,
            telemetry,
            plugins: None,
            geofence: None,
            auth: Arc::new(auth::Auth::disabled()),
            tls: None,
            recorder: None,
            election: None,
        }
    }

    /// Serves HTTPS with this configuration (see [`tls::server_config`]) in [`ApiServer`].
    pub fn with_tls(mut self, config: Arc<rustls::ServerConfig>) -> Self {
        self.tls = Some(config);
        self
    }

    /// Serves `/api/v1/recording` with this recorder (without it those answer 503), and
    /// records the commands the API accepts while it records.
    pub fn with_recorder(mut self, recorder: Arc<skein_record::Recorder>) -> Self {
        self.recorder = Some(recorder);
        self
    }

    /// Makes this API a coordinator candidate's ([`election`]): `GET /api/v1/coordinator`
    /// answers from `status`, and writes are refused (409) while it is a standby.
    pub fn with_election(
        mut self,
        status: tokio::sync::watch::Receiver<skein_swarm::election::ElectionStatus>,
    ) -> Self {
        self.election = Some(status);
        self
    }

    /// Requires these tokens (see [`auth`]; without this call every request is allowed).
    pub fn with_auth(mut self, auth: auth::Auth) -> Self {
        self.auth = Arc::new(auth);
        self
    }

    /// Serves `GET /api/v1/geofence` (without it that answers 404).
    pub fn with_geofence(mut self, fence: skein_model::safety::Geofence) -> Self {
        self.geofence = Some(Arc::new(fence));
        self
    }

    /// Serves `/api/v1/plugins` from `manager` (without it the listing shows only the
    /// built-in payloads and load / unload / reload answer 503). `refused` are the files
    /// the start-up scan refused, with the reason.
    pub fn with_plugins(
        mut self,
        manager: skein_plugin_host::PluginManager,
        refused: Vec<(std::path::PathBuf, String)>,
    ) -> Self {
        self.plugins = Some(plugins::PluginsApi::new(manager, refused));
        self
    }

    /// Keeps an accepted command in the running recording, if any.
    fn record_command(&self, command_id: u64, target: &str, body: &[u8]) {
        if let Some(r) = &self.recorder {
            let request = serde_json::from_slice(body).unwrap_or(serde_json::Value::Null);
            r.record_command(Some(command_id), target, &request);
        }
    }

    async fn ask<T: Send + 'static>(
        &self,
        msg: impl FnOnce(ractor::RpcReplyPort<T>) -> CoordinatorMsg,
    ) -> Result<T, ApiError> {
        match self.coordinator.call(msg, Some(COORDINATOR_TIMEOUT)).await {
            Ok(ractor::rpc::CallResult::Success(v)) => Ok(v),
            Ok(_) => Err(ApiError::unavailable(
                "the coordinator did not answer in time",
            )),
            Err(e) => Err(ApiError::unavailable(format!(
                "the coordinator is not running: {e}"
            ))),
        }
    }
}

/// The router (no socket: tests call it directly).
pub fn app(state: ApiState) -> Router {
    Router::new()
        .route("/api/v1/health", get(health))
        .route("/api/v1/openapi.json", get(openapi::serve))
        .route("/api/v1/auth/whoami", get(auth::whoami))
        .route("/api/v1/vehicles", get(list_vehicles))
        .route("/api/v1/vehicles/{id}", get(get_vehicle))
        .route("/api/v1/vehicles/{id}/commands", post(vehicle_command))
        .route("/api/v1/vehicles/{id}/params", get(px4_params::list_params))
        .route(
            "/api/v1/vehicles/{id}/params/{name}",
            get(px4_params::get_param).put(px4_params::put_param),
        )
        .route("/api/v1/swarm/commands", post(swarm_command))
        .route(
            "/api/v1/formation",
            get(get_formation)
                .put(put_formation)
                .delete(delete_formation),
        )
        .route("/api/v1/formation/leader/{command}", post(leader_command))
        .route("/api/v1/formation/shapes", get(shapes))
        .route(
            "/api/v1/vehicles/{id}/payloads",
            get(payloads::list_payloads).post(payloads::attach_payload),
        )
        .route(
            "/api/v1/vehicles/{id}/payloads/{slot}",
            post(payloads::payload_command).delete(payloads::detach_payload),
        )
        .route(
            "/api/v1/vehicles/{id}/payloads/{slot}/snapshot",
            get(video::payload_snapshot),
        )
        .route(
            "/api/v1/vehicles/{id}/payloads/{slot}/stream",
            get(video::payload_stream),
        )
        .route("/api/v1/plugins", get(list_plugins))
        .route("/api/v1/plugins/{op}", post(plugin_op))
        .route("/api/v1/supervision", get(supervision_tree))
        .route("/api/v1/faults", post(inject_fault))
        .route("/metrics", get(metrics))
        .route("/api/v1/links", get(links))
        .route("/api/v1/geofence", get(geofence))
        .route("/api/v1/stream", get(stream::stream))
        .route("/api/v1/tracks", get(tracks::list_tracks))
        .route(
            "/api/v1/tracks/{id}/observe",
            post(tracks::observe).delete(tracks::stop_observing),
        )
        .route("/api/v1/sim/truth", get(tracks::sim_truth))
        .route("/api/v1/recording", get(recording::status))
        .route("/api/v1/recording/start", post(recording::start))
        .route("/api/v1/recording/stop", post(recording::stop))
        .route("/api/v1/coordinator", get(election::status))
        .route("/api/{*rest}", axum::routing::any(api_not_found))
        // A standby coordinator refuses writes (inside auth: 401/403 come first).
        .route_layer(axum::middleware::from_fn_with_state(
            state.clone(),
            election::standby_refuses_writes,
        ))
        // Every route above (not the dashboard's static files below) goes through auth.
        .route_layer(axum::middleware::from_fn_with_state(
            state.clone(),
            auth::require,
        ))
        .fallback(get(static_files::static_file))
        .with_state(state)
}

/// Serves [`app`] on `listener` until `shutdown` resolves.
///
/// # Errors
/// The server's I/O error.
pub async fn serve(
    listener: tokio::net::TcpListener,
    state: ApiState,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    axum::serve(
        listener,
        app(state).into_make_service_with_connect_info::<std::net::SocketAddr>(),
    )
    .with_graceful_shutdown(shutdown)
    .await
}

async fn health(State(s): State<ApiState>) -> Result<Response, ApiError> {
    let mut h = s.ask(CoordinatorMsg::Health).await?;
    h.coordinator_role = s.election.as_ref().map(|e| e.borrow().role);
    Ok(Json(h).into_response())
}

async fn list_vehicles(State(s): State<ApiState>) -> Result<Response, ApiError> {
    let v = s.ask(CoordinatorMsg::ListVehicles).await?;
    Ok(Json(v).into_response())
}

async fn get_vehicle(
    State(s): State<ApiState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let id2 = id.clone();
    match s.ask(move |r| CoordinatorMsg::GetVehicle(id2, r)).await? {
        Some(v) => Ok(Json(v).into_response()),
        None => Err(ApiError::not_found(format!("no vehicle `{id}`"))),
    }
}

fn accepted(outcome: CommandOutcome) -> Response {
    (StatusCode::ACCEPTED, Json(outcome)).into_response()
}

async fn vehicle_command(
    State(s): State<ApiState>,
    Path(id): Path<String>,
    body: Bytes,
) -> Result<Response, ApiError> {
    let cmd = match requests::commands::vehicle_command(&body)? {
        requests::Command::Vehicle(cmd) => cmd,
        requests::Command::ClearHazard => {
            let id2 = id.clone();
            return match s.ask(move |r| CoordinatorMsg::ClearHazard(id2, r)).await? {
                Ok(()) => Ok(Json(responses::Cleared { cleared: id }).into_response()),
                Err(None) => Err(ApiError::not_found(format!("no vehicle `{id}`"))),
                Err(Some(reason)) => Err(ApiError::conflict(reason, Some("command"))),
            };
        }
    };
    let id2 = id.clone();
    match s
        .ask(move |r| CoordinatorMsg::VehicleCommand(id2, cmd, r))
        .await?
    {
        Ok(outcome) => {
            s.record_command(outcome.command_id, &id, &body);
            Ok(accepted(outcome))
        }
        Err(None) => Err(ApiError::not_found(format!("no vehicle `{id}`"))),
        Err(Some(reason)) => Err(ApiError::conflict(reason, Some("command"))),
    }
}

async fn swarm_command(State(s): State<ApiState>, body: Bytes) -> Result<Response, ApiError> {
    let cmd: VehicleCommand = requests::commands::swarm_command(&body)?;
    let outcome = s.ask(move |r| CoordinatorMsg::SwarmCommand(cmd, r)).await?;
    if outcome.accepted.is_empty() {
        let error = if outcome.refused.is_empty() {
            "no vehicles in the swarm".to_string()
        } else {
            outcome
                .refused
                .iter()
                .map(|r| format!("{}: {}", r.id, r.reason))
                .collect::<Vec<_>>()
                .join("; ")
        };
        return Err(ApiError::conflict(error, Some("command")));
    }
    s.record_command(outcome.command_id, "swarm", &body);
    Ok(accepted(outcome))
}

async fn get_formation(State(s): State<ApiState>) -> Result<Response, ApiError> {
    let f = s.ask(CoordinatorMsg::GetFormation).await?;
    Ok(Json(f).into_response())
}

async fn put_formation(State(s): State<ApiState>, body: Bytes) -> Result<Response, ApiError> {
    let spec = requests::formation::formation(&body)?;
    match s
        .ask(move |r| CoordinatorMsg::SetFormation(spec, r))
        .await?
    {
        Ok(status) => Ok(Json(status).into_response()),
        Err(e) => Err(ApiError::field(&e.field, e.error)),
    }
}

async fn leader_command(
    State(s): State<ApiState>,
    Path(command): Path<String>,
    body: Bytes,
) -> Result<Response, ApiError> {
    let motion = requests::leader::leader_motion(&command, &body)?;
    match s
        .ask(move |r| CoordinatorMsg::LeaderMotion(motion, r))
        .await?
    {
        Ok(status) => Ok(Json(status).into_response()),
        Err(e) if e.field == "formation" => Err(ApiError::conflict(e.error, Some("formation"))),
        Err(e) => Err(ApiError::field(&e.field, e.error)),
    }
}

async fn shapes() -> Response {
    use skein_model::formation::Shape;
    let list: Vec<responses::ShapeInfo> = Shape::ALL
        .iter()
        .map(|s| responses::ShapeInfo {
            shape: *s,
            min_vehicles: s.min_vehicles(),
        })
        .collect();
    Json(list).into_response()
}

async fn delete_formation(State(s): State<ApiState>) -> Result<Response, ApiError> {
    let f = s.ask(CoordinatorMsg::ClearFormation).await?;
    Ok(Json(f).into_response())
}

async fn list_plugins(State(s): State<ApiState>) -> Response {
    Json(plugins::list(s.plugins.as_deref())).into_response()
}

async fn plugin_op(
    State(s): State<ApiState>,
    Path(op): Path<String>,
    body: Bytes,
) -> Result<Response, ApiError> {
    let v = match op.as_str() {
        "load" => plugins::load(s.plugins.clone(), &body).await?,
        "unload" => plugins::unload(s.plugins.clone(), &body).await?,
        "reload" => plugins::reload(s.plugins.clone(), &body).await?,
        other => {
            return Err(ApiError::not_found(format!(
                "no such endpoint: /api/v1/plugins/{other} (load, unload, reload)"
            )));
        }
    };
    Ok(Json(v).into_response())
}

async fn supervision_tree(State(s): State<ApiState>) -> Result<Response, ApiError> {
    let t = s.ask(CoordinatorMsg::GetSupervision).await?;
    Ok(Json(t).into_response())
}

async fn metrics(State(s): State<ApiState>) -> Result<Response, ApiError> {
    let text = s.ask(CoordinatorMsg::RenderMetrics).await?;
    Ok((
        [(
            header::CONTENT_TYPE,
            "application/openmetrics-text; version=1.0.0; charset=utf-8",
        )],
        text,
    )
        .into_response())
}

async fn inject_fault(State(s): State<ApiState>, body: Bytes) -> Result<Response, ApiError> {
    let (target, kind) = requests::faults::fault(&body)?;
    let t = target.clone();
    match s
        .ask(move |r| CoordinatorMsg::InjectFault(t, kind, r))
        .await?
    {
        Ok(()) => Ok((
            StatusCode::ACCEPTED,
            Json(responses::FaultInjected { target, kind }),
        )
            .into_response()),
        Err(skein_swarm::FaultError::Disabled) => Err(ApiError {
            status: StatusCode::FORBIDDEN,
            error: "fault injection is disabled: start skein with --enable-fault-injection".into(),
            field: None,
        }),
        Err(skein_swarm::FaultError::UnknownTarget(why)) => Err(ApiError {
            status: StatusCode::NOT_FOUND,
            error: why,
            field: Some("target".into()),
        }),
        Err(skein_swarm::FaultError::Unreachable(why)) => Err(ApiError::unavailable(why)),
    }
}

async fn links(State(s): State<ApiState>) -> Result<Response, ApiError> {
    let l = s.ask(CoordinatorMsg::LinkStats).await?;
    Ok(Json(l).into_response())
}

async fn geofence(State(s): State<ApiState>) -> Result<Response, ApiError> {
    match &s.geofence {
        Some(f) => Ok(Json(f.as_ref()).into_response()),
        None => Err(ApiError::not_found("no geofence configured for this API")),
    }
}

async fn api_not_found(uri: axum::http::Uri) -> ApiError {
    ApiError::not_found(format!("no such endpoint: {}", uri.path()))
}
