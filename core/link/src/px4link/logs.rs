//! The `Px4Link` actor's log protocol ([`crate::log_transfer`]): one listing or download
//! at a time, its `LOG_ENTRY` and `LOG_DATA` taken from the vehicle's frames, its
//! resends and gap requests driven by a [`LOG_TICK`] while it runs; a download under the
//! process's log bandwidth cap asks for one window of the log per tick
//! ([`crate::log_bandwidth`]).

use super::{Px4LinkMsg, Px4LinkState};
use crate::command::LinkError;
use crate::log_bandwidth::LogShare;
use crate::log_transfer::{
    LIST_ATTEMPTS, LIST_QUIET_ANSWERS, LIST_TIMEOUT, LogDownload, LogEntry, LogListing,
};
use ractor::{ActorRef, RpcReplyPort};
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::{LOG_REQUEST_DATA_DATA, LOG_REQUEST_END_DATA, LOG_REQUEST_LIST_DATA};
use std::sync::Arc;
use std::sync::atomic::AtomicU64;
use std::time::{Duration, Instant};

/// How often a running transfer checks its resends and gaps.
pub const LOG_TICK: Duration = Duration::from_millis(100);

/// Where a listing's outcome goes: the vehicle's logs, oldest first.
pub type LogListReply = RpcReplyPort<Result<Vec<LogEntry>, LinkError>>;

/// Where a download's outcome goes: the log's bytes, every one of them.
pub type LogDownloadReply = RpcReplyPort<Result<Vec<u8>, LinkError>>;

/// What follows a listing.
pub(super) enum AfterListing {
    /// Answer it.
    Reply(LogListReply),
    /// Download this log (its size comes from the listing), counting into the progress.
    Download(u16, Arc<AtomicU64>, LogDownloadReply),
}

impl AfterListing {
    fn fail(self, e: LinkError) {
        match self {
            AfterListing::Reply(r) => drop(r.send(Err(e))),
            AfterListing::Download(_, _, r) => drop(r.send(Err(e))),
        }
    }
}

/// The transfer in progress.
#[derive(Default)]
pub(super) enum LogOp {
    #[default]
    Idle,
    Listing {
        listing: LogListing,
        attempts: u32,
        /// Listings the vehicle let pass without an entry while it was heard.
        quiet_answers: u32,
        sent: Instant,
        then: AfterListing,
    },
    Downloading {
        download: LogDownload,
        reply: LogDownloadReply,
        /// Its part of the process's log bandwidth ([`crate::log_bandwidth`]).
        share: LogShare,
    },
}

impl Px4LinkState {
    /// Starts a listing followed by `then`; refused while another transfer runs.
    pub(super) fn start_log_listing(&mut self, myself: &ActorRef<Px4LinkMsg>, then: AfterListing) {
        if !matches!(self.logs, LogOp::Idle) {
            then.fail(LinkError::Rejected {
                command: "log transfer".into(),
                result: "another log transfer of this vehicle is in progress".into(),
                statustexts: vec![],
            });
            return;
        }
        self.request_log_list();
        self.logs = LogOp::Listing {
            listing: LogListing::default(),
            attempts: 1,
            quiet_answers: 0,
            sent: Instant::now(),
            then,
        };
        self.log_generation += 1;
        let generation = self.log_generation;
        myself.send_after(LOG_TICK, move || Px4LinkMsg::LogTick(generation));
    }

    fn request_log_list(&self) {
        let (target_system, target_component) = self.target();
        let msg = MavMessage::LOG_REQUEST_LIST(LOG_REQUEST_LIST_DATA {
            start: 0,
            end: u16::MAX,
            target_system,
            target_component,
        });
        let _ = self.link.endpoint.send(self.link.sysid, &msg);
    }

    fn request_log_data(&self, id: u16, ofs: u32, count: u32) {
        let (target_system, target_component) = self.target();
        let msg = MavMessage::LOG_REQUEST_DATA(LOG_REQUEST_DATA_DATA {
            ofs,
            count,
            id,
            target_system,
            target_component,
        });
        let _ = self.link.endpoint.send(self.link.sysid, &msg);
    }

