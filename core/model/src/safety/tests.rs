//! The setpoint shaper's unit tests.

use super::*;

fn shaper(start: Ned) -> SetpointShaper {
    SetpointShaper::new(start, MotionLimits::default(), Geofence::default(), 3.0)
}

#[test]
fn carrot_respects_speed_and_reaches_target() {
    let mut s = shaper(Ned::ZERO);
    let target = Ned::new(100.0, 0.0, -10.0);
    let dt = 0.05;
    let mut prev = s.carrot();
    for _ in 0..2000 {
        let sp = s.step(target, Ned::ZERO, 0.0, dt, &[]);
        let v = (sp.position - prev) * (1.0 / dt);
        assert!(v.horizontal_norm() <= 8.0 + 1e-9, "{v:?}");
        assert!(-v.down_m <= 3.0 + 1e-9);
        prev = sp.position;
    }
    assert!((s.carrot() - target).norm() < 1e-6);
}

#[test]
fn acceleration_is_limited() {
    let mut s = shaper(Ned::ZERO);
    let sp = s.step(Ned::new(100.0, 0.0, 0.0), Ned::ZERO, 0.0, 0.1, &[]);
    assert!(
        (sp.velocity.norm() - 0.25).abs() < 1e-9,
        "{:?}",
        sp.velocity
    );
}

#[test]
fn target_outside_fence_is_clamped_and_reported() {
    let mut s = shaper(Ned::ZERO);
    s.enforce_floor(true);
    let sp = s.step(Ned::new(0.0, 0.0, -500.0), Ned::ZERO, 0.0, 0.05, &[]);
    assert_eq!(sp.fence, Some(FenceViolation::Ceiling));
    for _ in 0..5000 {
        s.step(Ned::new(0.0, 0.0, -500.0), Ned::ZERO, 0.0, 0.05, &[]);
    }
    // It stops the tracking buffer under the ceiling.
    assert!((s.carrot().down_m + 120.0 - FENCE_TRACKING_BUFFER_M).abs() < 1e-6);
}

/// A target running on out of the fence (a leader's motion, a push): the carrot
/// slows down toward the edge and reaches it at a walk, never at cruise speed.
#[test]
fn the_carrot_brakes_before_the_fence_edge_it_is_pushed_at() {
    let fence = Geofence {
        polygon: vec![[-60.0, -60.0], [-60.0, 60.0], [60.0, 60.0], [60.0, -60.0]],
        ..Geofence::default()
    };
    let mut s = SetpointShaper::new(
        Ned::new(0.0, 0.0, -10.0),
        MotionLimits::default(),
        fence,
        3.0,
    );
    let edge_m = 60.0 - FENCE_TRACKING_BUFFER_M;
    let brake = BRAKE_FRACTION * MotionLimits::default().max_accel_m_s2;
    let dt = 0.02;
    let mut target = Ned::new(5.0, 0.0, -10.0);
    let mut at_edge = None;
    for _ in 0..2000 {
        target.north_m += 8.0 * dt;
        let sp = s.step(target, Ned::new(8.0, 0.0, 0.0), 0.0, dt, &[]);
        let left_m = edge_m - sp.position.north_m;
        assert!(left_m > -1e-6, "past the edge: {sp:?}");
        // What the carrot can still brake away, with two steps' acceleration of slack
        // (the clamp's last sliver is stepped as velocity).
        let allowed =
            (2.0 * brake * left_m).sqrt() + 2.0 * MotionLimits::default().max_accel_m_s2 * dt;
        assert!(
            sp.velocity.north_m <= allowed + 1e-9,
            "{left_m} m left at {sp:?}"
        );
        if left_m < 0.05 && at_edge.is_none() {
            at_edge = Some(sp.velocity.north_m);
        }
    }
    let at_edge = at_edge.expect("the carrot reached the edge");
    assert!(at_edge < 0.5, "reached the edge at {at_edge} m/s");
}

