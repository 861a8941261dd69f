//! The events the simulated PX4 sends (`EVENT`), with PX4 v1.16's names, messages, log
//! levels and arguments, and the libevents metadata describing them (what PX4 ships as
//! `/etc/extras/all_events.json.xz`).
//!
//! One table ([`EVENTS`]) is both what the vehicle sends and what its metadata says, so
//! the two cannot disagree. Verified in PX4's sources: the commander's events
//! (`Commander.cpp`: `commander_armed_by` "Armed by {1}" with an `arm_disarm_reason_t`,
//! `commander_disarmed_by`, `commander_arm_denied_resolve_failures` (critical,
//! internally info), `commander_takeoff_detected`, `commander_landing_detected`,
//! `commander_landing_current_pos`, `commander_rtl`, `commander_disarm_denied_not_landed`),
//! the health and arming checks (`HealthAndArmingChecks/Common.cpp`: the
//! `commander_arming_check_summary` of type `summary` in group `arming_check` with
//! `chunk_idx`, `error`, `warning`, `can_arm`, `can_run`; `commander_health_summary` in
//! group `health` with `chunk_idx`, `is_present`, `error`, `warning`; each failing check
//! an event of group `arming_check` whose first two arguments are the affected
//! `navigation_mode_group_t` modes and the `health_component_index`:
//! `checks/openDroneIDCheck.cpp` `check_open_drone_id_missing`, `checks/modeCheck.cpp`
//! `check_modes_global_pos`, `check_modes_home_position`), and PX4's enums
//! (`src/lib/events/enums.json`: `navigation_mode_group_t` bit = PX4's `nav_state`,
//! `health_component_t`, `arm_disarm_reason_t`, and `navigation_mode_groups` mapping each
//! group to the `custom_mode` values of its modes).

use serde_json::{Map, Value, json};
use skein_mavlink::events::{LOG_PROTOCOL, px4_event_id};

/// libevents log levels used here.
pub mod level {
    /// Critical.
    pub const CRITICAL: u8 = 2;
    /// Error.
    pub const ERROR: u8 = 3;
    /// Info.
    pub const INFO: u8 = 6;
}

/// One event PX4 can send.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EventDef {
    /// PX4's name (`events::ID("name")`).
    pub name: &'static str,
    /// The metadata's event group (`default`, `arming_check`, `health`).
    pub group: &'static str,
    /// `summary` for the health report's summaries, else empty.
    pub kind: &'static str,
    /// The message, libevents' syntax (`{1}` the first argument).
    pub message: &'static str,
    /// The longer description (may hold `<param>` and `<profile>` tags).
    pub description: &'static str,
    /// Arguments: (type, name), in order.
    pub args: &'static [(&'static str, &'static str)],
    /// External log level.
    pub level: u8,
    /// Internal log level.
    pub internal: u8,
}

impl EventDef {
    /// The event's id.
    pub fn id(&self) -> u32 {
        px4_event_id(self.name)
    }
}

const CHECK_ARGS: &[(&str, &str)] = &[
    ("navigation_mode_group_t", "modes"),
    ("uint8_t", "health_component_index"),
];

const fn info(name: &'static str, message: &'static str) -> EventDef {
    EventDef {
        name,
        group: "default",
        kind: "",
        message,
        description: "",
        args: &[],
        level: level::INFO,
        internal: level::INFO,
    }
}

const fn denied(name: &'static str, message: &'static str) -> EventDef {
    EventDef {
        level: level::CRITICAL,
        ..info(name, message)
    }
}

/// "Armed by {1}".
pub const ARMED_BY: EventDef = EventDef {
    args: &[("px4::arm_disarm_reason_t", "reason")],
    ..info("commander_armed_by", "Armed by {1}")
};
/// "Disarmed by {1}".
pub const DISARMED_BY: EventDef = EventDef {
    args: &[("px4::arm_disarm_reason_t", "reason")],
    ..info("commander_disarmed_by", "Disarmed by {1}")
};
/// The commander's verdict after failed arming checks.
pub const ARM_DENIED_RESOLVE_FAILURES: EventDef = denied(
    "commander_arm_denied_resolve_failures",
    "Arming denied: Resolve system health failures first",
);
/// A disarm refused in the air.
pub const DISARM_DENIED_NOT_LANDED: EventDef = denied(
    "commander_disarm_denied_not_landed",
    "Disarming denied: not landed",
);
/// The land detector saw a take-off.
pub const TAKEOFF_DETECTED: EventDef = info("commander_takeoff_detected", "Takeoff detected");
/// The land detector saw a landing.
pub const LANDING_DETECTED: EventDef = info("commander_landing_detected", "Landing detected");
/// `MAV_CMD_NAV_LAND` accepted.
pub const LANDING_CURRENT_POS: EventDef = info(
    "commander_landing_current_pos",
    "Landing at current position",
);
/// `MAV_CMD_NAV_RETURN_TO_LAUNCH` accepted.
pub const RTL: EventDef = info("commander_rtl", "Returning to launch");

