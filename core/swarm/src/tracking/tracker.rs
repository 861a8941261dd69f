//! The multi-target tracker: bearings from every observation UAV in, 3D tracks out.
//!
//! Each [`Tracker::step`]:
//! 1. drops bearings that point at a swarm member (its known pose within
//!    `member_exclusion_m` of the ray): swarm members are never tracks;
//! 2. predicts every track (constant-velocity Kalman filter) to the batch's time and moves
//!    each ray by the track's velocity for its age, so bearings taken at different instants
//!    meet at one point;
//! 3. associates each observer's bearings with the tracks one-to-one by minimum total
//!    Mahalanobis distance (Hungarian algorithm, `pathfinding::kuhn_munkres_min`, integer
//!    weights), gated at χ² `gate_chi2` (or `gate_floor_m` across the ray);
//! 4. updates each track with the point its bearings fix ([`super::geometry::fuse_rays`]:
//!    least-squares triangulation when two observers see it, the range from apparent size
//!    along a lone ray);
//! 5. starts tentative tracks from bearings left over: pairs from two observers whose rays
//!    pass within `init_gate_m` (scaled by range) are triangulated; a bearing no other
//!    observer matched within `pair_window_s` starts a track from its size range;
//! 6. runs the lifecycle: tentative → confirmed after `confirm_hits` updates, at least one
//!    of them triangulated; confirmed → lost after `lost_after_s` without an update (a lost
//!    track that is seen again is recovered under its id); tentative tracks unseen for
//!    `tentative_timeout_s` and lost tracks unseen for `delete_after_s` are deleted; a
//!    track that comes within `merge_m` of an older one is merged into it.
//!
//! Ids are `track-<n>`, n from 1, never reused.

use super::filter::ConstantVelocity;
use super::geometry::{Ray, RayNoise, closest_approach, fuse_rays, perp};
use nalgebra::{Matrix3, Vector3};
use pathfinding::prelude::{Matrix, kuhn_munkres_min};
use serde::Serialize;
use std::collections::BTreeMap;

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
    /// Two tracks closer than this are one, metres.
    pub merge_m: f64,
}

impl Default for TrackerConfig {
    fn default() -> Self {
        TrackerConfig {
            bearing_sigma_deg: 0.15,
            size_range_rel_sigma: 0.35,
            accel_sigma_m_s2: 2.0,
            gate_chi2: 16.0,
            gate_floor_m: 1.5,
            init_gate_m: 2.0,
            pair_window_s: 0.4,
            member_exclusion_m: 2.0,
            confirm_hits: 3,
            lost_after_s: 1.5,
            tentative_timeout_s: 1.0,
            delete_after_s: 5.0,
            merge_m: 2.0,
        }
    }
}

/// Where a track is in its life.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, utoipa::ToSchema)]
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
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
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
#[derive(Debug, Clone, Copy, PartialEq, Serialize, utoipa::ToSchema)]
pub struct NedJson {
    /// North, metres.
    pub north_m: f64,
    /// East, metres.
    pub east_m: f64,
    /// Down, metres.
    pub down_m: f64,
}

/// A NED velocity as JSON.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, utoipa::ToSchema)]
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

struct Track {
    id: String,
    status: TrackStatus,
    filter: ConstantVelocity,
    /// Time of the filter's state, µs.
    t_us: u64,
    created_us: u64,
    last_update_us: u64,
    hits: u32,
    triangulated_hits: u32,
    observers: Vec<String>,
}

/// The tracker (see the module docs). Times are wall-clock microseconds.
pub struct Tracker {
    config: TrackerConfig,
    tracks: Vec<Track>,
    /// Bearings not associated yet, waiting for a partner.
    pending: Vec<Ray>,
    next_id: u64,
    counters: TrackerCounters,
}

const SCALE: f64 = 1000.0;
const UNASSIGNED: i64 = 1 << 40;

