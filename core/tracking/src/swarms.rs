//! Hostile swarm recognition: confirmed tracks that fly together, grouped into swarms with
//! ids that last while members come and go.
//!
//! Each [`SwarmRecognizer::step`] (every tracker step, 10 Hz):
//! 1. **Grouping**: the confirmed tracks whose velocity is known (σ within
//!    [`GroupingConfig::max_velocity_sigma_m_s`]: a young track's is a guess, and two
//!    guesses agreeing make no swarm), and the lost tracks that were members already (they
//!    coast on their prediction until the tracker deletes them), are clustered by
//!    DBSCAN (the `dbscan` crate) over position and velocity scaled by
//!    [`GroupingConfig::eps_position_m`] and [`GroupingConfig::eps_velocity_m_s`]: two
//!    tracks are neighbours when `(Δp / eps_p)² + (Δv / eps_v)² < 1`, and a cluster is
//!    every track reachable through neighbours (so a V of 6 m ranks, whose neighbours are
//!    8.5 m apart, is one swarm however long its arms). Tracks that cross at different
//!    velocities are never neighbours; two swarms flying apart separate once their
//!    distance and velocity difference together exceed the thresholds.
//!    A confirmed track whose velocity is less certain (σ up to
//!    [`GroupingConfig::join_velocity_sigma_m_s`]: an aircraft seen from observers close
//!    together, whose range, and so its velocity, the rays fix poorly) starts nothing, but
//!    joins a recognised swarm when it is a neighbour of one of its members with the
//!    velocity scale widened by its σ (`eps_v² + σ²`): the one aircraft of a V whose track
//!    is less sure is not left out as a lone track flying in the middle of the swarm.
//! 2. **Ids**: each cluster takes the id of the swarm it shares the most tracks with (the
//!    largest overlaps first; a tie goes to the older swarm), so an id survives members
//!    leaving, joining and being replaced; a cluster sharing no track takes the swarm whose
//!    predicted centroid and velocity it matches within 1.5 × the thresholds (every member
//!    got a new track id at once); otherwise it is a candidate, recognised once it has held
//!    together for [`GroupingConfig::detect_after_s`]. When a swarm splits, the larger part
//!    keeps the id; when two merge, the one sharing more tracks does and the other is lost.
//!    Ids `swarm-N` are never reused.
//! 3. **Hysteresis**: a member that falls out of its cluster stays while it is within
//!    [`GroupingConfig::keep_factor`] × the thresholds of another member, and for
//!    [`GroupingConfig::leave_after_s`] after that; a deleted track leaves at once. A shape
//!    change counts once the new shape has held for [`GroupingConfig::shape_hold_s`].
//! 4. **Events**: `Detected` when recognised, `Changed` when members joined or left or the
//!    shape changed, `Lost` when fewer than [`GroupingConfig::min_members`] have remained
//!    for [`GroupingConfig::lost_after_s`] (until then it is listed with the members it
//!    has, and a cluster sharing one of them takes its id again).
//!
//! The swarm's centroid and velocity are its members' means, its shape comes from
//! [`super::shape`]. Its forecast ([`super::forecast`]) is its centroid's own, from the
//! swarm's history (which outlives its members' tracks: a weaving swarm's mean course is
//! learnt over longer than any one track lives), once that has been judged; until then
//! the mean of its members'.

use super::forecast::mean_forecast;
use super::shape;
use dbscan::Classification;
use skein_protocol::tracks::{
    HostileSwarmEvent, NedJson, SwarmShape, SwarmView, TrackStatus, TrackView, VelocityJson,
};
use std::collections::{BTreeMap, BTreeSet};

/// Tuning of the grouping.
#[derive(Debug, Clone, PartialEq)]
pub struct GroupingConfig {
    /// Position scale of the neighbour test, metres.
    pub eps_position_m: f64,
    /// Velocity scale of the neighbour test, m/s.
    pub eps_velocity_m_s: f64,
    /// Fewest tracks that make a swarm.
    pub min_members: usize,
    /// A new group is recognised once it held together this long, s.
    pub detect_after_s: f64,
    /// A member out of its cluster stays while within this many times the thresholds of
    /// another member.
    pub keep_factor: f64,
    /// … and this long after that, s.
    pub leave_after_s: f64,
    /// A new shape counts once it held this long, s.
    pub shape_hold_s: f64,
    /// Tracks whose velocity σ exceeds this do not start a swarm or join a candidate,
    /// m/s.
    pub max_velocity_sigma_m_s: f64,
    /// Tracks whose velocity σ exceeds this do not join a recognised swarm either, m/s
    /// (see the module docs, step 1).
    pub join_velocity_sigma_m_s: f64,
    /// A swarm with fewer than `min_members` is lost after this long, s.
    pub lost_after_s: f64,
}

