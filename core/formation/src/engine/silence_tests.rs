//! Unit tests of the engine with members that drop out or fall silent: absent members
//! listed and counted, members riding through a silence on their slots, a silent leader.

use super::tests::{fence, fly, member};
use super::*;
use crate::spec::tests::line;
use crate::{FormationSpec, Member, VIRTUAL};
use skein_model::formation::Shape;

/// uav-1 to uav-3 flying `line()` behind uav-2, on their slots.
fn line_of_three_on_their_slots() -> (FormationEngine, BTreeMap<String, Member>) {
    let mut e = FormationEngine::default();
    e.set(line());
    let mut members: BTreeMap<String, Member> = [(-5.0, "uav-1"), (0.0, "uav-2"), (5.0, "uav-3")]
        .into_iter()
        .map(|(east_m, id)| (id.to_string(), member(0.0, east_m, -10.0)))
        .collect();
    for _ in 0..50 {
        fly(&mut e, &mut members);
    }
    (e, members)
}

#[test]
fn a_silent_member_stays_listed_and_counted_with_its_error_to_its_slot() {
    use crate::{Absence, Whereabouts};
    let (mut e, mut members) = line_of_three_on_their_slots();
    assert!(e.status(&[]).rms_error_m.unwrap() < 1e-6);
    // uav-3 falls silent and drifts 6 m off its slot: the formation re-forms without it...
    let before = e.status(&[]);
    let was = before.members.iter().find(|m| m.id == "uav-3").unwrap();
    let (slot_of_3, index_of_3) = (was.target, was.slot);
    let drifted = slot_of_3 + Ned::new(6.0, 0.0, 0.0);
    {
        let m = members.get_mut("uav-3").unwrap();
        m.silence = std::time::Duration::from_secs(2);
        m.position = drifted;
    }
    let slots = fly(&mut e, &mut members);
    assert!(!slots.contains_key("uav-3"));
    assert_eq!(e.absent_ids().collect::<Vec<_>>(), ["uav-3"]);
    // ...but the status says so: listed with its own error, and counted.
    let silent = BTreeMap::from([(
        "uav-3".to_string(),
        Whereabouts {
            position: Some(drifted),
            absence: Absence::Silent,
            state: "InFormation".into(),
        },
    )]);
    let st = e.status_with(&[], &silent);
    assert_eq!(st.absent.len(), 1, "{st:?}");
    let a = &st.absent[0];
    assert_eq!((a.id.as_str(), a.slot), ("uav-3", index_of_3));
    assert!((a.target - slot_of_3).norm() < 1e-6, "{a:?}");
    assert!((a.error_m.unwrap() - 6.0).abs() < 1e-6, "{a:?}");
    let flying: Vec<f64> = st.members.iter().map(|m| m.error_m).collect();
    let expected = ((flying.iter().map(|e| e * e).sum::<f64>() + 36.0) / 3.0).sqrt();
    assert!((st.rms_error_m.unwrap() - expected).abs() < 1e-9, "{st:?}");
    assert!(st.rms_error_m.unwrap() > 3.0);
    let members_rms = (flying.iter().map(|e| e * e).sum::<f64>() / flying.len() as f64).sqrt();
    assert!((st.members_rms_error_m.unwrap() - members_rms).abs() < 1e-9);
    // Where the coordinator knows nothing of it, it is not listed.
    let st = e.status_with(&[], &BTreeMap::new());
    assert!(st.absent.is_empty());
    assert_eq!(st.rms_error_m, st.members_rms_error_m);
    // Heard again, it flies a slot: no longer absent.
    members.get_mut("uav-3").unwrap().silence = std::time::Duration::ZERO;
    let slots = fly(&mut e, &mut members);
    assert!(slots.contains_key("uav-3"));
    assert_eq!(e.absent_ids().count(), 0);
}

#[test]
fn a_member_released_by_the_operator_is_not_absent() {
    let (mut e, mut members) = line_of_three_on_their_slots();
    e.release("uav-3");
    // Still in formation for a tick (the command is on its way), then gone.
    fly(&mut e, &mut members);
    members.remove("uav-3");
    fly(&mut e, &mut members);
    assert_eq!(e.absent_ids().count(), 0);
    // One that leaves unasked is absent; stopping the formation forgets it.
    members.remove("uav-1");
    fly(&mut e, &mut members);
    assert_eq!(e.absent_ids().collect::<Vec<_>>(), ["uav-1"]);
    e.deactivate();
    assert_eq!(e.absent_ids().count(), 0);
}

