//! The tracker's tuning. The types it publishes (a track as the API shows it, track
//! events, counters) are in [`skein_protocol::tracks`], which the event bus and the metrics read.

/// Tuning of the tracker.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackerConfig {
    /// Bearing noise, degrees (camera pointing and centroid).
    pub bearing_sigma_deg: f64,
    /// Relative noise of a range from apparent size.
    pub size_range_rel_sigma: f64,
    /// Unmodelled acceleration of a target, m/s².
    pub accel_sigma_m_s2: f64,
    /// Association gate, χ² (2 degrees of freedom across a ray).
    pub gate_chi2: f64,
    /// A bearing passing this close to a track is always in its gate, metres.
    pub gate_floor_m: f64,
    /// Two observers' rays pass within this of each other (plus 3 % of the range) to start
    /// a track, metres.
    pub init_gate_m: f64,
    /// How long a bearing waits for another observer's before it starts a track alone, s.
    pub pair_window_s: f64,
    /// A bearing within this of a swarm member's pose (plus 2 % of the range) is that
    /// member, metres.
    pub member_exclusion_m: f64,
    /// Updates before a track is confirmed.
    pub confirm_hits: u32,
    /// A confirmed track unseen this long is lost, s.
    pub lost_after_s: f64,
    /// A tentative track unseen this long is deleted, s.
    pub tentative_timeout_s: f64,
    /// A lost track unseen this long is deleted (ages out), s.
    pub delete_after_s: f64,
    /// Two tracks closer than this are one, metres (when their velocities agree, see
    /// [`Tracker`](super::tracker::Tracker)'s merge).
    pub merge_m: f64,
    /// Two observers' bearings that fix a point this close to a confirmed or lost track
    /// not updated in the step continue that track (it manoeuvred out of its gate, or came
    /// back from a blind spot) instead of starting a new one, metres; grows by
    /// `reacquire_m_per_s` for every second the track went unseen.
    pub reacquire_m: f64,
    /// Growth of `reacquire_m` per second unseen, m/s (capped at twice `reacquire_m`).
    pub reacquire_m_per_s: f64,
}

impl Default for TrackerConfig {
    fn default() -> Self {
        TrackerConfig {
            bearing_sigma_deg: 0.15,
            size_range_rel_sigma: 0.35,
            accel_sigma_m_s2: 3.0,
            gate_chi2: 16.0,
            gate_floor_m: 1.5,
            init_gate_m: 2.0,
            pair_window_s: 0.4,
            member_exclusion_m: 2.0,
            confirm_hits: 3,
            lost_after_s: 1.0,
            tentative_timeout_s: 1.0,
            delete_after_s: 5.0,
            merge_m: 2.0,
            reacquire_m: 6.0,
            reacquire_m_per_s: 3.0,
        }
    }
}
