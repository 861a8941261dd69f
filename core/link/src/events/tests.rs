//! The events' decoder with PX4's and libevents' real metadata snippets (libevents'
//! `libs/test.json`, PX4's `enums.json` and commander events), the health report from a
//! sequence of events, and the sequence's gaps.

use super::*;
use skein_mavlink::dialect::EVENT_DATA;
use skein_mavlink::events::px4_event_id;
use std::collections::HashMap;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Snippets of real metadata: libevents' test events (component 1, `test`) and PX4's
/// (component 1 is PX4's namespace on a vehicle; here PX4's under component 2 would
/// clash, so the test events live in component 0).
const META: &str = r#"{
  "version": 2,
  "components": {
    "0": {
      "namespace": "test",
      "event_groups": {"default": {"events": {
        "2307445": {"name": "test2", "message": "Arguments: {1} {2} {3} {4} {5:.2}",
          "description": "<unknown>content\\<</unknown>test\n\\<\\{\\}<param>PARAM</param><a>www.test.com</a>",
          "arguments": [{"type": "int8_t", "name": "a"}, {"type": "int16_t", "name": "b"},
            {"type": "int32_t", "name": "c"}, {"type": "int64_t", "name": "d"}, {"type": "float", "name": "e"}]},
        "2307042": {"name": "test3", "message": "Arguments: {1} {2:.1} {3} {4} {5}",
          "description": "<a href=\"www.test.com/a/b/c?x=1\">url</a>\n<profile name=\"!normal\">keep this. <param>P</param></profile>\n\n <profile name=\"!dev\">remove this</profile>",
          "arguments": [{"type": "uint8_t", "name": "a"}, {"type": "float", "name": "b"},
            {"type": "uint16_t", "name": "c"}, {"type": "uint32_t", "name": "d"}, {"type": "uint64_t", "name": "e"}]},
        "2307044": {"name": "test5", "message": "Testing units: {1m}", "arguments": [{"type": "float", "name": "a"}]},
        "9999": {"name": "broken", "message": "x", "arguments": [{"type": "nothing_t", "name": "a"}]}
      }}}
    },
    "1": {
      "namespace": "px4",
      "enums": {
        "arm_disarm_reason_t": {"type": "uint8_t", "entries": {
          "4": {"name": "command_external", "description": "external command"},
          "6": {"name": "auto_disarm_land", "description": "landing"}}},
        "navigation_mode_group_t": {"type": "uint32_t", "is_bitfield": true, "entries": {
          "1": {"name": "manual", "description": "Fully manual mode (w/o any controller support)"},
          "4": {"name": "posctl", "description": "Position mode"},
          "16": {"name": "loiter", "description": "Loiter"},
          "16384": {"name": "offboard", "description": "Offboard"}}},
        "health_component_t": {"type": "uint32_t", "is_bitfield": true, "entries": {
          "1073741824": {"name": "open_drone_id", "description": "Open Drone ID system"}}}
      },
      "event_groups": {
        "default": {"events": {
          "9489139": {"name": "commander_armed_by", "message": "Armed by {1}",
            "arguments": [{"type": "px4::arm_disarm_reason_t", "name": "reason"}]},
          "99": {"name": "modes_test", "message": "Modes: {1}",
            "arguments": [{"type": "navigation_mode_group_t", "name": "modes"}]}}},
        "arming_check": {"events": {
          "11047904": {"name": "commander_arming_check_summary", "type": "summary", "message": "Arming check summary event",
            "arguments": [{"type": "uint8_t", "name": "chunk_idx"}, {"type": "px4::health_component_t", "name": "error"},
              {"type": "px4::health_component_t", "name": "warning"}, {"type": "px4::navigation_mode_group_t", "name": "can_arm"},
              {"type": "px4::navigation_mode_group_t", "name": "can_run"}]},
          "10161216": {"name": "check_open_drone_id_missing", "message": "Open Drone ID system missing",
            "description": "Open Drone ID system failed to report.\n\n<profile name=\"dev\">\nThis check can be configured via <param>COM_ARM_ODID</param> parameter.\n</profile>",
            "arguments": [{"type": "navigation_mode_group_t", "name": "modes"}, {"type": "uint8_t", "name": "health_component_index"}]}}},
        "health": {"events": {
          "9999999": {"name": "commander_health_summary", "type": "summary", "message": "Health report summary event",
            "arguments": [{"type": "uint8_t", "name": "chunk_idx"}, {"type": "px4::health_component_t", "name": "is_present"},
              {"type": "px4::health_component_t", "name": "error"}, {"type": "px4::health_component_t", "name": "warning"}]}}}
      },
      "navigation_mode_groups": {"groups": {"4": [50593792], "14": [393216], "2": [196608]}}
    }
  }
}"#;

