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
pub mod error;
pub mod openapi;
pub mod params;
pub mod payloads;
pub mod plugins;
pub mod recording;
pub mod replay;
pub mod requests;
pub mod responses;
pub mod server;
pub mod tls;
pub mod tracks;

pub use server::ApiServer;

use axum::body::Bytes;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Path, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use error::ApiError;
use include_dir::{Dir, include_dir};
use ractor::ActorRef;
use skein_swarm::{CommandOutcome, CoordinatorMsg, SwarmEvent, VehicleCommand};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::broadcast;

/// The dashboard, embedded from `web-ui/`.
static WEB_UI: Dir<'static> = include_dir!("$CARGO_MANIFEST_DIR/../../web-ui");

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
}

impl ApiState {
    /// State for a running swarm. Starts the task that publishes the `vehicles` frames of
    /// the stream (it ends when the coordinator stops).
    pub fn new(
        coordinator: ActorRef<CoordinatorMsg>,
        events: broadcast::Sender<SwarmEvent>,
    ) -> Self {
        let (telemetry, _) = broadcast::channel(16);
        tokio::spawn(publish_telemetry(coordinator.clone(), telemetry.clone()));
        ApiState {
            coordinator,
            events,
            telemetry,
            plugins: None,
            geofence: None,
            auth: Arc::new(auth::Auth::disabled()),
            tls: None,
            recorder: None,
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

async fn publish_telemetry(coordinator: ActorRef<CoordinatorMsg>, tx: broadcast::Sender<Arc<str>>) {
    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / TELEMETRY_HZ));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    loop {
        tick.tick().await;
        if tx.receiver_count() == 0 {
            if coordinator.get_status() == ractor::ActorStatus::Stopped {
                return;
            }
            continue;
        }
        let Ok(ractor::rpc::CallResult::Success(list)) = coordinator
            .call(CoordinatorMsg::ListVehicles, Some(COORDINATOR_TIMEOUT))
            .await
        else {
            if coordinator.get_status() == ractor::ActorStatus::Stopped {
                return;
            }
            continue;
        };
        let frame = serde_json::json!({"type": "vehicles", "vehicles": list});
        let _ = tx.send(Arc::from(frame.to_string()));
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
        .route("/api/v1/vehicles/{id}/params", get(params::list_params))
        .route(
            "/api/v1/vehicles/{id}/params/{name}",
            get(params::get_param).put(params::put_param),
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
            get(list_payloads).post(attach_payload),
        )
        .route(
            "/api/v1/vehicles/{id}/payloads/{slot}",
            post(payload_command).delete(detach_payload),
        )
        .route(
            "/api/v1/vehicles/{id}/payloads/{slot}/snapshot",
            get(payload_snapshot),
        )
        .route(
            "/api/v1/vehicles/{id}/payloads/{slot}/stream",
            get(payload_stream),
        )
        .route("/api/v1/plugins", get(list_plugins))
        .route("/api/v1/plugins/{op}", post(plugin_op))
        .route("/api/v1/supervision", get(supervision_tree))
        .route("/api/v1/faults", post(inject_fault))
        .route("/metrics", get(metrics))
        .route("/api/v1/links", get(links))
        .route("/api/v1/geofence", get(geofence))
        .route("/api/v1/stream", get(stream))
        .route("/api/v1/tracks", get(tracks::list_tracks))
        .route(
            "/api/v1/tracks/{id}/observe",
            post(tracks::observe).delete(tracks::stop_observing),
        )
        .route("/api/v1/sim/truth", get(tracks::sim_truth))
        .route("/api/v1/recording", get(recording::status))
        .route("/api/v1/recording/start", post(recording::start))
        .route("/api/v1/recording/stop", post(recording::stop))
        .route("/api/{*rest}", axum::routing::any(api_not_found))
        // Every route above (not the dashboard's static files below) goes through auth.
        .route_layer(axum::middleware::from_fn_with_state(
            state.clone(),
            auth::require,
        ))
        .fallback(get(static_file))
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
    let h = s.ask(CoordinatorMsg::Health).await?;
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

async fn list_payloads(
    State(s): State<ApiState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let id2 = id.clone();
    match s.ask(move |r| CoordinatorMsg::GetVehicle(id2, r)).await? {
        Some(v) => Ok(Json(v.payloads).into_response()),
        None => Err(ApiError::not_found(format!("no vehicle `{id}`"))),
    }
}

async fn payload_command(
    State(s): State<ApiState>,
    Path((id, slot)): Path<(String, String)>,
    body: Bytes,
) -> Result<Response, ApiError> {
    let cmd = serde_json::Value::Object(requests::object(&body)?);
    payloads::require_running(&s, &id, &slot).await?;
    match s
        .ask(move |r| CoordinatorMsg::PayloadCommand(id, slot, cmd, r))
        .await?
    {
        Ok(answer) => Ok(Json(answer).into_response()),
        Err(e) => Err(payloads::payload_error(e)),
    }
}

async fn attach_payload(
    State(s): State<ApiState>,
    Path(id): Path<String>,
    body: Bytes,
) -> Result<Response, ApiError> {
    let spec = payloads::parse_attach(&body)?;
    match s
        .ask(move |r| CoordinatorMsg::AttachPayload(id, spec, r))
        .await?
    {
        Ok(payload) => Ok((StatusCode::CREATED, Json(payload)).into_response()),
        Err(e) => Err(payloads::payload_error(e)),
    }
}

async fn detach_payload(
    State(s): State<ApiState>,
    Path((id, slot)): Path<(String, String)>,
) -> Result<Response, ApiError> {
    match s
        .ask(move |r| CoordinatorMsg::DetachPayload(id, slot, r))
        .await?
    {
        Ok(answer) => Ok(Json(answer).into_response()),
        Err(e) => Err(payloads::payload_error(e)),
    }
}

async fn payload_of(
    s: &ApiState,
    id: String,
    slot: String,
) -> Result<std::sync::Arc<skein_swarm::payload::PayloadShared>, ApiError> {
    s.ask(move |r| CoordinatorMsg::GetPayload(id, slot, r))
        .await?
        .map_err(ApiError::not_found)
}

async fn payload_snapshot(
    State(s): State<ApiState>,
    Path((id, slot)): Path<(String, String)>,
) -> Result<Response, ApiError> {
    let p = payload_of(&s, id.clone(), slot.clone()).await?;
    match p.frame() {
        Some(jpeg) => Ok((
            [
                (header::CONTENT_TYPE, "image/jpeg"),
                (header::CACHE_CONTROL, "no-store"),
            ],
            jpeg.as_ref().clone(),
        )
            .into_response()),
        None => Err(ApiError::not_found(format!(
            "payload `{slot}` of {id} has published no frame yet"
        ))),
    }
}

/// Boundary of the MJPEG multipart stream.
const MJPEG_BOUNDARY: &str = "skeinframe";

async fn payload_stream(
    State(s): State<ApiState>,
    Path((id, slot)): Path<(String, String)>,
) -> Result<Response, ApiError> {
    let p = payload_of(&s, id, slot).await?;
    let rx = p.subscribe_frames();
    // Each part is sent once: the current frame first, then every new one.
    let frames = futures_util::stream::unfold((rx, true), |(mut rx, first)| async move {
        loop {
            if !first && rx.changed().await.is_err() {
                return None; // the payload is gone
            }
            let frame = rx.borrow_and_update().clone();
            let Some(jpeg) = frame else {
                if first {
                    // Nothing yet: wait for the first frame.
                    if rx.changed().await.is_err() {
                        return None;
                    }
                    continue;
                }
                continue;
            };
            let mut part = format!(
                "--{MJPEG_BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {}\r\n\r\n",
                jpeg.len()
            )
            .into_bytes();
            part.extend_from_slice(&jpeg);
            part.extend_from_slice(b"\r\n");
            return Some((
                Ok::<_, std::convert::Infallible>(Bytes::from(part)),
                (rx, false),
            ));
        }
    });
    let body = axum::body::Body::from_stream(frames);
    Ok((
        [
            (
                header::CONTENT_TYPE,
                format!("multipart/x-mixed-replace; boundary={MJPEG_BOUNDARY}"),
            ),
            (header::CACHE_CONTROL, "no-store".to_string()),
        ],
        body,
    )
        .into_response())
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

async fn stream(State(s): State<ApiState>, ws: WebSocketUpgrade) -> Response {
    ws.on_upgrade(move |socket| stream_session(socket, s))
}

async fn stream_session(mut socket: WebSocket, s: ApiState) {
    let mut events = s.events.subscribe();
    let mut telemetry = s.telemetry.subscribe();
    // Send the current picture at once so a new dashboard is never empty for a tick.
    if let Ok(list) = s.ask(CoordinatorMsg::ListVehicles).await {
        let frame = serde_json::json!({"type": "vehicles", "vehicles": list});
        if socket
            .send(Message::Text(frame.to_string().into()))
            .await
            .is_err()
        {
            return;
        }
    }
    loop {
        let text: String = tokio::select! {
            t = telemetry.recv() => match t {
                Ok(t) => t.to_string(),
                Err(broadcast::error::RecvError::Lagged(_)) => continue,
                Err(broadcast::error::RecvError::Closed) => return,
            },
            e = events.recv() => match e {
                Ok(e) => match serde_json::to_string(&e) { Ok(s) => s, Err(_) => continue },
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    serde_json::json!({"type": "events_dropped", "count": n}).to_string()
                }
                Err(broadcast::error::RecvError::Closed) => return,
            },
            incoming = socket.recv() => match incoming {
                Some(Ok(Message::Close(_))) | None | Some(Err(_)) => return,
                Some(Ok(_)) => continue,
            },
        };
        if socket.send(Message::Text(text.into())).await.is_err() {
            return;
        }
    }
}

fn content_type(path: &str) -> &'static str {
    match path.rsplit('.').next() {
        Some("html") => "text/html; charset=utf-8",
        Some("js") => "text/javascript; charset=utf-8",
        Some("css") => "text/css; charset=utf-8",
        Some("svg") => "image/svg+xml",
        Some("png") => "image/png",
        Some("json") => "application/json",
        Some("ico") => "image/x-icon",
        _ => "application/octet-stream",
    }
}

pub(crate) async fn static_file(uri: axum::http::Uri) -> Response {
    let path = uri.path().trim_start_matches('/');
    let path = if path.is_empty() { "index.html" } else { path };
    match WEB_UI.get_file(path) {
        Some(f) => (
            [
                (header::CONTENT_TYPE, content_type(path)),
                (header::CACHE_CONTROL, "no-cache"),
            ],
            f.contents(),
        )
            .into_response(),
        None => ApiError::not_found(format!("no such file: /{path}")).into_response(),
    }
}
