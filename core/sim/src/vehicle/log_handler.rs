//! The MAVLink log protocol, vehicle side (PX4 `mavlink_log_handler`): a ground station
//! lists the vehicle's flight logs (`flight_log`) and downloads them.
//!
//! As PX4 v1.16's handler (rewritten in 2024) does it:
//! - `LOG_REQUEST_LIST {start, end}` lists the logs anew (ids from 0, oldest first) and
//!   sends `LOG_ENTRY {id, num_logs, last_log_num, time_utc, size}` for every id from
//!   `start` to the last log (PX4 does not stop at `end`); `last_log_num` is `end`, or
//!   `num_logs` when `end` is 0xFFFF (sic). With no log it sends nothing: a ground
//!   station hears no entry at all.
//! - `LOG_REQUEST_DATA {id, ofs, count}` is ignored before the first listing and for an
//!   id past it; otherwise it streams `LOG_DATA {id, ofs, count, data[90]}` from `ofs`,
//!   90 bytes a chunk (the file's last one shorter), until it has sent `count` bytes or
//!   more (whole chunks: the last one may run past `count`; `count` 0 still sends one) or
//!   reached the end; nothing when `ofs` is past the end. A new request replaces the one
//!   in progress, and so does a listing.
//! - `LOG_REQUEST_END` stops what is being sent (the listing stays); `LOG_ERASE` also
//!   deletes every log (the one being written too).
//!
//! The listing keeps the logs as they were when it was taken (the one being written as
//! far as it was), so ids and sizes stay those of the listing until the next one.
//! PX4 sends as fast as its MAVLink buffer drains; the simulator paces the chunks at
//! [`LOG_DATA_RATE_BYTES_S`] on the simulation step. Everything goes out through the
//! vehicle's outbox, so the link's loss, latency and cuts apply to it as to telemetry.

use super::*;

/// Log bytes a download streams per second at most: 72 kB/s, 8 chunks of 90 bytes per
/// 10 ms step (about 87 kB/s on the wire with MAVLink 2 framing). PX4 sends as fast as
/// its link takes; a simulator must not: at this rate one step's chunks fit a datagram
/// with the telemetry, a swarm downloading at once does not flood the host's sockets, and
/// a download still goes about as fast as over a good telemetry link (a 100 kB flight
/// log in 1.4 s).
pub(crate) const LOG_DATA_RATE_BYTES_S: u64 = 72_000;
/// Bytes of log in one `LOG_DATA` (`data[90]`).
const LOG_DATA_CHUNK: u32 = 90;

/// What the handler sends on the next steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Activity {
    /// Nothing.
    Idle,
    /// `LOG_ENTRY`s for ids `next..` to the last log, each saying `last_log_num`.
    Listing { next: u16, last_log_num: u16 },
    /// `LOG_DATA` of log `id` from `ofs` until `ofs` reaches `until` or the end.
    Sending { id: u16, ofs: u32, until: u32 },
}

/// A listing (PX4's list helper): the logs as listed, and what is being sent of them.
#[derive(Debug)]
struct Listing {
    logs: Vec<FlightLog>,
    activity: Activity,
}

/// The log handler's state (PX4's `MavlinkLogHandler`): reset by a reboot, unlike the
/// logs.
#[derive(Debug, Default)]
pub(crate) struct LogHandler {
    /// `None` until the first `LOG_REQUEST_LIST` (PX4's `_logs_listed`).
    listing: Option<Listing>,
    /// Bytes of `LOG_DATA` the pacing allows now.
    credit_bytes: u64,
}

impl Listing {
    /// Sends the `LOG_ENTRY`s for ids `next..` to the last log (none when there is no
    /// log, or `next` is past the last).
    fn send_entries(&mut self, next: u16, last_log_num: u16, out: &mut Outbox) {
        let num_logs = u16::try_from(self.logs.len()).unwrap_or(u16::MAX);
        for (id, log) in self.logs.iter().enumerate().skip(usize::from(next)) {
            out.push(&MavMessage::LOG_ENTRY(LOG_ENTRY_DATA {
                time_utc: log.time_utc,
                size: log_size(log),
                id: id as u16,
                num_logs,
                last_log_num,
            }));
        }
        self.activity = Activity::Idle;
    }