#[test]
fn reaches_a_station_between_two_vehicles_on_theirs_without_swinging() {
    // Stations 8 m apart on one line; the vehicle comes from the side, past the far
    // one, which then is behind its target as it turns in.
    let (near, far) = (Ned::new(5.0, 16.0, -8.0), Ned::new(5.0, 0.0, -8.0));
    let target = Ned::new(5.0, 8.0, -8.0);
    let mut s = shaper(Ned::new(20.0, 2.0, -8.0));
    // Both hover under skein's control (each would take half of an avoidance).
    let still = |position| Obstacle {
        reciprocal: true,
        ..Obstacle::fixed(position)
    };
    let others = [still(near), still(far)];
    let dt = 0.02;
    let mut closest = f64::INFINITY;
    let mut arrived_s = None;
    for i in 0..1500 {
        let sp = s.step(target, Ned::ZERO, 0.0, dt, &others[..]);
        closest = closest.min((sp.position - near).norm().min((sp.position - far).norm()));
        if (sp.position - target).norm() < 0.5 {
            arrived_s = Some(i as f64 * dt);
            break;
        }
    }
    assert!(closest >= 3.0 - 1e-9, "came within {closest} m");
    // Around the vehicle in the way (a half circle of 4 m at the speeds the
    // separation allows) and in: seconds, not the 40 s of swinging between pushes.
    let t = arrived_s.expect("never reached the station in 30 s");
    assert!(t < 15.0, "reached it after {t} s");
}

#[test]
fn slides_around_a_vehicle_in_its_path_without_breaking_separation() {
    // The straight path from (0,0) to (20,0) runs through a vehicle hovering at (10,0).
    let other = Ned::new(10.0, 0.0, -10.0);
    let mut s = shaper(Ned::new(0.0, 0.0, -10.0));
    let target = Ned::new(20.0, 0.0, -10.0);
    let mut closest = f64::INFINITY;
    for _ in 0..4000 {
        let sp = s.step(target, Ned::ZERO, 0.0, 0.05, &[Obstacle::fixed(other)]);
        closest = closest.min((sp.position - other).norm());
    }
    assert!(closest >= 3.0 - 1e-9, "came within {closest} m");
    assert!(
        (s.carrot() - target).norm() < 1e-3,
        "stuck at {:?}",
        s.carrot()
    );
}

#[test]
fn at_full_speed_it_brakes_within_the_acceleration_limit_never_stopping_dead() {
    // Cruising at 8 m/s toward a vehicle hovering 60 m ahead, target 60 m beyond it:
    // the carrot must slow down and steer around in time (a hard stop would make the
    // real vehicle, which cannot brake harder than its limit, overshoot into the other).
    let other = Ned::new(60.0, 0.0, -10.0);
    let mut s = shaper(Ned::new(0.0, 0.0, -10.0));
    let dt = 0.05;
    for _ in 0..200 {
        s.step(Ned::new(1000.0, 0.0, -10.0), Ned::ZERO, 0.0, dt, &[]);
        if s.velocity.norm() > 7.99 {
            break;
        }
    }
    let mut prev_v = s.velocity;
    let mut closest = f64::INFINITY;
    for _ in 0..2000 {
        let sp = s.step(
            Ned::new(120.0, 0.0, -10.0),
            Ned::ZERO,
            0.0,
            dt,
            &[Obstacle::fixed(other)],
        );
        assert!(
            !sp.separation_hold,
            "the hard guard had to stop the carrot at {:?}",
            sp.position
        );
        let dv = (sp.velocity - prev_v).norm() / dt;
        assert!(dv <= 2.5 + 1e-6, "accelerated at {dv} m/s²");
        prev_v = sp.velocity;
        closest = closest.min((sp.position - other).norm());
    }
    assert!(closest >= 3.0, "came within {closest} m");
    assert!(
        (s.carrot() - Ned::new(120.0, 0.0, -10.0)).norm() < 1e-3,
        "stuck at {:?}",
        s.carrot()
    );
}

#[test]
fn a_target_left_of_an_obstacle_is_reached_around_its_left_side() {
    // The e2e case that once deadlocked: the obstacle sits right of the straight path
    // and the target lies beyond it to the left.
    let other = Ned::new(0.0, 0.0, -10.0);
    let mut s = shaper(Ned::new(3.0, -3.0, -10.0));
    let target = Ned::new(0.0, 5.0, -10.0);
    let mut closest = f64::INFINITY;
    for _ in 0..4000 {
        let sp = s.step(target, Ned::ZERO, 0.0, 0.05, &[Obstacle::fixed(other)]);
        closest = closest.min((sp.position - other).norm());
    }
    assert!(closest >= 3.0 - 1e-9, "came within {closest} m");
    assert!(
        (s.carrot() - target).norm() < 1e-3,
        "stuck at {:?}",
        s.carrot()
    );
}

