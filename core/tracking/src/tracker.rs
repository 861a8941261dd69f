//! The multi-target tracker: bearings from every observation UAV in, 3D tracks out.
//!
//! Each [`Tracker::step`]:
//! 1. drops bearings that point at a swarm member (its known pose, moved back along its
//!    velocity to the bearing's capture time, within `member_exclusion_m` of the ray,
//!    widened by the distance it flies in [`MEMBER_POSE_AGE_S`]): swarm members are never
//!    tracks, moving ones included;
//! 2. predicts every track (constant-velocity Kalman filter) to the batch's time and moves
//!    each ray by the track's velocity for its age, so bearings taken at different instants
//!    meet at one point;
//! 3. associates each observer's bearings with the tracks one-to-one by minimum total
//!    Mahalanobis distance (Hungarian algorithm, `pathfinding::kuhn_munkres_min`, integer
//!    weights), gated at χ² `gate_chi2` (or `gate_floor_m` across the ray); a lost
//!    track, whose covariance grew while it went unseen, only gets a bearing no other
//!    track in its gate can take;
//!    two tracks that each got one lone bearing, from two observers whose rays meet
//!    within reach (see 7) of the one that keeps its id (as in a merge, see 6), are one
//!    aircraft split over two cameras: it takes both bearings and the other is deleted;
//!    unless both were fixed by two
//!    observers within the last second: then they are two aircraft, and their rays meet at
//!    a ghost;
//!    a track no two observers fixed yet, fed by one camera, also takes a bearing of
//!    another observer left over in this step that meets its bearing's ray, and restarts
//!    at the point the two fix (its range was that one camera's guess);
//! 4. updates each track with the point its bearings fix ([`super::geometry::fuse_rays`]:
//!    least-squares triangulation when two observers see it, the range from apparent size
//!    along a lone ray);
//! 5. starts tentative tracks from bearings left over: pairs from two observers whose rays
//!    pass within `init_gate_m` (scaled by range) are triangulated; a bearing no other
//!    observer matched within `pair_window_s` starts a track from its size range;
//! 6. runs the lifecycle: tentative → confirmed after `confirm_hits` updates, at least one
//!    of them triangulated; confirmed → lost after `lost_after_s` without an update (a lost
//!    track that is seen again is recovered under its id); tentative tracks unseen for
//!    `tentative_timeout_s` and lost tracks unseen for `delete_after_s` are deleted; two
//!    tracks within `merge_m` of each other (at velocities they cannot tell apart) are
//!    merged, under the id of the one being followed (confirmed, then lost, then
//!    tentative; else the older);
//! 7. keeps ids through manoeuvres and blind spots: a pair of bearings left over in step 5
//!    whose point lies within `reacquire_m` of a confirmed or lost track that was not
//!    updated in the step continues that track (its filter restarts at the point, keeping
//!    its velocity with a widened uncertainty) rather than starting a second track on the
//!    same aircraft; a lone leftover bearing passing that close to such a track starts
//!    nothing.
//!
//! Step 5 and on live in [`super::management`]; the public types in [`super::track`].
//!
//! Ids are `track-<n>`, n from 1, never reused.

use super::filter::ConstantVelocity;
use super::geometry::{Ray, RayNoise, fuse_rays, perp};
use nalgebra::{Matrix3, Vector3};
use pathfinding::prelude::{Matrix, kuhn_munkres_min};
use std::collections::BTreeMap;

/// Velocity uncertainty of a new (or restarted) track, m/s per axis.
pub(super) const NEW_VELOCITY_SIGMA_M_S: f64 = 8.0;

pub use super::track::TrackerConfig;
pub(super) use skein_protocol::tracks::{
    NedJson, TrackEvent, TrackStatus, TrackView, TrackerCounters, VelocityJson,
};

pub(super) struct Track {
    pub(super) id: String,
    pub(super) status: TrackStatus,
    pub(super) filter: ConstantVelocity,
    /// Time of the filter's state, µs.
    pub(super) t_us: u64,
    pub(super) created_us: u64,
    pub(super) last_update_us: u64,
    pub(super) hits: u32,
    pub(super) triangulated_hits: u32,
    /// Time of the last update two observers fixed, µs.
    pub(super) last_triangulated_us: Option<u64>,
    pub(super) observers: Vec<String>,
}

/// The point a track's bearings of one step fix.
struct Fix {
    /// Swarm-frame NED, metres.
    point: Vector3<f64>,
    /// Its covariance, m².
    cov: Matrix3<f64>,
    /// The observers of the bearings, sorted, once each.
    observers: Vec<String>,
    /// Fixed by two observers or more.
    triangulated: bool,
}

