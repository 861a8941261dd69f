//! The track figures of `skein bench tracking`, from a sequence of samples (the truth,
//! which cameras see which intruder, the tracks), whether sampled live from `skein up` or
//! made by replaying a trace (see the [`super`] docs for what each figure means).

use serde_json::{Value, json};
use std::collections::{BTreeMap, BTreeSet};

/// A swarm-frame NED JSON object (`north_m`, `east_m`, `down_m`) as an array.
pub(super) fn ned(v: &Value) -> Option<[f64; 3]> {
    Some([
        v["north_m"].as_f64()?,
        v["east_m"].as_f64()?,
        v["down_m"].as_f64()?,
    ])
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Intruders matched one-to-one to confirmed tracks within 10 m, as CLEAR-MOT does: an
/// intruder keeps its previous track while that one is still within the gate, not taken,
/// and no nearer to another intruder (in a swarm of 6 m ranks the gate holds two
/// intruders: a track that went over to a neighbour follows the neighbour); the others go
/// to the nearest free track, closest pairs first. Returns intruder id → (track id,
/// distance m).
fn assign(
    intruders: &[(String, [f64; 3])],
    confirmed: &[(String, [f64; 3])],
    previous: &BTreeMap<String, Option<String>>,
) -> BTreeMap<String, (String, f64)> {
    const GATE_M: f64 = 10.0;
    let mut out: BTreeMap<String, (String, f64)> = BTreeMap::new();
    let mut taken: BTreeSet<&str> = BTreeSet::new();
    for (iid, p) in intruders {
        if let Some(Some(prev)) = previous.get(iid)
            && let Some((tid, q)) = confirmed.iter().find(|(t, _)| t == prev)
            && dist(*p, *q) <= GATE_M
            && intruders
                .iter()
                .all(|(other, o)| other == iid || dist(*o, *q) >= dist(*p, *q))
            && taken.insert(tid.as_str())
        {
            out.insert(iid.clone(), (tid.clone(), dist(*p, *q)));
        }
    }
    let mut pairs: Vec<(f64, &String, &String)> = intruders
        .iter()
        .filter(|(iid, _)| !out.contains_key(iid))
        .flat_map(|(iid, p)| {
            confirmed
                .iter()
                .map(move |(tid, q)| (dist(*p, *q), iid, tid))
        })
        .filter(|(d, _, tid)| *d <= GATE_M && !taken.contains(tid.as_str()))
        .collect();
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (d, iid, tid) in pairs {
        if out.contains_key(iid) || taken.contains(tid.as_str()) {
            continue;
        }
        taken.insert(tid.as_str());
        out.insert(iid.clone(), (tid.clone(), d));
    }
    out
}

/// The track figures, sample by sample.
#[derive(Default)]
pub(super) struct Scorer {
    sq_err: Vec<f64>,
    in_view_since: BTreeMap<String, f64>,
    confirmed_after: BTreeMap<String, Option<f64>>,
    matched: BTreeMap<String, Option<String>>,
    switches: u64,
    /// Per intruder: out of every camera's view since its last match.
    unseen_since_match: BTreeMap<String, bool>,
    /// Per path kind: (switches in view, reacquisitions).
    by_pattern: BTreeMap<String, (u64, u64)>,
    /// Every identity switch, as the report lists it.
    switch_log: Vec<Value>,
    /// Confirmed track id → (first, last) sample time it was confirmed, s.
    confirmed_seen: BTreeMap<String, (f64, f64)>,
    near_intruder: BTreeSet<String>,
}

impl Scorer {
    /// One sample at `t_s` seconds into the measurement: `truth` as `GET /api/v1/sim/truth`
    /// answers, `viewers` the number of cameras drawing each intruder (by id), `tracks` as
    /// `GET /api/v1/tracks` lists them. Returns which confirmed track each intruder was
    /// matched to, with the distance (intruder id → (track id, m)).
    pub(super) fn sample(
        &mut self,
        t: f64,
        truth: &Value,
        viewers: &BTreeMap<String, usize>,
        tracks: &[Value],
    ) -> BTreeMap<String, (String, f64)> {
        let members: Vec<[f64; 3]> = truth["vehicles"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(ned)
            .collect();
        let centre = members
            .iter()
            .fold([0.0; 3], |c, p| [c[0] + p[0], c[1] + p[1], c[2] + p[2]]);
        let centre = centre.map(|c| c / members.len().max(1) as f64);
        let confirmed: Vec<(String, [f64; 3])> = tracks
            .iter()
            .filter(|t| t["status"] == "confirmed")
            .filter_map(|t| Some((t["id"].as_str()?.to_string(), ned(&t["position"])?)))
            .collect();
        for (id, _) in &confirmed {
            let e = self.confirmed_seen.entry(id.clone()).or_insert((t, t));
            e.1 = t;
        }
        let intruders: Vec<(String, [f64; 3])> = truth["intruders"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(|i| Some((i["id"].as_str()?.to_string(), ned(i)?)))
            .collect();
        let assigned = assign(&intruders, &confirmed, &self.matched);
        for i in truth["intruders"].as_array().into_iter().flatten() {
            let (Some(iid), Some(p)) = (i["id"].as_str(), ned(i)) else {
                continue;
            };
            let nearest = assigned.get(iid).map(|(id, d)| (id, *d));
            if let Some((id, _)) = nearest {
                self.near_intruder.insert(id.clone());
            }
            let views = viewers.get(iid).copied().unwrap_or(0);
            let pattern = i["pattern"].as_str().unwrap_or("?").to_string();
            let kind = self.by_pattern.entry(pattern).or_default();
            if self.confirmed_after.get(iid).is_none_or(Option::is_none) {
                if views >= 2 {
                    self.in_view_since.entry(iid.to_string()).or_insert(t);
                    self.confirmed_after.entry(iid.to_string()).or_insert(None);
                } else if views == 0 {
                    // Out of every camera's view, still unconfirmed: the clock restarts
                    // when it is next in two views.
                    self.in_view_since.remove(iid);
                }
                if let Some(&t_in) = self.in_view_since.get(iid)
                    && nearest.is_some_and(|(_, d)| d <= 5.0)
                {
                    self.confirmed_after.insert(iid.to_string(), Some(t - t_in));
                }
            }
            let unseen = self
                .unseen_since_match
                .entry(iid.to_string())
                .or_insert(false);
            if views == 0 {
                *unseen = true;
            }
            let within = dist(p, centre) <= 100.0;
            if let Some((id, d)) = nearest.filter(|(_, d)| *d <= 10.0) {
                if within {
                    self.sq_err.push(d * d);
                }
                let last = self.matched.entry(iid.to_string()).or_insert(None);
                if let Some(previous) = last.as_ref().filter(|l| *l != id) {
                    self.switches += 1;
                    self.switch_log
                        .push(json!({"t_s": t, "intruder": iid, "pattern": i["pattern"],
                        "from": previous, "to": id, "in_view": !*unseen}));
                    if *unseen {
                        kind.1 += 1;
                    } else {
                        kind.0 += 1;
                    }
                }
                *last = Some(id.clone());
                *unseen = false;
            }
        }
        assigned
    }

    /// The `tracks` object of the report.
    pub(super) fn report(&self) -> Value {
        let false_tracks: Vec<(&String, f64)> = self
            .confirmed_seen
            .iter()
            .filter(|(id, _)| !self.near_intruder.contains(*id))
            .map(|(id, (a, b))| (id, b - a))
            .collect();
        let times: Vec<f64> = self.confirmed_after.values().flatten().copied().collect();
        let sq = &self.sq_err;
        json!({
            "rmse_m": (!sq.is_empty()).then(|| (sq.iter().sum::<f64>() / sq.len() as f64).sqrt()),
            "samples": sq.len(),
            "time_to_confirm_s": self.confirmed_after,
            "time_to_confirm_max_s": times.iter().copied().reduce(f64::max),
            "in_two_views": self.confirmed_after.len(),
            "id_switches": self.switches,
            "id_switches_in_view": self.by_pattern.values().map(|k| k.0).sum::<u64>(),
            "reacquisitions": self.by_pattern.values().map(|k| k.1).sum::<u64>(),
            "id_switch_list": self.switch_log,
            "id_switches_by_pattern": self.by_pattern.iter().map(|(p, k)| {
                (p.clone(), json!({"in_view": k.0, "reacquisitions": k.1}))
            }).collect::<BTreeMap<_, _>>(),
            "confirmed_tracks": self.confirmed_seen.len(),
            "false_tracks": false_tracks.len(),
            "false_track_longest_s": false_tracks.iter().map(|f| f.1).reduce(f64::max),
        })
    }
}