proptest::proptest! {
    #[test]
    fn reaches_any_target_around_a_stationary_vehicle(
        sx in -15.0..15.0f64, sy in -15.0..15.0f64,
        tx in -15.0..15.0f64, ty in -15.0..15.0f64,
    ) {
        let other = Ned::new(0.0, 0.0, -10.0);
        let start = Ned::new(sx, sy, -10.0);
        let target = Ned::new(tx, ty, -10.0);
        proptest::prop_assume!(start.horizontal_norm() > 3.5 && target.horizontal_norm() > 3.5);
        let mut s = shaper(start);
        let mut closest = f64::INFINITY;
        for _ in 0..6000 {
            let sp = s.step(target, Ned::ZERO, 0.0, 0.05, &[Obstacle::fixed(other)]);
            closest = closest.min((sp.position - other).norm());
        }
        proptest::prop_assert!(closest >= 3.0 - 1e-9, "came within {} m", closest);
        proptest::prop_assert!((s.carrot() - target).norm() < 1e-3, "stuck at {:?}", s.carrot());
    }
}

/// Every obstacle whatever the radii (what a source may always give), counting the
/// separation check's questions (those asked with the planned separation itself as
/// its radius; avoidance asks with a margin).
struct Everything(Vec<Obstacle>, std::cell::Cell<usize>, f64);

impl ObstacleSource for Everything {
    fn near(&self, _: Ned, _: f64, planned_radius_m: f64, out: &mut Vec<Obstacle>) {
        if planned_radius_m == self.2 {
            self.1.set(self.1.get() + 1);
        }
        out.clear();
        out.extend(self.0.iter().copied());
    }

    fn max_speed_m_s(&self) -> f64 {
        self.0.as_slice().max_speed_m_s()
    }
}

proptest::proptest! {
    /// The separation check reuses what avoidance found around the carrot: a source
    /// that answers by distance gives the same setpoints, step after step, as one
    /// that gives every obstacle, asked once a step while the fence moves nothing.
    #[test]
    fn one_question_a_step_gives_what_the_whole_swarm_gives(
        obstacles in proptest::collection::vec(
            (-12.0..12.0f64, -12.0..12.0f64, -3.0..3.0f64, -4.0..4.0f64, -4.0..4.0f64,
             proptest::bool::ANY, proptest::bool::ANY),
            1..12),
        tx in -20.0..20.0f64, ty in -20.0..20.0f64,
        planned_separation in 1.0..3.0f64,
    ) {
        let obstacles: Vec<Obstacle> = obstacles
            .into_iter()
            .map(|(n, e, d, vn, ve, reciprocal, planned)| Obstacle {
                position: Ned::new(n, e, -10.0 + d),
                velocity: Ned::new(vn, ve, 0.0),
                reciprocal,
                planned,
            })
            .collect();
        let start = Ned::new(0.0, 0.0, -10.0);
        let mut by_distance = shaper(start).with_planned_separation(planned_separation);
        let mut whole = by_distance.clone();
        let everything =
            Everything(obstacles.clone(), std::cell::Cell::new(0), planned_separation);
        let target = Ned::new(tx, ty, -10.0);
        for k in 0..400 {
            let a = by_distance.step(target, Ned::ZERO, 0.0, 0.02, obstacles.as_slice());
            let b = whole.step(target, Ned::ZERO, 0.0, 0.02, &everything);
            proptest::prop_assert_eq!(a, b, "step {}", k);
        }
        // Only avoidance's questions: no fence moves the carrot here.
        proptest::prop_assert_eq!(everything.1.get(), 0);
    }
}

