//! Prometheus metrics of the swarm (`GET /metrics`), with the `prometheus-client` crate.
//!
//! Supervision counters are labelled by actor kind (`kind="vehicle"`); gauges are set by
//! their owners (the formation loop, the link statistics).

use prometheus_client::encoding::text::encode;
use prometheus_client::metrics::counter::Counter;
use prometheus_client::metrics::family::Family;
use prometheus_client::metrics::gauge::Gauge;
use prometheus_client::registry::{Metric, Registry};
use skein_model::supervision::ChildKind;
use std::sync::atomic::AtomicU64;

type Labels = Vec<(String, String)>;

/// The metrics registry and the handles to update it.
pub struct Metrics {
    registry: Registry,
    failures: Family<Labels, Counter>,
    restarts: Family<Labels, Counter>,
    hangs: Family<Labels, Counter>,
    escalations: Family<Labels, Counter>,
    /// Vehicles known to the coordinator.
    pub vehicles: Gauge,
    /// Vehicles with a live link.
    pub vehicles_connected: Gauge,
    /// Root mean square of the formation slot errors, metres (NaN when no formation).
    pub formation_rms_error_m: Gauge<f64, AtomicU64>,
    /// Smallest distance between two airborne vehicles, metres.
    pub min_separation_m: Gauge<f64, AtomicU64>,
    /// Per-vehicle slot error, metres (`vehicle` label).
    pub slot_error_m: Family<Labels, Gauge<f64, AtomicU64>>,
    /// MAVLink frames dropped as malformed, per endpoint (`connection` label).
    pub mavlink_malformed: Family<Labels, Gauge>,
    /// Setpoints sent, per vehicle (`vehicle` label).
    pub setpoints_sent: Family<Labels, Gauge>,
    /// Longest pause of each vehicle's setpoint stream while streaming, ms (`vehicle`).
    pub setpoint_max_gap_ms: Family<Labels, Gauge<f64, AtomicU64>>,
    /// MAVLink frames dropped by signing checks (unsigned, bad signature, replayed, too
    /// old), per endpoint (`connection` label).
    pub mavlink_signing_dropped: Family<Labels, Gauge>,
    /// Ground-station forwarding, frames by `kind` (to_gcs, from_gcs, setpoints_dropped,
    /// no_route, to_gcs_dropped) and `connection`.
    pub gcs_forward_frames: Family<Labels, Gauge>,
    /// Payload driver threads given up because a call did not return in time (set by the
    /// coordinator from the payload actors' count before every render).
    pub payload_threads_abandoned: Gauge,
    /// DDS link samples since the start (`what` label: published, publish_errors,
    /// commands, malformed), set by the DDS link.
    pub dds_samples: Family<Labels, Gauge>,
    /// What DDS Security refused since the start (`reason` label: unauthenticated,
    /// identity, handshake, permissions, access_control, undecodable, replay; see
    /// `skein_dds::security::refusals`), set by the DDS link.
    pub dds_security_refusals: Family<Labels, Gauge>,
    /// Tracks by status (`status` label: tentative, confirmed, lost).
    tracks: Family<Labels, Gauge>,
    /// Tracker totals since the start (`what` label: bearings, bearings_excluded_members,
    /// bearings_associated, tracks_created, tracks_confirmed, tracks_lost, tracks_deleted).
    tracker_totals: Family<Labels, Gauge>,
    /// How late the process runs and what the watchdog forgave (`what` label, see
    /// [`Metrics::set_load`]).
    load: Family<Labels, Gauge<f64, AtomicU64>>,
    /// Optional work shed while short of CPU, by `work`.
    shed: Family<Labels, Gauge>,
}

impl std::fmt::Debug for Metrics {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Metrics").finish_non_exhaustive()
    }
}

impl Default for Metrics {
    fn default() -> Self {
        Self::new()
    }
}

/// A new metric of type `M`, registered in `registry` as `name` (after the `skein_`
/// prefix) with `help`; the handle that updates it.
fn registered<M>(registry: &mut Registry, name: &str, help: &str) -> M
where
    M: Metric + Clone + Default,
{
    let metric = M::default();
    registry.register(name, help, metric.clone());
    metric
}

