//! Counter-UAS tracking at run time: [`TrackingService`] steps the pure tracker of
//! `skein-tracking` (re-exported here, so `skein_swarm::tracking::...` names it) in a task
//! of its own beside the coordinator.
//!
//! At [`TRACKER_HZ`] it reads every frame the detectors processed since its last step from
//! their payload states, steps the tracker with them and the swarm members' poses (so
//! members are never tracks), forecasts the tracks and groups them into swarms, raises the
//! `track_*` and `swarm_*` events on the bus, and keeps the current tracks and swarms for
//! `GET /api/v1/tracks`, `GET /api/v1/swarms` and the metrics.

use crate::events::SwarmEvent;
use crate::metrics::Metrics;
use crate::tracks::{HostileSwarmEvent, SwarmView, TrackEvent, TrackView, TrackerCounters};
use crate::vehicle::fleet::Fleet;
use nalgebra::Vector3;
pub use skein_tracking::{
    AirPicture, GroupingConfig, MemberPose, Tracker, TrackerConfig, detection, filter, forecast,
    geometry, picture, shape, stations, swarms, target, track, tracker,
};
use std::collections::HashMap;
use std::sync::{Arc, PoisonError, RwLock};
use std::time::{Duration, SystemTime, UNIX_EPOCH};
use tokio::sync::broadcast;
use tokio::task::JoinHandle;

/// Rate of the tracker's steps, Hz.
pub const TRACKER_HZ: f64 = 10.0;

/// Wall-clock microseconds (the time base of detections and tracks).
pub fn now_us() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64)
}

/// What the tracker task publishes.
#[derive(Debug, Default)]
pub struct TrackingShared {
    tracks: RwLock<Vec<TrackView>>,
    swarms: RwLock<Vec<SwarmView>>,
    counters: RwLock<TrackerCounters>,
    malformed: std::sync::atomic::AtomicU64,
}

impl TrackingShared {
    /// The tracks as of the last step.
    pub fn tracks(&self) -> Vec<TrackView> {
        self.tracks
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// The hostile swarms as of the last step.
    pub fn swarms(&self) -> Vec<SwarmView> {
        self.swarms
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// The tracker's counters as of the last step.
    pub fn counters(&self) -> TrackerCounters {
        *self.counters.read().unwrap_or_else(PoisonError::into_inner)
    }

    /// Detector frames dropped as malformed.
    pub fn malformed_events(&self) -> u64 {
        self.malformed.load(std::sync::atomic::Ordering::Relaxed)
    }
}

/// The running tracker; the task stops when this is dropped.
#[derive(Debug)]
pub struct TrackingService {
    shared: Arc<TrackingShared>,
    task: JoinHandle<()>,
}

impl Drop for TrackingService {
    fn drop(&mut self) {
        self.task.abort();
    }
}

impl TrackingService {
    /// Starts the tracker task on the current runtime.
    pub fn spawn(
        config: TrackerConfig,
        fleet: Fleet,
        events: broadcast::Sender<SwarmEvent>,
        metrics: Arc<Metrics>,
    ) -> Self {
        let shared = Arc::new(TrackingShared::default());
        let task = tokio::spawn(run(
            Tracker::new(config),
            fleet,
            events,
            metrics,
            shared.clone(),
        ));
        TrackingService { shared, task }
    }

    /// What the task publishes.
    pub fn shared(&self) -> &Arc<TrackingShared> {
        &self.shared
    }
}

fn hostile_swarm_event(e: HostileSwarmEvent) -> SwarmEvent {
    match e {
        HostileSwarmEvent::Detected(swarm) => SwarmEvent::SwarmDetected { swarm },
        HostileSwarmEvent::Changed {
            swarm,
            joined,
            left,
        } => SwarmEvent::SwarmChanged {
            swarm,
            joined,
            left,
        },
        HostileSwarmEvent::Lost(swarm) => SwarmEvent::SwarmLost { swarm },
    }
}

fn to_swarm_event(e: TrackEvent) -> SwarmEvent {
    match e {
        TrackEvent::Created(track) => SwarmEvent::TrackCreated { track },
        TrackEvent::Confirmed(track) => SwarmEvent::TrackConfirmed { track },
        TrackEvent::Lost(track) => SwarmEvent::TrackLost { track },
        TrackEvent::Recovered(track) => SwarmEvent::TrackRecovered { track },
        TrackEvent::Deleted(track) => SwarmEvent::TrackDeleted { track },
    }
}

async fn run(
    mut tracker: Tracker,
    fleet: Fleet,
    events: broadcast::Sender<SwarmEvent>,
    metrics: Arc<Metrics>,
    shared: Arc<TrackingShared>,
) {
    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / TRACKER_HZ));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    // The newest frame read from each (vehicle, detector slot).
    let mut seen: HashMap<(String, String), u64> = HashMap::new();
    let mut picture = AirPicture::new(GroupingConfig::default());
    loop {
        tick.tick().await;
        let mut bearings = Vec::new();
        for (id, slot, state) in fleet.payload_states(detection::DETECTOR_KIND) {
            let key = (id, slot);
            let frames = detection::new_frames(&state, seen.get(&key).copied());
            for f in frames {
                if let Some(n) = f["frame"].as_u64() {
                    seen.insert(key.clone(), n);
                }
                match detection::parse_detections(&key.0, f) {
                    Ok(rays) => bearings.extend(rays),
                    Err(e) => {
                        shared
                            .malformed
                            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        tracing::debug!(vehicle = %key.0, "dropped a detector frame: {e}");
                    }
                }
            }
        }
        let members: Vec<MemberPose> = fleet.map_snapshots(|s| {
            let p = s.position.as_ref()?;
            let v = &s.velocity;
            Some(MemberPose {
                id: s.id.clone(),
                position: Vector3::new(p.north_m, p.east_m, p.down_m),
                velocity: Vector3::new(v.north_m_s, v.east_m_s, v.down_m_s),
            })
        });
        let now = now_us();
        for e in tracker.step(now, bearings, &members) {
            let _ = events.send(to_swarm_event(e));
        }
        let mut tracks = tracker.tracks(now);
        let (swarms, swarm_events) = picture.update(now, &mut tracks);
        for e in swarm_events {
            let _ = events.send(hostile_swarm_event(e));
        }
        metrics.set_tracking(&tracks, &tracker.counters());
        *shared
            .tracks
            .write()
            .unwrap_or_else(PoisonError::into_inner) = tracks;
        *shared
            .swarms
            .write()
            .unwrap_or_else(PoisonError::into_inner) = swarms;
        *shared
            .counters
            .write()
            .unwrap_or_else(PoisonError::into_inner) = tracker.counters();
    }
}
