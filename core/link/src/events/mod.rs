//! PX4's events interface, the receiving side: the `EVENT` messages PX4 sends instead of
//! (or beside) `STATUSTEXT`, decoded with the metadata the vehicle serves.
//!
//! - [`metadata`]: libevents' JSON (PX4's `all_events.json`), parsed.
//! - [`decode`]: an `EVENT` decoded: arguments by their types, the message formatted as
//!   libevents does (enums, bitfields, `{n}` placeholders, tags stripped).
//! - [`health`]: the health and arming check report assembled from its events.
//! - [`sequence`]: the events in sequence order, gaps asked for (`REQUEST_EVENT`).
//! - [`status`]: where the metadata came from, how the events arrived.
//!
//! What was verified, and where: event ids and log levels in PX4's
//! `px4_platform_common/events.h` (see `skein_mavlink::events`); the sending side in
//! PX4's `mavlink_events.cpp` (a buffer of 20, `CURRENT_EVENT_SEQUENCE` every 3 s and
//! with the reset flag while nothing was sent, `RESPONSE_EVENT_ERROR` for a sequence no
//! longer held); the report's protocol in libevents' `health_and_arming_checks.cpp` and
//! PX4's `HealthAndArmingChecks/Common.cpp`; the metadata format and the formatting in
//! libevents' `parser.cpp` and `libs/test.json`, PX4's `src/lib/events/enums.json`.
//! The link's side of it is `px4link/events.rs`; the metadata's fetch
//! `px4link/metadata.rs`.

pub mod decode;
pub mod health;
pub mod metadata;
pub mod sequence;
pub mod status;

pub use decode::{ArgValue, DecodedEvent, decode};
pub use health::{ArmingReport, HealthReportBuilder};
pub use metadata::EventsMetadata;
pub use sequence::EventSequence;
pub use status::{EventsStatus, MetadataInfo};

#[cfg(test)]
mod tests;
