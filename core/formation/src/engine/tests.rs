//! Unit tests of the whole engine: ticks over a handful of members, checking the slot
//! commands and the status they produce.

use super::*;
use crate::spec::tests::line;
use crate::{FormationFrame, FormationSpec, Member, PACE_STOP_M, SlotCommand, VIRTUAL};
use skein_model::formation::Shape;
use skein_model::safety::Geofence;

/// A member at rest at (`n`, `e`, `d`), swarm-frame NED metres, heard just now.
pub(crate) fn member(n: f64, e: f64, d: f64) -> Member {
    Member {
        position: Ned::new(n, e, d),
        velocity: Ned::ZERO,
        heading_rad: 0.0,
        silence: std::time::Duration::ZERO,
        target: None,
        ride_through: crate::LEADER_SILENCE,
    }
}

/// The default geofence (500 m radius, 0 to 120 m).
pub(crate) fn fence() -> Geofence {
    Geofence::default()
}

/// One tick in which every member ends up exactly where it was sent, moving as sent.
pub(super) fn fly(
    e: &mut FormationEngine,
    members: &mut BTreeMap<String, Member>,
) -> BTreeMap<String, SlotCommand> {
    let slots = e.tick(members, 0.1, &fence());
    for (id, s) in &slots {
        let m = members.get_mut(id).unwrap();
        m.position = s.position + s.velocity * 0.1;
        m.velocity = s.velocity;
    }
    slots
}

#[test]
fn line_around_the_leader_with_nearest_assignment() {
    let mut e = FormationEngine::default();
    e.set(line());
    let mut members = BTreeMap::new();
    members.insert("uav-1".to_string(), member(0.0, -3.0, -10.0));
    members.insert("uav-2".to_string(), member(0.0, 0.0, -10.0));
    members.insert("uav-3".to_string(), member(0.0, 3.0, -10.0));
    let slots = e.tick(&members, 0.1, &fence());
    assert_eq!(slots["uav-2"].slot, 0);
    assert!(slots["uav-2"].leader);
    assert!((slots["uav-1"].goal - Ned::new(0.0, -5.0, -10.0)).norm() < 1e-9);
    assert!((slots["uav-3"].goal - Ned::new(0.0, 5.0, -10.0)).norm() < 1e-9);
    // The transition to the slots starts where the members are.
    assert!((slots["uav-1"].position - Ned::new(0.0, -3.0, -10.0)).norm() < 1e-9);
    let positions: Vec<Ned> = members.values().map(|m| m.position).collect();
    let st = e.status(&positions);
    assert_eq!(st.leader_id.as_deref(), Some("uav-2"));
    assert!((st.rms_error_m.unwrap() - (8.0f64 / 3.0).sqrt()).abs() < 1e-9);
    assert!((st.min_separation_m.unwrap() - 3.0).abs() < 1e-9);
}

#[test]
fn the_leaders_hold_target_anchors_the_formation() {
    let mut e = FormationEngine::default();
    e.set(FormationSpec {
        leader: None,
        ..line()
    });
    let mut members = BTreeMap::new();
    let mut a = member(0.0, 0.0, -9.6);
    a.target = Some(Ned::new(0.0, 0.0, -10.0));
    members.insert("a".to_string(), a);
    members.insert("b".to_string(), member(0.0, 4.0, -9.6));
    let slots = e.tick(&members, 0.1, &fence());
    assert_eq!(slots["a"].position, Ned::new(0.0, 0.0, -10.0));
    // Followers anchor on the leader's measured position, at the formation altitude.
    assert!((slots["b"].goal - Ned::new(0.0, 5.0, -10.0)).norm() < 1e-9);
}