#[test]
fn two_vehicles_head_on_pass_each_other() {
    let mut a = shaper(Ned::new(0.0, 0.0, -10.0));
    let mut b = shaper(Ned::new(20.0, 0.0, -10.0));
    let (ta, tb) = (Ned::new(20.0, 0.0, -10.0), Ned::new(0.0, 0.0, -10.0));
    let mut closest = f64::INFINITY;
    for _ in 0..4000 {
        let (pa, pb) = (a.carrot(), b.carrot());
        let (va, vb) = (a.velocity, b.velocity);
        let ob = Obstacle {
            position: pb,
            velocity: vb,
            reciprocal: true,
            planned: false,
        };
        let oa = Obstacle {
            position: pa,
            velocity: va,
            reciprocal: true,
            planned: false,
        };
        a.step(ta, Ned::ZERO, 0.0, 0.05, &[ob]);
        b.step(tb, Ned::ZERO, 0.0, 0.05, &[oa]);
        closest = closest.min((a.carrot() - b.carrot()).norm());
    }
    assert!(closest >= 3.0 - 0.05, "came within {closest} m");
    assert!((a.carrot() - ta).norm() < 1e-3 && (b.carrot() - tb).norm() < 1e-3);
}

#[test]
fn inside_the_separation_it_never_closes_in_and_can_move_away() {
    let other = Ned::new(2.0, 0.0, 0.0);
    let mut s = shaper(Ned::ZERO);
    let mut dist = 2.0;
    for _ in 0..100 {
        let sp = s.step(
            Ned::new(10.0, 0.0, 0.0),
            Ned::ZERO,
            0.0,
            0.05,
            &[Obstacle::fixed(other)],
        );
        let d = (sp.position - other).norm();
        if dist < 3.0 {
            assert!(d >= dist - 1e-9, "closed in from {dist} to {d}");
        }
        dist = d;
    }
    let sp = s.step(
        Ned::new(-10.0, 0.0, 0.0),
        Ned::ZERO,
        0.0,
        0.05,
        &[Obstacle::fixed(other)],
    );
    assert!(!sp.separation_hold);
}

#[test]
fn a_vehicle_on_the_next_lane_ahead_does_not_push_it_off_its_own() {
    // A survey lane north along east 0 at full speed; a vehicle skein steers 8 m east,
    // 40 m ahead, slowing at the end of its own lane: the straight way passes it 8 m off.
    let other = Obstacle {
        velocity: Ned::new(0.5, 0.0, 0.0),
        reciprocal: true,
        ..Obstacle::fixed(Ned::new(40.0, 8.0, -10.0))
    };
    let mut s = shaper(Ned::new(0.0, 0.0, -10.0));
    let target = Ned::new(60.0, 0.0, -10.0);
    let mut farthest_off_m: f64 = 0.0;
    for _ in 0..4000 {
        let sp = s.step(target, Ned::ZERO, 0.0, 0.05, &[other]);
        farthest_off_m = farthest_off_m.max(sp.position.east_m.abs());
    }
    assert!(farthest_off_m < 0.01, "{farthest_off_m} m off the lane");
    assert!((s.carrot() - target).norm() < 1e-3);
}

#[test]
fn two_vehicles_on_neighbouring_lanes_keep_them() {
    // Side by side 8 m apart, both north at full speed, one a little ahead: neither is
    // in the other's way, and neither leaves its lane.
    let mut a = shaper(Ned::new(0.0, 0.0, -10.0));
    let mut b = shaper(Ned::new(5.0, 8.0, -10.0));
    let (ta, tb) = (Ned::new(60.0, 0.0, -10.0), Ned::new(60.0, 8.0, -10.0));
    let obstacle = |s: &SetpointShaper| Obstacle {
        position: s.carrot(),
        velocity: s.velocity,
        reciprocal: true,
        planned: false,
    };
    let mut farthest_off_m: f64 = 0.0;
    for _ in 0..4000 {
        let (oa, ob) = (obstacle(&a), obstacle(&b));
        a.step(ta, Ned::ZERO, 0.0, 0.05, &[ob]);
        b.step(tb, Ned::ZERO, 0.0, 0.05, &[oa]);
        farthest_off_m = farthest_off_m
            .max(a.carrot().east_m.abs())
            .max((b.carrot().east_m - 8.0).abs());
    }
    assert!(farthest_off_m < 0.01, "{farthest_off_m} m off a lane");
    assert!((a.carrot() - ta).norm() < 1e-3 && (b.carrot() - tb).norm() < 1e-3);
}
