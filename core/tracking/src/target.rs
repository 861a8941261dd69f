//! A track or a hostile swarm as a target to observe ([`locate`]): its centre, its points
//! now and as forecast [`PLAN_AHEAD_S`] ahead, and whether it is still fixed. The
//! coordinator points the observers' gimbals at the centre and plans their [`stations`]
//! for the points.
//!
//! [`stations`]: crate::stations

use skein_model::geo::Ned;
use skein_protocol::tracks::{NedJson, SWARM_PREFIX, SwarmView, TrackStatus, TrackView};

/// Stations are planned for the target's forecast this far ahead (about the time an
/// observer takes to get there), seconds.
pub const PLAN_AHEAD_S: f64 = 5.0;

/// A target where the coordinator sees it now: its centre (a track's position, a swarm's
/// centroid), its points now and as forecast [`PLAN_AHEAD_S`] ahead (a swarm's
/// members), and whether it is still fixed (a lost track is only predicted). Swarm-frame
/// NED, metres.
#[derive(Debug, Clone, PartialEq)]
pub struct TargetNow {
    /// A track's position, a swarm's centroid.
    pub centre: Ned,
    /// Its points now: the track, or the swarm's member tracks.
    pub now: Vec<Ned>,
    /// The same points as forecast [`PLAN_AHEAD_S`] ahead (where a track has no forecast
    /// yet, where it is).
    pub ahead: Vec<Ned>,
    /// False for a lost track.
    pub live: bool,
}

fn ned(p: &NedJson) -> Ned {
    Ned::new(p.north_m, p.east_m, p.down_m)
}

/// `track`'s forecast `horizon_s` ahead, or its position.
fn ahead_of(track: &TrackView, horizon_s: f64) -> Ned {
    track
        .forecast
        .iter()
        .find(|f| (f.horizon_s - horizon_s).abs() < 1e-9)
        .map_or(ned(&track.position), |f| ned(&f.position))
}

/// Where `id` (a track or a swarm) is, from the tracker's `tracks` and `swarms`; `None`
/// when it has neither.
pub fn locate(id: &str, tracks: &[TrackView], swarms: &[SwarmView]) -> Option<TargetNow> {
    let h = PLAN_AHEAD_S;
    if id.starts_with(SWARM_PREFIX) {
        let s = swarms.iter().find(|s| s.id == id)?;
        let members: Vec<&TrackView> = tracks
            .iter()
            .filter(|t| s.members.contains(&t.id))
            .collect();
        return Some(TargetNow {
            centre: ned(&s.centroid),
            now: members.iter().map(|t| ned(&t.position)).collect(),
            ahead: members.iter().map(|t| ahead_of(t, h)).collect(),
            live: true,
        });
    }
    let t = tracks.iter().find(|t| t.id == id)?;
    Some(TargetNow {
        centre: ned(&t.position),
        now: vec![ned(&t.position)],
        ahead: vec![ahead_of(t, h)],
        live: t.status != TrackStatus::Lost,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::AirPicture;
    use crate::swarm_tests::track;
    use crate::swarms::GroupingConfig;

    #[test]
    fn a_track_is_its_forecast_ahead_and_a_swarm_its_members() {
        let mut lost = track("track-3", [0.0, -40.0], [0.0, 0.0]);
        lost.status = TrackStatus::Lost;
        let mut tracks = vec![
            track("track-1", [30.0, 0.0], [0.0, 4.0]),
            track("track-2", [30.0, 6.0], [0.0, 4.0]),
            lost,
        ];
        // Two tracks flying together become a swarm and get forecasts.
        let mut picture = AirPicture::new(GroupingConfig::default());
        let mut swarms = Vec::new();
        for k in 0..100u64 {
            let now_us = k * 100_000;
            for t in tracks.iter_mut().take(2) {
                t.position.east_m += 0.4;
            }
            swarms = picture.update(now_us, &mut tracks).0;
        }
        let one = locate("track-1", &tracks, &swarms).unwrap();
        assert!(one.live);
        assert_eq!(one.now, vec![one.centre]);
        // 4 m/s east for PLAN_AHEAD_S.
        let gone = one.ahead[0].east_m - one.centre.east_m;
        assert!((gone - 4.0 * PLAN_AHEAD_S).abs() < 2.0, "{one:?}");
        assert!(!locate("track-3", &tracks, &swarms).unwrap().live);
        let id = &swarms.first().expect("a swarm of two").id;
        let swarm = locate(id, &tracks, &swarms).unwrap();
        assert_eq!((swarm.now.len(), swarm.ahead.len()), (2, 2));
        assert!((swarm.centre.east_m - (swarm.now[0].east_m + 3.0)).abs() < 1e-9);
        assert_eq!(locate("track-9", &tracks, &swarms), None);
        assert_eq!(locate("swarm-9", &tracks, &swarms), None);
    }
}
