//! The WebSocket event stream of a running skein, recorded in a thread.

use serde_json::Value;
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Listens to `ws://…/api/v1/stream` in a thread and keeps every event (not the
/// periodic `vehicles` frames).
pub struct EventLog {
    events: Arc<Mutex<Vec<Value>>>,
}

impl EventLog {
    /// Connects to the stream of `base` (`http://127.0.0.1:PORT`).
    pub fn connect(base: &str) -> EventLog {
        let url = format!("{}/api/v1/stream", base.replacen("http://", "ws://", 1));
        let events = Arc::new(Mutex::new(Vec::new()));
        let store = events.clone();
        let (ready_tx, ready_rx) = mpsc::channel();
        std::thread::spawn(move || {
            let rt = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .unwrap();
            rt.block_on(async move {
                use futures_util::StreamExt;
                let (mut ws, _) = tokio_tungstenite::connect_async(&url).await.expect("ws");
                let _ = ready_tx.send(());
                while let Some(Ok(msg)) = ws.next().await {
                    if let Ok(text) = msg.to_text()
                        && let Ok(v) = serde_json::from_str::<Value>(text)
                        && v["type"] != "vehicles"
                    {
                        store.lock().unwrap().push(v);
                    }
                }
            });
        });
        ready_rx
            .recv_timeout(Duration::from_secs(10))
            .expect("stream connected");
        EventLog { events }
    }

    /// Events of `kind` so far.
    pub fn of_type(&self, kind: &str) -> Vec<Value> {
        self.events
            .lock()
            .unwrap()
            .iter()
            .filter(|e| e["type"] == kind)
            .cloned()
            .collect()
    }
}
