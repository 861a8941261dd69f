//! A formation led by a track (`"leader": "track-7"`, `"standoff_m": 30`): the formation's
//! virtual leader is driven every formation tick toward the point `standoff_m` short of
//! the track on the line from the formation to it, at the formation's altitude, a little
//! faster than the track flies. The formation engine does the rest as for any virtual
//! leader (slots, pacing, separation, geofence clamping of the reference point). When the
//! track is lost or deleted, the leader holds: the formation stays where it is.
//!
//! A hostile swarm leads the same way (`"leader": "swarm-2"`), by its centroid as forecast
//! [`SWARM_LEAD_S`] ahead (the formation lags a target it chases; aiming where the swarm
//! will be makes up for it); a lost swarm makes the leader hold.

use super::CoordinatorState;
use super::messages::FieldError;
use super::observe::SWARM_PREFIX;
use crate::formation::{FormationSpec, LeaderMotion};
use crate::tracks::{SwarmView, TrackStatus, TrackView};
use skein_model::geo::Ned;

/// A swarm leader is followed by its centroid forecast this far ahead, seconds.
pub const SWARM_LEAD_S: f64 = 5.0;

/// Smallest and largest stand-off, metres.
pub const STANDOFF_RANGE_M: (f64, f64) = (5.0, 500.0);

/// Speed of the reference point: the track's horizontal speed plus this, m/s…
const CATCH_UP_M_S: f64 = 2.0;
/// … at most this (the vehicle models' default limit), m/s.
const MAX_SPEED_M_S: f64 = 8.0;

/// Checks a formation's track or swarm leader and stand-off against the tracker's
/// `tracks` and `swarms`: `standoff_m` only with such a leader, and then required within
/// [`STANDOFF_RANGE_M`]; the track must exist and be confirmed, the swarm must exist.
///
/// # Errors
/// The offending field (`leader`, `standoff_m`) and why.
pub fn validate_track_leader(
    spec: &FormationSpec,
    tracks: &[TrackView],
    swarms: &[SwarmView],
) -> Result<(), FieldError> {
    let err = |field: &str, error: String| {
        Err(FieldError {
            field: field.into(),
            error,
        })
    };
    let Some(track) = spec.track_leader() else {
        if spec.standoff_m.is_some() {
            return err(
                "standoff_m",
                "standoff_m goes with a track or swarm as leader (\"leader\": \"track-7\")".into(),
            );
        }
        return Ok(());
    };
    let (lo, hi) = STANDOFF_RANGE_M;
    match spec.standoff_m {
        Some(s) if s.is_finite() && (lo..=hi).contains(&s) => {}
        Some(s) => {
            return err(
                "standoff_m",
                format!("standoff_m {s} is outside {lo}..{hi} m"),
            );
        }
        None => {
            return err(
                "standoff_m",
                format!("a track as leader needs standoff_m ({lo}..{hi} m)"),
            );
        }
    }
    if track.starts_with(SWARM_PREFIX) {
        return match swarms.iter().find(|s| s.id == track) {
            Some(_) => Ok(()),
            None => err(
                "leader",
                format!("no swarm `{track}` (see GET /api/v1/swarms)"),
            ),
        };
    }
    match tracks.iter().find(|t| t.id == track) {
        None => err(
            "leader",
            format!("no track `{track}` (see GET /api/v1/tracks)"),
        ),
        Some(t) if t.status == TrackStatus::Lost => err(
            "leader",
            format!("track `{track}` is lost ({:.1} s unseen)", t.unseen_s),
        ),
        Some(t) if t.status == TrackStatus::Tentative => {
            err("leader", format!("track `{track}` is not confirmed yet"))
        }
        Some(_) => Ok(()),
    }
}

fn ned(t: &TrackView) -> Ned {
    Ned::new(t.position.north_m, t.position.east_m, t.position.down_m)
}

/// Where the reference point goes: `standoff_m` short of the track, horizontally, on the
/// line from `reference` to the track (along the track's velocity when they coincide),
/// at the reference's altitude.
pub fn follow_point(reference: Ned, track: Ned, track_velocity: Ned, standoff_m: f64) -> Ned {
    let d = Ned::new(
        track.north_m - reference.north_m,
        track.east_m - reference.east_m,
        0.0,
    );
    let toward = if d.horizontal_norm() > 1e-3 {
        d * (1.0 / d.horizontal_norm())
    } else if track_velocity.horizontal_norm() > 1e-3 {
        let v = Ned::new(track_velocity.north_m, track_velocity.east_m, 0.0);
        v * (1.0 / v.horizontal_norm())
    } else {
        Ned::new(1.0, 0.0, 0.0)
    };
    let p = Ned::new(track.north_m, track.east_m, reference.down_m) - toward * standoff_m;
    Ned::new(p.north_m, p.east_m, reference.down_m)
}