/// A wedge of `ids` behind the virtual leader, settled on its slots and cruising north at
/// 5 m/s; each member rides through `ride_through` of silence.
fn cruising_wedge(
    ids: &[&str],
    leader: &str,
    ride_through: std::time::Duration,
) -> (FormationEngine, BTreeMap<String, Member>) {
    let mut e = FormationEngine::default();
    e.set(FormationSpec {
        shape: Shape::Wedge,
        spacing_m: 6.0,
        leader: Some(leader.into()),
        ..line()
    });
    let mut members: BTreeMap<String, Member> = ids
        .iter()
        .enumerate()
        .map(|(i, id)| {
            let mut m = member(-6.0 * i as f64, 6.0 * i as f64, -10.0);
            m.ride_through = ride_through;
            (id.to_string(), m)
        })
        .collect();
    for _ in 0..100 {
        fly(&mut e, &mut members);
    }
    e.set_motion(crate::LeaderMotion::GoTo {
        target: Ned::new(400.0, 0.0, -10.0),
        speed_m_s: 5.0,
    })
    .unwrap();
    for _ in 0..80 {
        fly(&mut e, &mut members);
    }
    (e, members)
}

fn reference_speed(e: &FormationEngine) -> f64 {
    e.status(&[]).reference.unwrap().velocity.horizontal_norm()
}

#[test]
fn a_member_silent_within_its_ride_through_keeps_its_slot_and_does_not_slow_the_others() {
    let ride = std::time::Duration::from_secs(4);
    let (mut e, mut members) = cruising_wedge(&["uav-1", "uav-2", "uav-3"], VIRTUAL, ride);
    assert!((reference_speed(&e) - 5.0).abs() < 1e-6);
    // uav-3 falls silent: its position is stale (frozen where last heard) while its
    // agent flies it on.
    let frozen = members["uav-3"].position;
    let slot_before = e
        .status(&[])
        .members
        .iter()
        .find(|m| m.id == "uav-3")
        .unwrap()
        .slot;
    for k in 1..=30 {
        let silence = std::time::Duration::from_millis(100 * k);
        {
            let m = members.get_mut("uav-3").unwrap();
            m.silence = silence;
        }
        let slots = e.tick(&members, 0.1, &fence());
        for (id, s) in &slots {
            if id != "uav-3" {
                let m = members.get_mut(id).unwrap();
                m.position = s.position + s.velocity * 0.1;
                m.velocity = s.velocity;
            } else {
                members.get_mut(id).unwrap().position = frozen;
            }
        }
        // It keeps its slot, and the formation its speed: 3 s, 15 m on.
        assert_eq!(slots["uav-3"].slot, slot_before, "after {silence:?}");
        assert!(
            (reference_speed(&e) - 5.0).abs() < 1e-6,
            "after {silence:?}"
        );
    }
    // Its error is the one it had when last heard, not the 15 m its frozen position is
    // behind; the status says how long it has been silent.
    let st = e.status(&[]);
    let m = st.members.iter().find(|m| m.id == "uav-3").unwrap();
    assert!(m.error_m < 0.5, "{m:?}");
    assert!((m.silent_s.unwrap() - 3.0).abs() < 1e-9, "{m:?}");
    assert!(
        st.members
            .iter()
            .filter(|m| m.id != "uav-3")
            .all(|m| m.silent_s.is_none())
    );
    assert_eq!(e.absent_ids().count(), 0);
    // Past its ride-through it loses the slot: absent, and the others re-form.
    members.get_mut("uav-3").unwrap().silence = ride;
    let slots = e.tick(&members, 0.1, &fence());
    assert!(!slots.contains_key("uav-3"));
    assert_eq!(e.absent_ids().collect::<Vec<_>>(), ["uav-3"]);
}

#[test]
fn a_silent_leader_vehicle_rides_on_the_reference_and_the_pattern_with_it() {
    let ride = std::time::Duration::from_secs(4);
    let (mut e, mut members) = cruising_wedge(&["uav-1", "uav-2", "uav-3"], "uav-1", ride);
    assert_eq!(e.leader(), Some("uav-1"));
    let north = |e: &FormationEngine| e.status(&[]).reference.unwrap().position.north_m;
    let (start, frozen) = (north(&e), members["uav-1"].position);
    let mut slots = BTreeMap::new();
    for k in 1..=20 {
        members.get_mut("uav-1").unwrap().silence = std::time::Duration::from_millis(100 * k);
        slots = e.tick(&members, 0.1, &fence());
        for (id, s) in &slots {
            let m = members.get_mut(id).unwrap();
            m.position = if id == "uav-1" {
                frozen
            } else {
                s.position + s.velocity * 0.1
            };
        }
    }
    // Still the leader; the formation moved 10 m on, and the followers' slots with it
    // (laid around the reference, not around the leader's stale position).
    assert_eq!(e.leader(), Some("uav-1"));
    assert!(
        (north(&e) - start - 10.0).abs() < 0.2,
        "{} {start}",
        north(&e)
    );
    // (A wedge's first rank is 6 m back along the diagonals: 4.24 m behind.)
    let reference = e.status(&[]).reference.unwrap().position;
    let rank = 6.0 / 2f64.sqrt();
    for id in ["uav-2", "uav-3"] {
        let behind = reference.north_m - slots[id].goal.north_m;
        assert!(
            (behind - rank).abs() < 1e-6,
            "{id} {:?} {reference:?}",
            slots[id]
        );
    }
}
