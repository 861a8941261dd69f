//! The `Px4Link` actor's component metadata (MAVLink's Component Metadata Protocol, as
//! QGroundControl's `ComponentInformationManager` uses it): at first contact it asks
//! for `COMPONENT_METADATA` (`MAV_CMD_REQUEST_MESSAGE` 397), reads the general metadata
//! it names (`mftp://` through [`crate::ftp_client`]), then the events metadata the
//! general metadata lists (type 4), decompresses them (`.xz`, lzma-rs), checks their
//! CRCs (MAVLink's CRC32 of the JSON) and parses the events'.
//!
//! Each file is cached by its CRC in the link's cache directory
//! ([`crate::LinkSetup::metadata_cache_dir`]: `component_general-<crc>.json`,
//! `all_events-<crc>.json`, decompressed): a vehicle whose firmware's metadata is there,
//! after a restart too, reads nothing over the link. A vehicle that does not answer
//! (no `COMPONENT_METADATA`: an older PX4, another autopilot) has no events metadata,
//! and its `STATUSTEXT`s are all there is.

use super::{Px4LinkMsg, Px4LinkState};
use crate::command::LinkCommand;
use crate::events::{EventsMetadata, MetadataInfo};
use crate::ftp_client::{FtpError, FtpRead};
use ractor::ActorRef;
use skein_mavlink::dialect::COMPONENT_METADATA_DATA;
use skein_mavlink::ftp::{FtpPayload, crc32};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// How often a running read checks its resends.
pub const META_TICK: Duration = Duration::from_millis(100);
/// `COMPONENT_METADATA`'s message id.
pub const COMPONENT_METADATA_ID: u32 = 397;
/// `COMP_METADATA_TYPE_EVENTS`.
const TYPE_EVENTS: u64 = 4;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stage {
    General,
    Events,
}

/// A read of one metadata file in progress.
pub(super) struct Reading {
    stage: Stage,
    crc: u32,
    path: String,
    /// The component serving it (the URI's `[;comp=N]`, else the autopilot).
    component: u8,
    read: FtpRead,
}

/// The metadata's fetch (see the module docs).
#[derive(Default)]
pub(super) struct MetadataFetch {
    reading: Option<Reading>,
    started: Option<Instant>,
    general_crc: u32,
    ftp_bytes: usize,
    ftp_requests: u32,
    generation: u64,
}

/// The FTP path of an `mftp://[;comp=N]path` URI, and the component to ask.
fn mftp_path(uri: &str, autopilot: u8) -> Option<(String, u8)> {
    let rest = uri.strip_prefix("mftp://")?;
    let (comp, path) = match rest.strip_prefix("[;comp=") {
        Some(r) => {
            let (n, p) = r.split_once(']')?;
            (n.parse().ok()?, p)
        }
        None => (autopilot, rest),
    };
    Some((path.trim_start_matches('/').to_string(), comp))
}

fn cache_file(dir: &Option<PathBuf>, stem: &str, crc: u32) -> Option<PathBuf> {
    dir.as_ref()
        .map(|d| d.join(format!("{stem}-{crc:08x}.json")))
}

/// The cached file of `stem` with CRC `crc`, when it is there and whole (its CRC
/// checked: a file another process is writing, or a damaged one, is read again).
fn read_cache(dir: &Option<PathBuf>, stem: &str, crc: u32) -> Option<Vec<u8>> {
    let json = std::fs::read(cache_file(dir, stem, crc)?).ok()?;
    (crc32(&json) == crc).then_some(json)
}

/// Writes `json` into the cache as `stem` with CRC `crc`, through a file of this
/// process renamed (skein processes sharing the directory never see half a file).
fn write_cache(dir: &Option<PathBuf>, stem: &str, crc: u32, json: &[u8]) -> std::io::Result<()> {
    let Some(f) = cache_file(dir, stem, crc) else {
        return Ok(());
    };
    if let Some(d) = f.parent() {
        std::fs::create_dir_all(d)?;
    }
    let part = f.with_extension(format!("part-{}", std::process::id()));
    std::fs::write(&part, json)?;
    std::fs::rename(&part, &f)
}

impl Px4LinkState {
    /// At first contact: asks for `COMPONENT_METADATA`, unless the events metadata is
    /// loaded already.
    pub(super) fn request_component_metadata(&mut self, myself: &ActorRef<Px4LinkMsg>) {
        if self.px4_events.has_metadata() || self.metadata.reading.is_some() {
            return;
        }
        let cmd = LinkCommand::RequestMessage {
            message_id: COMPONENT_METADATA_ID,
        };
        self.start(myself, cmd, None);
    }

    /// `COMPONENT_METADATA`: the general metadata from the cache, or read.
    pub(super) fn on_component_metadata(
        &mut self,
        myself: &ActorRef<Px4LinkMsg>,
        m: &COMPONENT_METADATA_DATA,
    ) {
        if self.px4_events.has_metadata() || self.metadata.reading.is_some() {
            return;
        }
        let uri = m.uri.to_str().unwrap_or_default().to_string();
        self.metadata.started = Some(Instant::now());
        self.metadata.general_crc = m.file_crc;
        self.metadata.ftp_bytes = 0;
        self.metadata.ftp_requests = 0;
        let cached = cache_file(
            &self.link.setup.metadata_cache_dir,
            "component_general",
            m.file_crc,
        )
        .and_then(|f| std::fs::read(f).ok());
        match cached {
            Some(json) => self.general_loaded(myself, &json, true),
            None => self.read_file(myself, Stage::General, &uri, m.file_crc),
        }
    }