/// The leader motion that follows `track` (hold when it is missing or lost).
pub fn follow_motion(reference: Ned, track: Option<&TrackView>, standoff_m: f64) -> LeaderMotion {
    match track {
        Some(t) if t.status != TrackStatus::Lost => {
            let v = Ned::new(
                t.velocity.north_m_s,
                t.velocity.east_m_s,
                t.velocity.down_m_s,
            );
            follow(reference, ned(t), v, standoff_m)
        }
        _ => LeaderMotion::Hold,
    }
}

/// The leader motion that follows `swarm` by its centroid forecast [`SWARM_LEAD_S`] ahead
/// (its centroid until it has a forecast; hold when it is gone).
pub fn follow_swarm_motion(
    reference: Ned,
    swarm: Option<&SwarmView>,
    standoff_m: f64,
) -> LeaderMotion {
    let Some(s) = swarm else {
        return LeaderMotion::Hold;
    };
    let at = s
        .forecast
        .iter()
        .find(|f| (f.horizon_s - SWARM_LEAD_S).abs() < 1e-9)
        .map_or(s.centroid, |f| f.position);
    let v = Ned::new(
        s.velocity.north_m_s,
        s.velocity.east_m_s,
        s.velocity.down_m_s,
    );
    follow(
        reference,
        Ned::new(at.north_m, at.east_m, at.down_m),
        v,
        standoff_m,
    )
}

fn follow(reference: Ned, target: Ned, velocity: Ned, standoff_m: f64) -> LeaderMotion {
    LeaderMotion::GoTo {
        target: follow_point(reference, target, velocity, standoff_m),
        speed_m_s: (velocity.horizontal_norm() + CATCH_UP_M_S).min(MAX_SPEED_M_S),
    }
}

