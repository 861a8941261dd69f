//! `GET /api/v1/stream`: the WebSocket of the dashboard. The `vehicles` frames (every
//! vehicle and the process's load, [`crate::TELEMETRY_HZ`]) are made once by
//! [`publish_telemetry`] and shared by every session; each session adds the swarm's events
//! as they happen.

use crate::{ApiState, COORDINATOR_TIMEOUT, TELEMETRY_HZ};
use axum::extract::State;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::response::Response;
use ractor::ActorRef;
use skein_swarm::load::ShedWork;
use skein_swarm::{AdminMsg, CoordinatorMsg, SwarmReads};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::broadcast;

/// Publishes the `vehicles` frame at [`TELEMETRY_HZ`] while anyone listens (a fifth of
/// that while the process sheds optional work, see `skein_swarm::load`); ends when the
/// coordinator stops. Each frame carries the process's `load` (the dashboard's load
/// indicator) and the formation's `{"active","rms_error_m","absent"}` (the header's rms
/// error, absent members included; see `GET /api/v1/formation`).
pub(crate) async fn publish_telemetry(
    coordinator: ActorRef<CoordinatorMsg>,
    reads: SwarmReads,
    tx: broadcast::Sender<Arc<str>>,
) {
    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / TELEMETRY_HZ));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut load = None;
    let mut round: u64 = 0;
    loop {
        tick.tick().await;
        if coordinator.get_status() == ractor::ActorStatus::Stopped {
            return; // the frames are read without asking it: nothing else would notice
        }
        if tx.receiver_count() == 0 {
            continue;
        }
        if load.is_none()
            && let Ok(ractor::rpc::CallResult::Success(l)) = coordinator
                .call(|r| AdminMsg::GetLoad(r).into(), Some(COORDINATOR_TIMEOUT))
                .await
        {
            load = Some(l);
        }
        round += 1;
        if let Some(l) = &load
            && !l.keep(ShedWork::Dashboard, round)
        {
            continue;
        }
        // Published by the coordinator, read without asking it (`skein_swarm::SwarmReads`).
        let list = reads.vehicles();
        let f = reads.formation();
        let formation = Some(serde_json::json!({
            "active": f.active,
            "rms_error_m": f.rms_error_m,
            "absent": f.absent,
        }));
        let frame = serde_json::json!({
            "type": "vehicles",
            "vehicles": list,
            "load": load.as_ref().map(|l| l.status()),
            "formation": formation,
        });
        let _ = tx.send(Arc::from(frame.to_string()));
    }
}

/// WebSocket of vehicle states (10 Hz) and events
#[utoipa::path(get, path = "/api/v1/stream",
    responses((status = 101, description = "Switching to the WebSocket")))]
pub(crate) async fn stream(State(s): State<ApiState>, ws: WebSocketUpgrade) -> Response {
    ws.on_upgrade(move |socket| stream_session(socket, s))
}

async fn stream_session(mut socket: WebSocket, s: ApiState) {
    let mut events = s.events.subscribe();
    let mut telemetry = s.telemetry.subscribe();
    // Send the current picture at once so a new dashboard is never empty for a tick.
    {
        let frame = serde_json::json!({"type": "vehicles", "vehicles": s.reads.vehicles()});
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