impl Default for GroupingConfig {
    fn default() -> Self {
        GroupingConfig {
            eps_position_m: 20.0,
            eps_velocity_m_s: 3.0,
            min_members: 2,
            detect_after_s: 0.5,
            keep_factor: 1.5,
            leave_after_s: 1.0,
            shape_hold_s: 1.0,
            max_velocity_sigma_m_s: 2.5,
            join_velocity_sigma_m_s: 6.0,
            lost_after_s: 3.0,
        }
    }
}

/// A group of tracks: a recognised swarm, or a candidate.
#[derive(Debug, Clone)]
struct Group {
    /// `swarm-N` once recognised.
    id: Option<String>,
    /// Member track id → when it was last found with the group, s.
    members: BTreeMap<String, f64>,
    first_seen_s: f64,
    detected_s: f64,
    /// Its view as of the last step.
    view: Option<SwarmView>,
    last_t_s: f64,
    /// A shape seen lately that is not the view's yet, and since when.
    pending_shape: Option<(SwarmShape, f64)>,
    /// Since when it has had fewer than `min_members`, s.
    thin_since: Option<f64>,
    /// The centroid's own forecaster.
    forecaster: super::forecast::TrackForecaster,
}

impl Group {
    /// Gives `view` its centroid's own forecast, once the centroid's models have been
    /// judged (`members`: its tracks now).
    fn forecast_centroid(&mut self, t: f64, view: &mut SwarmView, members: &[&TrackView]) {
        let (cp, cv) = (&view.centroid, &view.velocity);
        let position = nalgebra::Vector3::new(cp.north_m, cp.east_m, cp.down_m);
        let velocity = nalgebra::Vector3::new(cv.north_m_s, cv.east_m_s, cv.down_m_s);
        self.forecaster.observe(t, position, velocity);
        if self.forecaster.judged() {
            let n = members.len() as f64;
            let var = members
                .iter()
                .map(|m| m.covariance_ne_m2[0][0] + m.covariance_ne_m2[1][1])
                .sum::<f64>()
                / n;
            let vs = members.iter().map(|m| m.velocity_sigma_m_s).sum::<f64>() / n;
            view.forecast = self
                .forecaster
                .forecast_from(t, position, velocity, var, vs);
        }
    }

    /// What the group's new `view` says happened to a recognised swarm: detected (its
    /// first view since recognised), or changed (its members, or its shape once the new
    /// one has held `shape_hold_s`; until then the view keeps the old shape).
    fn news(
        &mut self,
        t: f64,
        view: &mut SwarmView,
        c: &GroupingConfig,
    ) -> Option<HostileSwarmEvent> {
        let Some(before) = &self.view else {
            return self
                .id
                .is_some()
                .then(|| HostileSwarmEvent::Detected(view.clone()));
        };
        let mut shape_changed = false;
        if view.shape == before.shape {
            self.pending_shape = None;
        } else {
            let since = match self.pending_shape {
                Some((s, since)) if s == view.shape => since,
                _ => t,
            };
            self.pending_shape = Some((view.shape, since));
            if t - since + 1e-9 >= c.shape_hold_s {
                shape_changed = true;
                self.pending_shape = None;
            } else {
                view.shape = before.shape;
                view.shape_heading_deg = before.shape_heading_deg;
            }
        }
        let old: BTreeSet<&String> = before.members.iter().collect();
        let new: BTreeSet<&String> = view.members.iter().collect();
        let joined: Vec<String> = new.difference(&old).map(|s| (*s).clone()).collect();
        let left: Vec<String> = old.difference(&new).map(|s| (*s).clone()).collect();
        (self.id.is_some() && (shape_changed || !joined.is_empty() || !left.is_empty())).then(
            || HostileSwarmEvent::Changed {
                swarm: view.clone(),
                joined,
                left,
            },
        )
    }
}

/// The recognizer (see the module docs). Times are wall-clock microseconds.
#[derive(Debug)]
pub struct SwarmRecognizer {
    config: GroupingConfig,
    groups: Vec<Group>,
    next_id: u64,
}

