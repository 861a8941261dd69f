//! Scenario tests of swarm recognition and forecasts on scripted tracks: formations, a
//! crossing, a split, members replaced, a loiter and a zig-zag, stepped at the tracker's
//! 10 Hz with the tracks a tracker would give (confirmed, at their true positions plus a
//! little noise).

use super::picture::AirPicture;
use super::swarms::GroupingConfig;
use skein_protocol::tracks::{
    HostileSwarmEvent, MotionModel, NedJson, SwarmShape, TrackStatus, TrackView, VelocityJson,
};

/// A confirmed track at `p` (north, east; 15 m up) flying `v` (north, east), m and m/s.
pub(crate) fn track(id: &str, p: [f64; 2], v: [f64; 2]) -> TrackView {
    TrackView {
        id: id.to_string(),
        status: TrackStatus::Confirmed,
        position: NedJson {
            north_m: p[0],
            east_m: p[1],
            down_m: -15.0,
        },
        velocity: VelocityJson {
            north_m_s: v[0],
            east_m_s: v[1],
            down_m_s: 0.0,
        },
        covariance_ne_m2: [[0.25, 0.0], [0.0, 0.25]],
        position_sigma_m: 0.6,
        hits: 30,
        triangulated_hits: 30,
        observers: vec![],
        age_s: 5.0,
        unseen_s: 0.0,
        velocity_sigma_m_s: 0.3,
        forecast: vec![],
        swarm: None,
    }
}

/// Slot `i` of a V (0 leads; pairs behind, 6 m ranks) flying along `heading_deg`.
fn vee_slot(i: usize, heading_deg: f64) -> [f64; 2] {
    let (s, c) = heading_deg.to_radians().sin_cos();
    let (f, r) = ([c, s], [-s, c]);
    let rank = i.div_ceil(2) as f64;
    let side = if i % 2 == 1 { 1.0 } else { -1.0 };
    [
        -f[0] * 6.0 * rank + r[0] * side * 6.0 * rank,
        -f[1] * 6.0 * rank + r[1] * side * 6.0 * rank,
    ]
}

/// ±0.4 m and ±0.3 m/s of deterministic noise for step `k` and member `i`.
fn jitter(k: u64, i: usize) -> ([f64; 2], [f64; 2]) {
    let a = ((k * 7 + i as u64 * 13) % 11) as f64 / 10.0 - 0.5;
    let b = ((k * 5 + i as u64 * 3) % 7) as f64 / 6.0 - 0.5;
    ([0.8 * a, 0.8 * b], [0.6 * b, 0.6 * a])
}

/// Steps `picture` at 10 Hz over `t0..t1` s with the tracks `at(t, k)` gives; returns
/// every event with its time.
fn run(
    picture: &mut AirPicture,
    t0: f64,
    t1: f64,
    at: &dyn Fn(f64, u64) -> Vec<TrackView>,
) -> Vec<(f64, HostileSwarmEvent)> {
    let mut events = Vec::new();
    let mut k = (t0 * 10.0).round() as u64;
    while (k as f64) / 10.0 < t1 - 1e-9 {
        let t = k as f64 / 10.0;
        let mut tracks = at(t, k);
        let (_, ev) = picture.update(1_000_000_000 + (t * 1e6) as u64, &mut tracks);
        events.extend(ev.into_iter().map(|e| (t, e)));
        k += 1;
    }
    events
}

/// The V of `n` members (`track-1`…) led from `start` along `heading_deg` at `speed`.
fn formation(
    n: usize,
    start: [f64; 2],
    heading_deg: f64,
    speed: f64,
    t: f64,
    k: u64,
) -> Vec<TrackView> {
    let (s, c) = heading_deg.to_radians().sin_cos();
    let v = [speed * c, speed * s];
    (0..n)
        .map(|i| {
            let o = vee_slot(i, heading_deg);
            let (dp, dv) = jitter(k, i);
            track(
                &format!("track-{}", i + 1),
                [
                    start[0] + v[0] * t + o[0] + dp[0],
                    start[1] + v[1] * t + o[1] + dp[1],
                ],
                [v[0] + dv[0], v[1] + dv[1]],
            )
        })
        .collect()
}

