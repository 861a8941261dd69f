//! `STATUSTEXT` as PX4 sends it: a text longer than the message's 50 characters goes out
//! in chunks (MAVLink 2's `id` and `chunk_seq`), each full chunk without a NUL, the last
//! one padded with NULs (PX4's `mavlink/streams/STATUSTEXT.hpp`; every text gets an `id`
//! of its own, the first one 0). [`StatusTextAssembler`] joins the chunks back into the
//! text PX4 logged.
//!
//! A text of exactly 50 characters looks like a first chunk: it is complete when another
//! text starts or after [`CHUNK_TIMEOUT`] ([`StatusTextAssembler::flush`]). A chunk that
//! is missing (UDP loss) ends the text at the gap, marked with `…`.

use skein_mavlink::dialect::STATUSTEXT_DATA;
pub use skein_mavlink::statustext::{CHUNK_CHARS, chunks};
use std::time::{Duration, Instant};

/// How long a text waits for its next chunk. PX4 sends the chunks of a text back to
/// back in one stream update, so this is only the network's reordering.
pub const CHUNK_TIMEOUT: Duration = Duration::from_millis(100);

/// One text from the vehicle.
#[derive(Debug, Clone, PartialEq)]
pub struct StatusText {
    /// `MAV_SEVERITY` (0 emergency … 7 debug).
    pub severity: u8,
    /// The whole text.
    pub text: String,
}

/// A text still waiting for chunks.
#[derive(Debug)]
struct Partial {
    id: u16,
    next_seq: u8,
    text: StatusText,
    since: Instant,
}

/// Joins chunked `STATUSTEXT`s of one vehicle (see the module docs).
#[derive(Debug, Default)]
pub struct StatusTextAssembler {
    partial: Option<Partial>,
}

impl StatusTextAssembler {
    /// Takes one `STATUSTEXT` heard at `now`; returns the texts it completed, oldest
    /// first (none while a text waits for its next chunk; two when it ended one text
    /// and was a whole text itself).
    pub fn push(&mut self, m: &STATUSTEXT_DATA, now: Instant) -> Vec<StatusText> {
        let chunk = chunk_text(m);
        let last = chunk.chars().count() < CHUNK_CHARS;
        let mut done = Vec::new();
        if let Some(p) = self.partial.as_mut()
            && p.id == m.id
            && m.chunk_seq == p.next_seq
        {
            p.text.text.push_str(&chunk);
            p.next_seq = p.next_seq.wrapping_add(1);
            if last {
                done.extend(self.partial.take().map(|p| p.text));
            }
            return done;
        }
        if let Some(p) = self.partial.take() {
            done.push(p.text);
        }
        let mut text = StatusText {
            severity: m.severity as u8,
            text: chunk,
        };
        if m.chunk_seq != 0 {
            // Its first chunks were lost.
            text.text.insert(0, '…');
        }
        if last {
            done.push(text);
        } else {
            self.partial = Some(Partial {
                id: m.id,
                next_seq: m.chunk_seq.wrapping_add(1),
                text,
                since: now,
            });
        }
        done
    }

    /// The waiting text, when it waited [`CHUNK_TIMEOUT`] at `now` (a text of exactly 50
    /// characters, or one whose next chunk was lost: marked `…`).
    pub fn flush(&mut self, now: Instant) -> Option<StatusText> {
        let p = self.partial.as_ref()?;
        if now.saturating_duration_since(p.since) < CHUNK_TIMEOUT {
            return None;
        }
        self.partial.take().map(|p| p.text)
    }
}

/// The chunk's text up to its first NUL (invalid UTF-8 replaced).
fn chunk_text(m: &STATUSTEXT_DATA) -> String {
    let bytes = m.text.as_slice();
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    String::from_utf8_lossy(&bytes[..end]).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;
    use skein_mavlink::dialect::MavSeverity;

    const DENIED: &str = "Arming denied: Resolve system health failures first";

    #[test]
    fn a_text_longer_than_one_message_comes_back_whole() {
        let sent = chunks(MavSeverity::MAV_SEVERITY_CRITICAL, DENIED, 7);
        assert_eq!(sent.len(), 2, "{} characters", DENIED.len());
        let now = Instant::now();
        let mut a = StatusTextAssembler::default();
        assert_eq!(a.push(&sent[0], now), vec![]);
        let done = a.push(&sent[1], now);
        assert_eq!(
            done,
            vec![StatusText {
                severity: 2,
                text: DENIED.into()
            }]
        );
        assert_eq!(a.flush(now + CHUNK_TIMEOUT), None);
    }

    #[test]
    fn short_texts_are_whole_at_once_and_id_0_is_a_text_like_any_other() {
        let now = Instant::now();
        let mut a = StatusTextAssembler::default();
        for (id, t) in [(0, "Takeoff detected"), (1, "Landing detected")] {
            let m = &chunks(MavSeverity::MAV_SEVERITY_INFO, t, id)[0];
            assert_eq!(a.push(m, now)[0].text, t);
        }
    }

    #[test]
    fn a_text_of_exactly_50_characters_ends_with_the_next_text_or_the_timeout() {
        let fifty = "x".repeat(CHUNK_CHARS);
        let now = Instant::now();
        let mut a = StatusTextAssembler::default();
        let m = &chunks(MavSeverity::MAV_SEVERITY_INFO, &fifty, 3)[0];
        assert!(a.push(m, now).is_empty());
        assert_eq!(a.flush(now + CHUNK_TIMEOUT / 2), None);
        assert_eq!(a.flush(now + CHUNK_TIMEOUT).unwrap().text, fifty);
        // Or the next text ends it: both come out, in order.
        assert!(a.push(m, now).is_empty());
        let next = &chunks(MavSeverity::MAV_SEVERITY_INFO, "next", 4)[0];
        let done: Vec<String> = a.push(next, now).into_iter().map(|t| t.text).collect();
        assert_eq!(done, vec![fifty, "next".to_string()]);
    }

    #[test]
    fn a_lost_chunk_is_marked_where_it_was() {
        let long = format!("{}{}{}", "a".repeat(50), "b".repeat(50), "end");
        let sent = chunks(MavSeverity::MAV_SEVERITY_WARNING, &long, 9);
        assert_eq!(sent.len(), 3);
        let now = Instant::now();
        let mut a = StatusTextAssembler::default();
        // The first chunk is lost: the rest is one text marked at its start.
        assert!(a.push(&sent[1], now).is_empty());
        let done = a.push(&sent[2], now);
        assert_eq!(done[0].text, format!("…{}end", "b".repeat(50)));
        // The middle one is lost: the first ends at the gap, the last stands alone.
        assert!(a.push(&sent[0], now).is_empty());
        let done: Vec<String> = a.push(&sent[2], now).into_iter().map(|t| t.text).collect();
        assert_eq!(done, vec!["a".repeat(50), "…end".to_string()]);
    }
}