/// The health report's opening summary.
pub const ARMING_CHECK_SUMMARY: EventDef = EventDef {
    name: "commander_arming_check_summary",
    group: "arming_check",
    kind: "summary",
    message: "Arming check summary event",
    description: "",
    args: &[
        ("uint8_t", "chunk_idx"),
        ("px4::health_component_t", "error"),
        ("px4::health_component_t", "warning"),
        ("px4::navigation_mode_group_t", "can_arm"),
        ("px4::navigation_mode_group_t", "can_run"),
    ],
    level: LOG_PROTOCOL,
    internal: LOG_PROTOCOL,
};
/// The health report's closing summary.
pub const HEALTH_SUMMARY: EventDef = EventDef {
    name: "commander_health_summary",
    group: "health",
    kind: "summary",
    message: "Health report summary event",
    description: "",
    args: &[
        ("uint8_t", "chunk_idx"),
        ("px4::health_component_t", "is_present"),
        ("px4::health_component_t", "error"),
        ("px4::health_component_t", "warning"),
    ],
    level: LOG_PROTOCOL,
    internal: LOG_PROTOCOL,
};

const fn check(
    name: &'static str,
    message: &'static str,
    description: &'static str,
    level: u8,
) -> EventDef {
    EventDef {
        name,
        group: "arming_check",
        kind: "",
        message,
        description,
        args: CHECK_ARGS,
        level,
        internal: level,
    }
}

/// `COM_ARM_ODID` set and no Open Drone ID system reported.
pub const CHECK_OPEN_DRONE_ID_MISSING: EventDef = check(
    "check_open_drone_id_missing",
    "Open Drone ID system missing",
    "Open Drone ID system failed to report. Make sure it it setup and installed properly.\n\n<profile name=\"dev\">\nThis check can be configured via <param>COM_ARM_ODID</param> parameter.\n</profile>",
    level::ERROR,
);
/// No global position estimate yet.
pub const CHECK_MODES_GLOBAL_POS: EventDef = check(
    "check_modes_global_pos",
    "Navigation error: No valid global position estimate",
    "The available positioning data is not sufficient to execute the selected mode.",
    level::ERROR,
);
/// No home position yet.
pub const CHECK_MODES_HOME_POSITION: EventDef = check(
    "check_modes_home_position",
    "Home position not set",
    "",
    level::INFO,
);

/// Every event the simulator sends.
pub const EVENTS: &[EventDef] = &[
    ARMED_BY,
    DISARMED_BY,
    ARM_DENIED_RESOLVE_FAILURES,
    DISARM_DENIED_NOT_LANDED,
    TAKEOFF_DETECTED,
    LANDING_DETECTED,
    LANDING_CURRENT_POS,
    RTL,
    ARMING_CHECK_SUMMARY,
    HEALTH_SUMMARY,
    CHECK_OPEN_DRONE_ID_MISSING,
    CHECK_MODES_GLOBAL_POS,
    CHECK_MODES_HOME_POSITION,
];

/// PX4's `arm_disarm_reason_t` values the simulator uses.
pub mod arm_disarm_reason {
    /// "external command".
    pub const COMMAND_EXTERNAL: u8 = 4;
    /// "landing".
    pub const AUTO_DISARM_LAND: u8 = 6;
    /// "auto preflight disarming".
    pub const AUTO_DISARM_PREFLIGHT: u8 = 7;
}

/// `health_component_t` bit indices (the check events' `health_component_index`).
pub mod health_component {
    /// GPS.
    pub const GPS: u8 = 3;
    /// Absolute pressure.
    pub const ABSOLUTE_PRESSURE: u8 = 1;
    /// Battery.
    pub const BATTERY: u8 = 11;
    /// System.
    pub const SYSTEM: u8 = 20;
    /// Global position estimate.
    pub const GLOBAL_POSITION_ESTIMATE: u8 = 24;
    /// Magnetometer.
    pub const MAGNETOMETER: u8 = 27;
    /// Accelerometer.
    pub const ACCEL: u8 = 28;
    /// Gyroscope.
    pub const GYRO: u8 = 29;
    /// Open Drone ID system.
    pub const OPEN_DRONE_ID: u8 = 30;
}

const ARM_DISARM_REASONS: &[(u64, &str, &str)] = &[
    (0, "transition_to_standby", "Transition to standby"),
    (1, "rc_stick", "RC"),
    (2, "rc_switch", "RC (switch)"),
    (3, "command_internal", "internal command"),
    (4, "command_external", "external command"),
    (5, "mission_start", "mission start"),
    (6, "auto_disarm_land", "landing"),
    (7, "auto_disarm_preflight", "auto preflight disarming"),
    (8, "kill_switch", "kill switch"),
    (9, "lockdown", "lockdown"),
    (10, "failure_detector", "failure detector"),
    (11, "shutdown", "shutdown request"),
    (12, "unit_test", "unit tests"),
    (13, "rc_button", "RC (button)"),
    (14, "failsafe", "failsafe"),
];