fn detected(events: &[(f64, HostileSwarmEvent)]) -> Vec<(f64, &skein_protocol::tracks::SwarmView)> {
    events
        .iter()
        .filter_map(|(t, e)| match e {
            HostileSwarmEvent::Detected(s) => Some((*t, s)),
            _ => None,
        })
        .collect()
}

#[test]
fn a_v_of_five_is_one_wedge_swarm_and_a_crossing_single_is_not_in_it() {
    let mut pic = AirPicture::new(GroupingConfig::default());
    let scene = |t: f64, k: u64| {
        let mut v = formation(5, [30.0, -60.0], 90.0, 5.0, t, k);
        // A lone intruder flying north through the V's path.
        v.push(track("track-9", [-40.0 + 5.0 * t, -10.0], [5.0, 0.0]));
        v
    };
    let events = run(&mut pic, 0.0, 12.0, &scene);
    let found = detected(&events);
    assert_eq!(found.len(), 1, "{events:?}");
    let (t, s) = found[0];
    assert!(t <= 0.6, "recognised after {t} s");
    assert_eq!(s.id, "swarm-1");
    assert_eq!(
        s.members,
        ["track-1", "track-2", "track-3", "track-4", "track-5"]
    );
    assert_eq!(s.shape, SwarmShape::Wedge, "{s:?}");
    assert!((s.shape_heading_deg - 90.0).abs() < 10.0, "{s:?}");
    assert!((s.speed_m_s - 5.0).abs() < 0.5 && (s.course_deg - 90.0).abs() < 5.0);
    // The lone one crossed the V (within a few metres of members) and never joined it.
    assert!(
        events.iter().all(|(_, e)| match e {
            HostileSwarmEvent::Changed { joined, .. } => !joined.contains(&"track-9".into()),
            _ => true,
        }),
        "{events:?}"
    );
    let mut tracks = scene(12.0, 120);
    let (swarms, _) = pic.update(1_000_000_000 + 12_000_000, &mut tracks);
    assert_eq!(swarms.len(), 1);
    assert_eq!(tracks[0].swarm.as_deref(), Some("swarm-1"));
    assert_eq!(tracks[5].swarm, None);
    // Its forecast: the centroid 10 s on, 50 m east.
    let f10 = swarms[0]
        .forecast
        .iter()
        .find(|f| f.horizon_s == 10.0)
        .unwrap();
    let c = &swarms[0].centroid;
    assert!(
        (f10.position.east_m - c.east_m - 50.0).abs() < 5.0,
        "{f10:?} from {c:?}"
    );
    assert!(f10.sigma_m > 0.0 && f10.sigma_m < 10.0, "{f10:?}");
}

#[test]
fn the_id_stays_while_members_are_replaced_and_the_swarm_is_lost_when_it_thins_out() {
    let mut pic = AirPicture::new(GroupingConfig::default());
    let events = run(&mut pic, 0.0, 3.0, &|t, k| {
        formation(4, [0.0, 0.0], 0.0, 4.0, t, k)
    });
    assert_eq!(detected(&events).len(), 1);
    // track-2 is deleted and a new track-7 takes its place (a lost and recreated track).
    let renamed = |t: f64, k: u64| {
        let mut v = formation(4, [0.0, 0.0], 0.0, 4.0, t, k);
        v[1].id = "track-7".into();
        v
    };
    let events = run(&mut pic, 3.0, 5.0, &renamed);
    assert!(detected(&events).is_empty(), "{events:?}");
    let changed: Vec<_> = events
        .iter()
        .filter_map(|(_, e)| match e {
            HostileSwarmEvent::Changed {
                swarm,
                joined,
                left,
            } => Some((swarm, joined, left)),
            _ => None,
        })
        .collect();
    assert_eq!(changed.len(), 1, "{events:?}");
    assert_eq!(changed[0].0.id, "swarm-1");
    assert_eq!(changed[0].1, &["track-7".to_string()]);
    assert_eq!(changed[0].2, &["track-2".to_string()]);
    // Every member gets a new id at once: the centroid carries the id.
    let all_new = |t: f64, k: u64| {
        let mut v = formation(4, [0.0, 0.0], 0.0, 4.0, t, k);
        for (i, tr) in v.iter_mut().enumerate() {
            tr.id = format!("track-{}", 20 + i);
        }
        v
    };
    let events = run(&mut pic, 5.0, 7.0, &all_new);
    assert!(detected(&events).is_empty(), "{events:?}");
    // Its tracks all deleted (another flies alone): lost at once.
    let events = run(&mut pic, 7.0, 8.0, &|t, k| {
        vec![formation(4, [0.0, 0.0], 0.0, 4.0, t, k)[0].clone()]
    });
    let lost: Vec<_> = events
        .iter()
        .filter(|(_, e)| matches!(e, HostileSwarmEvent::Lost(s) if s.id == "swarm-1"))
        .collect();
    assert_eq!(lost.len(), 1, "{events:?}");
}

