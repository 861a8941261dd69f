//! The recorder: one MCAP file at a time, started and stopped at run time
//! (`POST /api/v1/recording/{start,stop}`) or for the whole run (`skein up --record`).

use crate::channels::{self, Kind};
use crate::sent::sent_json;
use crate::writer::{self, Command, Entry};
use base64::Engine as _;
use ractor::ActorRef;
use serde::Serialize;
use serde_json::{Value, json};
use skein_link::Endpoint;
use skein_model::vehicle::VehicleSnapshot;
use skein_swarm::coordinator::missions::MissionMsg;
use skein_swarm::{CoordinatorMsg, FleetMsg, FormationMsg, PayloadMsg, SwarmEvent};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::sync::{Arc, Mutex, RwLock};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use tokio::sync::{broadcast, oneshot};
use tokio::task::JoinHandle;

/// Vehicle snapshots and positions are recorded at this rate, Hz.
pub const STATE_HZ: f64 = 10.0;
/// The formation, and the missions while the coordinator holds any, are recorded at
/// least this often, s (the missions at the stop too).
pub const FORMATION_PERIOD_S: f64 = 1.0;
/// How long a coordinator query may take before the tick is skipped.
const ASK_TIMEOUT: Duration = Duration::from_secs(2);

/// Where a recording takes its data from.
#[derive(Clone)]
pub struct Sources {
    /// The coordinator (vehicle snapshots, formation, payload frames).
    pub coordinator: ActorRef<CoordinatorMsg>,
    /// The swarm's event bus (the stream's events).
    pub events: broadcast::Sender<SwarmEvent>,
    /// The MAVLink endpoints, whose sent messages are recorded.
    pub endpoints: Vec<Arc<Endpoint>>,
}

/// Why a recording could not start or stop.
#[derive(Debug, Clone, PartialEq)]
pub enum RecordError {
    /// A recording is running already (its file).
    AlreadyRecording(PathBuf),
    /// No recording is running.
    NotRecording,
    /// The requested name is not a plain file name (`[A-Za-z0-9_.-]`, 1–64 characters).
    BadName(String),
    /// The file could not be created or written.
    Io(String),
}