/// `(Δp / eps_p)² + Δv² / (eps_v² + σ²)`, rooted: below 1 the two are neighbours. `σ`
/// (`sigma_m_s`) widens the velocity scale for a less sure track, 0 for the others.
fn scaled_distance(c: &GroupingConfig, a: &TrackView, b: &TrackView, sigma_m_s: f64) -> f64 {
    let (p, q) = (&a.position, &b.position);
    let (u, w) = (&a.velocity, &b.velocity);
    let dp2 = (p.north_m - q.north_m).powi(2)
        + (p.east_m - q.east_m).powi(2)
        + (p.down_m - q.down_m).powi(2);
    let dv2 = (u.north_m_s - w.north_m_s).powi(2)
        + (u.east_m_s - w.east_m_s).powi(2)
        + (u.down_m_s - w.down_m_s).powi(2);
    (dp2 / c.eps_position_m.powi(2) + dv2 / (c.eps_velocity_m_s.powi(2) + sigma_m_s.powi(2))).sqrt()
}

fn features(c: &GroupingConfig, t: &TrackView) -> Vec<f64> {
    let (p, v) = (&t.position, &t.velocity);
    vec![
        p.north_m / c.eps_position_m,
        p.east_m / c.eps_position_m,
        p.down_m / c.eps_position_m,
        v.north_m_s / c.eps_velocity_m_s,
        v.east_m_s / c.eps_velocity_m_s,
        v.down_m_s / c.eps_velocity_m_s,
    ]
}

/// The σ a track's velocity scale is widened by: its own when it is a less sure one (see
/// [`GroupingConfig::join_velocity_sigma_m_s`]), else none.
fn less_sure_sigma(c: &GroupingConfig, t: &TrackView) -> f64 {
    if t.velocity_sigma_m_s > c.max_velocity_sigma_m_s {
        t.velocity_sigma_m_s
    } else {
        0.0
    }
}

/// The view of a swarm of `members` (their tracks) at `t_s`.
fn view_of(id: &str, members: &[&TrackView], age_s: f64) -> SwarmView {
    let n = members.len().max(1) as f64;
    let mean = |f: &dyn Fn(&TrackView) -> f64| members.iter().map(|t| f(t)).sum::<f64>() / n;
    let centroid = NedJson {
        north_m: mean(&|t| t.position.north_m),
        east_m: mean(&|t| t.position.east_m),
        down_m: mean(&|t| t.position.down_m),
    };
    let velocity = VelocityJson {
        north_m_s: mean(&|t| t.velocity.north_m_s),
        east_m_s: mean(&|t| t.velocity.east_m_s),
        down_m_s: mean(&|t| t.velocity.down_m_s),
    };
    let points: Vec<[f64; 2]> = members
        .iter()
        .map(|t| [t.position.north_m, t.position.east_m])
        .collect();
    let est = shape::estimate(&points, [velocity.north_m_s, velocity.east_m_s]);
    let speed = velocity.north_m_s.hypot(velocity.east_m_s);
    let course = if speed > 1e-6 {
        velocity
            .east_m_s
            .atan2(velocity.north_m_s)
            .to_degrees()
            .rem_euclid(360.0)
    } else {
        0.0
    };
    let forecasts: Vec<&[skein_protocol::tracks::ForecastPoint]> =
        members.iter().map(|t| t.forecast.as_slice()).collect();
    let mut ids: Vec<String> = members.iter().map(|t| t.id.clone()).collect();
    ids.sort_by_key(|id| track_number(id));
    SwarmView {
        id: id.to_string(),
        members: ids,
        centroid,
        velocity,
        speed_m_s: speed,
        course_deg: course,
        shape: est.shape,
        shape_heading_deg: est.heading_deg,
        extent: est.extent,
        forecast: mean_forecast(&forecasts),
        age_s,
    }
}

/// `track-12` → 12, for a natural order of member ids.
fn track_number(id: &str) -> (u64, String) {
    let n = id
        .rsplit('-')
        .next()
        .and_then(|n| n.parse().ok())
        .unwrap_or(u64::MAX);
    (n, id.to_string())
}

/// One step's clusters of the tracks (indices into the step's tracks).
struct Clustering {
    /// The tracks that may be clustered: confirmed ones sure enough of their velocity, and
    /// the confirmed or lost members of a group.
    eligible: Vec<usize>,
    /// Cluster number → its tracks.
    clusters: BTreeMap<usize, Vec<usize>>,
    /// Track → its cluster number.
    cluster_of: BTreeMap<usize, usize>,
}