#[test]
fn a_pair_that_loses_a_track_keeps_its_id_when_another_joins_and_young_tracks_wait() {
    let mut pic = AirPicture::new(GroupingConfig::default());
    // A young track (velocity unknown) and a settled one flying together: no swarm yet.
    let young = |t: f64, k: u64| {
        let mut v = formation(2, [0.0, 0.0], 90.0, 5.0, t, k);
        v[1].velocity_sigma_m_s = 6.0;
        v
    };
    assert!(detected(&run(&mut pic, 0.0, 2.0, &young)).is_empty());
    let events = run(&mut pic, 2.0, 4.0, &|t, k| {
        formation(2, [0.0, 0.0], 90.0, 5.0, t, k)
    });
    assert_eq!(detected(&events).len(), 1, "{events:?}");
    // track-2 is deleted; 2 s later track-3 flies beside track-1: still swarm-1.
    let alone = |t: f64, k: u64| vec![formation(2, [0.0, 0.0], 90.0, 5.0, t, k)[0].clone()];
    let events = run(&mut pic, 4.0, 6.0, &alone);
    assert!(
        events
            .iter()
            .all(|(_, e)| !matches!(e, HostileSwarmEvent::Lost(_))),
        "{events:?}"
    );
    let renamed = |t: f64, k: u64| {
        let mut v = formation(2, [0.0, 0.0], 90.0, 5.0, t, k);
        v[1].id = "track-3".into();
        v
    };
    let events = run(&mut pic, 6.0, 8.0, &renamed);
    assert!(detected(&events).is_empty(), "{events:?}");
    let mut tracks = renamed(8.0, 80);
    let (swarms, _) = pic.update(1_000_000_000 + 8_000_000, &mut tracks);
    assert_eq!(swarms.len(), 1);
    assert_eq!(swarms[0].id, "swarm-1");
    assert_eq!(swarms[0].members, ["track-1", "track-3"]);
    // Alone for 3 s: lost.
    let events = run(&mut pic, 8.0, 12.0, &alone);
    assert!(
        events
            .iter()
            .any(|(_, e)| matches!(e, HostileSwarmEvent::Lost(s) if s.id == "swarm-1")),
        "{events:?}"
    );
}