    fn read_file(&mut self, myself: &ActorRef<Px4LinkMsg>, stage: Stage, uri: &str, crc: u32) {
        let Some((path, component)) = mftp_path(uri, self.link.compid) else {
            self.metadata_failed(format!("{uri:?}: only mftp:// URIs are read"));
            return;
        };
        let read = FtpRead::new(&path, Instant::now());
        self.metadata.reading = Some(Reading {
            stage,
            crc,
            path,
            component,
            read,
        });
        self.metadata.generation += 1;
        self.flush_ftp();
        let generation = self.metadata.generation;
        myself.send_after(META_TICK, move || Px4LinkMsg::MetaTick(generation));
    }

    fn flush_ftp(&mut self) {
        let Some(r) = self.metadata.reading.as_mut() else {
            return;
        };
        let (sys, comp) = (self.link.sysid, r.component);
        for p in r.read.take_outgoing() {
            let _ = self.link.endpoint.send(sys, &p.to_message(sys, comp));
        }
    }

    /// A `FILE_TRANSFER_PROTOCOL` payload from the autopilot.
    pub(super) fn on_ftp_reply(&mut self, myself: &ActorRef<Px4LinkMsg>, p: &FtpPayload) {
        let Some(r) = self.metadata.reading.as_mut() else {
            return;
        };
        if let Some(done) = r.read.on_reply(p, Instant::now()) {
            self.read_done(myself, done);
        } else {
            self.flush_ftp();
        }
    }

    /// A [`META_TICK`] of read `generation`.
    pub(super) fn on_meta_tick(&mut self, myself: &ActorRef<Px4LinkMsg>, generation: u64) {
        if generation != self.metadata.generation {
            return;
        }
        let Some(r) = self.metadata.reading.as_mut() else {
            return;
        };
        match r.read.on_tick(Instant::now()) {
            Some(done) => self.read_done(myself, done),
            None => {
                self.flush_ftp();
                myself.send_after(META_TICK, move || Px4LinkMsg::MetaTick(generation));
            }
        }
    }

    fn read_done(&mut self, myself: &ActorRef<Px4LinkMsg>, done: Result<Vec<u8>, FtpError>) {
        self.flush_ftp(); // the TerminateSession
        let Some(r) = self.metadata.reading.take() else {
            return;
        };
        let stats = r.read.stats();
        self.metadata.ftp_requests += stats.requests + stats.retries;
        let bytes = match done {
            Ok(b) => b,
            Err(e) => return self.metadata_failed(e.to_string()),
        };
        self.metadata.ftp_bytes += bytes.len();
        let json = if r.path.ends_with(".xz") {
            let mut out = Vec::new();
            if let Err(e) = lzma_rs::xz_decompress(&mut std::io::Cursor::new(&bytes), &mut out) {
                return self.metadata_failed(format!("{}: not xz ({e})", r.path));
            }
            out
        } else {
            bytes
        };
        let stem = match r.stage {
            Stage::General => "component_general",
            Stage::Events => "all_events",
        };
        if crc32(&json) == r.crc {
            let dir = &self.link.setup.metadata_cache_dir;
            if let Err(e) = write_cache(dir, stem, r.crc, &json) {
                tracing::warn!(sysid = self.link.sysid, "metadata cache {stem}: {e}");
            }
        } else {
            tracing::warn!(
                sysid = self.link.sysid,
                "{}: CRC {:08x}, the vehicle said {:08x}: not cached",
                r.path,
                crc32(&json),
                r.crc
            );
        }
        match r.stage {
            Stage::General => self.general_loaded(myself, &json, false),
            Stage::Events => self.events_loaded(&json, false),
        }
    }

    fn general_loaded(&mut self, myself: &ActorRef<Px4LinkMsg>, json: &[u8], _cached: bool) {
        let general: serde_json::Value = match serde_json::from_slice(json) {
            Ok(v) => v,
            Err(e) => return self.metadata_failed(format!("general metadata: {e}")),
        };
        let events = general["metadataTypes"]
            .as_array()
            .into_iter()
            .flatten()
            .find(|t| t["type"].as_u64() == Some(TYPE_EVENTS));
        let Some(t) = events else {
            return self.metadata_failed("the vehicle's metadata lists no events metadata".into());
        };
        let uri = t["uri"].as_str().unwrap_or_default().to_string();
        let crc = t["fileCrc"].as_u64().unwrap_or(0) as u32;
        let cached = read_cache(&self.link.setup.metadata_cache_dir, "all_events", crc);
        match cached {
            Some(json) => self.events_loaded(&json, true),
            None => self.read_file(myself, Stage::Events, &uri, crc),
        }
    }

    fn events_loaded(&mut self, json: &[u8], cached: bool) {
        let meta = match EventsMetadata::parse(json) {
            Ok(m) => m,
            Err(e) => return self.metadata_failed(e),
        };
        let fetch_ms = self
            .metadata
            .started
            .map_or(0, |t| t.elapsed().as_millis() as u64);
        let downloaded = !cached || self.metadata.ftp_bytes > 0;
        let info = MetadataInfo {
            general_crc: self.metadata.general_crc,
            events_crc: crc32(json),
            source: if downloaded { "vehicle" } else { "cache" },
            ftp_bytes: self.metadata.ftp_bytes,
            ftp_requests: self.metadata.ftp_requests,
            fetch_ms,
            events: meta.events.len(),
        };
        tracing::info!(sysid = self.link.sysid, ?info, "PX4 events metadata loaded");
        self.link.with_telemetry_mut(|t| {
            t.px4_events.metadata = Some(info);
            t.px4_events.metadata_error = None;
        });
        self.set_events_metadata(Arc::new(meta));
    }

    fn metadata_failed(&mut self, why: String) {
        tracing::warn!(sysid = self.link.sysid, "PX4 events metadata: {why}");
        self.metadata.reading = None;
        self.link
            .with_telemetry_mut(|t| t.px4_events.metadata_error = Some(why));
    }
}
