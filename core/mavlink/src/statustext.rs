//! `STATUSTEXT` chunking as PX4 does it (`mavlink/streams/STATUSTEXT.hpp`): a text
//! longer than the message's 50 characters goes out as several messages sharing an `id`,
//! `chunk_seq` counting from 0; a full chunk has no NUL, the last one is padded with
//! NULs. The simulator sends this way; the link joins the chunks again
//! (`skein_link::statustext`).

use crate::dialect::{MavSeverity, STATUSTEXT_DATA};

/// Characters in one `STATUSTEXT.text`.
pub const CHUNK_CHARS: usize = 50;

/// `text` as PX4 sends it: one `STATUSTEXT` per 50 characters, `id` the text's own,
/// `chunk_seq` counting from 0 (a text of at most 50 bytes is one message).
pub fn chunks(severity: MavSeverity, text: &str, id: u16) -> Vec<STATUSTEXT_DATA> {
    let bytes = text.as_bytes();
    let mut out = Vec::new();
    for (seq, chunk) in bytes.chunks(CHUNK_CHARS).enumerate() {
        let mut field = [0u8; CHUNK_CHARS];
        field[..chunk.len()].copy_from_slice(chunk);
        out.push(STATUSTEXT_DATA {
            severity,
            text: field.into(),
            id,
            chunk_seq: seq as u8,
        });
    }
    out
}