fn us_to_s(a: u64, b: u64) -> f64 {
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

    fn noise(&self) -> RayNoise {
        RayNoise {
            bearing_sigma_rad: self.config.bearing_sigma_deg.to_radians(),
            size_range_rel_sigma: self.config.size_range_rel_sigma,
        }
    }

    fn view(&self, t: &Track, now_us: u64) -> TrackView {
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
        }
    }

    /// Every track now, predicted to `now_us`.
    pub fn tracks(&self, now_us: u64) -> Vec<TrackView> {
        self.tracks.iter().map(|t| self.view(t, now_us)).collect()
    }

    /// One step: `bearings` received since the last step, the swarm members' positions
    /// (id, swarm-frame NED) now. Returns what happened to the tracks.
    pub fn step(
        &mut self,
        now_us: u64,
        bearings: Vec<Ray>,
        members: &[(String, Vector3<f64>)],
    ) -> Vec<TrackEvent> {
        let mut events = Vec::new();
        self.counters.bearings += bearings.len() as u64;
        let (rays, excluded): (Vec<Ray>, Vec<Ray>) = bearings
            .into_iter()
            .partition(|r| !self.is_member(r, members));
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
        let leftover = self.associate_and_update(rays, &mut events);
        self.pending.extend(leftover);
        self.start_tracks(now_us, &mut events);
        self.lifecycle(now_us, &mut events);
        self.merge(now_us, &mut events);
        events
    }

    fn is_member(&self, r: &Ray, members: &[(String, Vector3<f64>)]) -> bool {
        members.iter().any(|(id, m)| {
            if *id == r.observer {
                return false;
            }
            let q = m - r.origin;
            let t = q.dot(&r.dir);
            t > 0.0 && (q - r.dir * t).norm() < self.config.member_exclusion_m + 0.02 * t
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

    fn associate_and_update(&mut self, rays: Vec<Ray>, events: &mut Vec<TrackEvent>) -> Vec<Ray> {
        let mut by_observer: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
        for (i, r) in rays.iter().enumerate() {
            by_observer.entry(r.observer.as_str()).or_default().push(i);
        }
        let mut assigned: Vec<Vec<usize>> = vec![Vec::new(); self.tracks.len()];
        let mut used = vec![false; rays.len()];
        let n_tracks = self.tracks.len();
        for idx in by_observer.values() {
            if n_tracks == 0 {
                break;
            }
            // Rows: this observer's bearings; columns: tracks, then one "new" column per
            // bearing (the cost of leaving it unassigned).
            let cols = n_tracks + idx.len();
            let mut m = Matrix::new(idx.len(), cols, UNASSIGNED * 4);
            for (row, &i) in idx.iter().enumerate() {
                m[(row, n_tracks + row)] = UNASSIGNED;
                for (c, t) in self.tracks.iter().enumerate() {
                    if let Some((d2, dist)) = self.ray_distance2(t, &rays[i])
                        && (d2 <= self.config.gate_chi2 || dist <= self.config.gate_floor_m)
                    {
                        m[(row, c)] = (d2.min(1e6) * SCALE) as i64;
                    }
                }
            }
            let (_, cols_of) = kuhn_munkres_min(&m);
            for (row, &c) in cols_of.iter().enumerate() {
                if c < n_tracks && m[(row, c)] < UNASSIGNED {
                    assigned[c].push(idx[row]);
                    used[idx[row]] = true;
                }
            }
        }
        let noise = self.noise();
        for (ti, ray_ids) in assigned.iter().enumerate() {
            if ray_ids.is_empty() {
                continue;
            }
            let t = &self.tracks[ti];
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
            let fix = fuse_rays(&fused, noise).or_else(|| {
                let along: Vec<_> = fused
                    .iter()
                    .map(|(o, d, _)| (*o, *d, Some((p - o).dot(d))))
                    .collect();
                fuse_rays(&along, noise)
            });
            let Some((z, cov)) = fix else {
                continue;
            };
            let view_before = self.tracks[ti].status;
            let t = &mut self.tracks[ti];
            if !t.filter.update(&z, &cov) {
                continue;
            }
            self.counters.bearings_associated += ray_ids.len() as u64;
            t.hits += 1;
            if triangulated {
                t.triangulated_hits += 1;
            }
            t.observers = observers;
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
        rays.into_iter()
            .zip(used)
            .filter_map(|(r, u)| (!u).then_some(r))
            .collect()
    }

    fn new_track(
        &mut self,
        z: Vector3<f64>,
        cov: Matrix3<f64>,
        t_us: u64,
        observers: Vec<String>,
    ) -> TrackEvent {
        let id = format!("track-{}", self.next_id);
        self.next_id += 1;
        let triangulated = u32::from(observers.len() >= 2);
        self.tracks.push(Track {
            id,
            status: TrackStatus::Tentative,
            filter: ConstantVelocity::new(z, cov, 8.0, self.config.accel_sigma_m_s2),
            t_us,
            created_us: t_us,
            last_update_us: t_us,
            hits: 1,
            triangulated_hits: triangulated,
            observers,
        });
        self.counters.tracks_created += 1;
        let t = self.tracks.last().expect("just pushed");
        TrackEvent::Created(self.view(t, t_us))
    }

    fn start_tracks(&mut self, now_us: u64, events: &mut Vec<TrackEvent>) {
        let noise = self.noise();
        let mut pending = std::mem::take(&mut self.pending);
        // Pairs of bearings from two observers whose rays meet: best pairs first.
        let mut pairs = Vec::new();
        for i in 0..pending.len() {
            for j in i + 1..pending.len() {
                let (a, b) = (&pending[i], &pending[j]);
                if a.observer == b.observer {
                    continue;
                }
                if let Some((t1, t2, miss)) = closest_approach(&a.origin, &a.dir, &b.origin, &b.dir)
                    && t1 > 0.0
                    && t2 > 0.0
                    && miss <= self.config.init_gate_m + 0.03 * t1.max(t2)
                {
                    pairs.push((miss, i, j));
                }
            }
        }
        pairs.sort_by(|x, y| x.0.total_cmp(&y.0));
        let mut taken = vec![false; pending.len()];
        for (_, i, j) in pairs {
            if taken[i] || taken[j] {
                continue;
            }
            let (a, b) = (&pending[i], &pending[j]);
            let rays = [
                (a.origin, a.dir, a.range_from_size_m),
                (b.origin, b.dir, b.range_from_size_m),
            ];
            if let Some((z, cov)) = fuse_rays(&rays, noise) {
                taken[i] = true;
                taken[j] = true;
                let t_us = a.stamp_us.max(b.stamp_us);
                let obs = vec![a.observer.clone(), b.observer.clone()];
                let ev = self.new_track(z, cov, t_us, obs);
                events.push(ev);
            }
        }
        // Bearings nobody matched in time start tracks alone, from their size range.
        let window_us = (self.config.pair_window_s * 1e6) as u64;
        let mut keep = Vec::new();
        for (r, t) in pending.drain(..).zip(taken) {
            if t {
                continue;
            }
            if now_us.saturating_sub(r.stamp_us) < window_us {
                keep.push(r);
                continue;
            }
            if let Some(rho) = r.range_from_size_m
                && let Some((z, cov)) = fuse_rays(&[(r.origin, r.dir, Some(rho))], noise)
            {
                let ev = self.new_track(z, cov, r.stamp_us, vec![r.observer.clone()]);
                events.push(ev);
            }
        }
        self.pending = keep;
    }

    fn lifecycle(&mut self, now_us: u64, events: &mut Vec<TrackEvent>) {
        let c = self.config.clone();
        let mut i = 0;
        while i < self.tracks.len() {
            let unseen = us_to_s(now_us, self.tracks[i].last_update_us);
            let status = self.tracks[i].status;
            let delete = match status {
                TrackStatus::Tentative => unseen > c.tentative_timeout_s,
                TrackStatus::Lost => unseen > c.delete_after_s,
                TrackStatus::Confirmed => false,
            };
            if delete {
                let t = self.tracks.remove(i);
                self.counters.tracks_deleted += 1;
                events.push(TrackEvent::Deleted(self.view(&t, now_us)));
                continue;
            }
            if status == TrackStatus::Confirmed && unseen > c.lost_after_s {
                self.tracks[i].status = TrackStatus::Lost;
                self.counters.tracks_lost += 1;
                events.push(TrackEvent::Lost(self.view(&self.tracks[i], now_us)));
            }
            i += 1;
        }
    }

    /// Two tracks on one target (as close as `merge_m`, velocities within 2 m/s): the
    /// younger (or the unconfirmed) one goes.
    fn merge(&mut self, now_us: u64, events: &mut Vec<TrackEvent>) {
        let rank = |t: &Track| {
            (
                t.status == TrackStatus::Confirmed,
                t.hits,
                u64::MAX - t.created_us,
            )
        };
        let mut doomed = Vec::new();
        for i in 0..self.tracks.len() {
            for j in i + 1..self.tracks.len() {
                let (a, b) = (&self.tracks[i], &self.tracks[j]);
                let d = (a.filter.position() - b.filter.position()).norm();
                let dv = (a.filter.velocity() - b.filter.velocity()).norm();
                // Crossing targets come close too, but not at the same velocity.
                if d < self.config.merge_m && dv < 2.0 {
                    doomed.push(if rank(a) >= rank(b) { j } else { i });
                }
            }
        }
        doomed.sort_unstable();
        doomed.dedup();
        for i in doomed.into_iter().rev() {
            let t = self.tracks.remove(i);
            self.counters.tracks_deleted += 1;
            events.push(TrackEvent::Deleted(self.view(&t, now_us)));
        }
    }
}