fn kind(k: ChildKind) -> Labels {
    vec![("kind".to_string(), k.name().to_string())]
}

impl Metrics {
    /// A registry with every skein metric registered (in this order on `/metrics`).
    pub fn new() -> Self {
        let mut r = Registry::with_prefix("skein");
        Metrics {
            dds_samples: registered(
                &mut r,
                "dds_samples",
                "DDS link samples since the start: published, failed writes, commands taken, \
                 malformed samples dropped",
            ),
            dds_security_refusals: registered(
                &mut r,
                "dds_security_refusals",
                "What DDS Security refused since the start, by reason: participants without a \
                 certificate (unauthenticated), from another CA (identity), failed handshakes, \
                 invalid or expired permissions, endpoints the permissions do not grant \
                 (access_control), secured messages that failed to authenticate or decrypt \
                 (undecodable), samples of authentic messages RTPS had already delivered \
                 (replay)",
            ),
            load: registered(
                &mut r,
                "load",
                "How late the process runs and what it did about it: lag_ms (now), max_lag_ms \
                 (last 30 s), shedding (1 while optional work yields), shedding_episodes, \
                 tick_overruns (actor ticks skipped), watchdog_late (late pings forgiven while \
                 the process was late), calls_extended (payload calls given more time), \
                 restarts_deferred (held back by the tree's restart rate limit)",
            ),
            shed: registered(
                &mut r,
                "shed",
                "Units of optional work shed while short of CPU, by work (snapshots, dashboard, \
                 dds)",
            ),
            tracks: registered(
                &mut r,
                "tracks",
                "Tracks of non-cooperative aircraft, by status",
            ),
            tracker_totals: registered(
                &mut r,
                "tracker",
                "Counter-UAS tracker totals since the start: bearings received, excluded as \
                 swarm members, associated; tracks created, confirmed, lost, deleted",
            ),
            failures: registered(
                &mut r,
                "actor_failures",
                "Supervised actor failures (panic, error, hang), by actor kind",
            ),
            restarts: registered(
                &mut r,
                "actor_restarts",
                "Supervised actor restarts, by actor kind",
            ),
            hangs: registered(
                &mut r,
                "actor_hangs",
                "Actors killed by the watchdog for not answering, by actor kind",
            ),
            escalations: registered(
                &mut r,
                "actor_escalations",
                "Restart budgets spent (escalated to the parent), by actor kind",
            ),
            vehicles: registered(&mut r, "vehicles", "Vehicles known"),
            vehicles_connected: registered(
                &mut r,
                "vehicles_connected",
                "Vehicles with a live link",
            ),
            formation_rms_error_m: registered(
                &mut r,
                "formation_rms_error_m",
                "Root mean square of the formation slot errors, metres",
            ),
            min_separation_m: registered(
                &mut r,
                "min_separation_m",
                "Smallest distance between two airborne vehicles, metres",
            ),
            slot_error_m: registered(
                &mut r,
                "slot_error_m",
                "Distance from each vehicle to its formation slot, metres",
            ),
            mavlink_malformed: registered(
                &mut r,
                "mavlink_malformed_frames",
                "MAVLink input dropped as malformed (bad CRC, unknown id, garbage), per endpoint",
            ),
            mavlink_signing_dropped: registered(
                &mut r,
                "mavlink_signing_dropped_frames",
                "MAVLink frames dropped by MAVLink 2 signing checks (unsigned, bad signature, \
                 replayed, too old), per endpoint",
            ),
            gcs_forward_frames: registered(
                &mut r,
                "gcs_forward_frames",
                "Ground-station forwarding: frames to and from the ground station and dropped, \
                 by kind",
            ),
            setpoints_sent: registered(
                &mut r,
                "setpoints_sent",
                "Offboard setpoints sent, per vehicle",
            ),
            setpoint_max_gap_ms: registered(
                &mut r,
                "setpoint_max_gap_ms",
                "Longest pause of each vehicle's offboard setpoint stream while streaming, ms \
                 (PX4 fails safe after COM_OF_LOSS_T, 1 s; skein keeps it under 100 ms)",
            ),
            payload_threads_abandoned: registered(
                &mut r,
                "payload_driver_threads_abandoned",
                "Payload driver threads given up because a plugin call did not return within \
                 its deadline (each still holds its stuck driver)",
            ),
            registry: r,
        }
    }

