//! Scenario tests of the tracker: bearings generated from known targets and observers.

use super::geometry::Ray;
use super::tracker::{MemberPose, TrackEvent, TrackStatus, Tracker, TrackerConfig};
use nalgebra::{Rotation3, Vector3};

const OBSERVERS: [(&str, [f64; 3]); 2] =
    [("uav-2", [0.0, 0.0, -10.0]), ("uav-4", [0.0, 10.0, -10.0])];

/// A bearing from `observer` at `o` to `target`, rotated by `noise_rad` about the vertical,
/// with the range from size the detector would give (±10 %).
fn bearing(
    observer: &str,
    o: Vector3<f64>,
    target: Vector3<f64>,
    t_us: u64,
    noise_rad: f64,
) -> Ray {
    let rot = Rotation3::from_axis_angle(&Vector3::z_axis(), noise_rad);
    let range = (target - o).norm();
    Ray {
        origin: o,
        dir: rot * (target - o).normalize(),
        range_from_size_m: Some(range * if noise_rad > 0.0 { 1.1 } else { 0.9 }),
        stamp_us: t_us,
        observer: observer.to_string(),
        confidence: 0.9,
    }
}

/// Runs the tracker at 10 Hz from `start_s` for `duration_s` with two cameras at 5 Hz
/// (staggered by 0.1 s) seeing every target `targets(t)` returns; returns every event.
fn fly(
    tracker: &mut Tracker,
    start_s: f64,
    duration_s: f64,
    targets: &dyn Fn(f64) -> Vec<Vector3<f64>>,
) -> Vec<TrackEvent> {
    let mut events = Vec::new();
    let steps = (duration_s * 10.0).round() as u64;
    for k in 0..steps {
        let t = start_s + k as f64 * 0.1;
        let t_us = (t * 1e6) as u64 + 1_000_000;
        // The cameras take turns by the absolute step, so runs can be chained.
        let step = (t * 10.0).round() as u64;
        let (name, o) = OBSERVERS[(step % 2) as usize];
        let o = Vector3::from(o);
        let noise = if step % 4 < 2 { 0.001 } else { -0.001 };
        let bearings = targets(t)
            .into_iter()
            .map(|p| bearing(name, o, p, t_us, noise))
            .collect();
        let members: Vec<MemberPose> = OBSERVERS
            .iter()
            .map(|(n, p)| MemberPose {
                id: n.to_string(),
                position: Vector3::from(*p),
                velocity: Vector3::zeros(),
            })
            .collect();
        events.extend(tracker.step(t_us, bearings, &members));
    }
    events
}

/// A track the tracker has followed for a while: at `p` moving at `v` (confident: 0.3 m,
/// 0.1 m/s), created at `created_us`, last updated at `seen_us`, last fixed by two
/// observers at `triangulated_us`; 20 hits, 5 of them triangulated.
fn settled_track(
    id: &str,
    status: TrackStatus,
    p: Vector3<f64>,
    v: Vector3<f64>,
    created_us: u64,
    seen_us: u64,
    triangulated_us: Option<u64>,
) -> super::tracker::Track {
    let mut filter =
        super::filter::ConstantVelocity::new(p, nalgebra::Matrix3::identity() * 0.1, 0.1, 2.0);
    filter.x.fixed_rows_mut::<3>(3).copy_from(&v);
    super::tracker::Track {
        id: id.to_string(),
        status,
        filter,
        t_us: seen_us,
        created_us,
        last_update_us: seen_us,
        hits: 20,
        triangulated_hits: 5,
        last_triangulated_us: triangulated_us,
        observers: vec![],
    }
}