#[test]
fn a_member_less_sure_of_its_velocity_joins_the_recognised_swarm_but_starts_none() {
    let mut pic = AirPicture::new(GroupingConfig::default());
    // Two aircraft flying together, both seen poorly (σ 4 m/s): two guesses, no swarm.
    let unsure = |t: f64, k: u64| {
        let mut v = formation(2, [0.0, 0.0], 90.0, 5.0, t, k);
        for tr in &mut v {
            tr.velocity_sigma_m_s = 4.0;
        }
        v
    };
    assert!(detected(&run(&mut pic, 0.0, 3.0, &unsure)).is_empty());
    // A V of five whose leader's track is unsure (σ 4 m/s, its velocity 2 m/s off), and a
    // single track as unsure crossing the V at right angles: the V is one swarm of five,
    // the crossing one is not in it.
    let mut pic = AirPicture::new(GroupingConfig::default());
    let scene = |t: f64, k: u64| {
        let mut v = formation(5, [0.0, 0.0], 90.0, 5.0, t, k);
        v[0].velocity_sigma_m_s = 4.0;
        v[0].velocity.north_m_s += 2.0;
        let mut crossing = track("track-9", [30.0 - 5.0 * t, 5.0 * t - 3.0], [-5.0, 0.0]);
        crossing.velocity_sigma_m_s = 4.0;
        v.push(crossing);
        v
    };
    let events = run(&mut pic, 0.0, 8.0, &scene);
    let d = detected(&events);
    assert_eq!(d.len(), 1, "{events:?}");
    let mut tracks = scene(8.0, 80);
    let (swarms, _) = pic.update(1_000_000_000 + 8_000_000, &mut tracks);
    assert_eq!(swarms.len(), 1, "{swarms:?}");
    assert_eq!(
        swarms[0].members,
        ["track-1", "track-2", "track-3", "track-4", "track-5"],
        "{swarms:?}"
    );
    assert_eq!(tracks[5].swarm, None);
    // Beyond `join_velocity_sigma_m_s` it does not join.
    let mut pic = AirPicture::new(GroupingConfig::default());
    let guess = |t: f64, k: u64| {
        let mut v = formation(5, [0.0, 0.0], 90.0, 5.0, t, k);
        v[0].velocity_sigma_m_s = 7.0;
        v
    };
    run(&mut pic, 0.0, 4.0, &guess);
    let mut tracks = guess(4.0, 40);
    let (swarms, _) = pic.update(1_000_000_000 + 4_000_000, &mut tracks);
    assert_eq!(swarms.len(), 1, "{swarms:?}");
    assert_eq!(swarms[0].members.len(), 4, "{swarms:?}");
}

#[test]
fn two_swarms_crossing_keep_their_ids_and_members() {
    let mut pic = AirPicture::new(GroupingConfig::default());
    // One V flies east, one north, their leaders meeting at the origin at t = 12 s.
    let scene = |t: f64, k: u64| {
        let mut a = formation(3, [0.0, -60.0], 90.0, 5.0, t, k);
        let mut b = formation(3, [-60.0, 0.0], 0.0, 5.0, t, k + 3);
        for (i, tr) in b.iter_mut().enumerate() {
            tr.id = format!("track-{}", 11 + i);
        }
        a.append(&mut b);
        a
    };
    let events = run(&mut pic, 0.0, 24.0, &scene);
    let found = detected(&events);
    assert_eq!(found.len(), 2, "{events:?}");
    let lost_or_changed: Vec<_> = events
        .iter()
        .filter(|(_, e)| !matches!(e, HostileSwarmEvent::Detected(_)))
        .collect();
    assert!(lost_or_changed.is_empty(), "{lost_or_changed:?}");
    let mut tracks = scene(24.0, 240);
    let (swarms, _) = pic.update(1_000_000_000 + 24_000_000, &mut tracks);
    let members: Vec<Vec<String>> = swarms.iter().map(|s| s.members.clone()).collect();
    assert_eq!(
        members,
        [
            vec!["track-1", "track-2", "track-3"],
            vec!["track-11", "track-12", "track-13"]
        ]
    );
}

#[test]
fn a_swarm_splitting_in_two_keeps_its_id_on_the_larger_part() {
    let mut pic = AirPicture::new(GroupingConfig::default());
    // A V of five flies north; at 6 s members 2 and 4 (its right arm) turn 40° right.
    let scene = |t: f64, k: u64| {
        let mut v = formation(5, [0.0, 0.0], 0.0, 5.0, t, k);
        if t > 6.0 {
            let (s, c) = 40f64.to_radians().sin_cos();
            for i in [1, 3] {
                let d = t - 6.0;
                v[i].position.north_m += 5.0 * d * (c - 1.0);
                v[i].position.east_m += 5.0 * d * s;
                v[i].velocity.north_m_s = 5.0 * c;
                v[i].velocity.east_m_s = 5.0 * s;
            }
        }
        v
    };
    let events = run(&mut pic, 0.0, 16.0, &scene);
    let found = detected(&events);
    assert_eq!(found.len(), 2, "{events:?}");
    assert_eq!(found[0].1.id, "swarm-1");
    let (t_split, second) = found[1];
    assert_eq!(second.id, "swarm-2");
    assert_eq!(second.members, ["track-2", "track-4"]);
    assert!(
        t_split > 6.0 && t_split < 10.0,
        "split recognised at {t_split} s"
    );
    let left: Vec<_> = events
        .iter()
        .filter_map(|(_, e)| match e {
            HostileSwarmEvent::Changed { swarm, left, .. } if !left.is_empty() => {
                Some((swarm.id.clone(), left.clone()))
            }
            _ => None,
        })
        .collect();
    assert_eq!(
        left,
        [(
            "swarm-1".to_string(),
            vec!["track-2".to_string(), "track-4".to_string()]
        )]
    );
}