    /// Sends the `LOG_DATA` chunks `credit_bytes` allows, spending it.
    fn send_data(&mut self, credit_bytes: &mut u64, out: &mut Outbox) {
        let Activity::Sending { id, mut ofs, until } = self.activity else {
            return;
        };
        let Some(log) = self.logs.get(usize::from(id)) else {
            self.activity = Activity::Idle;
            return;
        };
        let size = log_size(log);
        let mut done = ofs >= size;
        while !done && *credit_bytes >= u64::from(LOG_DATA_CHUNK) {
            let count = (size - ofs).min(LOG_DATA_CHUNK);
            let start = ofs as usize;
            let mut data = [0u8; LOG_DATA_CHUNK as usize];
            data[..count as usize].copy_from_slice(&log.bytes[start..start + count as usize]);
            out.push(&MavMessage::LOG_DATA(LOG_DATA_DATA {
                ofs,
                id,
                count: count as u8,
                data,
            }));
            ofs += count;
            *credit_bytes -= u64::from(LOG_DATA_CHUNK);
            done = ofs >= until || ofs >= size;
        }
        self.activity = if done {
            Activity::Idle
        } else {
            Activity::Sending { id, ofs, until }
        };
    }
}

/// `LOG_ENTRY.size` of `log`, bytes.
fn log_size(log: &FlightLog) -> u32 {
    u32::try_from(log.bytes.len()).unwrap_or(u32::MAX)
}

impl Vehicle {
    /// `LOG_REQUEST_LIST`: the logs listed anew, their entries sent from `start`.
    pub(super) fn on_log_request_list(&mut self, r: &LOG_REQUEST_LIST_DATA) {
        let logs = self.flight_logs.list();
        let num_logs = u16::try_from(logs.len()).unwrap_or(u16::MAX);
        let last_log_num = if r.end == u16::MAX { num_logs } else { r.end };
        self.log_handler.listing = Some(Listing {
            logs,
            activity: Activity::Listing {
                next: r.start,
                last_log_num,
            },
        });
    }

    /// `LOG_REQUEST_DATA`: log `id` from `ofs`, `count` bytes (whole chunks).
    pub(super) fn on_log_request_data(&mut self, r: &LOG_REQUEST_DATA_DATA) {
        let Some(listing) = self.log_handler.listing.as_mut() else {
            return; // PX4: "Logs not yet listed"
        };
        let Some(log) = listing.logs.get(usize::from(r.id)) else {
            listing.activity = Activity::Idle;
            return; // PX4: "Requested log N but we only have M"
        };
        listing.activity = if r.ofs >= log_size(log) {
            Activity::Idle // PX4: "Request offset greater than file size"
        } else {
            Activity::Sending {
                id: r.id,
                ofs: r.ofs,
                until: r.ofs.saturating_add(r.count),
            }
        };
    }

    /// `LOG_REQUEST_END`: nothing more is sent (the listing stays).
    pub(super) fn on_log_request_end(&mut self) {
        if let Some(l) = self.log_handler.listing.as_mut() {
            l.activity = Activity::Idle;
        }
    }

    /// `LOG_ERASE`: every log is deleted (a data request then finds none).
    pub(super) fn on_log_erase(&mut self) {
        if let Some(l) = self.log_handler.listing.as_mut() {
            l.logs.clear();
            l.activity = Activity::Idle;
        }
        self.flight_logs.erase();
    }

    /// Every step (`dt_s` long): the `LOG_ENTRY`s of a listing, or the `LOG_DATA` of a
    /// download that [`LOG_DATA_RATE_BYTES_S`] allows.
    pub(super) fn log_handler_send(&mut self, dt_s: f64, out: &mut Outbox) {
        let h = &mut self.log_handler;
        let Some(listing) = h.listing.as_mut() else {
            h.credit_bytes = 0;
            return;
        };
        match listing.activity {
            Activity::Idle => h.credit_bytes = 0,
            Activity::Listing { next, last_log_num } => {
                listing.send_entries(next, last_log_num, out)
            }
            Activity::Sending { .. } => {
                let dt_us = (dt_s.max(0.0) * 1e6).round() as u64;
                h.credit_bytes += LOG_DATA_RATE_BYTES_S * dt_us / 1_000_000;
                listing.send_data(&mut h.credit_bytes, out);
            }
        }
    }
}