impl std::fmt::Display for RecordError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RecordError::AlreadyRecording(p) => write!(f, "already recording to {}", p.display()),
            RecordError::NotRecording => write!(f, "no recording is running"),
            RecordError::BadName(n) => write!(
                f,
                "name `{n}` must be 1-64 characters of letters, digits, `_`, `-` and `.`, not starting with `.`"
            ),
            RecordError::Io(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for RecordError {}

/// A running recording, as `GET /api/v1/recording` shows it.
#[derive(Debug, Clone, Serialize)]
pub struct RecordingInfo {
    /// The MCAP file.
    pub path: PathBuf,
    /// Seconds since it started.
    pub elapsed_s: f64,
}

/// A finished recording.
#[derive(Debug, Clone, Serialize)]
pub struct RecordingSummary {
    /// The MCAP file.
    pub path: PathBuf,
    /// Messages written.
    pub messages: u64,
    /// Channels (topics) written.
    pub channels: usize,
    /// File size, bytes.
    pub bytes: u64,
    /// From the first to the last message, s.
    pub duration_s: f64,
}

/// Starts and stops recordings (one at a time) into a directory.
pub struct Recorder {
    sources: Sources,
    dir: PathBuf,
    active: Mutex<Option<Recording>>,
}

impl Recorder {
    /// A recorder writing into `dir` (created when the first recording starts).
    pub fn new(sources: Sources, dir: PathBuf) -> Arc<Recorder> {
        Arc::new(Recorder {
            sources,
            dir,
            active: Mutex::new(None),
        })
    }

    /// The directory recordings go to.
    pub fn dir(&self) -> &std::path::Path {
        &self.dir
    }

    /// Starts recording to `<dir>/<name>.mcap` (`name` default `skein-<unix seconds>`),
    /// or to `path` when given (`skein up --record FILE`). Must run inside the tokio
    /// runtime.
    ///
    /// # Errors
    /// [`RecordError::AlreadyRecording`], [`RecordError::BadName`], or
    /// [`RecordError::Io`] when the file exists already or cannot be created.
    pub fn start(
        &self,
        name: Option<&str>,
        path: Option<&Path>,
    ) -> Result<RecordingInfo, RecordError> {
        let mut active = self.active.lock().expect("recorder lock");
        if let Some(r) = active.as_ref() {
            return Err(RecordError::AlreadyRecording(r.path.clone()));
        }
        let path = match path {
            Some(p) => p.to_path_buf(),
            None => {
                let name = match name {
                    Some(n) => valid_name(n)?.to_string(),
                    None => format!("skein-{}", now_ns() / 1_000_000_000),
                };
                std::fs::create_dir_all(&self.dir).map_err(|e| {
                    RecordError::Io(format!("cannot create {}: {e}", self.dir.display()))
                })?;
                self.dir.join(format!("{name}.mcap"))
            }
        };
        let r = Recording::start(&path, &self.sources)?;
        let info = r.info();
        *active = Some(r);
        Ok(info)
    }

    /// Stops the running recording and finishes its file.
    ///
    /// # Errors
    /// [`RecordError::NotRecording`], or [`RecordError::Io`] when the file could not be
    /// finished.
    pub async fn stop(&self) -> Result<RecordingSummary, RecordError> {
        let r = self
            .active
            .lock()
            .expect("recorder lock")
            .take()
            .ok_or(RecordError::NotRecording)?;
        r.finish().await
    }

    /// The running recording, if any.
    pub fn status(&self) -> Option<RecordingInfo> {
        self.active
            .lock()
            .expect("recorder lock")
            .as_ref()
            .map(Recording::info)
    }

    /// Records a command the API accepted (`/skein/commands`): its id (as in the
    /// `command_result` event), target (a vehicle id or `"swarm"`) and request body.
    /// Nothing happens when no recording runs.
    pub fn record_command(&self, command_id: Option<u64>, target: &str, request: &Value) {
        if let Some(r) = self.active.lock().expect("recorder lock").as_ref() {
            r.put(
                channels::COMMANDS.into(),
                Kind::Command,
                &json!({"command_id": command_id, "target": target, "request": request}),
            );
        }
    }
}

fn valid_name(n: &str) -> Result<&str, RecordError> {
    let ok = (1..=64).contains(&n.len())
        && !n.starts_with('.')
        && n.chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'));
    if ok {
        Ok(n)
    } else {
        Err(RecordError::BadName(n.to_string()))
    }
}

/// Wall-clock time, ns since the Unix epoch.
pub(crate) fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// One recording: the writer thread, the collecting tasks and the endpoint taps.
pub struct Recording {
    path: PathBuf,
    started: Instant,
    tx: mpsc::Sender<Command>,
    tasks: Vec<JoinHandle<()>>,
    /// Tells the events task to record what the bus already holds and stop.
    events_stop: Option<oneshot::Sender<()>>,
    events_task: JoinHandle<()>,
    endpoints: Vec<Arc<Endpoint>>,
    /// Asked for the missions once more at the stop.
    coordinator: ActorRef<CoordinatorMsg>,
}

impl Recording {
    /// Creates `path` (never overwriting a file) and starts collecting from `sources`.
    ///
    /// # Errors
    /// [`RecordError::Io`] when the file exists or cannot be created.
    pub fn start(path: &Path, sources: &Sources) -> Result<Recording, RecordError> {
        let tx = writer::spawn(path)
            .map_err(|e| RecordError::Io(format!("cannot create {}: {e}", path.display())))?;
        let sysids: Arc<RwLock<HashMap<u8, String>>> = Arc::default();
        for ep in &sources.endpoints {
            let (tx, sysids) = (tx.clone(), sysids.clone());
            ep.set_sent_tap(Some(Arc::new(move |sysid, msg| {
                let id = sysids
                    .read()
                    .expect("sysid map lock")
                    .get(&sysid)
                    .cloned()
                    .unwrap_or_else(|| format!("sysid-{sysid}"));
                put(
                    &tx,
                    channels::vehicle_topic(&id, "sent"),
                    Kind::Sent,
                    &sent_json(sysid, msg),
                );
            })));
        }
        let (events_stop, stop) = oneshot::channel();
        let events_task = tokio::spawn(record_events(sources.events.subscribe(), stop, tx.clone()));
        let tasks = vec![tokio::spawn(record_swarm(
            sources.coordinator.clone(),
            tx.clone(),
            sysids,
        ))];
        tracing::info!("recording to {}", path.display());
        Ok(Recording {
            path: path.to_path_buf(),
            started: Instant::now(),
            tx,
            tasks,
            events_stop: Some(events_stop),
            events_task,
            endpoints: sources.endpoints.clone(),
            coordinator: sources.coordinator.clone(),
        })
    }

    fn info(&self) -> RecordingInfo {
        RecordingInfo {
            path: self.path.clone(),
            elapsed_s: self.started.elapsed().as_secs_f64(),
        }
    }

    fn put(&self, topic: String, kind: Kind, value: &Value) {
        put(&self.tx, topic, kind, value);
    }

    /// Stops collecting and finishes the file. Every event sent on the bus before this
    /// call is in the file (an API request that emitted one and returned before the stop
    /// request is recorded, however busy the runtime), and so are the missions as they
    /// are at the stop (a plan stored within the last second included).
    ///
    /// # Errors
    /// [`RecordError::Io`] when the file could not be written or finished.
    pub async fn finish(mut self) -> Result<RecordingSummary, RecordError> {
        for ep in &self.endpoints {
            ep.set_sent_tap(None);
        }
        for t in &self.tasks {
            t.abort();
        }
        if let Some(stop) = self.events_stop.take() {
            let _ = stop.send(());
        }
        let _ = (&mut self.events_task).await;
        record_missions(&self.coordinator, &self.tx).await;
        let (reply_tx, reply_rx) = mpsc::channel();
        self.tx
            .send(Command::Finish(reply_tx))
            .map_err(|_| RecordError::Io("the recording's writer stopped".into()))?;
        let path = self.path.clone();
        let summary = tokio::task::spawn_blocking(move || reply_rx.recv())
            .await
            .map_err(|e| RecordError::Io(e.to_string()))?
            .map_err(|_| RecordError::Io("the recording's writer stopped".into()))?
            .map_err(|e| RecordError::Io(format!("{}: {e}", path.display())))?;
        tracing::info!(
            "recording {} finished: {} messages",
            path.display(),
            summary.messages
        );
        Ok(RecordingSummary {
            path,
            messages: summary.messages,
            channels: summary.channels,
            bytes: summary.bytes,
            duration_s: match (summary.first_ns, summary.last_ns) {
                (Some(a), Some(b)) => (b.saturating_sub(a)) as f64 * 1e-9,
                _ => 0.0,
            },
        })
    }
}

fn put(tx: &mpsc::Sender<Command>, topic: String, kind: Kind, value: &Value) {
    if let Ok(data) = serde_json::to_vec(value) {
        let _ = tx.send(Command::Write(Entry {
            topic,
            kind,
            time_ns: now_ns(),
            data,
        }));
    }
}

/// Records the bus's events until `stop`, then the events the bus held for it at the
/// stop (sent before it), so that none sent before the recording stops is lost.
async fn record_events(
    mut events: broadcast::Receiver<SwarmEvent>,
    mut stop: oneshot::Receiver<()>,
    tx: mpsc::Sender<Command>,
) {
    loop {
        let received = tokio::select! {
            biased;
            _ = &mut stop => break,
            r = events.recv() => r,
        };
        if !record_event(&tx, received) {
            return;
        }
    }
    // What the bus held at the stop, however fast events go on arriving.
    for _ in 0..events.len() {
        let received = match events.try_recv() {
            Ok(e) => Ok(e),
            Err(broadcast::error::TryRecvError::Lagged(n)) => {
                Err(broadcast::error::RecvError::Lagged(n))
            }
            Err(_) => return,
        };
        record_event(&tx, received);
    }
}

/// Writes one received event (or a count of those the bus dropped for a slow reader,
/// as an `events_dropped` event); false once the bus is closed.
fn record_event(
    tx: &mpsc::Sender<Command>,
    received: Result<SwarmEvent, broadcast::error::RecvError>,
) -> bool {
    match received {
        Ok(e) => {
            if let Ok(v) = serde_json::to_value(&e) {
                put(tx, channels::EVENTS.into(), Kind::Event, &v);
            }
        }
        Err(broadcast::error::RecvError::Lagged(n)) => put(
            tx,
            channels::EVENTS.into(),
            Kind::Event,
            &json!({"type": "events_dropped", "count": n}),
        ),
        Err(broadcast::error::RecvError::Closed) => return false,
    }
    true
}

async fn ask<T: Send + 'static>(
    c: &ActorRef<CoordinatorMsg>,
    msg: impl FnOnce(ractor::RpcReplyPort<T>) -> CoordinatorMsg,
) -> Option<T> {
    match c.call(msg, Some(ASK_TIMEOUT)).await {
        Ok(ractor::rpc::CallResult::Success(v)) => Some(v),
        _ => None,
    }
}