    /// A frame of the autopilot: the transfer's, if it is a log message.
    pub(super) fn on_log_message(&mut self, msg: &MavMessage) {
        let done = match (msg, &mut self.logs) {
            (MavMessage::LOG_ENTRY(e), LogOp::Listing { listing, .. }) => listing.on_entry(e),
            (MavMessage::LOG_DATA(d), LogOp::Downloading { download, .. }) => {
                download.on_data(d, Instant::now())
            }
            _ => false,
        };
        if done {
            match self.logs {
                LogOp::Listing { .. } => self.listing_done(),
                _ => self.download_done(),
            }
        }
    }

    fn listing_done(&mut self) {
        let LogOp::Listing { listing, then, .. } = std::mem::take(&mut self.logs) else {
            return;
        };
        let entries = listing.entries();
        match then {
            AfterListing::Reply(r) => {
                let _ = r.send(Ok(entries));
            }
            AfterListing::Download(id, progress, reply) => {
                let Some(entry) = entries.iter().find(|e| e.id == id).copied() else {
                    let _ = reply.send(Err(LinkError::Rejected {
                        command: format!("log {id} download"),
                        result: format!("the vehicle has no log {id} ({} logs)", entries.len()),
                        statustexts: vec![],
                    }));
                    return;
                };
                let share = self.link.setup.log_bandwidth.join();
                let window = share.window_bytes(LOG_TICK).unwrap_or(u32::MAX);
                let now = Instant::now();
                let mut download = LogDownload::new(entry, progress, now);
                let first = (0, window.min(entry.size_bytes));
                download.requested(now, first);
                self.request_log_data(id, first.0, first.1);
                self.logs = LogOp::Downloading {
                    download,
                    reply,
                    share,
                };
                if entry.size_bytes == 0 {
                    self.download_done();
                }
            }
        }
    }

    fn download_done(&mut self) {
        let LogOp::Downloading {
            download, reply, ..
        } = std::mem::take(&mut self.logs)
        else {
            return;
        };
        let (target_system, target_component) = self.target();
        let end = MavMessage::LOG_REQUEST_END(LOG_REQUEST_END_DATA {
            target_system,
            target_component,
        });
        let _ = self.link.endpoint.send(self.link.sysid, &end);
        let _ = reply.send(Ok(download.into_bytes()));
    }

    /// A [`LOG_TICK`] of transfer `generation`: resends a listing, asks for a gap, or
    /// gives up (see [`crate::log_transfer`]).
    pub(super) fn on_log_tick(&mut self, myself: &ActorRef<Px4LinkMsg>, generation: u64) {
        if generation != self.log_generation {
            return;
        }
        let now = Instant::now();
        match &mut self.logs {
            LogOp::Idle => return,
            LogOp::Listing {
                listing,
                attempts,
                quiet_answers,
                sent,
                ..
            } => {
                let waited = now.saturating_duration_since(*sent);
                if waited >= LIST_TIMEOUT {
                    let heard = self.link.silence().is_some_and(|s| s < waited);
                    if heard && listing.is_empty() {
                        *quiet_answers += 1;
                    }
                    if *quiet_answers >= LIST_QUIET_ANSWERS {
                        // Heard, but no entry: PX4 v1.16's way of saying "no log".
                        self.listing_done();
                        return;
                    }
                    if *attempts >= LIST_ATTEMPTS {
                        let attempts = *attempts;
                        self.fail_log_transfer(LinkError::Timeout {
                            command: "log list".into(),
                            attempts,
                        });
                        return;
                    }
                    *attempts += 1;
                    *sent = now;
                    self.request_log_list();
                }
            }
            LogOp::Downloading {
                download, share, ..
            } => {
                if download.stalled(now) {
                    let id = download.entry().id;
                    self.fail_log_transfer(LinkError::Timeout {
                        command: format!("log {id} download (no byte for 60 s)"),
                        attempts: 0,
                    });
                    return;
                }
                if let Some((ofs, count)) = download.gap_to_request(now) {
                    let count = share.window_bytes(LOG_TICK).map_or(count, |w| count.min(w));
                    download.requested(now, (ofs, count));
                    let id = download.entry().id;
                    self.request_log_data(id, ofs, count);
                }
            }
        }
        myself.send_after(LOG_TICK, move || Px4LinkMsg::LogTick(generation));
    }

    fn fail_log_transfer(&mut self, e: LinkError) {
        match std::mem::take(&mut self.logs) {
            LogOp::Idle => {}
            LogOp::Listing { then, .. } => then.fail(e),
            LogOp::Downloading { reply, .. } => drop(reply.send(Err(e))),
        }
    }
}
