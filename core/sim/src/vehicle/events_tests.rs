//! Unit tests of the events interface and the health report, on a synthetic clock.

use super::test_harness::{Harness, env};
use super::*;
use crate::client;
use crate::px4_events as ev;
use skein_mavlink::events::px4_event_id;

/// A vehicle with `params`, its EKF fix after 0.5 s.
fn harness(params: Vec<(String, f64)>) -> Harness {
    Harness::new(Environment {
        params,
        seed: 1,
        ekf_fix_delay: Duration::from_millis(500),
        ..env(WindConfig::default(), 0.0, 1)
    })
}

fn events(msgs: &[MavMessage]) -> Vec<EVENT_DATA> {
    msgs.iter()
        .filter_map(|m| match m {
            MavMessage::EVENT(e) => Some(e.clone()),
            _ => None,
        })
        .collect()
}

fn u32_at(a: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([a[at], a[at + 1], a[at + 2], a[at + 3]])
}

#[test]
fn an_arming_refused_for_open_drone_id_is_reported_as_px4s_events_and_texts() {
    let mut h = harness(vec![("COM_ARM_ODID".into(), 2.0)]);
    h.input(client::gcs_heartbeat());
    h.run(1.0); // position and home: only the Open Drone ID check fails
    let out = h.input(client::command(
        MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    ));
    let evs = events(&out);
    let ids: Vec<u32> = evs.iter().map(|e| e.id).collect();
    assert_eq!(
        ids,
        [
            ev::ARMING_CHECK_SUMMARY.id(),
            px4_event_id("check_open_drone_id_missing"),
            ev::HEALTH_SUMMARY.id(),
            px4_event_id("commander_arm_denied_resolve_failures"),
        ]
    );
    for w in evs.windows(2) {
        assert_eq!(w[1].sequence, w[0].sequence.wrapping_add(1));
    }
    // The summary: the Open Drone ID component (bit 30) in error, no mode can arm.
    let s = &evs[0].arguments;
    assert_eq!((s[0], u32_at(s, 1)), (0, 1 << 30));
    assert_eq!(u32_at(s, 9), 0, "can_arm");
    // The check: every mode, health component index 30, log level error.
    let c = &evs[1];
    assert_eq!(u32_at(&c.arguments, 0), ev::all_mode_groups());
    assert_eq!(c.arguments[4], 30);
    assert_eq!(c.log_levels & 0x0f, ev::level::ERROR);
    assert_eq!(evs[3].log_levels, 0x62, "critical outside, info inside");
    let texts: Vec<String> = out
        .iter()
        .filter_map(|m| match m {
            MavMessage::STATUSTEXT(t) => Some(t.text.to_str().unwrap_or_default().to_string()),
            _ => None,
        })
        .collect();
    assert!(
        texts.contains(&"Preflight Fail: Open Drone ID system missing".to_string()),
        "{texts:?}"
    );
    assert!(
        texts
            .iter()
            .any(|t| t.starts_with("Arming denied: Resolve system health failure")),
        "{texts:?}"
    );
    assert!(out.iter().any(|m| matches!(m, MavMessage::COMMAND_ACK(a)
        if a.result == MavResult::MAV_RESULT_TEMPORARILY_REJECTED)));
}

#[test]
fn a_changed_result_is_reported_and_arming_says_who_armed() {
    let mut h = harness(vec![]);
    // Before the position: the global position and home checks fail.
    let first = events(&h.run(0.2));
    assert!(
        first
            .iter()
            .any(|e| e.id == px4_event_id("check_modes_global_pos"))
    );
    let later = events(&h.run(1.0));
    let summary = later
        .iter()
        .rev()
        .find(|e| e.id == ev::ARMING_CHECK_SUMMARY.id())
        .unwrap();
    assert_eq!(
        u32_at(&summary.arguments, 9),
        ev::all_mode_groups(),
        "all can arm now"
    );
    let out = h.input(client::command(
        MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    ));
    let armed = events(&out)
        .into_iter()
        .find(|e| e.id == px4_event_id("commander_armed_by"))
        .unwrap();
    assert_eq!(armed.arguments[0], ev::arm_disarm_reason::COMMAND_EXTERNAL);
}

#[test]
fn requested_events_come_again_and_old_ones_are_unavailable() {
    let mut h = harness(vec![]);
    let msgs = h.run(4.0);
    assert!(
        msgs.iter()
            .any(|m| matches!(m, MavMessage::CURRENT_EVENT_SEQUENCE(_)))
    );
    // Thirty events: the buffer holds the last twenty.
    for _ in 0..15 {
        h.input(client::command(
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        ));
        h.input(client::command(
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        ));
    }
    let last = h.v.events.next_sequence.wrapping_sub(1);
    let first = last.wrapping_sub(24);
    let out = h.input(MavMessage::REQUEST_EVENT(REQUEST_EVENT_DATA {
        first_sequence: first,
        last_sequence: last,
        target_system: 1,
        target_component: 1,
    }));
    let resent: Vec<u16> = events(&out).iter().map(|e| e.sequence).collect();
    assert_eq!(resent, (last - 19..=last).collect::<Vec<_>>());
    let errors: Vec<&RESPONSE_EVENT_ERROR_DATA> = out
        .iter()
        .filter_map(|m| match m {
            MavMessage::RESPONSE_EVENT_ERROR(e) => Some(e),
            _ => None,
        })
        .collect();
    // The part no longer held: one error, naming the oldest still held.
    assert_eq!(errors.len(), 1);
    assert_eq!(
        (errors[0].sequence, errors[0].sequence_oldest_available),
        (first, last - 19)
    );
    assert_eq!(errors[0].target_system, 245);
}