/// Vehicle snapshots and fixes at [`STATE_HZ`], the formation and the missions each
/// [`FORMATION_PERIOD_S`], and a frame watcher per payload that publishes frames.
async fn record_swarm(
    coordinator: ActorRef<CoordinatorMsg>,
    tx: mpsc::Sender<Command>,
    sysids: Arc<RwLock<HashMap<u8, String>>>,
) {
    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / STATE_HZ));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut watched: HashSet<(String, String)> = HashSet::new();
    // Aborted with this task (its future is dropped when the recording finishes).
    let mut watchers = Watchers(Vec::new());
    let mut last_formation: Option<Instant> = None;
    loop {
        tick.tick().await;
        let Some(list) = ask(&coordinator, |r| FleetMsg::ListVehicles(r).into()).await else {
            if coordinator.get_status() == ractor::ActorStatus::Stopped {
                return;
            }
            continue;
        };
        for v in &list {
            record_vehicle(&tx, v);
            sysids
                .write()
                .expect("sysid map lock")
                .entry(v.sysid)
                .or_insert_with(|| v.id.clone());
            for p in &v.payloads {
                let (Some(slot), Some(frames)) = (p["slot"].as_str(), p["frames"].as_u64()) else {
                    continue;
                };
                let key = (v.id.clone(), slot.to_string());
                if frames == 0 || watched.contains(&key) {
                    continue;
                }
                let shared = ask(&coordinator, |r| {
                    PayloadMsg::GetPayload(key.0.clone(), key.1.clone(), r).into()
                })
                .await;
                if let Some(Ok(shared)) = shared {
                    watched.insert(key.clone());
                    let rx = shared.subscribe_frames();
                    watchers
                        .0
                        .push(tokio::spawn(record_frames(key, rx, tx.clone())));
                }
            }
        }
        if last_formation.is_none_or(|t| t.elapsed().as_secs_f64() >= FORMATION_PERIOD_S) {
            last_formation = Some(Instant::now());
            if let Some(f) = ask(&coordinator, |r| FormationMsg::GetFormation(r).into()).await
                && let Ok(v) = serde_json::to_value(&f)
            {
                put(&tx, channels::FORMATION.into(), Kind::Formation, &v);
            }
            record_missions(&coordinator, &tx).await;
        }
    }
}

