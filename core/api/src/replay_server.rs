//! `skein replay FILE.mcap`: a recording (see `skein_record`) played back into the
//! dashboard. The same dashboard and the read side of the API (vehicles, formation,
//! camera frames, the stream with its `vehicles` frames and events) answer from the
//! recording at its own pace (`speed` × real time); everything that would change the
//! swarm answers 409: a replay flies nothing.

use crate::error::ApiError;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Path, State};
use axum::http::{Method, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::{Json, Router};
use base64::Engine as _;
use serde_json::{Value, json};
use skein_record::Timeline;
use skein_record::channels::{EVENTS, FORMATION};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, RwLock};
use std::time::{Duration, Instant};
use tokio::sync::broadcast;

/// Shortest interval between two `vehicles` frames of the stream, wall-clock s (the live
/// API's 10 Hz).
const VEHICLES_FRAME_S: f64 = 0.1;

/// Latest JPEG per (vehicle id, payload slot).
type Frames = BTreeMap<(String, String), Arc<Vec<u8>>>;

/// A recording being played back; cheap to clone (shared).
#[derive(Clone)]
pub struct ReplayState {
    inner: Arc<Inner>,
}

struct Inner {
    file: String,
    timeline: Timeline,
    speed: f64,
    /// Latest snapshot per vehicle id.
    vehicles: RwLock<BTreeMap<String, Value>>,
    /// Latest formation.
    formation: RwLock<Option<Value>>,
    frames: RwLock<Frames>,
    /// Stream frames (JSON text), as the live stream sends them.
    stream: broadcast::Sender<Arc<str>>,
    /// Recording time reached, s since its first message (f64 bits).
    position_s: AtomicU64,
    finished: AtomicBool,
}

impl ReplayState {
    /// A replay of `timeline` (read from `file`) at `speed` × real time (> 0).
    pub fn new(file: &std::path::Path, timeline: Timeline, speed: f64) -> Self {
        let (stream, _) = broadcast::channel(256);
        ReplayState {
            inner: Arc::new(Inner {
                file: file.display().to_string(),
                timeline,
                speed: if speed.is_finite() && speed > 0.0 {
                    speed
                } else {
                    1.0
                },
                vehicles: RwLock::default(),
                formation: RwLock::default(),
                frames: RwLock::default(),
                stream,
                position_s: AtomicU64::new(0f64.to_bits()),
                finished: AtomicBool::new(false),
            }),
        }
    }

    /// Plays the recording once, from its first message to its last; afterwards the
    /// API keeps showing the final state.
    pub fn spawn_player(&self) -> tokio::task::JoinHandle<()> {
        let inner = self.inner.clone();
        tokio::spawn(async move { inner.play().await })
    }

    /// `GET /api/v1/replay`: file, position and duration (s), speed, finished.
    pub fn info(&self) -> Value {
        let i = &self.inner;
        json!({
            "file": i.file,
            "position_s": f64::from_bits(i.position_s.load(Ordering::Relaxed)),
            "duration_s": i.timeline.duration_s(),
            "speed": i.speed,
            "messages": i.timeline.messages.len(),
            "finished": i.finished.load(Ordering::Relaxed),
        })
    }
}

impl Inner {
    async fn play(&self) {
        let start_ns = self.timeline.start_ns();
        let t0 = Instant::now();
        let mut dirty = false;
        let mut last_frame: Option<Instant> = None;
        for m in &self.timeline.messages {
            let at_s = m.time_ns.saturating_sub(start_ns) as f64 * 1e-9;
            let wait_s = at_s / self.speed - t0.elapsed().as_secs_f64();
            if wait_s > 0.0 {
                if dirty {
                    self.send_vehicles();
                    dirty = false;
                    last_frame = Some(Instant::now());
                }
                tokio::time::sleep(Duration::from_secs_f64(wait_s)).await;
            }
            self.position_s.store(at_s.to_bits(), Ordering::Relaxed);
            dirty |= self.apply(&m.topic, &m.schema, &m.value);
            if dirty && last_frame.is_none_or(|t| t.elapsed().as_secs_f64() >= VEHICLES_FRAME_S) {
                self.send_vehicles();
                dirty = false;
                last_frame = Some(Instant::now());
            }
        }
        if dirty {
            self.send_vehicles();
        }
        self.finished.store(true, Ordering::Relaxed);
    }

    /// Applies one message; true when a vehicle snapshot changed.
    fn apply(&self, topic: &str, schema: &str, value: &Value) -> bool {
        match (topic, schema) {
            (EVENTS, _) => {
                if value["type"] == "formation_changed" && value["formation"].is_object() {
                    *self.formation.write().expect("formation lock") =
                        Some(value["formation"].clone());
                }
                let _ = self.stream.send(Arc::from(value.to_string()));
                false
            }
            (FORMATION, _) => {
                *self.formation.write().expect("formation lock") = Some(value.clone());
                false
            }
            (_, "skein.VehicleState") => match value["id"].as_str() {
                Some(id) => {
                    self.vehicles
                        .write()
                        .expect("vehicles lock")
                        .insert(id.to_string(), value.clone());
                    true
                }
                None => false,
            },
            (_, "foxglove.CompressedImage") => {
                // Topic /skein/<id>/<slot>/image.
                let parts: Vec<&str> = topic.trim_start_matches('/').split('/').collect();
                if let ([_, id, slot, "image"], Some(data)) =
                    (parts.as_slice(), value["data"].as_str())
                    && let Ok(jpeg) = base64::engine::general_purpose::STANDARD.decode(data)
                {
                    self.frames
                        .write()
                        .expect("frames lock")
                        .insert((id.to_string(), slot.to_string()), Arc::new(jpeg));
                }
                false
            }
            _ => false,
        }
    }

