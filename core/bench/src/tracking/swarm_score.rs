//! The hostile-swarm figures of `skein bench tracking`, from the same samples as the track
//! figures ([`super::score`]) plus the swarms (`GET /api/v1/swarms`), against the
//! simulator's truth, whose intruders flying together carry a `group`:
//!
//! - `groups`: per truth group, `all_confirmed_at_s` (the first sample with every member
//!   matched to a confirmed track that follows it: within [`LOCKED_M`] and
//!   [`LOCKED_M_S`] of its truth; a ghost passing near a member, at another velocity, is
//!   no confirmation of it), `recognised_at_s` (the first sample from then on where one
//!   swarm holds all of them and nothing else: precision and recall 1),
//!   `recognition_s` (the difference: the goal is 3 s), `first_confirmed_at_s` (the
//!   first member's confirmed track) and `from_first_detection_s`;
//! - membership `precision` and `recall`, per group and overall, over every sample from a
//!   group's recognition on: the swarm sharing the most tracks with the group counts its
//!   tracks of the group (true), its other confirmed tracks (false members) and the group's
//!   tracks it lacks (misses); `lone_in_swarm_samples` counts samples where a lone
//!   intruder's track was in a swarm;
//! - `forecast_error_m`: the error of each forecast when its time comes, horizontally,
//!   against the truth (moved back along its velocity to the forecast's exact time),
//!   `median` and `p90` per horizon (5, 10, 20 s): `swarm_centroid` (a swarm's forecast
//!   against the true centroid of the intruders its members were matched to when it was
//!   made), and `tracks_by_pattern` (each matched track's forecast against its intruder);
//! - `rmse_observed_m`: the tracks' RMSE over the group intruders while some swarm was
//!   observed (`observing`), `observed_samples`.

use super::score::ned;
use serde_json::{Value, json};
use std::collections::{BTreeMap, BTreeSet};

/// A track follows an intruder when it is this close to it, metres…
pub const LOCKED_M: f64 = 3.0;
/// … and its velocity this close to the intruder's, m/s.
pub const LOCKED_M_S: f64 = 2.0;

/// A forecast waiting for its time: due s, horizon s, kind, the intruders whose (mean)
/// position it predicts, the prediction (north, east).
type Pending = (f64, f64, String, Vec<String>, [f64; 2]);

#[derive(Default)]
struct GroupScore {
    members: usize,
    first_confirmed: Option<f64>,
    all_confirmed: Option<f64>,
    recognised: Option<f64>,
    tp: u64,
    fp: u64,
    fn_: u64,
}

/// The swarm figures, sample by sample.
#[derive(Default)]
pub(super) struct SwarmScorer {
    groups: BTreeMap<String, GroupScore>,
    lone_in_swarm: u64,
    pending: Vec<Pending>,
    errors: BTreeMap<(String, u64), Vec<f64>>,
    swarm_ids: BTreeSet<String>,
    observed_sq: Vec<f64>,
}

fn percentile(sorted: &[f64], p: f64) -> Option<f64> {
    if sorted.is_empty() {
        return None;
    }
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    Some(sorted[i])
}

fn ratio(a: u64, b: u64) -> Value {
    if b == 0 {
        Value::Null
    } else {
        json!(a as f64 / b as f64)
    }
}

/// One sample's views of the truth, the matches, the tracks and the swarms.
struct SampleView<'a> {
    /// Intruders of the truth by id.
    by_id: BTreeMap<&'a str, &'a Value>,
    /// Intruder → matched confirmed track, and its distance (m).
    assigned: &'a BTreeMap<String, (String, f64)>,
    /// Intruder → its matched track.
    track_of: BTreeMap<&'a str, &'a str>,
    /// Matched track → its intruder.
    intruder_of: BTreeMap<&'a str, &'a str>,
    /// Confirmed tracks.
    confirmed: BTreeSet<&'a str>,
    /// Tracks' velocities (north, east), m/s.
    velocity_of: BTreeMap<&'a str, [f64; 2]>,
    /// Swarms by id, with their member tracks.
    members: Vec<(String, BTreeSet<&'a str>)>,
}

