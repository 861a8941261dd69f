//! The hub between a corrections source and the vehicles: every good RTCM3 frame is cut
//! into `GPS_RTCM_DATA` fragments once ([`crate::fragment`]) and queued for every vehicle
//! of this process under its rate cap, then sent paced to PX4's inject queue
//! ([`skein_link::corrections`]); and what was seen is kept for [`RtkStatus`]. The frames
//! of this process's own source are also tapped on their way ([`Hub::tap`]: what a relay
//! publishes); frames relayed from another process ([`crate::relay`]) go to the vehicles
//! the same way, untapped.

use crate::fragment::{TooLarge, fragments};
use crate::framer::{BaseStation, Frame, FramerCounts};
use crate::status::{BaseStatus, RtkStatus, SourceState, VehicleCorrections};
use skein_link::VehicleLink;
use skein_link::corrections::PACE_PERIOD;
use skein_model::geo::GeoPoint;
use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use tokio::sync::broadcast;

/// The vehicles corrections go to: `(vehicle id, its link)` of every vehicle of this
/// process, asked for each frame (vehicles join and leave).
pub type Vehicles = Arc<dyn Fn() -> Vec<(String, Arc<VehicleLink>)> + Send + Sync>;

/// The window of [`RtkStatus::bytes_per_s`].
const RATE_WINDOW: Duration = Duration::from_secs(5);

/// Frames a tap holds for a reader that falls behind (one that falls further behind
/// loses the oldest: `RecvError::Lagged`); a second of a busy base is about a dozen.
pub const TAP_DEPTH: usize = 64;

/// What the hub has seen (see [`Hub::status`]).
#[derive(Debug)]
struct Progress {
    source: Option<String>,
    state: SourceState,
    error: Option<String>,
    since: Instant,
    connects: u64,
    bytes_total: u64,
    recent: VecDeque<(Instant, usize)>,
    counts: FramerCounts,
    too_large: u64,
    last_frame: Option<Instant>,
    base: Option<(BaseStation, Instant)>,
    gga_position: Option<GeoPoint>,
    max_bytes_s: f64,
    stall_timeout_s: f64,
    sequence: u8,
}

impl Progress {
    fn new(source: Option<String>, max_bytes_s: f64, stall_timeout_s: f64) -> Self {
        Progress {
            state: if source.is_some() {
                SourceState::Connecting
            } else {
                SourceState::Idle
            },
            source,
            error: None,
            since: Instant::now(),
            connects: 0,
            bytes_total: 0,
            recent: VecDeque::new(),
            counts: FramerCounts::default(),
            too_large: 0,
            last_frame: None,
            base: None,
            gga_position: None,
            max_bytes_s,
            stall_timeout_s,
            sequence: 0,
        }
    }
}

/// Sends corrections to the vehicles and keeps the status (shared by the source's task
/// and the API).
pub struct Hub {
    progress: Mutex<Progress>,
    vehicles: Vehicles,
    /// Fragments wait for the pacing ([`Hub::pump_held_back`]).
    waiting: tokio::sync::Notify,
    /// Every good frame of the source ([`Hub::tap`]).
    tap: broadcast::Sender<Frame>,
}

impl Hub {
    /// A hub sending to `vehicles`, with no source yet.
    pub fn new(vehicles: Vehicles) -> Arc<Self> {
        Arc::new(Hub {
            progress: Mutex::new(Progress::new(None, crate::config::DEFAULT_MAX_BYTES_S, 0.0)),
            vehicles,
            waiting: tokio::sync::Notify::new(),
            tap: broadcast::channel(TAP_DEPTH).0,
        })
    }

    /// Every good frame of this process's own source from now on, as it goes to the
    /// vehicles (frames relayed from another process are not tapped); [`TAP_DEPTH`]
    /// frames are held for a reader that falls behind.
    pub fn tap(&self) -> broadcast::Receiver<Frame> {
        self.tap.subscribe()
    }

    fn lock(&self) -> MutexGuard<'_, Progress> {
        self.progress.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// A new source (or none): counters start again (the `GPS_RTCM_DATA` sequence goes
    /// on).
    pub(crate) fn reset(&self, source: Option<String>, max_bytes_s: f64, stall_timeout_s: f64) {
        let mut p = self.lock();
        let sequence = p.sequence;
        *p = Progress::new(source, max_bytes_s, stall_timeout_s);
        p.sequence = sequence;
    }

    /// A connection to the source is being opened (the error of the last one is kept
    /// until this one streams).
    pub(crate) fn connecting(&self) {
        let mut p = self.lock();
        if p.state != SourceState::Connecting {
            p.since = Instant::now();
        }
        p.state = SourceState::Connecting;
        p.connects += 1;
    }

    /// The source's state changed (`error`: why it failed or stalled).
    pub(crate) fn set_state(&self, state: SourceState, error: Option<String>) {
        let mut p = self.lock();
        if p.state != state {
            p.since = Instant::now();
        }
        p.state = state;
        if error.is_some() || state == SourceState::Streaming {
            p.error = error;
        }
    }

    /// Bytes arrived from the source, with the framer's counts after them.
    pub(crate) fn received(&self, bytes: usize, counts: &FramerCounts) {
        let now = Instant::now();
        let mut p = self.lock();
        p.bytes_total += bytes as u64;
        p.recent.push_back((now, bytes));
        while p
            .recent
            .front()
            .is_some_and(|(t, _)| now - *t > RATE_WINDOW)
        {
            p.recent.pop_front();
        }
        p.counts = counts.clone();
    }