#[test]
fn a_virtual_leader_moves_the_whole_formation() {
    let mut e = FormationEngine::default();
    e.set(FormationSpec {
        leader: Some(VIRTUAL.into()),
        altitude_m: Some(10.0),
        frame: FormationFrame::Leader,
        ..line()
    });
    let mut members = BTreeMap::new();
    members.insert("a".to_string(), member(0.0, -5.0, -10.0));
    members.insert("b".to_string(), member(0.0, 5.0, -10.0));
    e.tick(&members, 0.1, &fence());
    e.set_motion(LeaderMotion::GoTo {
        target: Ned::new(100.0, 0.0, -10.0),
        speed_m_s: 5.0,
    })
    .unwrap();
    // The members track what they are sent perfectly (the pace would stop a
    // formation whose members stay behind).
    let mut fly = |e: &mut FormationEngine| {
        let slots = e.tick(&members, 0.1, &fence());
        for (id, s) in &slots {
            let m = members.get_mut(id).unwrap();
            m.position = s.position + s.velocity * 0.1;
            m.velocity = s.velocity;
        }
        slots
    };
    let mut slots = BTreeMap::new();
    for _ in 0..100 {
        slots = fly(&mut e);
    }
    // After 10 s at up to 5 m/s (accelerating at 2 m/s²): moving north at 5 m/s.
    let r = e.status(&[]).reference.unwrap();
    assert!((r.velocity.north_m - 5.0).abs() < 1e-6, "{r:?}");
    assert!(
        r.position.north_m > 40.0 && r.position.north_m < 50.0,
        "{r:?}"
    );
    for s in slots.values() {
        assert!(
            (s.velocity.north_m - 5.0).abs() < 1e-6,
            "feed-forward {s:?}"
        );
        assert!((s.yaw_rad).abs() < 1e-9);
    }
    assert_eq!(e.leader(), Some(VIRTUAL));
    for _ in 0..300 {
        fly(&mut e);
    }
    let r = e.status(&[]).reference.unwrap();
    assert!(
        (r.position - Ned::new(100.0, 0.0, -10.0)).norm() < 0.1,
        "{r:?}"
    );
}

#[test]
fn a_member_left_behind_stops_the_virtual_leader() {
    let mut e = FormationEngine::default();
    e.set(FormationSpec {
        leader: Some(VIRTUAL.into()),
        altitude_m: Some(10.0),
        ..line()
    });
    let mut members = BTreeMap::new();
    members.insert("a".to_string(), member(0.0, -5.0, -10.0));
    members.insert("b".to_string(), member(0.0, 5.0, -10.0));
    e.tick(&members, 0.1, &fence());
    e.set_motion(LeaderMotion::GoTo {
        target: Ned::new(100.0, 0.0, -10.0),
        speed_m_s: 5.0,
    })
    .unwrap();
    // The members never move: the reference sets off, then waits for them (for less
    // than the replan time: a replan starts the change again from where they are).
    for _ in 0..95 {
        e.tick(&members, 0.1, &fence());
    }
    let r = e.status(&[]).reference.unwrap();
    assert!(r.velocity.norm() < 1e-6, "{r:?}");
    assert!(
        r.position.north_m > 0.5 && r.position.north_m < PACE_STOP_M + 1.0,
        "{r:?}"
    );
}

#[test]
fn custom_shapes_have_a_capacity() {
    let mut e = FormationEngine::default();
    e.set(FormationSpec {
        shape: Shape::Custom,
        leader: Some("a".into()),
        offsets: vec![Ned::new(-5.0, 0.0, 0.0)],
        ..line()
    });
    let mut members = BTreeMap::new();
    members.insert("a".to_string(), member(0.0, 0.0, -10.0));
    members.insert("b".to_string(), member(-4.0, 0.0, -10.0));
    members.insert("c".to_string(), member(30.0, 30.0, -10.0));
    let slots = e.tick(&members, 0.1, &fence());
    assert_eq!(slots.len(), 2);
    assert_eq!(slots["b"].goal, Ned::new(-5.0, 0.0, -10.0));
    assert!(
        !slots.contains_key("c"),
        "beyond capacity: the farthest waits"
    );
}

#[test]
fn inactive_engine_gives_nothing() {
    let mut e = FormationEngine::default();
    let mut members = BTreeMap::new();
    members.insert("a".to_string(), member(0.0, 0.0, 0.0));
    assert!(e.tick(&members, 0.1, &fence()).is_empty());
    e.set(line());
    e.deactivate();
    assert!(e.tick(&members, 0.1, &fence()).is_empty());
    assert!(!e.status(&[]).active);
    assert!(e.set_motion(LeaderMotion::Hold).is_err());
}