impl<'a> SampleView<'a> {
    fn new(
        intruders: &[&'a Value],
        assigned: &'a BTreeMap<String, (String, f64)>,
        tracks: &'a [Value],
        swarms: &'a [Value],
    ) -> SampleView<'a> {
        let by_id = intruders
            .iter()
            .filter_map(|i| Some((i["id"].as_str()?, *i)))
            .collect();
        let track_of: BTreeMap<&str, &str> = assigned
            .iter()
            .map(|(i, (tr, _))| (i.as_str(), tr.as_str()))
            .collect();
        let intruder_of = track_of.iter().map(|(i, tr)| (*tr, *i)).collect();
        let confirmed = tracks
            .iter()
            .filter(|t| t["status"] == "confirmed")
            .filter_map(|t| t["id"].as_str())
            .collect();
        let velocity_of = tracks
            .iter()
            .filter_map(|t| Some((t["id"].as_str()?, ned_velocity(&t["velocity"])?)))
            .collect();
        let members = swarms
            .iter()
            .filter_map(|s| {
                let m = s["members"]
                    .as_array()?
                    .iter()
                    .filter_map(Value::as_str)
                    .collect();
                Some((s["id"].as_str()?.to_string(), m))
            })
            .collect();
        SampleView {
            by_id,
            assigned,
            track_of,
            intruder_of,
            confirmed,
            velocity_of,
            members,
        }
    }

    /// Whether intruder `iid`'s matched track follows it (see the module docs).
    fn locked(&self, iid: &str) -> bool {
        let (Some((tr, d)), Some(truth)) = (self.assigned.get(iid), self.by_id.get(iid)) else {
            return false;
        };
        let (Some(v), Some(w)) = (
            self.velocity_of.get(tr.as_str()),
            ned_velocity(&truth["velocity"]),
        ) else {
            return false;
        };
        *d <= LOCKED_M && (v[0] - w[0]).hypot(v[1] - w[1]) <= LOCKED_M_S
    }
}

impl SwarmScorer {
    /// One sample at `t` s: `truth` (`GET /api/v1/sim/truth`), `assigned` (intruder →
    /// matched confirmed track, from [`super::score::Scorer::sample`]), `tracks` and
    /// `swarms` as the API lists them, and whether some swarm is being observed.
    pub(super) fn sample(
        &mut self,
        t: f64,
        truth: &Value,
        assigned: &BTreeMap<String, (String, f64)>,
        tracks: &[Value],
        swarms: &[Value],
        observing: bool,
    ) {
        let intruders: Vec<&Value> = truth["intruders"]
            .as_array()
            .into_iter()
            .flatten()
            .collect();
        let view = SampleView::new(&intruders, assigned, tracks, swarms);
        self.resolve(t, &view.by_id);
        for (id, _) in &view.members {
            self.swarm_ids.insert(id.clone());
        }
        for (g, ids) in self.groups_of(&intruders, &view) {
            if ids.len() >= 2 {
                self.score_group(t, g, &ids, &view, observing);
            }
        }
        self.expect_forecasts(t, tracks, swarms, &view);
    }

    /// The intruders flying together, by truth group; counts the lone intruders whose
    /// track is in a swarm.
    fn groups_of<'a>(
        &mut self,
        intruders: &[&'a Value],
        view: &SampleView,
    ) -> BTreeMap<&'a str, Vec<&'a str>> {
        let mut groups: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
        for i in intruders {
            let Some(iid) = i["id"].as_str() else {
                continue;
            };
            match i["group"].as_str() {
                Some(g) => groups.entry(g).or_default().push(iid),
                None => {
                    if view
                        .track_of
                        .get(iid)
                        .is_some_and(|tr| view.members.iter().any(|(_, m)| m.contains(tr)))
                    {
                        self.lone_in_swarm += 1;
                    }
                }
            }
        }
        groups
    }

    /// Scores truth group `g` (intruders `ids`) at `t`: its first confirmed member, all
    /// locked, recognition, then membership counts, and the observed errors.
    fn score_group(&mut self, t: f64, g: &str, ids: &[&str], view: &SampleView, observing: bool) {
        let score = self.groups.entry(g.to_string()).or_default();
        score.members = score.members.max(ids.len());
        let tracked: BTreeSet<&str> = ids
            .iter()
            .filter_map(|i| view.track_of.get(i).copied())
            .collect();
        if !tracked.is_empty() {
            score.first_confirmed.get_or_insert(t);
        }
        let all_locked = ids.iter().all(|i| view.locked(i));
        if all_locked {
            score.all_confirmed.get_or_insert(t);
        }
        let best = view
            .members
            .iter()
            .max_by_key(|(_, m)| m.intersection(&tracked).count())
            .filter(|(_, m)| m.intersection(&tracked).count() > 0);
        let (tp, fp) = best.map_or((0, 0), |(_, m)| {
            let tp = m.intersection(&tracked).count() as u64;
            let fp = m
                .iter()
                .filter(|tr| !tracked.contains(*tr))
                .filter(|tr| view.intruder_of.contains_key(*tr) || view.confirmed.contains(*tr))
                .count() as u64;
            (tp, fp)
        });
        let fn_ = tracked.len() as u64 - tp;
        if score.recognised.is_none()
            && score.all_confirmed.is_some()
            && all_locked
            && fn_ == 0
            && fp == 0
        {
            score.recognised = Some(t);
        }
        if score.recognised.is_some() {
            score.tp += tp;
            score.fp += fp;
            score.fn_ += fn_;
        }
        if observing {
            for i in ids {
                if let Some((_, d)) = view.assigned.get(*i) {
                    self.observed_sq.push(d * d);
                }
            }
        }
    }

