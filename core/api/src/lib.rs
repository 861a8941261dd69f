//! The web face of skein: the v1 HTTP API, the WebSocket stream and the embedded
//! dashboard.
//!
//! [`app`] builds the axum router (tests call it without a socket); [`serve`] runs it on a
//! listener. Handlers reach the swarm only by messages to the coordinator (`call` with a
//! timeout). Errors are JSON, `{"error": "...", "field": "..."}`, with a 4xx status naming
//! the problem (see [`error::ApiError`]; handlers use `?`, the `From` impls there decide
//! the status). With tokens configured every route but health and the contract needs
//! `Authorization: Bearer <token>` with a role (see [`auth`]).
//!
//! Every route is declared once, by its handler's `#[utoipa::path]` and its registration
//! in its role's router ([`openapi::routes`]); the router, the role table and the contract
//! (`GET /api/v1/openapi.json`, OpenAPI 3.1, see [`openapi`]) are built from that, and
//! docs/api.md lists them. The handlers, by concept: [`vehicles`] (vehicles and commands),
//! [`preflight`] (the fleet's pre-flight checks), [`flight_logs`] (the vehicles' ULogs
//! brought home; by themselves after landing: [`log_autofetch`]), [`px4_params`], [`formation_control`] (formation and leader motion), [`payloads`] and
//! the camera's frames, [`plugins`], [`swarm_status`] (health, supervision, metrics,
//! links), [`geofence`], [`map`] (the tiles under the plan), [`fault_injection`],
//! [`tracks`], [`recording`], [`rtk`] (RTK corrections), [`missions`] and their
//! [`rehearsals`], [`election`], the
//! stream (`GET /api/v1/stream`: WebSocket, `{"type": "vehicles", "vehicles": [...]}` at
//! [`TELEMETRY_HZ`] plus every [`skein_swarm::SwarmEvent`]). Any other `/api/…` path
//! answers 404 JSON; every other path is the dashboard (`web-ui/`, embedded at build time).
#![warn(missing_docs)]

pub mod auth;
pub mod election;
pub mod error;
pub mod fault_injection;
pub mod flight_logs;
pub mod formation_control;
pub mod geofence;
pub mod log_autofetch;
pub mod map;
pub mod missions;
pub mod openapi;
pub mod path_params;
pub mod payloads;
pub mod plugins;
pub mod preflight;
pub mod px4_params;
pub mod recording;
pub mod rehearsals;
pub mod replay_server;
pub mod requests;
pub mod responses;
pub mod roles;
pub mod rtk;
pub mod server;
mod static_files;
mod stream;
pub mod swarm_status;
pub mod swarms;
pub mod tls;
pub mod tracks;
pub mod vehicles;
mod video;

pub use server::ApiServer;

use axum::Router;
use axum::middleware::from_fn_with_state;
use axum::routing::{any, get};
use error::ApiError;
use ractor::ActorRef;
use roles::{Access, Role};
use skein_swarm::{CoordinatorMsg, SwarmEvent};
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
    /// The coordinator's published state: the pure reads never wait in its mailbox.
    reads: skein_swarm::SwarmReads,
    events: broadcast::Sender<SwarmEvent>,
    telemetry: broadcast::Sender<Arc<str>>,
    plugins: Option<Arc<plugins::PluginsApi>>,
    map: Arc<map::MapTiles>,
    auth: Arc<auth::Auth>,
    tls: Option<Arc<rustls::ServerConfig>>,
    recorder: Option<Arc<skein_record::Recorder>>,
    /// The vehicles' flight logs brought home ([`flight_logs`]).
    flight_logs: Arc<flight_logs::FlightLogs>,
    /// RTK corrections to this process's vehicles ([`rtk`]); without it `/api/v1/rtk`
    /// answers 503.
    rtk: Option<Arc<skein_rtk::RtkService>>,
    election: Option<tokio::sync::watch::Receiver<skein_swarm::election::ElectionStatus>>,
    clocks: Option<Arc<skein_swarm::clocks::PeerClocks>>,
    /// Under DDS Security, who the swarm link proves is speaking (a candidate only).
    link_security: Option<Arc<skein_swarm::link_security::LinkSecurity>>,
    /// The missions' rehearsals ([`rehearsals`]).
    rehearsals: Arc<rehearsals::Rehearsals>,
}