impl CoordinatorState {
    /// Drives the virtual leader of a formation led by a track (every formation tick).
    pub(super) fn follow_track_tick(&mut self) {
        let Some(spec) = self.formation.spec().filter(|_| self.formation.is_active()) else {
            return;
        };
        let (Some(track), Some(standoff)) =
            (spec.track_leader().map(str::to_string), spec.standoff_m)
        else {
            return;
        };
        let Some(reference) = self.formation.status(&[]).reference else {
            return;
        };
        let motion = if track.starts_with(SWARM_PREFIX) {
            let swarms = self.tracking.shared().swarms();
            follow_swarm_motion(
                reference.position,
                swarms.iter().find(|s| s.id == track),
                standoff,
            )
        } else {
            let tracks = self.tracking.shared().tracks();
            follow_motion(
                reference.position,
                tracks.iter().find(|t| t.id == track),
                standoff,
            )
        };
        if motion == LeaderMotion::Hold && reference.motion != LeaderMotion::Hold {
            tracing::info!(%track, "formation leader track missing or lost: the formation holds");
        }
        let _ = self.formation.set_motion(motion);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracks::{NedJson, VelocityJson};

    fn track(id: &str, status: TrackStatus, p: (f64, f64, f64)) -> TrackView {
        TrackView {
            id: id.into(),
            status,
            position: NedJson {
                north_m: p.0,
                east_m: p.1,
                down_m: p.2,
            },
            velocity: VelocityJson {
                north_m_s: 0.0,
                east_m_s: 3.0,
                down_m_s: 0.0,
            },
            covariance_ne_m2: [[1.0, 0.0], [0.0, 1.0]],
            position_sigma_m: 1.0,
            hits: 5,
            triangulated_hits: 5,
            observers: vec![],
            age_s: 3.0,
            unseen_s: 0.1,
            velocity_sigma_m_s: 0.2,
            forecast: vec![],
            swarm: None,
        }
    }

    fn spec(leader: &str, standoff_m: Option<f64>) -> FormationSpec {
        FormationSpec {
            shape: skein_model::formation::Shape::Wedge,
            spacing_m: 6.0,
            leader: Some(leader.into()),
            heading_deg: 0.0,
            altitude_m: None,
            frame: crate::formation::FormationFrame::World,
            offsets: vec![],
            standoff_m,
        }
    }

    #[test]
    fn unknown_lost_or_tentative_tracks_and_bad_standoffs_are_refused_by_field() {
        let tracks = [
            track("track-1", TrackStatus::Confirmed, (50.0, 0.0, -15.0)),
            track("track-2", TrackStatus::Lost, (50.0, 0.0, -15.0)),
            track("track-3", TrackStatus::Tentative, (50.0, 0.0, -15.0)),
        ];
        let field = |s: FormationSpec| validate_track_leader(&s, &tracks, &[]).unwrap_err().field;
        assert!(validate_track_leader(&spec("track-1", Some(30.0)), &tracks, &[]).is_ok());
        assert_eq!(field(spec("track-9", Some(30.0))), "leader");
        assert_eq!(field(spec("track-2", Some(30.0))), "leader");
        assert_eq!(field(spec("track-3", Some(30.0))), "leader");
        assert_eq!(field(spec("track-1", None)), "standoff_m");
        assert_eq!(field(spec("track-1", Some(1.0))), "standoff_m");
        assert_eq!(field(spec("uav-1", Some(30.0))), "standoff_m");
        assert!(validate_track_leader(&spec("uav-1", None), &tracks, &[]).is_ok());
        assert_eq!(field(spec("swarm-1", Some(30.0))), "leader");
        assert!(spec("track-1", Some(30.0)).track_leader().is_some());
        assert!(spec("uav-1", None).track_leader().is_none());
    }

    #[test]
    fn the_leader_keeps_the_standoff_on_the_line_to_the_track_and_holds_when_it_is_lost() {
        let reference = Ned::new(0.0, 0.0, -10.0);
        let t = track("track-1", TrackStatus::Confirmed, (40.0, 30.0, -20.0));
        match follow_motion(reference, Some(&t), 20.0) {
            LeaderMotion::GoTo { target, speed_m_s } => {
                // 50 m away along (0.8, 0.6): 20 m short is (24, 18), at the formation's
                // altitude; a little faster than the track's 3 m/s.
                assert!(
                    (target - Ned::new(24.0, 18.0, -10.0)).norm() < 1e-9,
                    "{target:?}"
                );
                assert!((speed_m_s - 5.0).abs() < 1e-9);
            }
            other => panic!("{other:?}"),
        }
        let lost = TrackView {
            status: TrackStatus::Lost,
            ..t.clone()
        };
        assert_eq!(
            follow_motion(reference, Some(&lost), 20.0),
            LeaderMotion::Hold
        );
        assert_eq!(follow_motion(reference, None, 20.0), LeaderMotion::Hold);
        // Right on top of it: back off against its velocity (east).
        let on_top = follow_point(
            Ned::new(40.0, 30.0, -10.0),
            Ned::new(40.0, 30.0, -20.0),
            Ned::new(0.0, 3.0, 0.0),
            20.0,
        );
        assert!(
            (on_top - Ned::new(40.0, 10.0, -10.0)).norm() < 1e-9,
            "{on_top:?}"
        );
    }

    #[test]
    fn a_swarm_leads_by_its_centroid_forecast_and_holds_when_gone() {
        use crate::tracks::{ForecastPoint, MotionModel, SwarmExtent, SwarmShape};
        let at = |n: f64, e: f64| NedJson {
            north_m: n,
            east_m: e,
            down_m: -15.0,
        };
        let swarm = SwarmView {
            id: "swarm-2".into(),
            members: vec!["track-1".into(), "track-2".into()],
            centroid: at(40.0, 0.0),
            velocity: VelocityJson {
                north_m_s: 0.0,
                east_m_s: 4.0,
                down_m_s: 0.0,
            },
            speed_m_s: 4.0,
            course_deg: 90.0,
            shape: SwarmShape::Line,
            shape_heading_deg: 0.0,
            extent: SwarmExtent {
                length_m: 6.0,
                width_m: 0.0,
                radius_m: 3.0,
            },
            forecast: [5.0, 10.0]
                .iter()
                .map(|h| ForecastPoint {
                    horizon_s: *h,
                    position: at(40.0, 4.0 * h),
                    sigma_m: 1.0,
                    model: MotionModel::ConstantVelocity,
                })
                .collect(),
            age_s: 3.0,
        };
        let reference = Ned::new(0.0, 20.0, -10.0);
        match follow_swarm_motion(reference, Some(&swarm), 20.0) {
            LeaderMotion::GoTo { target, speed_m_s } => {
                // The 5 s forecast is (40, 20): 40 m north of the formation, 20 m short.
                assert!(
                    (target - Ned::new(20.0, 20.0, -10.0)).norm() < 1e-9,
                    "{target:?}"
                );
                assert!((speed_m_s - 6.0).abs() < 1e-9);
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(
            follow_swarm_motion(reference, None, 20.0),
            LeaderMotion::Hold
        );
        let sw = [swarm];
        assert!(validate_track_leader(&spec("swarm-2", Some(30.0)), &[], &sw).is_ok());
        let e = validate_track_leader(&spec("swarm-2", None), &[], &sw).unwrap_err();
        assert_eq!(e.field, "standoff_m");
    }
}
