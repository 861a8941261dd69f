//! Counter-UAS tracks as the rest of skein sees them: a track as the API, the stream and
//! the DDS `/skein/tracks` topic show it ([`TrackView`], swarm frame), what happens to
//! tracks ([`TrackEvent`]) and the tracker's counters. A leaf: the tracker
//! ([`crate::tracking`]) makes these, the event bus and the metrics read them.

use serde::{Deserialize, Serialize};

/// Where a track is in its life.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum TrackStatus {
    /// Seen, not yet confirmed.
    Tentative,
    /// Confirmed and being updated.
    Confirmed,
    /// Confirmed once, not seen for `lost_after_s`: predicted on, until it ages out.
    Lost,
}

/// A track as the API and the stream show it (swarm frame).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct TrackView {
    /// `track-<n>`.
    pub id: String,
    /// Lifecycle state.
    pub status: TrackStatus,
    /// Estimated position, swarm-frame NED, metres.
    pub position: NedJson,
    /// Estimated velocity, NED, m/s.
    pub velocity: VelocityJson,
    /// Horizontal position covariance `[[nn, ne], [ne, ee]]`, m² (the uncertainty ellipse).
    pub covariance_ne_m2: [[f64; 2]; 2],
    /// Root of the position covariance's trace, metres.
    pub position_sigma_m: f64,
    /// Updates so far.
    pub hits: u32,
    /// Updates fixed by two or more observers.
    pub triangulated_hits: u32,
    /// Observers of the last update.
    pub observers: Vec<String>,
    /// Seconds since the track started.
    pub age_s: f64,
    /// Seconds since its last update.
    pub unseen_s: f64,
}

/// A swarm-frame NED position as JSON.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct NedJson {
    /// North, metres.
    pub north_m: f64,
    /// East, metres.
    pub east_m: f64,
    /// Down, metres.
    pub down_m: f64,
}

/// A NED velocity as JSON.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct VelocityJson {
    /// North, m/s.
    pub north_m_s: f64,
    /// East, m/s.
    pub east_m_s: f64,
    /// Down, m/s.
    pub down_m_s: f64,
}

/// Something that happened to a track (the stream's `track_*` events).
#[derive(Debug, Clone, PartialEq)]
pub enum TrackEvent {
    /// A tentative track started.
    Created(TrackView),
    /// A tentative track was confirmed.
    Confirmed(TrackView),
    /// A confirmed track was not seen for `lost_after_s`.
    Lost(TrackView),
    /// A lost track was seen again (same id).
    Recovered(TrackView),
    /// A track was deleted (aged out, never confirmed, or merged into another).
    Deleted(TrackView),
}

/// Counters since the tracker started.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct TrackerCounters {
    /// Bearings received.
    pub bearings: u64,
    /// Bearings dropped as pointing at a swarm member.
    pub bearings_excluded_members: u64,
    /// Bearings that updated a track.
    pub bearings_associated: u64,
    /// Tracks started.
    pub tracks_created: u64,
    /// Tracks confirmed.
    pub tracks_confirmed: u64,
    /// Tracks lost.
    pub tracks_lost: u64,
    /// Tracks deleted.
    pub tracks_deleted: u64,
}