    /// Queues the swarms' and the matched tracks' forecasts, to check when their time
    /// comes.
    fn expect_forecasts(&mut self, t: f64, tracks: &[Value], swarms: &[Value], view: &SampleView) {
        for s in swarms {
            let Some(m) = s["members"].as_array() else {
                continue;
            };
            let ints: Vec<String> = m
                .iter()
                .filter_map(Value::as_str)
                .filter_map(|tr| view.intruder_of.get(tr).map(|i| i.to_string()))
                .collect();
            if ints.len() < 2 {
                continue;
            }
            self.expect(t, &s["forecast"], "swarm_centroid", ints);
        }
        for tr in tracks {
            let Some(i) = tr["id"].as_str().and_then(|id| view.intruder_of.get(id)) else {
                continue;
            };
            let pattern = view
                .by_id
                .get(i)
                .and_then(|v| v["pattern"].as_str())
                .unwrap_or("?");
            self.expect(
                t,
                &tr["forecast"],
                &format!("track_{pattern}"),
                vec![i.to_string()],
            );
        }
    }

    fn expect(&mut self, t: f64, forecast: &Value, kind: &str, intruders: Vec<String>) {
        for f in forecast.as_array().into_iter().flatten() {
            let (Some(h), Some(p)) = (f["horizon_s"].as_f64(), ned(&f["position"])) else {
                continue;
            };
            self.pending
                .push((t + h, h, kind.to_string(), intruders.clone(), [p[0], p[1]]));
        }
    }

    /// Scores the forecasts due by `t` against the truth (`by_id`) moved back along the
    /// velocity to their exact time.
    fn resolve(&mut self, t: f64, by_id: &BTreeMap<&str, &Value>) {
        let pending = std::mem::take(&mut self.pending);
        for (due, h, kind, ints, p) in pending {
            if due > t + 0.1 {
                self.pending.push((due, h, kind, ints, p));
                continue;
            }
            if t - due > 0.5 {
                continue; // a gap in the samples
            }
            let mut sum = [0.0, 0.0];
            let mut all = true;
            for i in &ints {
                let Some(v) = by_id.get(i.as_str()) else {
                    all = false;
                    break;
                };
                let (Some(q), Some(vel)) = (ned(v), ned_velocity(&v["velocity"])) else {
                    all = false;
                    break;
                };
                sum[0] += q[0] - vel[0] * (t - due);
                sum[1] += q[1] - vel[1] * (t - due);
            }
            if !all {
                continue;
            }
            let n = ints.len() as f64;
            let e = (sum[0] / n - p[0]).hypot(sum[1] / n - p[1]);
            self.errors
                .entry((kind, h.round() as u64))
                .or_default()
                .push(e);
        }
    }

