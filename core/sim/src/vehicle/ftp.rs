//! The vehicle's MAVLink FTP ([`crate::ftp_server`]) serving its component metadata
//! ([`crate::component_metadata`]), and `COMPONENT_METADATA` on request.
//!
//! `FILE_TRANSFER_PROTOCOL` addressed to the autopilot (system id ours or 0, component
//! 1 or 0) is answered to its sender; a payload whose `size` is out of range is counted
//! and dropped. PX4 streams a burst as fast as its transmit buffer drains; the
//! simulator paces it at [`FTP_BURST_RATE_BYTES_S`] on the simulation step, so that a
//! burst and the telemetry share a datagram and the link's loss and cuts apply to it.

use super::*;
use crate::component_metadata::{GENERAL_URI, MetadataFiles};
use crate::ftp_server::FtpServer;
use skein_mavlink::ftp::FtpPayload;

/// Burst bytes sent per second at most (about 840 messages/s).
pub(crate) const FTP_BURST_RATE_BYTES_S: u64 = 200_000;
/// Bytes of one `FILE_TRANSFER_PROTOCOL` payload, for the pacing.
const MESSAGE_BYTES: u64 = 251;

fn metadata_file(path: &str) -> Option<&'static [u8]> {
    MetadataFiles::get().file(path)
}

/// The server and its pacing.
#[derive(Debug)]
pub(crate) struct FtpLink {
    server: FtpServer,
    credit_bytes: u64,
    /// Payloads dropped as malformed.
    pub malformed: u64,
    /// Requests handled.
    pub requests: u64,
}

impl Default for FtpLink {
    fn default() -> Self {
        FtpLink {
            server: FtpServer::new(metadata_file),
            credit_bytes: 0,
            malformed: 0,
            requests: 0,
        }
    }
}

impl Vehicle {
    /// A `FILE_TRANSFER_PROTOCOL` from `from`.
    pub(super) fn on_ftp(
        &mut self,
        now: Instant,
        m: &FILE_TRANSFER_PROTOCOL_DATA,
        from: (u8, u8),
        out: &mut Outbox,
    ) {
        if !self.targets_me(m.target_system, m.target_component) {
            return;
        }
        let Ok(req) = FtpPayload::decode(&m.payload) else {
            self.ftp.malformed += 1;
            return;
        };
        self.ftp.requests += 1;
        if let Some(reply) = self.ftp.server.handle(&req, from, now) {
            out.push(&reply.to_message(from.0, from.1));
        }
    }

    /// Every step (`dt_s` long): the burst in progress, as far as the pacing allows.
    pub(super) fn ftp_send(&mut self, now: Instant, dt_s: f64, out: &mut Outbox) {
        let dt_us = (dt_s.max(0.0) * 1e6).round() as u64;
        self.ftp.credit_bytes = (self.ftp.credit_bytes
            + FTP_BURST_RATE_BYTES_S * dt_us / 1_000_000)
            .min(16 * MESSAGE_BYTES);
        let max = (self.ftp.credit_bytes / MESSAGE_BYTES) as usize;
        let sent = self.ftp.server.pump(now, max);
        if sent.is_empty() {
            self.ftp.credit_bytes = 0;
        }
        for ((sys, comp), p) in sent {
            self.ftp.credit_bytes -= MESSAGE_BYTES;
            out.push(&p.to_message(sys, comp));
        }
    }

    /// MAVLink FTP requests this vehicle handled (its reboots included).
    pub(crate) fn ftp_requests(&self) -> u64 {
        self.ftp.requests
    }

    /// `COMPONENT_METADATA` as PX4 answers `MAV_CMD_REQUEST_MESSAGE` 397: the general
    /// metadata's URI and CRC.
    pub(crate) fn component_metadata(&self, now: Instant) -> MavMessage {
        MavMessage::COMPONENT_METADATA(COMPONENT_METADATA_DATA {
            time_boot_ms: self.time_boot_ms(now),
            file_crc: MetadataFiles::get().general_crc,
            uri: GENERAL_URI.into(),
        })
    }
}