const HEALTH_COMPONENTS: &[&str] = &[
    "none:None",
    "absolute_pressure:Absolute pressure",
    "differential_pressure:Differential pressure",
    "gps:GPS",
    "optical_flow:Optical flow",
    "vision_position:Vision position estimate",
    "distance_sensor:Distance sensor",
    "remote_control:Remote Control (RC or Joystick)",
    "motors_escs:Motors/ESCs",
    "utm:UTM",
    "logging:Logging",
    "battery:Battery",
    "communication_links:Communication links",
    "rate_controller:Rate controller",
    "attitude_controller:Attitude controller",
    "position_controller:Position controller",
    "attitude_estimate:Attitude estimate",
    "local_position_estimate:Local position estimate",
    "mission:Mission",
    "avoidance:Avoidance",
    "system:System",
    "camera:Camera",
    "gimbal:Gimbal",
    "payload:Payload",
    "global_position_estimate:Global position estimate",
    "storage:Storage",
    "parachute:Parachute",
    "magnetometer:Magnetometer",
    "accel:Accelerometer",
    "gyro:Gyroscope",
    "open_drone_id:Open Drone ID system",
];

/// PX4's navigation mode groups (bit = `nav_state`), with the `custom_mode` of each.
pub const MODE_GROUPS: &[(u8, &str, &str, u32)] = &[
    (
        0,
        "manual",
        "Fully manual mode (w/o any controller support)",
        65536,
    ),
    (1, "altctl", "Altitude mode", 131_072),
    (2, "posctl", "Position mode", 196_608),
    (3, "mission", "Mission mode", 67_371_008),
    (4, "loiter", "Loiter", 50_593_792),
    (5, "rtl", "RTL", 84_148_224),
    (10, "acro", "Acro", 327_680),
    (14, "offboard", "Offboard", 393_216),
    (15, "stab", "Stabilized", 458_752),
    (17, "takeoff", "Takeoff", 33_816_576),
    (18, "land", "Land", 100_925_440),
    (19, "follow_target", "Follow Target", 134_479_872),
    (20, "precland", "Precision Land", 151_257_088),
];

/// Every mode group's bit.
pub fn all_mode_groups() -> u32 {
    MODE_GROUPS.iter().fold(0, |m, g| m | (1 << g.0))
}

fn enum_json(kind: &str, desc: &str, bitfield: bool, entries: Vec<(u64, &str, &str)>) -> Value {
    let mut e = Map::new();
    for (value, name, description) in entries {
        e.insert(
            value.to_string(),
            json!({"name": name, "description": description}),
        );
    }
    json!({"type": kind, "description": desc, "is_bitfield": bitfield, "entries": e})
}

fn px4_enums() -> Value {
    let health = HEALTH_COMPONENTS
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let (n, d) = s.split_once(':').unwrap_or((s, s));
            (1u64 << i, n, d)
        })
        .collect();
    let groups = MODE_GROUPS
        .iter()
        .map(|g| (1u64 << g.0, g.1, g.2))
        .collect();
    json!({
        "navigation_mode_group_t": enum_json("uint32_t",
            "Navigation/flight mode group bits. All modes within a group share the same arming checks. For now we directly map group == mode.",
            true, groups),
        "health_component_t": enum_json("uint32_t", "Bitfield for subsystems & components", true, health),
        "arm_disarm_reason_t": enum_json("uint8_t", "Reason for arming/disarming", false,
            ARM_DISARM_REASONS.to_vec()),
    })
}

/// The libevents metadata of [`EVENTS`] (PX4's `all_events.json`, format version 2):
/// namespace `px4` under component `1`, events keyed by their 24-bit sub id within
/// their groups, the enums, and the mode groups.
pub fn events_metadata_json() -> Value {
    let mut groups: Map<String, Value> = Map::new();
    for e in EVENTS {
        let mut def = json!({
            "name": e.name,
            "message": e.message,
            "arguments": e.args.iter().map(|(t, n)| json!({"type": t, "name": n})).collect::<Vec<_>>(),
        });
        if !e.description.is_empty() {
            def["description"] = json!(e.description);
        }
        if !e.kind.is_empty() {
            def["type"] = json!(e.kind);
        }
        let group = groups
            .entry(e.group)
            .or_insert_with(|| json!({"events": {}}));
        group["events"][(e.id() & 0x00ff_ffff).to_string()] = def;
    }
    let mut mode_groups = Map::new();
    for g in MODE_GROUPS {
        mode_groups.insert(g.0.to_string(), json!([g.3]));
    }
    json!({
        "version": 2,
        "components": {
            "1": {
                "namespace": "px4",
                "enums": px4_enums(),
                "event_groups": groups,
                "supported_protocols": ["health_and_arming_check"],
                "navigation_mode_groups": {"groups": mode_groups},
            }
        }
    })
}
