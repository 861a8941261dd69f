//! The ground station's own GNSS receiver: where the operator stands, for Remote ID's
//! `LIVE_GNSS` operator location (`skein_link::remote_id`).
//!
//! A field laptop or a companion computer has its receiver as gpsd (the Linux GNSS
//! daemon, JSON on TCP 2947) or as NMEA 0183 sentences on a serial port (a USB
//! receiver) or over TCP. One [`GnssReader`] per process keeps the source connected
//! and holds the latest fix; every vehicle link of the process reads it without waiting.
//!
//! - [`source`]: the source strings (`gpsd://HOST[:PORT]`, `serial:DEVICE:BAUD`,
//!   `tcp://HOST:PORT`).
//! - [`fix`]: a fix and what a receiver reports ([`GnssReport`]).
//! - [`nmea0183`]: NMEA 0183 `GGA` and `RMC` sentences (checksums checked by the `nmea`
//!   crate) to reports.
//! - [`gpsd`]: gpsd's JSON protocol: the `?WATCH` command, `TPV` reports to reports.
//! - [`lines`]: lines out of a byte stream, an over-long one dropped and counted.
//! - [`reader`]: [`GnssReader`], the connection kept up with backoff, and [`GnssState`],
//!   what it knows now.
//!
//! Bad input is counted and dropped: a sentence whose checksum or fields are wrong, a
//! JSON line that does not parse, a line longer than [`lines::MAX_LINE`].
#![warn(missing_docs)]

pub mod fix;
pub mod gpsd;
pub mod lines;
pub mod nmea0183;
pub mod reader;
mod session;
pub mod source;

pub use fix::{GnssFix, GnssReport};
pub use reader::{GnssReader, GnssState};
pub use source::{GnssSource, SourceError};
