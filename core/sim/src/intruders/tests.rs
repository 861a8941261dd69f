//! Tests of the intruders' paths and groups.

use super::*;
use crate::PX4_SITL_HOME;

fn intruders(cfg: IntruderConfig) -> Intruders {
    Intruders::new(PX4_SITL_HOME, cfg, Instant::now()).expect("valid config")
}

#[test]
fn straight_pass_crosses_at_its_closest_point_at_speed() {
    let cfg = IntruderConfig {
        count: 1,
        pattern: Some(IntruderPattern::Straight),
        heading_deg: Some(90.0),
        cpa_m: Some(60.0),
        range_m: 100.0,
        speed_m_s: 5.0,
        altitude_m: 20.0,
        ..IntruderConfig::default()
    };
    let ints = intruders(cfg);
    let at_start = &ints.truth_at(0.0)[0];
    assert!((at_start.home_ned_m.north_m - 60.0).abs() < 1e-9);
    assert!((at_start.home_ned_m.east_m + 100.0).abs() < 1e-9);
    assert!((at_start.home_ned_m.down_m + 20.0).abs() < 1e-9);
    // 20 s later: at the closest point of approach, flying east at 5 m/s.
    let mid = &ints.truth_at(20.0)[0];
    assert!(mid.home_ned_m.east_m.abs() < 1e-6, "{mid:?}");
    assert!((mid.velocity_ned_m_s.east_m - 5.0).abs() < 1e-6);
    // After the pass it comes back.
    let back = &ints.truth_at(45.0)[0];
    assert!(
        (back.velocity_ned_m_s.east_m + 5.0).abs() < 1e-6,
        "{back:?}"
    );
    assert_eq!(at_start.id, "intruder-1");
}

#[test]
fn every_pattern_flies_at_its_speed_and_seeds_repeat() {
    let cfg = IntruderConfig {
        count: 3,
        seed: 7,
        speed_m_s: 6.0,
        ..IntruderConfig::default()
    };
    let a = intruders(cfg.clone());
    let b = intruders(cfg.clone());
    let pats: Vec<_> = a.truth_at(0.0).iter().map(|t| t.pattern).collect();
    assert_eq!(
        pats,
        [
            IntruderPattern::Straight,
            IntruderPattern::Loiter,
            IntruderPattern::Zigzag
        ]
    );
    for t in [1.0, 13.3, 77.0] {
        assert_eq!(a.truth_at(t), b.truth_at(t));
        for tr in a.truth_at(t) {
            let speed = tr.velocity_ned_m_s.norm();
            assert!((speed - 6.0).abs() < 0.05, "{} at {t}: {speed}", tr.id);
            assert!((tr.home_ned_m.down_m + 20.0).abs() < 1e-9);
        }
    }
    let other = intruders(IntruderConfig { seed: 8, ..cfg });
    assert_ne!(a.truth_at(5.0), other.truth_at(5.0));
}

#[test]
fn formation_flies_a_v_behind_its_leader() {
    let ints = intruders(IntruderConfig {
        count: 3,
        pattern: Some(IntruderPattern::Formation),
        heading_deg: Some(0.0),
        cpa_m: Some(0.0),
        ..IntruderConfig::default()
    });
    let t = ints.truth_at(10.0);
    // Flying north: members 2 and 3 are 6 m behind, 6 m to either side.
    let d1 = t[1].home_ned_m - t[0].home_ned_m;
    let d2 = t[2].home_ned_m - t[0].home_ned_m;
    assert!((d1.north_m + 6.0).abs() < 1e-9 && (d1.east_m.abs() - 6.0).abs() < 1e-9);
    assert!((d2.north_m + 6.0).abs() < 1e-9 && (d2.east_m + d1.east_m).abs() < 1e-9);
}

#[test]
fn crossing_swarms_and_a_split_fly_in_their_groups() {
    let cfg = |pattern| IntruderConfig {
        count: 5,
        pattern: Some(pattern),
        heading_deg: Some(0.0),
        cpa_m: Some(40.0),
        range_m: 100.0,
        ..IntruderConfig::default()
    };
    // Crossing: three fly north, two east, their leaders over the same point 3 s apart.
    let x = intruders(cfg(IntruderPattern::Crossing));
    let t = x.truth_at(20.0);
    let groups: Vec<_> = t.iter().map(|i| i.group.clone().unwrap()).collect();
    assert_eq!(
        groups,
        ["group-1", "group-1", "group-1", "group-2", "group-2"]
    );
    assert!((t[0].velocity_ned_m_s.north_m - 5.0).abs() < 1e-6);
    assert!(
        (t[3].velocity_ned_m_s.east_m - 5.0).abs() < 1e-6,
        "{:?}",
        t[3]
    );
    let meet = (100.0 - CROSSING_BEFORE_CPA_M) / 5.0;
    let (a, b) = (x.truth_at(meet), x.truth_at(meet + 3.0));
    assert!((b[3].home_ned_m - a[0].home_ned_m).horizontal_norm() < 1e-6);
    // Split: 30 m before the closest point the right arm turns 40° right and is group 2.
    let s = intruders(cfg(IntruderPattern::Split));
    let at = (100.0 - SPLIT_BEFORE_CPA_M) / 5.0;
    let before = s.truth_at(at - 1.0);
    assert!(before.iter().all(|i| i.group.as_deref() == Some("group-1")));
    let after = s.truth_at(at + 5.0);
    for (i, tr) in after.iter().enumerate() {
        let v = tr.velocity_ned_m_s;
        let course = v.east_m.atan2(v.north_m).to_degrees();
        if i % 2 == 1 {
            assert_eq!(tr.group.as_deref(), Some("group-2"));
            assert!((course - SPLIT_TURN_DEG).abs() < 0.5, "{course}");
        } else {
            assert_eq!(tr.group.as_deref(), Some("group-1"));
            assert!(course.abs() < 0.5, "{course}");
        }
        assert!((v.norm() - 5.0).abs() < 0.05);
    }
    // The zig-zag V weaves together: its slots keep their offsets.
    let z = intruders(cfg(IntruderPattern::FormationZigzag));
    let (a, b) = (z.truth_at(7.0), z.truth_at(13.0));
    let d = |t: &[IntruderTruth]| t[1].home_ned_m - t[0].home_ned_m;
    assert!((d(&a) - d(&b)).norm() < 1e-9);
    assert!(
        (a[0].velocity_ned_m_s.east_m - b[0].velocity_ned_m_s.east_m).abs() > 1.0,
        "it weaves"
    );
    assert_eq!(
        IntruderPattern::parse("formation-zigzag"),
        Ok(Some(IntruderPattern::FormationZigzag))
    );
    // Lone intruders belong to no group.
    let lone = intruders(IntruderConfig {
        count: 3,
        ..IntruderConfig::default()
    });
    assert!(lone.truth_at(1.0).iter().all(|i| i.group.is_none()));
}

#[test]
fn bad_configs_are_refused() {
    let bad = IntruderConfig {
        count: 1,
        speed_m_s: 0.0,
        ..IntruderConfig::default()
    };
    assert!(Intruders::new(PX4_SITL_HOME, bad, Instant::now()).is_err());
    assert!(IntruderPattern::parse("spiral").is_err());
    assert_eq!(IntruderPattern::parse("mixed"), Ok(None));
}
