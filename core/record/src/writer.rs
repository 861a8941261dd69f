//! The MCAP file, owned by a thread of its own so that file I/O never runs on the
//! async runtime or in a vehicle's control loop: producers hand it [`Entry`]s through an
//! unbounded channel.

use crate::channels::{Kind, MESSAGE_ENCODING, SCHEMA_ENCODING};
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;
use std::sync::mpsc;

/// One message for the file.
#[derive(Debug)]
pub(crate) struct Entry {
    /// Channel topic.
    pub topic: String,
    /// What it carries (its schema).
    pub kind: Kind,
    /// When it was taken, ns since the Unix epoch.
    pub time_ns: u64,
    /// JSON message.
    pub data: Vec<u8>,
}

/// What the writer thread is told.
pub(crate) enum Command {
    Write(Entry),
    /// Finish the file and report.
    Finish(mpsc::Sender<Result<WriterSummary, String>>),
}

/// What was written.
#[derive(Debug, Clone, Default)]
pub(crate) struct WriterSummary {
    pub messages: u64,
    pub channels: usize,
    pub first_ns: Option<u64>,
    pub last_ns: Option<u64>,
    pub bytes: u64,
}

/// Creates `path` (refusing to overwrite an existing file) and starts the writer
/// thread.
pub(crate) fn spawn(path: &Path) -> std::io::Result<mpsc::Sender<Command>> {
    let file = File::options().write(true).create_new(true).open(path)?;
    let mut writer = mcap::WriteOptions::new()
        .compression(None)
        .profile("")
        .create(BufWriter::new(file))
        .map_err(std::io::Error::other)?;
    let (tx, rx) = mpsc::channel::<Command>();
    let path = path.to_path_buf();
    std::thread::Builder::new()
        .name("skein-record".into())
        .spawn(move || {
            let mut channels: HashMap<String, u16> = HashMap::new();
            let mut schemas: HashMap<Kind, u16> = HashMap::new();
            let mut summary = WriterSummary::default();
            let mut failed: Option<String> = None;
            let mut sequence = 0u32;
            for cmd in rx {
                match cmd {
                    Command::Write(e) => {
                        if failed.is_some() {
                            continue;
                        }
                        let r = write(&mut writer, &mut channels, &mut schemas, &e, sequence);
                        sequence = sequence.wrapping_add(1);
                        match r {
                            Ok(()) => {
                                summary.messages += 1;
                                summary.first_ns.get_or_insert(e.time_ns);
                                summary.last_ns = Some(e.time_ns);
                            }
                            Err(err) => {
                                tracing::error!("recording {}: {err}", path.display());
                                failed = Some(err.to_string());
                            }
                        }
                    }
                    Command::Finish(reply) => {
                        let result = match failed.take() {
                            Some(e) => Err(e),
                            None => writer.finish().map_err(|e| e.to_string()).map(|_| {
                                summary.channels = channels.len();
                                summary.bytes =
                                    std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
                                summary.clone()
                            }),
                        };
                        let _ = reply.send(result);
                        return;
                    }
                }
            }
            // Every sender dropped without Finish: close the file properly anyway.
            let _ = writer.finish();
        })?;
    Ok(tx)
}

fn write(
    writer: &mut mcap::Writer<BufWriter<File>>,
    channels: &mut HashMap<String, u16>,
    schemas: &mut HashMap<Kind, u16>,
    e: &Entry,
    sequence: u32,
) -> Result<(), mcap::McapError> {
    let channel_id = match channels.get(&e.topic) {
        Some(id) => *id,
        None => {
            let schema_id = match schemas.get(&e.kind) {
                Some(id) => *id,
                None => {
                    let data = serde_json::to_vec(&e.kind.schema()).unwrap_or_default();
                    let id = writer.add_schema(e.kind.schema_name(), SCHEMA_ENCODING, &data)?;
                    schemas.insert(e.kind, id);
                    id
                }
            };
            let id = writer.add_channel(schema_id, &e.topic, MESSAGE_ENCODING, &BTreeMap::new())?;
            channels.insert(e.topic.clone(), id);
            id
        }
    };
    writer.write_to_known_channel(
        &mcap::records::MessageHeader {
            channel_id,
            sequence,
            log_time: e.time_ns,
            publish_time: e.time_ns,
        },
        &e.data,
    )
}