    fn vehicles_frame(&self) -> Value {
        let list: Vec<Value> = self
            .vehicles
            .read()
            .expect("vehicles lock")
            .values()
            .cloned()
            .collect();
        json!({"type": "vehicles", "vehicles": list})
    }

    fn send_vehicles(&self) {
        let _ = self
            .stream
            .send(Arc::from(self.vehicles_frame().to_string()));
    }
}

/// Serves [`app`] on `listener` until `shutdown` completes.
///
/// # Errors
/// The server's I/O error.
pub async fn serve(
    listener: tokio::net::TcpListener,
    state: ReplayState,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    axum::serve(listener, app(state))
        .with_graceful_shutdown(shutdown)
        .await
}

/// The replay's router: the dashboard and the read side of the API.
pub fn app(state: ReplayState) -> Router {
    Router::new()
        .route("/api/v1/health", get(health))
        .route("/api/v1/replay", get(replay_info))
        .route("/api/v1/auth/whoami", get(whoami))
        .route("/api/v1/vehicles", get(vehicles))
        .route("/api/v1/vehicles/{id}", get(vehicle))
        .route("/api/v1/formation", get(formation))
        .route("/api/v1/vehicles/{id}/payloads/{slot}/frame", get(frame))
        .route("/api/v1/stream", get(stream))
        .route("/api/{*rest}", axum::routing::any(not_replayed))
        .fallback(get(crate::static_files::static_file))
        .with_state(state)
}

async fn health(State(s): State<ReplayState>) -> Json<Value> {
    let n = s.inner.vehicles.read().expect("vehicles lock").len();
    Json(json!({"status": "ok", "vehicles": n, "replay": s.info()}))
}

async fn replay_info(State(s): State<ReplayState>) -> Json<Value> {
    Json(s.info())
}

/// A viewer: the dashboard hides every control.
async fn whoami() -> Json<Value> {
    Json(json!({"auth": false, "name": "replay", "role": "viewer"}))
}

async fn vehicles(State(s): State<ReplayState>) -> Json<Value> {
    Json(s.inner.vehicles_frame()["vehicles"].clone())
}

async fn vehicle(
    State(s): State<ReplayState>,
    Path(id): Path<String>,
) -> Result<Json<Value>, ApiError> {
    s.inner
        .vehicles
        .read()
        .expect("vehicles lock")
        .get(&id)
        .cloned()
        .map(Json)
        .ok_or_else(|| ApiError::not_found(format!("no vehicle `{id}` in the recording so far")))
}

async fn formation(State(s): State<ReplayState>) -> Result<Json<Value>, ApiError> {
    s.inner
        .formation
        .read()
        .expect("formation lock")
        .clone()
        .map(Json)
        .ok_or_else(|| ApiError::not_found("no formation in the recording so far"))
}

async fn frame(
    State(s): State<ReplayState>,
    Path((id, slot)): Path<(String, String)>,
) -> Result<Response, ApiError> {
    let jpeg = s
        .inner
        .frames
        .read()
        .expect("frames lock")
        .get(&(id.clone(), slot.clone()))
        .cloned()
        .ok_or_else(|| {
            ApiError::not_found(format!("no frame of {id}/{slot} in the recording so far"))
        })?;
    Ok((
        [
            (header::CONTENT_TYPE, "image/jpeg"),
            (header::CACHE_CONTROL, "no-store"),
        ],
        jpeg.as_ref().clone(),
    )
        .into_response())
}

async fn stream(State(s): State<ReplayState>, ws: WebSocketUpgrade) -> Response {
    ws.on_upgrade(move |socket| stream_session(socket, s))
}

async fn stream_session(mut socket: WebSocket, s: ReplayState) {
    let mut rx = s.inner.stream.subscribe();
    let first = s.inner.vehicles_frame().to_string();
    if socket.send(Message::Text(first.into())).await.is_err() {
        return;
    }
    loop {
        let text: Arc<str> = tokio::select! {
            m = rx.recv() => match m {
                Ok(t) => t,
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    Arc::from(json!({"type": "events_dropped", "count": n}).to_string())
                }
                Err(broadcast::error::RecvError::Closed) => return,
            },
            incoming = socket.recv() => match incoming {
                Some(Ok(Message::Close(_))) | None | Some(Err(_)) => return,
                Some(Ok(_)) => continue,
            },
        };
        if socket
            .send(Message::Text(text.to_string().into()))
            .await
            .is_err()
        {
            return;
        }
    }
}

/// Reads the replay does not have answer 404; writes 409 (a replay flies nothing).
async fn not_replayed(
    State(s): State<ReplayState>,
    method: Method,
    uri: axum::http::Uri,
) -> ApiError {
    if method == Method::GET || method == Method::HEAD {
        ApiError::not_found(format!("{} is not part of a replay", uri.path()))
    } else {
        ApiError::status(
            StatusCode::CONFLICT,
            format!("replaying {}: the replay is read-only", s.inner.file),
        )
    }
}