/// What a step regroups: its time (seconds), its tracks, their clusters, and each track's
/// index by id.
struct Regrouping<'a> {
    t: f64,
    tracks: &'a [TrackView],
    clustering: &'a Clustering,
    index: &'a BTreeMap<String, usize>,
}

/// Clusters the eligible `tracks` by DBSCAN over their scaled position and velocity
/// (`member_of`: track id → the group it is a member of).
fn cluster(
    c: &GroupingConfig,
    tracks: &[TrackView],
    member_of: &BTreeMap<String, usize>,
) -> Clustering {
    let eligible: Vec<usize> = (0..tracks.len())
        .filter(|&i| {
            let member = member_of.contains_key(&tracks[i].id);
            match tracks[i].status {
                TrackStatus::Confirmed => {
                    member || tracks[i].velocity_sigma_m_s <= c.max_velocity_sigma_m_s
                }
                TrackStatus::Lost => member,
                TrackStatus::Tentative => false,
            }
        })
        .collect();
    let input: Vec<Vec<f64>> = eligible.iter().map(|&i| features(c, &tracks[i])).collect();
    let classes = dbscan::cluster(1.0, c.min_members.max(2), &input);
    let mut clusters: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    let mut cluster_of: BTreeMap<usize, usize> = BTreeMap::new();
    for (k, class) in classes.iter().enumerate() {
        if let Classification::Core(n) | Classification::Edge(n) = class {
            clusters.entry(*n).or_default().push(eligible[k]);
            cluster_of.insert(eligible[k], *n);
        }
    }
    Clustering {
        eligible,
        clusters,
        cluster_of,
    }
}

