//! Flight recording: what happened in the swarm, written to an MCAP file that Foxglove
//! and the reference `mcap` readers open, and read back for `skein replay`.
//!
//! A [`Recording`] collects, while it runs:
//! - every vehicle's snapshot at 10 Hz (`/skein/<id>/state`, the `GET /api/v1/vehicles`
//!   shape) and its position as `foxglove.LocationFix` (`/skein/<id>/fix`, WGS-84);
//! - every MAVLink message skein sends to a vehicle (`/skein/<id>/sent`: setpoints with
//!   their `type_mask`, commands with their parameters);
//! - the swarm events of the stream (`/skein/events`: state changes, command outcomes,
//!   failovers, hazards, plugin events) and the commands the API accepted
//!   (`/skein/commands`);
//! - the formation (`/skein/formation`, on every change and each second);
//! - the missions (`/skein/missions`, each second while the coordinator holds any, and at
//!   the stop: the `GET /api/v1/missions` list, each one's state, step and progress per
//!   group);
//! - camera frames as `foxglove.CompressedImage` (`/skein/<id>/<slot>/image`, JPEG).
//!
//! Messages are JSON with a JSON Schema per channel (MCAP `jsonschema` encoding), stamped
//! with the wall-clock time they were taken (ns since the Unix epoch). See
//! [`channels`] for the schemas and [`reader`] for reading a file back.

pub mod channels;
pub mod reader;
pub mod recorder;
mod sent;
mod writer;

pub use reader::{ReplayError, Timeline};
pub use recorder::{RecordError, Recorder, Recording, RecordingSummary, Sources};