fn meta() -> EventsMetadata {
    EventsMetadata::parse(META.as_bytes()).unwrap()
}

fn event(id: u32, sequence: u16, log_levels: u8, parts: &[&[u8]]) -> EVENT_DATA {
    let mut arguments = [0u8; 40];
    let mut at = 0;
    for p in parts {
        arguments[at..at + p.len()].copy_from_slice(p);
        at += p.len();
    }
    EVENT_DATA {
        id,
        event_time_boot_ms: 0,
        sequence,
        destination_component: 0,
        destination_system: 0,
        log_levels,
        arguments,
    }
}

#[test]
fn arguments_are_read_by_their_types_and_formatted_as_libevents_does() {
    let m = meta();
    assert_eq!(m.skipped, 1, "the event with an unknown type is left out");
    let e = event(
        2_307_445,
        0,
        0x66,
        &[
            &(-3i8).to_le_bytes(),
            &(-300i16).to_le_bytes(),
            &(-70_000i32).to_le_bytes(),
            &(-5_000_000_000i64).to_le_bytes(),
            &1.23456f32.to_le_bytes(),
        ],
    );
    let d = decode(&m, &e).unwrap();
    assert_eq!(d.message, "Arguments: -3 -300 -70000 -5000000000 1.23");
    assert_eq!(d.description, "test\n<{}PARAMwww.test.com");
    assert_eq!((d.name.as_str(), d.log_level), ("test::test2", 6));
    let e = event(
        2_307_042,
        0,
        6,
        &[
            &[200],
            &2.25f32.to_le_bytes(),
            &65_000u16.to_le_bytes(),
            &4_000_000_000u32.to_le_bytes(),
            &u64::MAX.to_le_bytes(),
        ],
    );
    let d = decode(&m, &e).unwrap();
    assert_eq!(
        d.message,
        format!("Arguments: 200 2.2 65000 4000000000 {}", u64::MAX)
    );
    // Profile `normal`: "!normal" hidden, "!dev" shown; a link shows its text.
    assert_eq!(d.description, "url\n\n\n remove this");
    let e = event(2_307_044, 0, 6, &[&12.5f32.to_le_bytes()]);
    assert_eq!(decode(&m, &e).unwrap().message, "Testing units: 12.5 m");
    assert!(
        decode(&m, &event(1234, 0, 6, &[])).is_none(),
        "an id the metadata lacks"
    );
}

#[test]
fn enums_show_their_descriptions_and_bitfields_their_bits() {
    let m = meta();
    let armed = px4_event_id("commander_armed_by");
    assert_eq!(armed, (1 << 24) | 9_489_139);
    assert_eq!(
        decode(&m, &event(armed, 0, 6, &[&[4]])).unwrap().message,
        "Armed by external command"
    );
    assert_eq!(
        decode(&m, &event(armed, 0, 6, &[&[99]])).unwrap().message,
        "Armed by (unknown: 99)"
    );
    let modes = decode(&m, &event((1 << 24) | 99, 0, 6, &[&5u32.to_le_bytes()])).unwrap();
    assert_eq!(
        modes.message,
        "Modes: Fully manual mode (w/o any controller support)|Position mode"
    );
}

fn report_events(can_arm: u32, seq0: u16) -> Vec<EVENT_DATA> {
    let odid = 1u32 << 30;
    vec![
        event(
            (1 << 24) | 11_047_904,
            seq0,
            0x88,
            &[
                &[0],
                &odid.to_le_bytes(),
                &0u32.to_le_bytes(),
                &can_arm.to_le_bytes(),
                &can_arm.to_le_bytes(),
            ],
        ),
        event(
            (1 << 24) | 10_161_216,
            seq0.wrapping_add(1),
            0x33,
            &[&0xffff_ffffu32.to_le_bytes(), &[30]],
        ),
        event(
            (1 << 24) | 9_999_999,
            seq0.wrapping_add(2),
            0x88,
            &[
                &[0],
                &odid.to_le_bytes(),
                &0u32.to_le_bytes(),
                &0u32.to_le_bytes(),
            ],
        ),
    ]
}

