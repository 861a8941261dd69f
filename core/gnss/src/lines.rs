//! Lines out of a byte stream (NMEA 0183 and gpsd's JSON are both one report a line,
//! `\n` or `\r\n` ended). A line longer than [`MAX_LINE`] is dropped whole and counted:
//! a stream that never ends a line (a receiver in a binary protocol, the wrong baud
//! rate) cannot grow the buffer without bound.

/// The longest line kept, bytes: an NMEA sentence is at most 82 characters; gpsd's
/// longest reports (`SKY` with every satellite in view) are a few kilobytes.
pub const MAX_LINE: usize = 16 * 1024;

/// Splits bytes into lines.
#[derive(Debug, Default)]
pub struct LineSplitter {
    buf: Vec<u8>,
    /// The line being read is past [`MAX_LINE`]: skip to its end.
    skipping: bool,
}

/// One piece of the stream: a whole line, or a line dropped for its length.
#[derive(Debug, PartialEq, Eq)]
pub enum Line<'a> {
    /// A line, without its `\r\n` or `\n`.
    Text(&'a [u8]),
    /// A line longer than [`MAX_LINE`], dropped.
    TooLong,
}

impl LineSplitter {
    /// Feeds `bytes`, calling `each` for every line they end (and once for every
    /// over-long line).
    pub fn push(&mut self, mut bytes: &[u8], mut each: impl FnMut(Line<'_>)) {
        while !bytes.is_empty() {
            let end = bytes.iter().position(|&b| b == b'\n');
            let (part, rest) = match end {
                Some(i) => (&bytes[..i], &bytes[i + 1..]),
                None => (bytes, &[][..]),
            };
            bytes = rest;
            if !self.skipping {
                self.buf.extend_from_slice(part);
                if self.buf.len() > MAX_LINE {
                    self.buf.clear();
                    self.skipping = true;
                    each(Line::TooLong);
                }
            }
            if end.is_some() {
                if !self.skipping {
                    let line = self.buf.strip_suffix(b"\r").unwrap_or(&self.buf);
                    each(Line::Text(line));
                }
                self.buf.clear();
                self.skipping = false;
            }
        }
    }

    /// Forgets a partial line (a new connection starts afresh).
    pub fn reset(&mut self) {
        self.buf.clear();
        self.skipping = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn split(s: &mut LineSplitter, bytes: &[u8]) -> Vec<String> {
        let mut out = Vec::new();
        s.push(bytes, |l| {
            out.push(match l {
                Line::Text(t) => String::from_utf8_lossy(t).into_owned(),
                Line::TooLong => "<too long>".into(),
            })
        });
        out
    }

    #[test]
    fn lines_split_across_reads_come_out_whole() {
        let mut s = LineSplitter::default();
        assert_eq!(split(&mut s, b"$GPGGA,1"), Vec::<String>::new());
        assert_eq!(
            split(&mut s, b"23\r\n$GPRMC\n\n{\"a\""),
            ["$GPGGA,123", "$GPRMC", ""]
        );
        assert_eq!(split(&mut s, b":1}\n"), ["{\"a\":1}"]);
    }

    #[test]
    fn an_endless_line_is_dropped_once_and_the_next_is_read() {
        let mut s = LineSplitter::default();
        let junk = vec![b'x'; MAX_LINE / 2 + 1];
        assert!(split(&mut s, &junk).is_empty());
        assert_eq!(split(&mut s, &junk), ["<too long>"]);
        assert!(split(&mut s, &junk).is_empty());
        assert_eq!(split(&mut s, b"tail\n$GPGGA\n"), ["$GPGGA"]);
    }
}