    /// Where the fleet was said to be (GGA).
    pub(crate) fn told_position(&self, p: GeoPoint) {
        self.lock().gga_position = Some(p);
    }

    /// The mean position of the vehicles that report one (for GGA); `None` without any.
    pub(crate) fn fleet_position(&self) -> Option<GeoPoint> {
        let points: Vec<GeoPoint> = (self.vehicles)()
            .iter()
            .filter_map(|(_, l)| {
                l.with_telemetry(|t| t.global.map(|g| g.geo).or(t.home.map(|h| h.geo)))
            })
            .collect();
        let n = points.len() as f64;
        (n > 0.0).then(|| {
            let sum = points.iter().fold((0.0, 0.0, 0.0), |a, p| {
                (a.0 + p.lat_deg, a.1 + p.lon_deg, a.2 + p.alt_amsl_m)
            });
            GeoPoint::new(sum.0 / n, sum.1 / n, sum.2 / n)
        })
    }

    /// Sends a good frame of this process's source to every vehicle, and to the tap's
    /// readers ([`Hub::tap`]); the first frame after connecting makes the source
    /// [`SourceState::Streaming`].
    pub fn deliver(&self, frame: &Frame) {
        if self.tap.receiver_count() > 0 {
            // Fails only when the last reader left meanwhile.
            let _ = self.tap.send(frame.clone());
        }
        self.deliver_relayed(frame);
    }

    /// Sends a good frame relayed from another process to every vehicle, as
    /// [`Hub::deliver`] does, without tapping it.
    pub fn deliver_relayed(&self, frame: &Frame) {
        let now = Instant::now();
        let (sequence, cap) = {
            let mut p = self.lock();
            p.last_frame = Some(now);
            if let Some(b) = frame.base {
                p.base = Some((b, now));
            }
            if p.state != SourceState::Streaming && p.source.is_some() {
                p.state = SourceState::Streaming;
                p.since = now;
                p.error = None;
            }
            p.sequence = p.sequence.wrapping_add(1);
            (p.sequence, p.max_bytes_s)
        };
        let parts = match fragments(&frame.bytes, sequence) {
            Ok(f) => f,
            Err(TooLarge(n)) => {
                tracing::debug!("RTCM message of {n} bytes is too large for GPS_RTCM_DATA");
                self.lock().too_large += 1;
                return;
            }
        };
        for (_, link) in (self.vehicles)() {
            if !link.is_lost() {
                link.corrections()
                    .offer(parts.clone(), frame.bytes.len(), cap, now);
            }
        }
        if self.pump_all(now) {
            self.waiting.notify_one();
        }
    }

    /// Sends what each vehicle's pacing allows now ([`skein_link::corrections`]); true
    /// when fragments are still waiting.
    fn pump_all(&self, now: Instant) -> bool {
        let mut waiting = false;
        for (_, link) in (self.vehicles)() {
            waiting |= link
                .corrections()
                .pump(now, |m| link.endpoint.send(link.sysid, m).is_ok());
        }
        waiting
    }

    /// Sends the fragments the pacing held back, every [`PACE_PERIOD`] while any wait;
    /// for ever (beside the service's task).
    pub(crate) async fn pump_held_back(&self) {
        loop {
            self.waiting.notified().await;
            loop {
                tokio::time::sleep(PACE_PERIOD).await;
                if !self.pump_all(Instant::now()) {
                    break;
                }
            }
        }
    }

    /// The status now.
    pub fn status(&self) -> RtkStatus {
        let now = Instant::now();
        let p = self.lock();
        let window = p
            .recent
            .front()
            .map_or(RATE_WINDOW, |(t, _)| (now - *t).max(Duration::from_secs(1)))
            .min(RATE_WINDOW);
        let recent: usize = p.recent.iter().map(|(_, n)| n).sum();
        RtkStatus {
            source: p.source.clone(),
            state: p.state,
            error: p.error.clone(),
            state_age_s: (now - p.since).as_secs_f64(),
            connects: p.connects,
            bytes_total: p.bytes_total,
            bytes_per_s: recent as f64 / window.as_secs_f64(),
            frames: p.counts.frames,
            crc_failures: p.counts.crc_failures,
            garbage_bytes: p.counts.garbage_bytes,
            too_large: p.too_large,
            message_types: p
                .counts
                .message_types
                .iter()
                .map(|(t, n)| (t.to_string(), *n))
                .collect(),
            last_frame_age_s: p.last_frame.map(|t| (now - t).as_secs_f64()),
            base: p.base.map(|(b, t)| BaseStatus {
                station_id: b.station_id,
                position: b.position,
                age_s: (now - t).as_secs_f64(),
            }),
            gga_position: p.gga_position,
            max_bytes_s: p.max_bytes_s,
            stall_timeout_s: p.stall_timeout_s,
            vehicles: self.vehicle_corrections(),
            relay: None,
        }
    }

    fn vehicle_corrections(&self) -> Vec<VehicleCorrections> {
        let now_ms = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_millis() as u64);
        (self.vehicles)()
            .into_iter()
            .map(|(id, link)| {
                let s = link.corrections().sent();
                VehicleCorrections {
                    id,
                    messages: s.messages,
                    bytes: s.bytes,
                    dropped_over_cap: s.dropped_over_cap,
                    dropped_send: s.dropped_send,
                    correction_age_s: s
                        .last_unix_ms
                        .map(|t| now_ms.saturating_sub(t) as f64 / 1000.0),
                    fix_type: link.with_telemetry(|t| t.gps_fix_type),
                }
            })
            .collect()
    }
}