impl ApiState {
    /// State for a running swarm. Starts the task that publishes the `vehicles` frames of
    /// the stream (it ends when the coordinator stops).
    pub fn new(
        coordinator: ActorRef<CoordinatorMsg>,
        reads: skein_swarm::SwarmReads,
        events: broadcast::Sender<SwarmEvent>,
    ) -> Self {
        let (telemetry, _) = broadcast::channel(16);
        tokio::spawn(stream::publish_telemetry(
            coordinator.clone(),
            reads.clone(),
            telemetry.clone(),
        ));
        ApiState {
            coordinator,
            reads,
            events,
            telemetry,
            plugins: None,
            map: Arc::new(map::MapTiles::none()),
            auth: Arc::new(auth::Auth::disabled()),
            tls: None,
            recorder: None,
            flight_logs: flight_logs::FlightLogs::new(std::path::PathBuf::from(
                "recordings/flight-logs",
            )),
            rtk: None,
            election: None,
            clocks: None,
            link_security: None,
            rehearsals: Arc::default(),
        }
    }

    /// Serves `/api/v1/rtk` with this corrections service.
    pub fn with_rtk(mut self, rtk: Arc<skein_rtk::RtkService>) -> Self {
        self.rtk = Some(rtk);
        self
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

    /// Writes downloaded flight logs under `dir` (default `recordings/flight-logs`).
    pub fn with_flight_logs_dir(mut self, dir: std::path::PathBuf) -> Self {
        self.flight_logs = flight_logs::FlightLogs::new(dir);
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

    /// Shows this process's estimates of its peers' clocks in `GET /api/v1/coordinator`
    /// (`clocks`, see [`skein_swarm::clocks`]).
    pub fn with_clocks(mut self, clocks: Arc<skein_swarm::clocks::PeerClocks>) -> Self {
        self.clocks = Some(clocks);
        self
    }

    /// Shows the swarm link's DDS Security in `GET /api/v1/coordinator` (`dds_security`).
    pub fn with_link_security(
        mut self,
        record: Arc<skein_swarm::link_security::LinkSecurity>,
    ) -> Self {
        self.link_security = Some(record);
        self
    }

    /// Requires these tokens (see [`auth`]; without this call every request is allowed).
    pub fn with_auth(mut self, auth: auth::Auth) -> Self {
        self.auth = Arc::new(auth);
        self
    }

    /// Serves this map under the plan (`GET /api/v1/map`, its tiles); without it the
    /// map is `none`.
    pub fn with_map(mut self, map: map::MapTiles) -> Self {
        self.map = Arc::new(map);
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

    /// A write through the coordinator: `msg`'s answer, given once the coordinator has
    /// also published what the write did (one more question, a `Ping` queued behind it,
    /// see `skein_swarm::coordinator::published`): a client answered a write reads its
    /// effect from [`ApiState::reads`]. The `Ping` going unanswered does not undo the
    /// write's answer.
    async fn write<T: Send + 'static>(
        &self,
        msg: impl FnOnce(ractor::RpcReplyPort<T>) -> CoordinatorMsg,
    ) -> Result<T, ApiError> {
        let answer = self.ask(msg).await?;
        let _ = self.ask(|r| skein_swarm::AdminMsg::Ping(r).into()).await;
        Ok(answer)
    }

    /// A question to the coordinator, answered within [`COORDINATOR_TIMEOUT`].
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

/// The router (no socket: tests call it directly): every route of [`openapi::routes`]
/// behind its role's gate, `/api/…` paths that are no route (404 JSON, with a viewer
/// token), and the dashboard's files for everything else (no token).
pub fn app(state: ApiState) -> Router {
    let mut router = Router::new();
    for (access, routes) in openapi::routes::by_role() {
        let (routes, _) = routes.split_for_parts();
        router = router.merge(gated(routes, &state, access));
    }
    let unknown = Router::new().route("/api/{*rest}", any(api_not_found));
    router
        .merge(gated(unknown, &state, Access::Role(Role::Viewer)))
        .fallback(get(static_files::static_file))
        .with_state(state)
}

/// `routes` behind their role's gate: authentication and the role first (401 / 403 /
/// 429), then a standby coordinator's refusal of writes (409).
fn gated(routes: Router<ApiState>, state: &ApiState, access: Access) -> Router<ApiState> {
    routes
        .route_layer(from_fn_with_state(
            state.clone(),
            election::standby_refuses_writes,
        ))
        .route_layer(from_fn_with_state(
            auth::Gate::new(state.clone(), access),
            auth::require,
        ))
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

async fn api_not_found(uri: axum::http::Uri) -> ApiError {
    ApiError::not_found(format!("no such endpoint: {}", uri.path()))
}
