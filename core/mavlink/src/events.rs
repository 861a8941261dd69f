//! PX4's events interface on the wire (`EVENT`, `CURRENT_EVENT_SEQUENCE`,
//! `REQUEST_EVENT`, `RESPONSE_EVENT_ERROR`): how an event's id is made and what its
//! `log_levels` byte holds, shared by the simulator (which sends events) and the link
//! (which decodes them).
//!
//! Verified in PX4's `px4_platform_common/events.h`: `events::ID("name")` is the 32-bit
//! FNV-1a hash of the name (offset basis 0x811c9dc5, prime 0x01000193, the terminating
//! NUL not hashed), its low 24 bits as the sub id, ORed with component id 1 (the
//! autopilot's namespace `px4`) in the top 8 bits; `log_levels` is
//! `internal << 4 | external`, each a libevents log level (0 emergency … 7 debug,
//! 8 protocol, 9 disabled).

/// The component id of PX4's own namespace (`px4`) in an event id's top byte.
pub const PX4_COMPONENT: u8 = 1;

/// Log level `protocol` (8): an event of a protocol (the health report), not for users.
pub const LOG_PROTOCOL: u8 = 8;

/// The 32-bit FNV-1a hash PX4 makes event ids from.
pub fn fnv1a_32(name: &str) -> u32 {
    name.bytes().fold(0x811c_9dc5u32, |h, b| {
        (h ^ u32::from(b)).wrapping_mul(0x0100_0193)
    })
}

/// `events::ID(name)`: the id of PX4's event `name` (component 1, 24-bit hash).
pub fn px4_event_id(name: &str) -> u32 {
    (u32::from(PX4_COMPONENT) << 24) | (fnv1a_32(name) & 0x00ff_ffff)
}

/// The `log_levels` byte of an event of `external` level (what a user sees) and
/// `internal` level (what the vehicle logs).
pub fn log_levels(external: u8, internal: u8) -> u8 {
    (internal << 4) | (external & 0x0f)
}

/// The external (user-facing) log level of a `log_levels` byte.
pub fn external_level(log_levels: u8) -> u8 {
    log_levels & 0x0f
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_px4s_hash_of_the_name_in_component_1() {
        // Values worked out with PX4's hash_32_fnv1a_const.
        assert_eq!(px4_event_id("check_open_drone_id_missing"), 0x019b_0c40);
        assert_eq!(px4_event_id("commander_armed_by"), 0x0190_caf3);
        assert_eq!(px4_event_id("commander_arming_check_summary"), 0x01a8_93e0);
        assert_eq!(log_levels(2, 6), 0x62);
        assert_eq!(external_level(0x62), 2);
    }
}