#[test]
fn the_health_report_is_built_from_its_events_and_says_what_prevents_arming() {
    let m = meta();
    let groups = Arc::new(m.mode_groups.clone());
    let mut b = HealthReportBuilder::default();
    let mut reports = Vec::new();
    for e in report_events(0, 10) {
        reports.extend(b.on_event(&decode(&m, &e).unwrap(), &groups));
    }
    assert_eq!(reports.len(), 1);
    let loiter = Some(50_593_792);
    let checks = reports[0].checks_for(loiter);
    assert_eq!(checks.len(), 1);
    assert_eq!(checks[0].message, "Open Drone ID system missing");
    assert_eq!(
        checks[0].description,
        "Open Drone ID system failed to report."
    );
    assert_eq!(
        (checks[0].severity.as_str(), checks[0].prevents_arming),
        ("error", true)
    );
    // COM_ARM_ODID 1: reported for every mode, every mode can arm.
    let mut b = HealthReportBuilder::default();
    let r: Vec<_> = report_events(u32::MAX, 20)
        .iter()
        .filter_map(|e| b.on_event(&decode(&m, e).unwrap(), &groups))
        .collect();
    assert!(!r[0].checks_for(loiter)[0].prevents_arming);
    // A check without its summary, or a health summary of another chunk: no report.
    let mut b = HealthReportBuilder::default();
    let evs = report_events(0, 30);
    assert!(b.on_event(&decode(&m, &evs[1]).unwrap(), &groups).is_none());
    assert!(b.on_event(&decode(&m, &evs[2]).unwrap(), &groups).is_none());
}

#[test]
fn a_gap_is_asked_for_and_the_events_come_out_in_order() {
    let mut s = EventSequence::default();
    let t0 = Instant::now();
    let evs = report_events(0, 65_534); // wraps: 65534, 65535, 0
    assert_eq!(s.on_event(evs[0].clone(), t0).0.len(), 1);
    let (ready, request) = s.on_event(evs[2].clone(), t0);
    assert!(ready.is_empty());
    assert_eq!(request, Some((65_535, 65_535)));
    assert_eq!(
        s.on_tick(t0 + Duration::from_millis(100)).1,
        None,
        "asked already"
    );
    assert_eq!(
        s.on_tick(t0 + sequence::REQUEST_RETRY).1,
        Some((65_535, 65_535))
    );
    let (ready, _) = s.on_event(evs[1].clone(), t0);
    assert_eq!(
        ready.iter().map(|e| e.sequence).collect::<Vec<_>>(),
        [65_535, 0]
    );
    assert!(
        s.on_event(evs[1].clone(), t0).0.is_empty(),
        "a repeat is dropped"
    );
    // Missed at the end: the current sequence says so.
    assert_eq!(
        s.on_current(3, false, t0 + Duration::from_secs(1)),
        Some((1, 3))
    );
    // The vehicle no longer holds them: skipped.
    let later = report_events(0, 4);
    assert!(s.on_event(later[0].clone(), t0).0.is_empty());
    assert_eq!(s.on_unavailable(1, 3).len(), 0, "3 still missing");
    let ready = s.on_unavailable(3, 4);
    assert_eq!(ready.iter().map(|e| e.sequence).collect::<Vec<_>>(), [4]);
    assert_eq!(s.lost, 3);
    // A gap nobody fills is given up after GAP_GIVE_UP.
    s.on_event(later[2].clone(), t0);
    let (ready, _) = s.on_tick(t0 + sequence::GAP_GIVE_UP);
    assert_eq!(ready.iter().map(|e| e.sequence).collect::<Vec<_>>(), [6]);
    // A reboot: the sequence restarts.
    assert_eq!(s.on_current(0, true, t0), None);
    assert_eq!(s.on_event(event(1, 1, 6, &[]), t0).0.len(), 1);
    let _ = HashMap::<u32, u8>::new();
}