/// Feeds `path(t)` (position, velocity) through a forecaster at 10 Hz for `seconds`;
/// returns the 10 s forecasts made after the first 16 s with their errors against the
/// path, and the model each used.
fn forecast_errors(
    path: &dyn Fn(f64) -> ([f64; 2], [f64; 2]),
    seconds: f64,
) -> (Vec<f64>, Vec<MotionModel>) {
    let mut f = super::forecast::Forecaster::default();
    let (mut errors, mut models) = (Vec::new(), Vec::new());
    let mut k = 0u64;
    while (k as f64) / 10.0 < seconds {
        let t = k as f64 / 10.0;
        let (p, v) = path(t);
        let mut tracks = vec![track("track-1", p, v)];
        f.update(1_000_000_000 + (t * 1e6) as u64, &mut tracks);
        if t >= 16.0 && k.is_multiple_of(5) {
            let f10 = tracks[0]
                .forecast
                .iter()
                .find(|x| x.horizon_s == 10.0)
                .unwrap();
            let (q, _) = path(t + 10.0);
            errors.push((f10.position.north_m - q[0]).hypot(f10.position.east_m - q[1]));
            models.push(f10.model);
        }
        k += 1;
    }
    errors.sort_by(f64::total_cmp);
    (errors, models)
}

fn median(v: &[f64]) -> f64 {
    v[v.len() / 2]
}

/// The median error of constant-velocity forecasts `h_s` ahead made from the true state
/// every 0.5 s over `t0..t1`.
fn cv_median_error(path: &dyn Fn(f64) -> ([f64; 2], [f64; 2]), t0: f64, t1: f64, h_s: f64) -> f64 {
    let mut e: Vec<f64> = (0..)
        .map(|k| t0 + k as f64 * 0.5)
        .take_while(|t| *t < t1)
        .map(|t| {
            let ((p, v), (q, _)) = (path(t), path(t + h_s));
            (p[0] + v[0] * h_s - q[0]).hypot(p[1] + v[1] * h_s - q[1])
        })
        .collect();
    e.sort_by(f64::total_cmp);
    median(&e)
}