    /// Sets the load metrics from the process's [`crate::load::LoadStatus`].
    pub fn set_load(&self, status: &crate::load::LoadStatus) {
        let shedding = status.level == crate::load::LoadLevel::Shedding;
        for (what, v) in [
            ("lag_ms", status.lag_ms),
            ("max_lag_ms", status.max_lag_ms),
            ("shedding", if shedding { 1.0 } else { 0.0 }),
            ("shedding_episodes", status.shedding_episodes as f64),
            ("tick_overruns", status.tick_overruns as f64),
            ("watchdog_late", status.watchdog_late as f64),
            ("calls_extended", status.calls_extended as f64),
            ("restarts_deferred", status.restarts_deferred as f64),
        ] {
            self.load.get_or_create(&Self::label("what", what)).set(v);
        }
        for (work, n) in &status.shed {
            self.shed
                .get_or_create(&Self::label("work", work))
                .set(*n as i64);
        }
    }

    /// Sets the tracking metrics from the tracker's current tracks and totals.
    pub fn set_tracking(
        &self,
        tracks: &[crate::tracks::TrackView],
        c: &crate::tracks::TrackerCounters,
    ) {
        use crate::tracks::TrackStatus;
        for (status, name) in [
            (TrackStatus::Tentative, "tentative"),
            (TrackStatus::Confirmed, "confirmed"),
            (TrackStatus::Lost, "lost"),
        ] {
            let n = tracks.iter().filter(|t| t.status == status).count();
            self.tracks
                .get_or_create(&Self::label("status", name))
                .set(n as i64);
        }
        for (what, v) in [
            ("bearings", c.bearings),
            ("bearings_excluded_members", c.bearings_excluded_members),
            ("bearings_associated", c.bearings_associated),
            ("tracks_created", c.tracks_created),
            ("tracks_confirmed", c.tracks_confirmed),
            ("tracks_lost", c.tracks_lost),
            ("tracks_deleted", c.tracks_deleted),
        ] {
            self.tracker_totals
                .get_or_create(&Self::label("what", what))
                .set(v as i64);
        }
    }

    /// Counts a failure of an actor of `k`.
    pub fn failed(&self, k: ChildKind) {
        self.failures.get_or_create(&kind(k)).inc();
    }

    /// Counts a restart.
    pub fn restarted(&self, k: ChildKind) {
        self.restarts.get_or_create(&kind(k)).inc();
    }

    /// Counts a hang.
    pub fn hung(&self, k: ChildKind) {
        self.hangs.get_or_create(&kind(k)).inc();
    }

    /// Counts an escalation.
    pub fn escalated(&self, k: ChildKind) {
        self.escalations.get_or_create(&kind(k)).inc();
    }

    /// One label set (`[("vehicle", "uav-1")]`).
    pub fn label(name: &str, value: &str) -> Labels {
        vec![(name.to_string(), value.to_string())]
    }

    /// The OpenMetrics text exposition.
    pub fn render(&self) -> String {
        let mut out = String::new();
        encode(&mut out, &self.registry).expect("writing to a String cannot fail");
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counters_render_with_kind_labels() {
        let m = Metrics::new();
        m.failed(ChildKind::Vehicle);
        m.failed(ChildKind::Vehicle);
        m.restarted(ChildKind::Px4Link);
        m.formation_rms_error_m.set(0.25);
        let text = m.render();
        assert!(
            text.contains("skein_actor_failures_total{kind=\"vehicle\"} 2"),
            "{text}"
        );
        assert!(
            text.contains("skein_actor_restarts_total{kind=\"px4link\"} 1"),
            "{text}"
        );
        assert!(text.contains("skein_formation_rms_error_m 0.25"), "{text}");
        assert!(text.ends_with("# EOF\n"));
    }
}
