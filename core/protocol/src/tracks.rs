//! Counter-UAS tracks as the rest of skein sees them: a track as the API, the stream and
//! the DDS `/skein/tracks` topic show it ([`TrackView`], swarm frame), what happens to
//! tracks ([`TrackEvent`]) and the tracker's counters; the hostile swarms the tracks are
//! grouped into ([`SwarmView`], [`HostileSwarmEvent`]) and the forecasts of
//! both ([`ForecastPoint`]). A leaf: the tracker (`skein_tracking`) makes these, the
//! event bus and the metrics read them.

use serde::{Deserialize, Serialize};

/// Hostile swarm ids are `swarm-<n>` (track ids `track-<n>`).
pub const SWARM_PREFIX: &str = "swarm-";

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
    /// Root of the velocity covariance's trace, m/s.
    #[serde(default)]
    pub velocity_sigma_m_s: f64,
    /// Where it will be in 5, 10 and 20 s (see `skein_tracking::forecast`); empty
    /// until the tracker has forecast it.
    #[serde(default)]
    pub forecast: Vec<ForecastPoint>,
    /// The hostile swarm it belongs to (`swarm-N`), if any.
    #[serde(default)]
    pub swarm: Option<String>,
}

/// The motion model a forecast extrapolates with (chosen per track, per horizon, by the
/// recent forecast residuals of each: see `skein_tracking::forecast`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum MotionModel {
    /// Straight on at the current velocity.
    ConstantVelocity,
    /// Turning at the current turn rate, at the current speed.
    ConstantTurn,
    /// On at the velocity averaged over the last seconds (a weaving path's mean course).
    MeanVelocity,
}

/// A predicted position: where the target will be `horizon_s` from now.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct ForecastPoint {
    /// How far ahead, seconds.
    pub horizon_s: f64,
    /// Predicted position, swarm-frame NED, metres.
    pub position: NedJson,
    /// One standard deviation of the horizontal error, metres (the filter's uncertainty
    /// grown over the horizon, and the model's recent residuals at that horizon).
    pub sigma_m: f64,
    /// The model it comes from.
    pub model: MotionModel,
}

/// The shape a hostile swarm flies in, from its members' horizontal positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum SwarmShape {
    /// Members along one line (abreast, in trail or echelon); two members are a line.
    Line,
    /// A V or wedge: a member ahead, the others swept back on both sides.
    Wedge,
    /// Anything else: a loose group.
    Cluster,
}

/// The size of a hostile swarm, horizontal, metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct SwarmExtent {
    /// Along the swarm's heading (`shape_heading_deg`), front to back, metres.
    pub length_m: f64,
    /// Across it, metres.
    pub width_m: f64,
    /// Largest distance of a member from the centroid, metres.
    pub radius_m: f64,
}

/// A hostile swarm: confirmed tracks flying together (see `skein_tracking::swarms`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct SwarmView {
    /// `swarm-<n>`, n from 1, never reused.
    pub id: String,
    /// Its tracks (`track-N`), sorted.
    pub members: Vec<String>,
    /// Mean of the members' positions, swarm-frame NED, metres.
    pub centroid: NedJson,
    /// Mean of the members' velocities, NED, m/s.
    pub velocity: VelocityJson,
    /// Horizontal speed of the centroid, m/s.
    pub speed_m_s: f64,
    /// Course over the ground, degrees clockwise from north (0 when hovering).
    pub course_deg: f64,
    /// Its shape.
    pub shape: SwarmShape,
    /// Where the shape points, degrees clockwise from north: a wedge's apex direction,
    /// a line's axis (0..180), a cluster's course.
    pub shape_heading_deg: f64,
    /// Its size.
    pub extent: SwarmExtent,
    /// Where its centroid will be in 5, 10 and 20 s (the mean of its members' forecasts).
    pub forecast: Vec<ForecastPoint>,
    /// Seconds since it was recognised.
    pub age_s: f64,
}

/// Something that happened to a hostile swarm (the stream's `swarm_*` events).
#[derive(Debug, Clone, PartialEq)]
pub enum HostileSwarmEvent {
    /// Tracks flying together were recognised as a swarm.
    Detected(SwarmView),
    /// Its members or its shape changed: `joined` and `left` name the tracks.
    Changed {
        /// The swarm now.
        swarm: SwarmView,
        /// Tracks that joined it.
        joined: Vec<String>,
        /// Tracks that left it.
        left: Vec<String>,
    },
    /// Fewer than two of its tracks fly together any more.
    Lost(SwarmView),
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