#[test]
fn forecasts_choose_the_model_that_fits_straight_turning_and_weaving_paths() {
    // Straight at 5 m/s: right to the metre (constant and mean velocity agree there).
    let (e, m) = forecast_errors(&|t| ([0.0, 5.0 * t], [0.0, 5.0]), 40.0);
    assert!(e[e.len() - 1] < 1.0, "{e:?}");
    assert!(!m.contains(&MotionModel::ConstantTurn), "{m:?}");
    // A 30 m loiter at 5 m/s: constant turn, where constant velocity is tens of metres off.
    let w = 5.0 / 30.0;
    let circle = |t: f64| {
        let a = w * t;
        (
            [30.0 * a.cos(), 30.0 * a.sin()],
            [-5.0 * a.sin(), 5.0 * a.cos()],
        )
    };
    let (e, m) = forecast_errors(&circle, 60.0);
    assert!(median(&e) < 5.0, "{e:?}");
    assert!(
        m.iter()
            .filter(|m| **m == MotionModel::ConstantTurn)
            .count()
            * 10
            >= m.len() * 9,
        "{m:?}"
    );
    let cv = cv_median_error(&circle, 16.0, 60.0, 10.0);
    assert!(cv > 20.0, "constant velocity would be {cv} m off");
    // The simulator's zig-zag (±15 m every 40 m at 5 m/s): mean velocity at 10 s.
    let slope: f64 = 4.0 * 15.0 / 40.0;
    let along = 5.0 / (1.0 + slope * slope).sqrt();
    let tri = |x: f64| {
        let f = (x + 0.25).rem_euclid(1.0);
        if f < 0.5 {
            4.0 * f - 1.0
        } else {
            3.0 - 4.0 * f
        }
    };
    let zigzag = |t: f64| {
        let s = along * t;
        let dt = 1e-3;
        let e = |t: f64| 15.0 * tri(along * t / 40.0);
        ([s, e(t)], [along, (e(t + dt) - e(t)) / dt])
    };
    let (e, m) = forecast_errors(&zigzag, 90.0);
    assert!(median(&e) < 20.0, "{e:?}");
    assert!(
        m.iter()
            .filter(|m| **m == MotionModel::MeanVelocity)
            .count()
            * 2
            > m.len(),
        "{m:?}"
    );
    let cv = cv_median_error(&zigzag, 16.0, 90.0, 10.0);
    assert!(
        cv > median(&e),
        "constant velocity {cv} m, chosen {} m",
        median(&e)
    );
}

#[test]
fn a_weaving_swarm_is_forecast_by_its_mean_course_though_its_tracks_are_short_lived() {
    // A V of three on the simulator's zig-zag (±15 m every 40 m at 5 m/s, flying north);
    // every 8 s each member's track is replaced by a new one (ids change), so no track
    // lives long enough to learn the weave: the swarm's own history does.
    let slope: f64 = 4.0 * 15.0 / 40.0;
    let along = 5.0 / (1.0 + slope * slope).sqrt();
    let tri = |x: f64| {
        let f = (x + 0.25).rem_euclid(1.0);
        if f < 0.5 {
            4.0 * f - 1.0
        } else {
            3.0 - 4.0 * f
        }
    };
    let lead = |t: f64| -> ([f64; 2], [f64; 2]) {
        let e = |t: f64| 15.0 * tri(along * t / 40.0);
        ([along * t, e(t)], [along, (e(t + 1e-3) - e(t)) / 1e-3])
    };
    let scene = |t: f64, k: u64| -> Vec<TrackView> {
        let (p, v) = lead(t);
        let epoch = (t / 8.0) as usize;
        (0..3)
            .map(|i| {
                let o = vee_slot(i, 0.0);
                let (dp, dv) = jitter(k, i);
                track(
                    &format!("track-{}", 1 + i + 10 * epoch),
                    [p[0] + o[0] + dp[0], p[1] + o[1] + dp[1]],
                    [v[0] + dv[0], v[1] + dv[1]],
                )
            })
            .collect()
    };
    let mut pic = AirPicture::new(GroupingConfig::default());
    let mut errors = Vec::new();
    let mut ids = std::collections::BTreeSet::new();
    for k in 0..900u64 {
        let t = k as f64 / 10.0;
        let mut tracks = scene(t, k);
        let (swarms, _) = pic.update(1_000_000_000 + (t * 1e6) as u64, &mut tracks);
        for s in &swarms {
            ids.insert(s.id.clone());
        }
        if t >= 30.0 && k.is_multiple_of(5) && swarms.len() == 1 {
            let f = swarms[0]
                .forecast
                .iter()
                .find(|f| f.horizon_s == 10.0)
                .unwrap();
            let (q, _) = lead(t + 10.0);
            // The true centroid: the leader's point moved by the mean slot offset.
            let c = [
                q[0] + (0..3).map(|i| vee_slot(i, 0.0)[0]).sum::<f64>() / 3.0,
                q[1],
            ];
            errors.push((f.position.north_m - c[0]).hypot(f.position.east_m - c[1]));
        }
    }
    assert_eq!(ids.len(), 1, "one swarm throughout: {ids:?}");
    errors.sort_by(f64::total_cmp);
    assert!(errors.len() > 100);
    assert!(median(&errors) < 20.0, "median {} m", median(&errors));
}