fn nearest_id(tracker: &Tracker, now_us: u64, p: Vector3<f64>) -> (String, f64) {
    tracker
        .tracks(now_us)
        .into_iter()
        .map(|t| {
            let q = Vector3::new(t.position.north_m, t.position.east_m, t.position.down_m);
            (t.id, (q - p).norm())
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .expect("a track")
}

#[test]
fn a_target_seen_by_two_cameras_is_confirmed_and_tracked() {
    let mut tr = Tracker::new(TrackerConfig::default());
    let target = |t: f64| vec![Vector3::new(60.0, -20.0 + 5.0 * t, -20.0)];
    let events = fly(&mut tr, 0.0, 6.0, &target);
    let confirmed: Vec<_> = events
        .iter()
        .filter_map(|e| match e {
            TrackEvent::Confirmed(v) => Some(v.clone()),
            _ => None,
        })
        .collect();
    assert_eq!(confirmed.len(), 1, "{events:?}");
    // Confirmed within a second of the first bearings.
    assert!(confirmed[0].age_s < 1.0, "{:?}", confirmed[0]);
    let tracks = tr.tracks(6_900_000);
    assert_eq!(tracks.len(), 1, "{tracks:?}");
    let t = &tracks[0];
    assert_eq!(t.id, "track-1");
    assert_eq!(t.status, TrackStatus::Confirmed);
    let err = (Vector3::new(t.position.north_m, t.position.east_m, t.position.down_m)
        - target(5.9)[0])
        .norm();
    assert!(err < 1.5, "position error {err} m: {t:?}");
    assert!((t.velocity.east_m_s - 5.0).abs() < 1.0, "{t:?}");
}

#[test]
fn crossing_targets_keep_their_ids() {
    let mut tr = Tracker::new(TrackerConfig::default());
    // Two targets crossing at t = 6 s, 70 m out, 2 m apart vertically.
    let targets = |t: f64| {
        vec![
            Vector3::new(70.0, -30.0 + 5.0 * t, -20.0),
            Vector3::new(70.0, 30.0 - 5.0 * t, -22.0),
        ]
    };
    fly(&mut tr, 0.0, 3.0, &targets);
    let now = |t: f64| (t * 1e6) as u64 + 1_000_000;
    let (id_a, ea) = nearest_id(&tr, now(2.9), targets(2.9)[0]);
    let (id_b, eb) = nearest_id(&tr, now(2.9), targets(2.9)[1]);
    assert_ne!(id_a, id_b);
    assert!(ea < 2.0 && eb < 2.0, "{ea} {eb}");
    let events = fly(&mut tr, 3.0, 7.0, &targets);
    let (after_a, ea) = nearest_id(&tr, now(9.9), targets(9.9)[0]);
    let (after_b, eb) = nearest_id(&tr, now(9.9), targets(9.9)[1]);
    assert_eq!((after_a, after_b), (id_a, id_b), "ids swapped: {events:?}");
    assert!(ea < 2.0 && eb < 2.0, "{ea} {eb}");
    assert!(
        !events.iter().any(|e| matches!(e, TrackEvent::Created(_))),
        "no new track through the crossing: {events:?}"
    );
}

#[test]
fn a_lost_track_ages_out() {
    let cfg = TrackerConfig::default();
    let mut tr = Tracker::new(cfg.clone());
    let target = |t: f64| vec![Vector3::new(50.0, 10.0, -15.0 + 0.0 * t)];
    fly(&mut tr, 0.0, 3.0, &target);
    assert_eq!(tr.tracks(4_000_000)[0].status, TrackStatus::Confirmed);
    // Nothing seen any more.
    let events = fly(
        &mut tr,
        3.0,
        cfg.lost_after_s + cfg.delete_after_s + 1.0,
        &|_| vec![],
    );
    let kinds: Vec<&str> = events
        .iter()
        .map(|e| match e {
            TrackEvent::Lost(_) => "lost",
            TrackEvent::Deleted(_) => "deleted",
            _ => "other",
        })
        .collect();
    assert_eq!(kinds, ["lost", "deleted"]);
    assert!(tr.tracks(20_000_000).is_empty());
    assert_eq!(tr.counters().tracks_deleted, 1);
}

#[test]
fn swarm_members_never_become_tracks() {
    let mut tr = Tracker::new(TrackerConfig::default());
    // Each camera sees the other observer (a swarm member) and nothing else.
    let mut events = Vec::new();
    for k in 0..40u64 {
        let t_us = 1_000_000 + k * 100_000;
        let (me, other) = if k % 2 == 0 { (0, 1) } else { (1, 0) };
        let o = Vector3::from(OBSERVERS[me].1);
        let p = Vector3::from(OBSERVERS[other].1);
        let members: Vec<MemberPose> = OBSERVERS
            .iter()
            .map(|(n, p)| MemberPose {
                id: n.to_string(),
                position: Vector3::from(*p),
                velocity: Vector3::zeros(),
            })
            .collect();
        let b = bearing(OBSERVERS[me].0, o, p, t_us, 0.0);
        events.extend(tr.step(t_us, vec![b], &members));
    }
    assert!(events.is_empty(), "{events:?}");
    assert_eq!(tr.counters().bearings_excluded_members, 40);
}

#[test]
fn a_moving_member_seen_in_an_older_frame_is_still_a_member() {
    // uav-4 flies east at 6 m/s, 25 m north of uav-2, whose frames reach the tracker
    // 0.4 s after their capture: the bearing points where uav-4 was, 2.4 m behind it.
    let mut tr = Tracker::new(TrackerConfig::default());
    let o = Vector3::new(0.0, 0.0, -10.0);
    let v = Vector3::new(0.0, 6.0, 0.0);
    let mut events = Vec::new();
    for k in 0..40u64 {
        let t_us = 1_000_000 + k * 100_000;
        let t = k as f64 * 0.1;
        let now = Vector3::new(25.0, -10.0 + 6.0 * t, -10.0);
        let members = vec![MemberPose {
            id: "uav-4".into(),
            position: now,
            velocity: v,
        }];
        let then = now - v * 0.4;
        let b = bearing("uav-2", o, then, t_us - 400_000, 0.0);
        events.extend(tr.step(t_us, vec![b], &members));
    }
    assert!(events.is_empty(), "{events:?}");
    assert_eq!(tr.counters().bearings_excluded_members, 40);
}

#[test]
fn a_target_only_one_camera_sees_starts_from_its_size_but_is_not_confirmed_alone() {
    let mut tr = Tracker::new(TrackerConfig::default());
    let mut events = Vec::new();
    for k in 0..20u64 {
        let t_us = 1_000_000 + k * 200_000;
        let o = Vector3::from(OBSERVERS[0].1);
        let b = bearing("uav-2", o, Vector3::new(40.0, 0.0, -12.0), t_us, 0.0);
        events.extend(tr.step(t_us, vec![b], &[]));
    }
    assert!(events.iter().any(|e| matches!(e, TrackEvent::Created(_))));
    assert!(!events.iter().any(|e| matches!(e, TrackEvent::Confirmed(_))));
    let t = &tr.tracks(5_000_000)[0];
    assert_eq!(t.status, TrackStatus::Tentative);
    // 10 % short (the size range), straight along the bearing.
    assert!((t.position.north_m - 36.0).abs() < 3.0, "{t:?}");
}

/// Ids of the confirmed tracks nearest the target at each step after `settle_s`.
fn ids_along(
    tracker: &mut Tracker,
    duration_s: f64,
    settle_s: f64,
    target: &dyn Fn(f64) -> Vector3<f64>,
) -> Vec<String> {
    let mut ids = Vec::new();
    let steps = (duration_s * 10.0).round() as u64;
    for k in 0..steps {
        let t = k as f64 * 0.1;
        fly(tracker, t, 0.1, &|s| vec![target(s)]);
        let now = (t * 1e6) as u64 + 1_000_000;
        let nearest = tracker
            .tracks(now)
            .into_iter()
            .filter(|v| v.status == TrackStatus::Confirmed)
            .map(|v| {
                let q = Vector3::new(v.position.north_m, v.position.east_m, v.position.down_m);
                (v.id, (q - target(t)).norm())
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if t >= settle_s
            && let Some((id, d)) = nearest
            && d < 10.0
            && ids.last() != Some(&id)
        {
            ids.push(id);
        }
    }
    ids
}

#[test]
fn a_zigzagging_target_keeps_its_id() {
    // The simulator's zig-zag: 5 m/s along a weave of ±15 m every 40 m, each leg a sharp
    // turn (the velocity across the cameras' line of sight flips by 8 m/s at once),
    // coming in from 80 m.
    let zigzag = |t: f64| {
        let along = 2.77 * t;
        let f = (along / 40.0 + 0.25).rem_euclid(1.0);
        let tri = if f < 0.5 {
            4.0 * f - 1.0
        } else {
            3.0 - 4.0 * f
        };
        Vector3::new(80.0 - along, 5.0 + 15.0 * tri, -18.0)
    };
    let mut tr = Tracker::new(TrackerConfig::default());
    let ids = ids_along(&mut tr, 20.0, 2.0, &zigzag);
    assert_eq!(ids.len(), 1, "one id through three turns: {ids:?}");
}

#[test]
fn a_target_back_from_a_blind_spot_keeps_its_id() {
    // A loiter (20 m radius, 5 m/s) that the cameras lose for 4 s of every lap: the
    // track is lost, predicted straight on, and off the circle when the target returns.
    let centre = Vector3::new(50.0, 0.0, -18.0);
    let circle = |t: f64| {
        let a = 0.25 * t;
        centre + Vector3::new(20.0 * a.cos(), 20.0 * a.sin(), 0.0)
    };
    let mut tr = Tracker::new(TrackerConfig::default());
    let mut ids: Vec<String> = Vec::new();
    for k in 0..400u64 {
        let t = k as f64 * 0.1;
        // Blind while the target is on the far side (angle 2.4..3.4 rad of each lap).
        let blind = (0.25 * t).rem_euclid(std::f64::consts::TAU);
        let seen = !(2.4..3.4).contains(&blind);
        fly(&mut tr, t, 0.1, &|s| {
            if seen { vec![circle(s)] } else { vec![] }
        });
        let now = (t * 1e6) as u64 + 1_000_000;
        if t > 2.0
            && seen
            && let Some((id, d)) = tr
                .tracks(now)
                .into_iter()
                .filter(|v| v.status == TrackStatus::Confirmed)
                .map(|v| {
                    let q = Vector3::new(v.position.north_m, v.position.east_m, v.position.down_m);
                    (v.id, (q - circle(t)).norm())
                })
                .min_by(|a, b| a.1.total_cmp(&b.1))
            && d < 10.0
            && ids.last() != Some(&id)
        {
            ids.push(id);
        }
    }
    assert_eq!(ids.len(), 1, "one id through the blind spots: {ids:?}");
    let confirmed = tr.counters().tracks_confirmed;
    assert_eq!(confirmed, 1, "no second confirmed track on the target");
}

#[test]
fn two_tracks_of_one_target_are_merged_under_the_older_id() {
    let mut tr = Tracker::new(TrackerConfig::default());
    let track = |id: &str, status, p, v, created_us, seen_us| {
        settled_track(id, status, p, v, created_us, seen_us, Some(seen_us))
    };
    let v = Vector3::new(0.0, 5.0, 0.0);
    // An old confirmed track coasting 0.5 s, and a younger one updated just now, 1 m off,
    // at the same velocity: one aircraft.
    tr.tracks.push(track(
        "track-1",
        TrackStatus::Confirmed,
        Vector3::new(40.0, 0.0, -15.0),
        v,
        1_000_000,
        9_500_000,
    ));
    tr.tracks.push(track(
        "track-7",
        TrackStatus::Confirmed,
        Vector3::new(40.0, 3.5, -15.0),
        v,
        6_000_000,
        10_000_000,
    ));
    // A third, crossing the first at 10 m/s: another aircraft.
    tr.tracks.push(track(
        "track-9",
        TrackStatus::Confirmed,
        Vector3::new(40.5, 3.0, -15.0),
        Vector3::new(0.0, -5.0, 0.0),
        6_000_000,
        10_000_000,
    ));
    let events = tr.step(10_000_000, vec![], &[]);
    let ids: Vec<String> = tr.tracks(10_000_000).into_iter().map(|t| t.id).collect();
    assert_eq!(ids, ["track-1", "track-9"], "{events:?}");
    assert!(
        matches!(&events[..], [TrackEvent::Deleted(d)] if d.id == "track-7"),
        "{events:?}"
    );
    // The survivor took the fresher state.
    let t1 = &tr.tracks(10_000_000)[0];
    assert!(
        (t1.position.east_m - 3.5).abs() < 1e-9 && t1.unseen_s == 0.0,
        "{t1:?}"
    );
}

#[test]
fn an_aircraft_split_over_two_cameras_tracks_is_joined_under_the_older_id() {
    let target = Vector3::new(30.0, 5.0, -12.0);
    let (o2, o4) = (Vector3::from(OBSERVERS[0].1), Vector3::from(OBSERVERS[1].1));
    // Each track sits on one camera's ray, 5 m off in range: each gate holds only that
    // camera's bearing.
    let on_ray =
        |o: Vector3<f64>, off: f64| o + (target - o).normalize() * ((target - o).norm() + off);
    // Each fed by its one camera for the last 4 s.
    let track = |id: &str, p, created_us| {
        let (seen_us, fixed_us) = (9_900_000, Some(5_900_000));
        let v = Vector3::zeros();
        settled_track(
            id,
            TrackStatus::Confirmed,
            p,
            v,
            created_us,
            seen_us,
            fixed_us,
        )
    };
    let mut tr = Tracker::new(TrackerConfig::default());
    tr.tracks.push(track("track-1", on_ray(o2, 5.0), 1_000_000));
    tr.tracks
        .push(track("track-5", on_ray(o4, -5.0), 5_000_000));
    let bearings = vec![
        bearing("uav-2", o2, target, 10_000_000, 0.0),
        bearing("uav-4", o4, target, 10_000_000, 0.0),
    ];
    let events = tr.step(10_000_000, bearings, &[]);
    let tracks = tr.tracks(10_000_000);
    assert_eq!(tracks.len(), 1, "{events:?}");
    let t = &tracks[0];
    assert_eq!(t.id, "track-1");
    assert_eq!((t.triangulated_hits, t.observers.len()), (6, 2), "{t:?}");
    let p = Vector3::new(t.position.north_m, t.position.east_m, t.position.down_m);
    // The triangulated fix pulled it in from 5 m off (against its confident prior).
    assert!((p - target).norm() < 3.0, "{t:?}");
}

#[test]
fn two_aircraft_whose_rays_cross_near_one_of_them_stay_two_tracks() {
    let (o2, o4) = (Vector3::from(OBSERVERS[0].1), Vector3::from(OBSERVERS[1].1));
    // uav-2 sees only the first aircraft, uav-4 only the second; uav-4's ray crosses
    // uav-2's 4 m beyond the first: a ghost within reach of its track.
    let t1 = Vector3::new(40.0, 0.0, -10.0);
    let ghost = Vector3::new(44.0, 0.0, -10.0);
    let t2 = o4 + (ghost - o4) * 1.5;
    let mut tr = Tracker::new(TrackerConfig::default());
    // Both fixed by two cameras a moment ago.
    for (id, p, created_us) in [("track-1", t1, 1_000_000), ("track-2", t2, 2_000_000)] {
        let (seen_us, fixed_us) = (9_900_000, Some(9_900_000));
        let v = Vector3::zeros();
        tr.tracks.push(settled_track(
            id,
            TrackStatus::Confirmed,
            p,
            v,
            created_us,
            seen_us,
            fixed_us,
        ));
    }
    let bearings = vec![
        bearing("uav-2", o2, t1, 10_000_000, 0.0),
        bearing("uav-4", o4, t2, 10_000_000, 0.0),
    ];
    let events = tr.step(10_000_000, bearings, &[]);
    assert!(
        !events.iter().any(|e| matches!(e, TrackEvent::Deleted(_))),
        "{events:?}"
    );
    let tracks = tr.tracks(10_000_000);
    assert_eq!(tracks.len(), 2, "{events:?}");
    for (t, truth) in tracks.iter().zip([t1, t2]) {
        let p = Vector3::new(t.position.north_m, t.position.east_m, t.position.down_m);
        assert!((p - truth).norm() < 1.0, "{t:?} is not at {truth}");
        assert_eq!(t.unseen_s, 0.0, "{t:?}");
    }
}

#[test]
fn a_track_one_camera_put_at_a_wrong_range_is_fixed_by_a_second_camera() {
    let (o2, o4) = (Vector3::from(OBSERVERS[0].1), Vector3::from(OBSERVERS[1].1));
    let target = Vector3::new(50.0, 3.0, -14.0);
    // Fed by uav-2's bearings alone (distant blurs, no size range): confidently on the ray,
    // 15 m beyond the aircraft.
    let wrong = o2 + (target - o2).normalize() * ((target - o2).norm() + 15.0);
    let mut t = settled_track(
        "track-3",
        TrackStatus::Tentative,
        wrong,
        Vector3::zeros(),
        8_000_000,
        9_900_000,
        None,
    );
    (t.hits, t.triangulated_hits) = (5, 0);
    let mut tr = Tracker::new(TrackerConfig::default());
    tr.tracks.push(t);
    let blur = |mut r: super::geometry::Ray| {
        r.range_from_size_m = None;
        r
    };
    let bearings = vec![
        blur(bearing("uav-2", o2, target, 10_000_000, 0.0)),
        blur(bearing("uav-4", o4, target, 10_000_000, 0.0)),
    ];
    let events = tr.step(10_000_000, bearings, &[]);
    let tracks = tr.tracks(10_000_000);
    assert_eq!(tracks.len(), 1, "{events:?}");
    let t = &tracks[0];
    assert_eq!(t.id, "track-3");
    let p = Vector3::new(t.position.north_m, t.position.east_m, t.position.down_m);
    assert!((p - target).norm() < 1.0, "{t:?}");
    // Fixed by two cameras: confirmed.
    assert_eq!((t.triangulated_hits, t.status), (1, TrackStatus::Confirmed));
}

#[test]
fn a_lost_track_does_not_take_the_bearing_of_a_tracked_aircraft() {
    let o2 = Vector3::from(OBSERVERS[0].1);
    let target = Vector3::new(40.0, 0.0, -10.0);
    let mut tr = Tracker::new(TrackerConfig::default());
    // Tracked, 1.4 m behind the aircraft after a turn (inside the 1.5 m gate floor).
    tr.tracks.push(settled_track(
        "track-1",
        TrackStatus::Confirmed,
        target + Vector3::new(0.0, 1.4, 0.0),
        Vector3::zeros(),
        1_000_000,
        9_900_000,
        Some(9_900_000),
    ));
    // Unseen for 3 s, 4 m the other side, its covariance grown to 5 m.
    let mut lost = settled_track(
        "track-2",
        TrackStatus::Lost,
        target - Vector3::new(0.0, 4.0, 0.0),
        Vector3::zeros(),
        2_000_000,
        7_000_000,
        Some(7_000_000),
    );
    lost.filter
        .p
        .fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(nalgebra::Matrix3::identity() * 25.0));
    lost.t_us = 9_900_000;
    tr.tracks.push(lost);
    let events = tr.step(
        10_000_000,
        vec![bearing("uav-2", o2, target, 10_000_000, 0.0)],
        &[],
    );
    let tracks = tr.tracks(10_000_000);
    let (t1, t2) = (&tracks[0], &tracks[1]);
    assert_eq!(
        (t1.id.as_str(), t1.unseen_s),
        ("track-1", 0.0),
        "{events:?}"
    );
    assert_eq!(t2.status, TrackStatus::Lost, "{events:?}");
    assert!(t2.unseen_s > 2.9, "{t2:?}");
}

#[test]
fn a_lost_track_that_drifted_onto_a_followed_aircraft_gives_up_its_id() {
    let mut tr = Tracker::new(TrackerConfig::default());
    let v = Vector3::new(3.0, 0.0, 0.0);
    // The older track went unseen 1.2 s ago and coasted onto the aircraft that the
    // younger one follows (1 m apart now, same velocity).
    tr.tracks.push(settled_track(
        "track-4",
        TrackStatus::Lost,
        Vector3::new(-26.0 - 3.6, -17.0, -15.0),
        v,
        1_000_000,
        8_800_000,
        Some(5_000_000),
    ));
    tr.tracks.push(settled_track(
        "track-7",
        TrackStatus::Confirmed,
        Vector3::new(-26.0, -16.0, -15.0),
        v,
        3_000_000,
        10_000_000,
        Some(10_000_000),
    ));
    let events = tr.step(10_000_000, vec![], &[]);
    let ids: Vec<String> = tr.tracks(10_000_000).into_iter().map(|t| t.id).collect();
    assert_eq!(ids, ["track-7"], "{events:?}");
    assert!(
        matches!(&events[..], [TrackEvent::Deleted(d)] if d.id == "track-4"),
        "{events:?}"
    );
}