impl SwarmRecognizer {
    /// A recognizer with no swarm.
    pub fn new(config: GroupingConfig) -> Self {
        SwarmRecognizer {
            config,
            groups: Vec::new(),
            next_id: 1,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &GroupingConfig {
        &self.config
    }

    /// The recognised swarms as of the last step, by id number.
    pub fn swarms(&self) -> Vec<SwarmView> {
        let mut v: Vec<SwarmView> = self
            .groups
            .iter()
            .filter(|g| g.id.is_some())
            .filter_map(|g| g.view.clone())
            .collect();
        v.sort_by_key(|s| track_number(&s.id));
        v
    }

    /// One step over the tracks as of `now_us` (with their forecasts): regroups them,
    /// sets each track's `swarm`, and returns what happened to the swarms.
    pub fn step(&mut self, now_us: u64, tracks: &mut [TrackView]) -> Vec<HostileSwarmEvent> {
        let t = now_us as f64 / 1e6;
        let member_of: BTreeMap<String, usize> = self
            .groups
            .iter()
            .enumerate()
            .flat_map(|(g, grp)| grp.members.keys().map(move |id| (id.clone(), g)))
            .collect();
        let clustering = cluster(&self.config, tracks, &member_of);
        let index: BTreeMap<String, usize> = tracks
            .iter()
            .enumerate()
            .map(|(i, t)| (t.id.clone(), i))
            .collect();
        let assigned = self.match_clusters(t, tracks, &clustering.clusters, &member_of);
        let joining = self.less_sure_joiners(
            &self.config,
            tracks,
            &clustering.eligible,
            &clustering.clusters,
            &assigned,
        );
        let step = Regrouping {
            t,
            tracks,
            clustering: &clustering,
            index: &index,
        };
        self.update_members(&step, &assigned, &joining);
        self.add_candidates(&step, &assigned);
        let events = self.update_views(t, tracks, &index);
        for tr in tracks.iter_mut() {
            tr.swarm = None;
        }
        for g in self.groups.iter().filter(|g| g.id.is_some()) {
            for id in g.members.keys() {
                if let Some(&i) = index.get(id) {
                    tracks[i].swarm = g.id.clone();
                }
            }
        }
        events
    }

    /// Each group takes the tracks of its cluster (`assigned`: group index → cluster
    /// number) and its less sure `joining` ones, and keeps those that still fly with it:
    /// a member leaves when it is deleted or no longer eligible, when it went to another
    /// cluster, or when it has been away from the others (beyond `keep_factor`) for
    /// `leave_after_s`; a swarm down to one track keeps it while it waits for a partner.
    fn update_members(
        &mut self,
        step: &Regrouping,
        assigned: &BTreeMap<usize, usize>,
        joining: &BTreeMap<usize, Vec<usize>>,
    ) {
        let (c, t, tracks) = (&self.config, step.t, step.tracks);
        let Clustering {
            eligible,
            clusters,
            cluster_of,
        } = step.clustering;
        let mut eligible_set: BTreeSet<usize> = eligible.iter().copied().collect();
        eligible_set.extend(joining.values().flatten().copied());
        for (g, group) in self.groups.iter_mut().enumerate() {
            let cluster = assigned.get(&g).map(|k| clusters[k].clone());
            let mine = cluster
                .as_ref()
                .and_then(|m| m.first())
                .and_then(|i| cluster_of.get(i));
            for &i in cluster
                .iter()
                .flatten()
                .chain(joining.get(&g).into_iter().flatten())
            {
                group.members.insert(tracks[i].id.clone(), t);
            }
            let current: Vec<usize> = group
                .members
                .keys()
                .filter_map(|id| step.index.get(id).copied())
                .collect();
            let thin = group.id.is_some() && current.len() < c.min_members.max(2);
            group.members.retain(|id, last_in| {
                let Some(&i) = step.index.get(id) else {
                    return false; // deleted
                };
                if !eligible_set.contains(&i) {
                    return false;
                }
                if let Some(k) = cluster_of.get(&i) {
                    return Some(k) == mine; // in another cluster: it went there
                }
                let sigma = less_sure_sigma(c, &tracks[i]);
                let near = current
                    .iter()
                    .filter(|&&j| j != i)
                    .any(|&j| scaled_distance(c, &tracks[i], &tracks[j], sigma) < c.keep_factor);
                if near {
                    *last_in = t;
                }
                thin || t - *last_in <= c.leave_after_s
            });
        }
    }

    /// The clusters no group took (`assigned`: group index → cluster number) become
    /// candidates, recognised once they hold together (see `update_views`).
    fn add_candidates(&mut self, step: &Regrouping, assigned: &BTreeMap<usize, usize>) {
        let t = step.t;
        let taken: BTreeSet<usize> = assigned.values().copied().collect();
        for (k, members) in &step.clustering.clusters {
            if taken.contains(k) {
                continue;
            }
            self.groups.push(Group {
                id: None,
                members: members
                    .iter()
                    .map(|&i| (step.tracks[i].id.clone(), t))
                    .collect(),
                first_seen_s: t,
                detected_s: t,
                view: None,
                last_t_s: t,
                pending_shape: None,
                thin_since: None,
                forecaster: Default::default(),
            });
        }
    }

    /// The confirmed tracks too unsure of their velocity to be clustered (σ between
    /// `max_velocity_sigma_m_s` and `join_velocity_sigma_m_s`) that join a recognised
    /// swarm this step: group index → track indices. Each joins the recognised group whose
    /// clustered member it is nearest to, when that distance, its velocity scale widened
    /// by its σ, is under 1.
    fn less_sure_joiners(
        &self,
        c: &GroupingConfig,
        tracks: &[TrackView],
        eligible: &[usize],
        clusters: &BTreeMap<usize, Vec<usize>>,
        assigned: &BTreeMap<usize, usize>,
    ) -> BTreeMap<usize, Vec<usize>> {
        let clustered: BTreeSet<usize> = eligible.iter().copied().collect();
        let mut out: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
        for (i, tr) in tracks.iter().enumerate() {
            let sigma = tr.velocity_sigma_m_s;
            if clustered.contains(&i)
                || tr.status != TrackStatus::Confirmed
                || sigma <= c.max_velocity_sigma_m_s
                || sigma > c.join_velocity_sigma_m_s
            {
                continue;
            }
            let best = assigned
                .iter()
                .filter(|(g, _)| self.groups[**g].id.is_some())
                .flat_map(|(g, k)| clusters[k].iter().map(move |&j| (*g, j)))
                .map(|(g, j)| (g, scaled_distance(c, tr, &tracks[j], sigma)))
                .filter(|(_, d)| *d < 1.0)
                .min_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((g, _)) = best {
                out.entry(g).or_default().push(i);
            }
        }
        out
    }

    /// Each group's cluster (group index → cluster number): by the most shared tracks,
    /// then by predicted centroid and velocity.
    fn match_clusters(
        &self,
        t: f64,
        tracks: &[TrackView],
        clusters: &BTreeMap<usize, Vec<usize>>,
        member_of: &BTreeMap<String, usize>,
    ) -> BTreeMap<usize, usize> {
        let mut overlap: BTreeMap<(usize, usize), usize> = BTreeMap::new();
        for (k, members) in clusters {
            for &i in members {
                if let Some(&g) = member_of.get(&tracks[i].id) {
                    *overlap.entry((g, *k)).or_default() += 1;
                }
            }
        }
        let mut pairs: Vec<((usize, usize), usize)> = overlap.into_iter().collect();
        // Most shared first; then recognised swarms before candidates, older first.
        pairs.sort_by(|((ga, _), na), ((gb, _), nb)| {
            let (a, b) = (&self.groups[*ga], &self.groups[*gb]);
            nb.cmp(na)
                .then(b.id.is_some().cmp(&a.id.is_some()))
                .then(a.first_seen_s.total_cmp(&b.first_seen_s))
        });
        let mut assigned: BTreeMap<usize, usize> = BTreeMap::new();
        let mut taken: BTreeSet<usize> = BTreeSet::new();
        for ((g, k), _) in pairs {
            if assigned.contains_key(&g) || taken.contains(&k) {
                continue;
            }
            assigned.insert(g, k);
            taken.insert(k);
        }
        // Clusters sharing no track: the unmatched swarm they continue, if any.
        let c = &self.config;
        for (k, members) in clusters {
            if taken.contains(k) {
                continue;
            }
            let refs: Vec<&TrackView> = members.iter().map(|&i| &tracks[i]).collect();
            let here = view_of("", &refs, 0.0);
            let best = self
                .groups
                .iter()
                .enumerate()
                .filter(|(g, _)| !assigned.contains_key(g))
                .filter_map(|(g, grp)| {
                    let v = grp.view.as_ref()?;
                    let dt = t - grp.last_t_s;
                    let dp2 = (v.centroid.north_m + v.velocity.north_m_s * dt
                        - here.centroid.north_m)
                        .powi(2)
                        + (v.centroid.east_m + v.velocity.east_m_s * dt - here.centroid.east_m)
                            .powi(2);
                    let dv2 = (v.velocity.north_m_s - here.velocity.north_m_s).powi(2)
                        + (v.velocity.east_m_s - here.velocity.east_m_s).powi(2);
                    let d =
                        (dp2 / c.eps_position_m.powi(2) + dv2 / c.eps_velocity_m_s.powi(2)).sqrt();
                    (d < c.keep_factor).then_some((g, d))
                })
                .min_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((g, _)) = best {
                assigned.insert(g, *k);
                taken.insert(*k);
            }
        }
        assigned
    }

    /// Recomputes every group's view; recognises candidates that held together; drops
    /// groups with too few members. Returns the events.
    fn update_views(
        &mut self,
        t: f64,
        tracks: &[TrackView],
        index: &BTreeMap<String, usize>,
    ) -> Vec<HostileSwarmEvent> {
        let c = self.config.clone();
        let mut events = Vec::new();
        let mut keep = Vec::with_capacity(self.groups.len());
        for mut g in std::mem::take(&mut self.groups) {
            let members: Vec<&TrackView> = g
                .members
                .keys()
                .filter_map(|id| index.get(id).map(|&i| &tracks[i]))
                .collect();
            let min = c.min_members.max(2);
            if members.len() < min {
                // A candidate is gone at once; a swarm after `lost_after_s`, or when none
                // of its tracks is left.
                let since = *g.thin_since.get_or_insert(t);
                if g.id.is_none() || members.is_empty() || t - since + 1e-9 >= c.lost_after_s {
                    if let (Some(_), Some(v)) = (&g.id, g.view.take()) {
                        events.push(HostileSwarmEvent::Lost(v));
                    }
                    continue;
                }
            } else {
                g.thin_since = None;
            }
            if g.id.is_none() && t - g.first_seen_s + 1e-9 >= c.detect_after_s {
                g.id = Some(format!(
                    "{}{}",
                    skein_protocol::tracks::SWARM_PREFIX,
                    self.next_id
                ));
                self.next_id += 1;
                g.detected_s = t;
                g.view = None;
            }
            let id = g.id.clone().unwrap_or_default();
            let mut view = view_of(&id, &members, t - g.detected_s);
            g.forecast_centroid(t, &mut view, &members);
            events.extend(g.news(t, &mut view, &c));
            g.view = Some(view);
            g.last_t_s = t;
            keep.push(g);
        }
        self.groups = keep;
        events
    }
}