/// Every mission the coordinator holds (none: nothing is written), as
/// `GET /api/v1/missions` lists them: where each is, step by step.
async fn record_missions(coordinator: &ActorRef<CoordinatorMsg>, tx: &mpsc::Sender<Command>) {
    let Some(missions) = ask(coordinator, |r| MissionMsg::List(r).into()).await else {
        return;
    };
    if missions.is_empty() {
        return;
    }
    if let Ok(v) = serde_json::to_value(&missions) {
        put(
            tx,
            channels::MISSIONS.into(),
            Kind::Missions,
            &json!({ "missions": v }),
        );
    }
}

/// Frame watcher tasks, aborted when dropped.
struct Watchers(Vec<JoinHandle<()>>);

impl Drop for Watchers {
    fn drop(&mut self) {
        for w in &self.0 {
            w.abort();
        }
    }
}

/// A vehicle's snapshot and, once it has a position, its `foxglove.LocationFix`.
fn record_vehicle(tx: &mpsc::Sender<Command>, v: &VehicleSnapshot) {
    if let Ok(state) = serde_json::to_value(v) {
        put(
            tx,
            channels::vehicle_topic(&v.id, "state"),
            Kind::VehicleState,
            &state,
        );
    }
    if let Some(p) = &v.position {
        let fix = json!({
            "timestamp": channels::foxglove_time(now_ns()),
            "frame_id": v.id,
            "latitude": p.lat_deg,
            "longitude": p.lon_deg,
            "altitude": p.alt_amsl_m,
            "position_covariance": vec![0.0; 9],
            "position_covariance_type": 0,
        });
        put(
            tx,
            channels::vehicle_topic(&v.id, "fix"),
            Kind::LocationFix,
            &fix,
        );
    }
}