#[test]
fn a_world_heading_turns_the_pattern() {
    let mut e = FormationEngine::default();
    e.set(FormationSpec {
        heading_deg: 90.0,
        ..line()
    });
    let mut members = BTreeMap::new();
    members.insert("uav-1".to_string(), member(-4.0, 0.0, -10.0));
    members.insert("uav-2".to_string(), member(0.0, 0.0, -10.0));
    members.insert("uav-3".to_string(), member(4.0, 0.0, -10.0));
    let slots = e.tick(&members, 0.1, &fence());
    // Facing east, "right" is south.
    assert!((slots["uav-1"].goal - Ned::new(-5.0, 0.0, -10.0)).norm() < 1e-9);
    assert!((slots["uav-3"].goal - Ned::new(5.0, 0.0, -10.0)).norm() < 1e-9);
    assert_eq!(slots["uav-1"].slot, 1);
    for s in slots.values() {
        assert!((s.yaw_rad - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }
}

#[test]
fn a_change_during_a_transition_waits_for_it_to_end() {
    let mut e = FormationEngine::default();
    e.set(line());
    let mut members = BTreeMap::new();
    members.insert("uav-1".to_string(), member(0.0, -4.0, -10.0));
    members.insert("uav-2".to_string(), member(0.0, 0.0, -10.0));
    members.insert("uav-3".to_string(), member(0.0, 4.0, -10.0));
    fly(&mut e, &mut members);
    let progress = e.status(&[]).transition_progress.expect("a transition");
    assert!(progress < 0.01, "{progress}");
    let wider = FormationSpec {
        spacing_m: 8.0,
        ..line()
    };
    e.set(wider.clone());
    assert_eq!(e.pending(), Some(&wider));
    assert_eq!(e.spec().unwrap().spacing_m, 5.0);
    assert_eq!(e.status(&[]).pending.as_ref(), Some(&wider));
    // 1 m each: a triangle of 2√2 s ≈ 2.8 s; the pending spec waits until then.
    for _ in 0..25 {
        fly(&mut e, &mut members);
        assert!(!e.take_pending_applied());
    }
    let mut applied_at = None;
    for k in 0..20 {
        fly(&mut e, &mut members);
        if e.take_pending_applied() {
            applied_at = Some(k);
            break;
        }
    }
    assert!(applied_at.is_some(), "never applied");
    assert!(!e.take_pending_applied(), "reported once");
    assert_eq!(e.spec(), Some(&wider));
    assert!(e.pending().is_none());
    // The wider line is flown to in turn.
    for _ in 0..200 {
        fly(&mut e, &mut members);
    }
    let st = e.status(&[]);
    assert!(st.transition_progress.is_none());
    assert!((members["uav-3"].position - Ned::new(0.0, 8.0, -10.0)).norm() < 1e-6);
    assert!((members["uav-1"].position - Ned::new(0.0, -8.0, -10.0)).norm() < 1e-6);
    assert!(st.rms_error_m.unwrap() < 1e-6);
}

#[test]
fn status_measures_the_closest_airborne_pair() {
    let e = FormationEngine::default();
    let st = e.status(&[Ned::ZERO]);
    assert_eq!((st.min_separation_m, st.rms_error_m), (None, None));
    let airborne = [
        Ned::ZERO,
        Ned::new(10.0, 0.0, 0.0),
        Ned::new(10.0, 4.0, -3.0),
    ];
    assert_eq!(e.status(&airborne).min_separation_m, Some(5.0));
    assert!(!st.active && st.spec.is_none() && st.reference.is_none());
}

#[test]
fn deactivating_keeps_the_spec_for_later() {
    let mut e = FormationEngine::new(5.0);
    e.set(line());
    let mut members = BTreeMap::new();
    members.insert("uav-2".to_string(), member(0.0, 0.0, -10.0));
    e.tick(&members, 0.1, &fence());
    assert!(e.set_motion(LeaderMotion::Hold).is_ok());
    assert_eq!(e.leader(), Some("uav-2"));
    e.deactivate();
    assert!(!e.is_active());
    assert_eq!(e.leader(), None);
    assert_eq!(e.spec(), Some(&line()));
    assert!(e.status(&[]).members.is_empty());
    e.set(line());
    assert!(e.is_active());
    assert_eq!(e.tick(&members, 0.1, &fence()).len(), 1);
}

fn lost(id: &str, n: f64, e: f64, radius_m: f64) -> crate::Hazard {
    crate::Hazard {
        id: id.into(),
        position: Ned::new(n, e, -10.0),
        radius_m,
        unseen_s: radius_m,
        reason: "Lost".into(),
    }
}

#[test]
fn slots_move_the_least_needed_to_clear_a_hazard() {
    // A line of three behind a virtual leader; a lost vehicle hovers on the east slot.
    let mut e = FormationEngine::default();
    e.set(FormationSpec {
        leader: Some(VIRTUAL.into()),
        ..line()
    });
    let mut members = BTreeMap::new();
    members.insert("a".to_string(), member(0.0, -5.0, -10.0));
    members.insert("b".to_string(), member(0.0, 0.0, -10.0));
    members.insert("c".to_string(), member(0.0, 5.0, -10.0));
    fly(&mut e, &mut members);
    e.set_hazards(vec![lost("uav-9", 0.0, 6.0, 2.0)]);
    let slots = fly(&mut e, &mut members);
    let h = &e.hazards()[0];
    for (id, s) in &slots {
        let d = (s.goal - h.position).norm();
        assert!(d >= h.clearance_m(DEFAULT_SEPARATION_M) - 1e-6, "{id} {d}");
    }
    // The line slides west along itself: 5.5 m of clearance needed, 1 m there.
    let shift = slots["a"].goal.east_m + 5.0;
    assert!((-4.6..-4.4).contains(&shift), "{shift}");
    assert!(e.status(&[]).blocked.is_none());
    assert_eq!(e.status(&[]).hazards.len(), 1);
}

#[test]
fn a_formation_that_cannot_clear_the_hazards_holds_and_says_so() {
    let mut e = FormationEngine::default();
    e.set(FormationSpec {
        leader: Some(VIRTUAL.into()),
        ..line()
    });
    let mut members = BTreeMap::new();
    members.insert("a".to_string(), member(0.0, -5.0, -10.0));
    members.insert("b".to_string(), member(0.0, 0.0, -10.0));
    members.insert("c".to_string(), member(0.0, 5.0, -10.0));
    fly(&mut e, &mut members);
    // A ring of huge hazards around the formation.
    let ring: Vec<_> = (0..12)
        .map(|k| {
            let a = k as f64 * std::f64::consts::TAU / 12.0;
            lost(&format!("h{k}"), 60.0 * a.cos(), 60.0 * a.sin(), 50.0)
        })
        .chain(std::iter::once(lost("centre", 0.0, 0.0, 1.0)))
        .collect();
    e.set_hazards(ring);
    fly(&mut e, &mut members);
    let why = e.status(&[]).blocked.expect("blocked");
    assert!(why.contains("centre"), "{why}");
    assert_eq!(e.take_blocked_change(), Some(Some(why)));
    assert_eq!(e.take_blocked_change(), None);
}

#[test]
fn a_member_held_too_long_makes_the_change_planned_again() {
    let mut e = FormationEngine::default();
    e.set_replan_after_s(2.0);
    e.set(FormationSpec {
        leader: Some(VIRTUAL.into()),
        ..line()
    });
    let mut members = BTreeMap::new();
    members.insert("a".to_string(), member(0.0, -20.0, -10.0));
    members.insert("b".to_string(), member(0.0, 0.0, -10.0));
    members.insert("c".to_string(), member(0.0, 20.0, -10.0));
    // "c" never moves (something stops it); the others fly as sent.
    let mut replans = Vec::new();
    for _ in 0..60 {
        let slots = e.tick(&members, 0.1, &fence());
        for (id, s) in &slots {
            if id != "c" {
                let m = members.get_mut(id).unwrap();
                m.position = s.position;
            }
        }
        replans.extend(e.take_replans());
    }
    assert!(!replans.is_empty(), "no replan in 6 s");
    assert_eq!(replans[0].stuck, vec!["c".to_string()]);
    assert!(
        replans[0].reason.contains("c held"),
        "{}",
        replans[0].reason
    );
    // Planned again from where they are: c's plan starts where c is.
    let slots = e.tick(&members, 0.1, &fence());
    assert!((slots["c"].position - members["c"].position).norm() < 1.0);
}