    /// The `swarms` object of the report.
    pub(super) fn report(&self) -> Value {
        let mut groups = BTreeMap::new();
        let (mut tp, mut fp, mut fn_) = (0, 0, 0);
        let mut worst: Option<f64> = None;
        for (g, s) in &self.groups {
            let recognition = match (s.all_confirmed, s.recognised) {
                (Some(a), Some(r)) => Some(r - a),
                _ => None,
            };
            if let Some(r) = recognition {
                worst = Some(worst.map_or(r, |w| w.max(r)));
            }
            tp += s.tp;
            fp += s.fp;
            fn_ += s.fn_;
            groups.insert(
                g.clone(),
                json!({
                    "members": s.members,
                    "first_confirmed_at_s": s.first_confirmed,
                    "all_confirmed_at_s": s.all_confirmed,
                    "recognised_at_s": s.recognised,
                    "recognition_s": recognition,
                    "from_first_detection_s": match (s.first_confirmed, s.recognised) {
                        (Some(a), Some(r)) => Some(r - a),
                        _ => None,
                    },
                    "precision": ratio(s.tp, s.tp + s.fp),
                    "recall": ratio(s.tp, s.tp + s.fn_),
                }),
            );
        }
        let mut errors: BTreeMap<String, BTreeMap<String, Value>> = BTreeMap::new();
        for ((kind, h), e) in &self.errors {
            let mut e = e.clone();
            e.sort_by(f64::total_cmp);
            errors.entry(kind.clone()).or_default().insert(
                format!("{h}s"),
                json!({"median": percentile(&e, 0.5), "p90": percentile(&e, 0.9), "n": e.len()}),
            );
        }
        let sq = &self.observed_sq;
        json!({
            "groups": groups,
            "recognition_s_max": worst,
            "precision": ratio(tp, tp + fp),
            "recall": ratio(tp, tp + fn_),
            "swarm_ids": self.swarm_ids,
            "lone_in_swarm_samples": self.lone_in_swarm,
            "forecast_error_m": errors,
            "rmse_observed_m": (!sq.is_empty()).then(|| (sq.iter().sum::<f64>() / sq.len() as f64).sqrt()),
            "observed_samples": sq.len(),
        })
    }
}

fn ned_velocity(v: &Value) -> Option<[f64; 2]> {
    Some([v["north_m_s"].as_f64()?, v["east_m_s"].as_f64()?])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn intruder(id: &str, group: Option<&str>, n: f64, e: f64) -> Value {
        json!({"id": id, "group": group, "pattern": "formation", "north_m": n, "east_m": e,
            "down_m": -15.0, "velocity": {"north_m_s": 0.0, "east_m_s": 5.0, "down_m_s": 0.0}})
    }

    #[test]
    fn recognition_membership_and_forecasts_are_scored_against_the_truth() {
        let mut s = SwarmScorer::default();
        let assigned: BTreeMap<String, (String, f64)> = [
            ("intruder-1", "track-1"),
            ("intruder-2", "track-2"),
            ("intruder-3", "track-3"),
        ]
        .iter()
        .map(|(i, t)| (i.to_string(), (t.to_string(), 1.0)))
        .collect();
        let tracks: Vec<Value> = (1..=4)
            .map(|i| {
                json!({"id": format!("track-{i}"), "status": "confirmed", "forecast": [],
                    "velocity": {"north_m_s": 0.0, "east_m_s": 5.2, "down_m_s": 0.0}})
            })
            .collect();
        for k in 0..=20 {
            let t = k as f64 * 0.5;
            let truth = json!({"intruders": [
                intruder("intruder-1", Some("group-1"), 0.0, 5.0 * t),
                intruder("intruder-2", Some("group-1"), -6.0, 5.0 * t),
                intruder("intruder-3", None, 50.0, 5.0 * t),
            ]});
            // Recognised at 2 s, with the lone intruder's track wrongly in it from 8 s.
            let swarms: Vec<Value> = if t < 2.0 {
                vec![]
            } else {
                let mut m = vec!["track-1", "track-2"];
                if t >= 8.0 {
                    m.push("track-3");
                }
                vec![json!({"id": "swarm-1", "members": m, "forecast": [
                    {"horizon_s": 5.0, "position": {"north_m": -3.0, "east_m": 5.0 * (t + 5.0) + 1.0, "down_m": -15.0}}
                ]})]
            };
            s.sample(t, &truth, &assigned, &tracks, &swarms, t >= 4.0);
        }
        let r = s.report();
        let g = &r["groups"]["group-1"];
        assert_eq!(g["all_confirmed_at_s"], 0.0, "{r}");
        assert_eq!(g["recognition_s"], 2.0, "{r}");
        // 17 samples from 2 s: 34 true; 5 samples from 8 s with one false member.
        assert!(
            (g["precision"].as_f64().unwrap() - 34.0 / 39.0).abs() < 1e-9,
            "{r}"
        );
        assert_eq!(g["recall"], 1.0);
        assert_eq!(r["lone_in_swarm_samples"], 5);
        // Every swarm forecast due by 10 s was made before the lone track joined: 1 m off.
        let f = &r["forecast_error_m"]["swarm_centroid"]["5s"];
        assert_eq!(f["median"], 1.0, "{r}");
        assert!(r["observed_samples"].as_u64().unwrap() == 26, "{r}");
    }
}