/// Every frame a payload publishes, as `foxglove.CompressedImage` (JPEG).
async fn record_frames(
    (id, slot): (String, String),
    mut rx: tokio::sync::watch::Receiver<Option<Arc<Vec<u8>>>>,
    tx: mpsc::Sender<Command>,
) {
    let topic = channels::image_topic(&id, &slot);
    let frame_id = format!("{id}/{slot}");
    loop {
        let frame = rx.borrow_and_update().clone();
        if let Some(jpeg) = frame {
            let image = json!({
                "timestamp": channels::foxglove_time(now_ns()),
                "frame_id": frame_id,
                "data": base64::engine::general_purpose::STANDARD.encode(jpeg.as_slice()),
                "format": "jpeg",
            });
            put(&tx, topic.clone(), Kind::CompressedImage, &image);
        }
        if rx.changed().await.is_err() {
            return; // the payload is gone
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_plain_file_names() {
        assert!(valid_name("flight-1_a.b").is_ok());
        for bad in ["", "../etc", "a/b", ".hidden", "x y", &"n".repeat(65)] {
            assert_eq!(valid_name(bad), Err(RecordError::BadName(bad.to_string())));
        }
    }

    /// Events on the bus when the recording stops, not yet read by its task, are
    /// written all the same (a formation set just before `recording/stop` was lost).
    #[tokio::test]
    async fn events_sent_before_the_stop_are_recorded() {
        let (bus, _) = broadcast::channel(16);
        let (tx, rx) = mpsc::channel();
        let (stop_tx, stop) = oneshot::channel();
        let task = tokio::spawn(record_events(bus.subscribe(), stop, tx));
        for n in 0..3 {
            let formation = json!({ "n": n });
            bus.send(SwarmEvent::FormationChanged { formation })
                .unwrap();
        }
        stop_tx.send(()).unwrap();
        task.await.unwrap();
        let written: Vec<Value> = rx
            .try_iter()
            .map(|c| match c {
                Command::Write(e) => serde_json::from_slice(&e.data).unwrap(),
                Command::Finish(_) => panic!("the events task finished the file"),
            })
            .collect();
        let ns: Vec<Value> = written
            .iter()
            .map(|v| v["formation"]["n"].clone())
            .collect();
        assert_eq!(ns, [json!(0), json!(1), json!(2)], "{written:?}");
        assert!(written.iter().all(|v| v["type"] == "formation_changed"));
    }
}
