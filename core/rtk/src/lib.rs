//! RTK corrections for the whole fleet: one corrections source (an NTRIP caster, a TCP
//! or UDP stream of RTCM3, a base station on a serial port) kept connected, its RTCM3
//! frames checked, and each sent to every vehicle of this process as MAVLink
//! `GPS_RTCM_DATA` (fragmented by MAVLink's rules) under a per-vehicle rate cap.
//!
//! - [`source`]: the source strings (`ntrip://user:pass@host:2101/MOUNT`, ...).
//! - [`config`]: `[rtk]` of the configuration and the body of `PUT /api/v1/rtk`.
//! - [`ntrip`]: the NTRIP client's request, the caster's answers (1.0 and 2.0), chunked
//!   transfer coding, NMEA GGA for network RTK.
//! - [`framer`]: RTCM3 frames in a byte stream (`rtcm-rs`), bad CRCs and noise counted,
//!   the base station's position.
//! - [`fragment`]: one RTCM message as `GPS_RTCM_DATA` fragments.
//! - [`hub`]: every frame to every vehicle, and the status.
//! - [`session`], [`service`]: one connection; kept connected with backoff.
//! - [`relay`]: corrections relayed between the processes of a distributed swarm (the
//!   active coordinator's source's frames tapped, an agent's taken as its source).
//! - [`status`]: what `GET /api/v1/rtk` shows.
//! - [`testing`]: RTCM3 frames for tests and rehearsals.
//!
//! PX4 has no NTRIP client of its own: it passes each `GPS_RTCM_DATA` to its GPS driver,
//! which writes the bytes to the receiver. In a distributed swarm each agent runs its own
//! service for its own vehicles, its source its own or the active coordinator's frames
//! relayed over DDS ([`relay`]).
#![warn(missing_docs)]

pub mod config;
pub mod fragment;
pub mod framer;
pub mod hub;
pub mod ntrip;
pub mod relay;
pub mod service;
mod session;
pub mod source;
pub mod status;
pub mod testing;

pub use config::{ConfigError, RtkConfig, RtkSettings};
pub use hub::{Hub, Vehicles};
pub use relay::{RelayRole, RelayStatus, Relayed};
pub use service::RtkService;
pub use source::{Source, SourceError};
pub use status::{RtkStatus, SourceState};
