//! Track management of the [`Tracker`]: births from leftover bearings, continuing a
//! track that manoeuvred out of its gate or came back from a blind spot, the lifecycle,
//! and merging two tracks of one aircraft (see the [`super::tracker`] module docs).

use super::filter::ConstantVelocity;
use super::geometry::{Ray, closest_approach, fuse_rays};
use super::tracker::{NEW_VELOCITY_SIGMA_M_S, Track, TrackEvent, TrackStatus, Tracker, us_to_s};
use nalgebra::{Matrix3, Vector3};

/// Two tracks two observers each fixed this recently are two aircraft, not the halves of
/// one split over two cameras, seconds (see [`Tracker::join_split`]).
const SPLIT_AFTER_S: f64 = 1.0;

/// Which of two tracks on one aircraft keeps its id: the one being followed (a confirmed
/// track before a lost one, which may have coasted onto another aircraft; a lost one
/// before a tentative one, the aircraft back from a blind spot), else the older.
fn id_rank(t: &Track) -> (u8, u64) {
    let status = match t.status {
        TrackStatus::Confirmed => 2,
        TrackStatus::Lost => 1,
        TrackStatus::Tentative => 0,
    };
    (status, u64::MAX - t.created_us)
}

impl Tracker {
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
            filter: ConstantVelocity::new(
                z,
                cov,
                NEW_VELOCITY_SIGMA_M_S,
                self.config.accel_sigma_m_s2,
            ),
            t_us,
            created_us: t_us,
            last_update_us: t_us,
            hits: 1,
            triangulated_hits: triangulated,
            last_triangulated_us: (triangulated > 0).then_some(t_us),
            observers,
        });
        self.counters.tracks_created += 1;
        let t = self.tracks.last().expect("just pushed");
        TrackEvent::Created(self.view(t, t_us))
    }

    /// Two bearings of two observers that could be one aircraft: their rays pass within
    /// `init_gate_m` + 3 % of the range of each other, in front of both. Returns the
    /// distances along each ray to the closest approach and the miss distance, metres.
    fn rays_meet(&self, a: &Ray, b: &Ray) -> Option<(f64, f64, f64)> {
        if a.observer == b.observer {
            return None;
        }
        let (t1, t2, miss) = closest_approach(&a.origin, &a.dir, &b.origin, &b.dir)?;
        (t1 > 0.0 && t2 > 0.0 && miss <= self.config.init_gate_m + 0.03 * t1.max(t2))
            .then_some((t1, t2, miss))
    }

    /// Pairs of pending bearings from two observers whose rays meet in front of both:
    /// `(miss distance m, i, j)`, best first.
    fn meeting_pairs(&self) -> Vec<(f64, usize, usize)> {
        let pending = &self.pending;
        let mut pairs = Vec::new();
        for i in 0..pending.len() {
            for j in i + 1..pending.len() {
                if let Some((_, _, miss)) = self.rays_meet(&pending[i], &pending[j]) {
                    pairs.push((miss, i, j));
                }
            }
        }
        pairs.sort_by(|x, y| x.0.total_cmp(&y.0));
        pairs
    }

    /// One aircraft split over two tracks, each fed by one camera: two tracks that each
    /// got one lone bearing in this step, from two observers whose rays meet within reach
    /// of the track that keeps its id ([`id_rank`]), unless two observers fixed each of
    /// them within [`SPLIT_AFTER_S`] (two tracks each triangulated just before are two
    /// aircraft: the rays of two cameras each on another of them meet at a ghost). That
    /// track takes both bearings (and so a triangulated fix); returns the others,
    /// ascending, for the caller to delete after the updates.
    pub(super) fn join_split(&self, rays: &[Ray], assigned: &mut [Vec<usize>]) -> Vec<usize> {
        let fixed_lately = |t: &Track, at_us: u64| {
            t.last_triangulated_us
                .is_some_and(|l| us_to_s(at_us, l) < SPLIT_AFTER_S)
        };
        let mut gone = Vec::new();
        for a in 0..assigned.len() {
            for b in a + 1..assigned.len() {
                if assigned[a].len() != 1 || assigned[b].len() != 1 {
                    continue;
                }
                let (ra, rb) = (&rays[assigned[a][0]], &rays[assigned[b][0]]);
                let at_us = ra.stamp_us.max(rb.stamp_us);
                if fixed_lately(&self.tracks[a], at_us) && fixed_lately(&self.tracks[b], at_us) {
                    continue;
                }
                let Some((t1, t2, _)) = self.rays_meet(ra, rb) else {
                    continue;
                };
                let meet = (ra.origin + ra.dir * t1 + rb.origin + rb.dir * t2) / 2.0;
                let (keep, drop) = if id_rank(&self.tracks[a]) >= id_rank(&self.tracks[b]) {
                    (a, b)
                } else {
                    (b, a)
                };
                let k = &self.tracks[keep];
                if (k.filter.position() - meet).norm()
                    > self.reach_m(k, ra.stamp_us.max(rb.stamp_us))
                {
                    continue;
                }
                let moved = assigned[drop][0];
                assigned[drop].clear();
                assigned[keep].push(moved);
                gone.push(drop);
            }
        }
        gone.sort_unstable();
        gone.dedup();
        gone
    }

    /// A track no two observers have fixed yet has only one camera's guess of its range
    /// (the size range, or none for a distant blur): while it takes that camera's
    /// bearings, another camera's bearing of the same aircraft passes far from it and is
    /// left over, with no partner to start a track with. So when a bearing left over in
    /// this step (`used` false), from another observer, meets the ray of the one bearing
    /// such a track got (as two bearings must to start a track), the track takes it too;
    /// returns the tracks that did, for the caller to restart at the point the two fix.
    pub(super) fn triangulate_lone(
        &self,
        rays: &[Ray],
        assigned: &mut [Vec<usize>],
        used: &mut [bool],
    ) -> Vec<bool> {
        let mut restart = vec![false; assigned.len()];
        for (ti, ids) in assigned.iter_mut().enumerate() {
            if self.tracks[ti].triangulated_hits > 0 || ids.len() != 1 {
                continue;
            }
            let a = &rays[ids[0]];
            let best = rays
                .iter()
                .enumerate()
                .filter(|(j, _)| !used[*j])
                .filter_map(|(j, b)| Some((j, self.rays_meet(a, b)?.2)))
                .min_by(|x, y| x.1.total_cmp(&y.1));
            if let Some((j, _)) = best {
                used[j] = true;
                ids.push(j);
                restart[ti] = true;
            }
        }
        restart
    }

    /// How far from its prediction a confirmed or lost track may be continued, metres.
    pub(super) fn reach_m(&self, t: &Track, at_us: u64) -> f64 {
        let c = &self.config;
        let unseen = us_to_s(at_us, t.last_update_us).max(0.0);
        (c.reacquire_m + c.reacquire_m_per_s * unseen).min(2.0 * c.reacquire_m)
    }

    /// The confirmed or lost track (not `updated` in this step, not in `skip`) whose
    /// prediction at `at_us` lies nearest `z` within its reach.
    fn continuable(
        &self,
        z: &Vector3<f64>,
        at_us: u64,
        updated: &[bool],
        skip: &[bool],
    ) -> Option<usize> {
        self.tracks
            .iter()
            .enumerate()
            .filter(|(i, t)| !updated[*i] && !skip[*i] && t.status != TrackStatus::Tentative)
            .filter_map(|(i, t)| {
                let mut f = t.filter.clone();
                f.predict(us_to_s(at_us, t.t_us));
                let d = (f.position() - z).norm();
                (d <= self.reach_m(t, at_us)).then_some((i, d))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i)
    }

    /// Continues confirmed and lost tracks that no bearing updated in this step
    /// (`updated`) with the pending pairs of bearings that fix a point within their reach:
    /// the aircraft manoeuvred out of the track's gate, or came back from a blind spot.
    /// The filter restarts at the point and keeps its velocity, with the uncertainty of a
    /// new track's; the id stays.
    pub(super) fn reacquire(&mut self, updated: &[bool], events: &mut Vec<TrackEvent>) {
        if self.pending.len() < 2
            || self
                .tracks
                .iter()
                .all(|t| t.status == TrackStatus::Tentative)
        {
            return;
        }
        let noise = self.noise();
        let mut taken = vec![false; self.pending.len()];
        let mut continued = vec![false; self.tracks.len()];
        for (_, i, j) in self.meeting_pairs() {
            if taken[i] || taken[j] {
                continue;
            }
            let (a, b) = (&self.pending[i], &self.pending[j]);
            let rays = [
                (a.origin, a.dir, a.range_from_size_m),
                (b.origin, b.dir, b.range_from_size_m),
            ];
            let Some((z, cov)) = fuse_rays(&rays, noise) else {
                continue;
            };
            let t_us = a.stamp_us.max(b.stamp_us);
            let Some(ti) = self.continuable(&z, t_us, updated, &continued) else {
                continue;
            };
            let mut observers = vec![a.observer.clone(), b.observer.clone()];
            observers.sort();
            taken[i] = true;
            taken[j] = true;
            continued[ti] = true;
            let accel = self.config.accel_sigma_m_s2;
            let t = &mut self.tracks[ti];
            let mut f = t.filter.clone();
            f.predict(us_to_s(t_us, t.t_us));
            let v = f.velocity();
            t.filter = ConstantVelocity::new(z, cov, NEW_VELOCITY_SIGMA_M_S, accel);
            t.filter.x.fixed_rows_mut::<3>(3).copy_from(&v);
            t.t_us = t_us;
            t.last_update_us = t.last_update_us.max(t_us);
            t.hits += 1;
            t.triangulated_hits += 1;
            t.last_triangulated_us = Some(t_us);
            t.observers = observers;
            self.counters.bearings_associated += 2;
            if t.status == TrackStatus::Lost {
                t.status = TrackStatus::Confirmed;
                events.push(TrackEvent::Recovered(self.view(&self.tracks[ti], t_us)));
            }
        }
        let pending = std::mem::take(&mut self.pending);
        self.pending = pending
            .into_iter()
            .zip(taken)
            .filter_map(|(r, t)| (!t).then_some(r))
            .collect();
    }

    pub(super) fn start_tracks(&mut self, now_us: u64, events: &mut Vec<TrackEvent>) {
        let noise = self.noise();
        let pairs = self.meeting_pairs();
        let mut pending = std::mem::take(&mut self.pending);
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
        // Bearings nobody matched in time start tracks alone, from their size range, unless
        // they pass within reach of a confirmed or lost track: that aircraft is tracked
        // already (a second track on it would be a duplicate).
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
            let near_a_track = self.tracks.iter().any(|t| {
                if t.status == TrackStatus::Tentative {
                    return false;
                }
                let mut f = t.filter.clone();
                f.predict(us_to_s(r.stamp_us, t.t_us));
                let q = f.position() - r.origin;
                let along = q.dot(&r.dir);
                along > 0.0 && (q - r.dir * along).norm() <= self.reach_m(t, r.stamp_us)
            });
            if near_a_track {
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

    pub(super) fn lifecycle(&mut self, now_us: u64, events: &mut Vec<TrackEvent>) {
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

    /// Two tracks on one aircraft: closer than `merge_m` at velocities they cannot tell
    /// apart (within 2 m/s, or within three standard deviations of the two estimates, as a
    /// young track's is). The one [`id_rank`] prefers stays; it takes the other's state
    /// when that one was updated more recently.
    pub(super) fn merge(&mut self, now_us: u64, events: &mut Vec<TrackEvent>) {
        let mut doomed = vec![false; self.tracks.len()];
        for i in 0..self.tracks.len() {
            for j in i + 1..self.tracks.len() {
                if doomed[i] || doomed[j] {
                    continue;
                }
                let (a, b) = (&self.tracks[i], &self.tracks[j]);
                let (fa, fb) = (&a.filter, &b.filter);
                // Compared at the same instant.
                let at = a.t_us.max(b.t_us);
                let (mut fa, mut fb) = (fa.clone(), fb.clone());
                fa.predict(us_to_s(at, a.t_us));
                fb.predict(us_to_s(at, b.t_us));
                let d = (fa.position() - fb.position()).norm();
                let dv = (fa.velocity() - fb.velocity()).norm();
                let v_var =
                    fa.p.fixed_view::<3, 3>(3, 3).trace() + fb.p.fixed_view::<3, 3>(3, 3).trace();
                // Crossing targets come close too, but at velocities known to differ.
                if d < self.config.merge_m && (dv < 2.0 || dv * dv <= 9.0 * v_var) {
                    let (keep, drop) = if id_rank(a) >= id_rank(b) {
                        (i, j)
                    } else {
                        (j, i)
                    };
                    doomed[drop] = true;
                    if self.tracks[drop].last_update_us > self.tracks[keep].last_update_us {
                        let d = &self.tracks[drop];
                        let (filter, t_us, last, observers) = (
                            d.filter.clone(),
                            d.t_us,
                            d.last_update_us,
                            d.observers.clone(),
                        );
                        let (hits, tri, fixed) =
                            (d.hits, d.triangulated_hits, d.last_triangulated_us);
                        let k = &mut self.tracks[keep];
                        k.filter = filter;
                        k.t_us = t_us;
                        k.last_update_us = last;
                        k.observers = observers;
                        k.hits = k.hits.max(hits);
                        k.triangulated_hits = k.triangulated_hits.max(tri);
                        k.last_triangulated_us = k.last_triangulated_us.max(fixed);
                        if k.status == TrackStatus::Lost {
                            k.status = TrackStatus::Confirmed;
                            events
                                .push(TrackEvent::Recovered(self.view(&self.tracks[keep], now_us)));
                        }
                    }
                }
            }
        }
        for i in (0..self.tracks.len()).rev() {
            if doomed[i] {
                let t = self.tracks.remove(i);
                self.counters.tracks_deleted += 1;
                events.push(TrackEvent::Deleted(self.view(&t, now_us)));
            }
        }
    }
}