/// The tracker (see the module docs). Times are wall-clock microseconds.
pub struct Tracker {
    pub(super) config: TrackerConfig,
    pub(super) tracks: Vec<Track>,
    /// Bearings not associated yet, waiting for a partner.
    pub(super) pending: Vec<Ray>,
    pub(super) next_id: u64,
    pub(super) counters: TrackerCounters,
}

/// A swarm member's pose as the tracker gets it: id, swarm-frame NED position (m) and
/// velocity (m/s) now.
#[derive(Debug, Clone, PartialEq)]
pub struct MemberPose {
    /// Vehicle id.
    pub id: String,
    /// Position, swarm-frame NED, metres.
    pub position: Vector3<f64>,
    /// Velocity, NED, m/s.
    pub velocity: Vector3<f64>,
}

/// How old a member's pose may be when the tracker reads it (its 10 Hz snapshot), s.
pub const MEMBER_POSE_AGE_S: f64 = 0.1;

const SCALE: f64 = 1000.0;
const UNASSIGNED: i64 = 1 << 40;

pub(super) fn us_to_s(a: u64, b: u64) -> f64 {
    (a as f64 - b as f64) / 1e6
}

impl Tracker {
    /// An empty tracker.
    pub fn new(config: TrackerConfig) -> Self {
        Tracker {
            config,
            tracks: Vec::new(),
            pending: Vec::new(),
            next_id: 1,
            counters: TrackerCounters::default(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &TrackerConfig {
        &self.config
    }

    /// Counters since the start.
    pub fn counters(&self) -> TrackerCounters {
        self.counters
    }

    pub(super) fn noise(&self) -> RayNoise {
        RayNoise {
            bearing_sigma_rad: self.config.bearing_sigma_deg.to_radians(),
            size_range_rel_sigma: self.config.size_range_rel_sigma,
        }
    }

    pub(super) fn view(&self, t: &Track, now_us: u64) -> TrackView {
        let mut f = t.filter.clone();
        f.predict(us_to_s(now_us, t.t_us));
        let (p, v, c) = (f.position(), f.velocity(), f.position_cov());
        TrackView {
            id: t.id.clone(),
            status: t.status,
            position: NedJson {
                north_m: p.x,
                east_m: p.y,
                down_m: p.z,
            },
            velocity: VelocityJson {
                north_m_s: v.x,
                east_m_s: v.y,
                down_m_s: v.z,
            },
            covariance_ne_m2: [[c[(0, 0)], c[(0, 1)]], [c[(1, 0)], c[(1, 1)]]],
            position_sigma_m: c.trace().max(0.0).sqrt(),
            hits: t.hits,
            triangulated_hits: t.triangulated_hits,
            observers: t.observers.clone(),
            age_s: us_to_s(now_us, t.created_us).max(0.0),
            unseen_s: us_to_s(now_us, t.last_update_us).max(0.0),
            velocity_sigma_m_s: f.p.fixed_view::<3, 3>(3, 3).trace().max(0.0).sqrt(),
            forecast: Vec::new(),
            swarm: None,
        }
    }

    /// Every track now, predicted to `now_us`.
    pub fn tracks(&self, now_us: u64) -> Vec<TrackView> {
        self.tracks.iter().map(|t| self.view(t, now_us)).collect()
    }

    /// One step: `bearings` received since the last step, the swarm members' poses now.
    /// Returns what happened to the tracks.
    pub fn step(
        &mut self,
        now_us: u64,
        bearings: Vec<Ray>,
        members: &[MemberPose],
    ) -> Vec<TrackEvent> {
        let mut events = Vec::new();
        self.counters.bearings += bearings.len() as u64;
        let (rays, excluded): (Vec<Ray>, Vec<Ray>) = bearings
            .into_iter()
            .partition(|r| !self.is_member(r, members, now_us));
        self.counters.bearings_excluded_members += excluded.len() as u64;
        let mut rays = rays;
        rays.sort_by_key(|r| r.stamp_us);
        // The batch is processed at the time of its newest bearing.
        let batch_us = rays.last().map_or(now_us, |r| r.stamp_us);
        for t in &mut self.tracks {
            let dt = us_to_s(batch_us, t.t_us);
            if dt > 0.0 {
                t.filter.predict(dt);
                t.t_us = batch_us;
            }
        }
        let before: BTreeMap<String, u32> = self
            .tracks
            .iter()
            .map(|t| (t.id.clone(), t.triangulated_hits))
            .collect();
        let leftover = self.associate_and_update(rays, &mut events);
        // Tracks two observers fixed in this step are never continued by leftover
        // bearings (those are another aircraft's).
        let updated: Vec<bool> = self
            .tracks
            .iter()
            .map(|t| before.get(&t.id).is_some_and(|b| *b != t.triangulated_hits))
            .collect();
        self.pending.extend(leftover);
        self.reacquire(&updated, &mut events);
        self.start_tracks(now_us, &mut events);
        self.lifecycle(now_us, &mut events);
        self.merge(now_us, &mut events);
        events
    }

    fn is_member(&self, r: &Ray, members: &[MemberPose], now_us: u64) -> bool {
        members.iter().any(|m| {
            if m.id == r.observer {
                return false;
            }
            // Where it was when the frame was taken.
            let then = m.position - m.velocity * us_to_s(now_us, r.stamp_us).max(0.0);
            let q = then - r.origin;
            let t = q.dot(&r.dir);
            let gate =
                self.config.member_exclusion_m + 0.02 * t + m.velocity.norm() * MEMBER_POSE_AGE_S;
            t > 0.0 && (q - r.dir * t).norm() < gate
        })
    }

    /// The ray moved by the track's velocity for its age, so it points at where the
    /// target is at the batch time.
    fn shifted(r: &Ray, velocity: &Vector3<f64>, batch_us: u64) -> Vector3<f64> {
        r.origin + velocity * us_to_s(batch_us, r.stamp_us)
    }

    /// Mahalanobis distance² across the ray from the track's predicted position.
    fn ray_distance2(&self, t: &Track, r: &Ray) -> Option<(f64, f64)> {
        let o = Self::shifted(r, &t.filter.velocity(), t.t_us);
        let p = t.filter.position();
        let q = p - o;
        let along = q.dot(&r.dir);
        if along <= 0.0 {
            return None;
        }
        let pp = perp(&r.dir);
        let e = pp * q;
        let s_perp = self.config.bearing_sigma_deg.to_radians() * along;
        let s =
            pp * t.filter.position_cov() * pp + pp * (s_perp * s_perp) + r.dir * r.dir.transpose();
        let d2 = s.try_inverse().map(|si| (e.transpose() * si * e)[0])?;
        Some((d2, e.norm()))
    }

    /// Steps 3 and 4 of the module docs: associates `rays` with the tracks and updates
    /// each track with the point its bearings fix; deletes the tracks split over two
    /// cameras. Returns the bearings no track took.
    fn associate_and_update(&mut self, rays: Vec<Ray>, events: &mut Vec<TrackEvent>) -> Vec<Ray> {
        let (mut assigned, mut used) = self.associate(&rays);
        let split = self.join_split(&rays, &mut assigned);
        let restart = self.triangulate_lone(&rays, &mut assigned, &mut used);
        let noise = self.noise();
        for (ti, ray_ids) in assigned.iter().enumerate() {
            if ray_ids.is_empty() {
                continue;
            }
            let Some(fix) = Self::fix(&self.tracks[ti], &rays, ray_ids, noise) else {
                continue;
            };
            self.update(ti, fix, restart[ti], ray_ids.len(), events);
        }
        for i in split.into_iter().rev() {
            let t = self.tracks.remove(i);
            self.counters.tracks_deleted += 1;
            events.push(TrackEvent::Deleted(self.view(&t, t.t_us)));
        }
        rays.into_iter()
            .zip(used)
            .filter_map(|(r, u)| (!u).then_some(r))
            .collect()
    }

    /// Each observer's bearings to the tracks one-to-one, by minimum total gated cost
    /// ([`Tracker::costs`], Hungarian algorithm); bearings of different observers may go
    /// to one track. Returns each track's bearings (indices into `rays`) and which
    /// bearings a track took.
    fn associate(&self, rays: &[Ray]) -> (Vec<Vec<usize>>, Vec<bool>) {
        let mut by_observer: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
        for (i, r) in rays.iter().enumerate() {
            by_observer.entry(r.observer.as_str()).or_default().push(i);
        }
        let n_tracks = self.tracks.len();
        let mut assigned: Vec<Vec<usize>> = vec![Vec::new(); n_tracks];
        let mut used = vec![false; rays.len()];
        if n_tracks == 0 {
            return (assigned, used);
        }
        for idx in by_observer.values() {
            let m = self.costs(rays, idx);
            let (_, cols_of) = kuhn_munkres_min(&m);
            for (row, &c) in cols_of.iter().enumerate() {
                if c < n_tracks && m[(row, c)] < UNASSIGNED {
                    assigned[c].push(idx[row]);
                    used[idx[row]] = true;
                }
            }
        }
        (assigned, used)
    }

    /// The cost matrix of one observer's bearings (`idx` into `rays`): rows its bearings;
    /// columns the tracks, then one "new" column per bearing (the cost of leaving it
    /// unassigned). A track outside a bearing's gate costs more than leaving it.
    fn costs(&self, rays: &[Ray], idx: &[usize]) -> Matrix<i64> {
        let n_tracks = self.tracks.len();
        let mut m = Matrix::new(idx.len(), n_tracks + idx.len(), UNASSIGNED * 4);
        for (row, &i) in idx.iter().enumerate() {
            m[(row, n_tracks + row)] = UNASSIGNED;
            for (c, t) in self.tracks.iter().enumerate() {
                if let Some((d2, dist)) = self.ray_distance2(t, &rays[i])
                    && (d2 <= self.config.gate_chi2 || dist <= self.config.gate_floor_m)
                {
                    // A lost track's covariance has grown while it went unseen, so it
                    // would win bearings from a track being updated: it only gets one
                    // no such track can take.
                    let lost = if t.status == TrackStatus::Lost {
                        self.config.gate_chi2.max(1.0) * 4.0
                    } else {
                        0.0
                    };
                    m[(row, c)] = ((d2 + lost).min(1e6) * SCALE) as i64;
                }
            }
        }
        m
    }

    /// The point the bearings `ray_ids` (into `rays`) fix for track `t`, each moved by the
    /// track's velocity for its age; `None` when they fix none.
    fn fix(t: &Track, rays: &[Ray], ray_ids: &[usize], noise: RayNoise) -> Option<Fix> {
        let v = t.filter.velocity();
        let p = t.filter.position();
        let mut observers: Vec<String> =
            ray_ids.iter().map(|&i| rays[i].observer.clone()).collect();
        observers.sort();
        observers.dedup();
        let triangulated = observers.len() >= 2;
        let fused: Vec<_> = ray_ids
            .iter()
            .map(|&i| {
                let r = &rays[i];
                let o = Self::shifted(r, &v, t.t_us);
                // Two observers fix the point by triangulation alone (a size range is
                // far coarser); a lone bearing uses its size range, or without one
                // keeps the track's range.
                let range = if triangulated {
                    None
                } else {
                    r.range_from_size_m.or(Some((p - o).dot(&r.dir)))
                };
                (o, r.dir, range)
            })
            .collect();
        // Nearly parallel rays of two observers fix no point: keep the track's range.
        let (point, cov) = fuse_rays(&fused, noise).or_else(|| {
            let along: Vec<_> = fused
                .iter()
                .map(|(o, d, _)| (*o, *d, Some((p - o).dot(d))))
                .collect();
            fuse_rays(&along, noise)
        })?;
        Some(Fix {
            point,
            cov,
            observers,
            triangulated,
        })
    }

    /// Updates track `ti` with `fix` from `bearings` bearings (or, on `restart`, starts
    /// its filter again there: its range was one camera's guess), and runs its
    /// confirmation or recovery.
    fn update(
        &mut self,
        ti: usize,
        fix: Fix,
        restart: bool,
        bearings: usize,
        events: &mut Vec<TrackEvent>,
    ) {
        let view_before = self.tracks[ti].status;
        let accel = self.config.accel_sigma_m_s2;
        let t = &mut self.tracks[ti];
        if restart {
            t.filter = ConstantVelocity::new(fix.point, fix.cov, NEW_VELOCITY_SIGMA_M_S, accel);
        } else if !t.filter.update(&fix.point, &fix.cov) {
            return;
        }
        self.counters.bearings_associated += bearings as u64;
        t.hits += 1;
        if fix.triangulated {
            t.triangulated_hits += 1;
            t.last_triangulated_us = Some(t.t_us);
        }
        t.observers = fix.observers;
        t.last_update_us = t.t_us;
        let t_us = t.t_us;
        let confirm = view_before == TrackStatus::Tentative
            && t.hits >= self.config.confirm_hits
            && t.triangulated_hits >= 1;
        if confirm {
            t.status = TrackStatus::Confirmed;
            self.counters.tracks_confirmed += 1;
            events.push(TrackEvent::Confirmed(self.view(&self.tracks[ti], t_us)));
        } else if view_before == TrackStatus::Lost {
            self.tracks[ti].status = TrackStatus::Confirmed;
            events.push(TrackEvent::Recovered(self.view(&self.tracks[ti], t_us)));
        }
    }
}
