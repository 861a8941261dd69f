//! The NTRIP client's side of the protocol (RTCM 10410.1, NTRIP 2.0; NTRIP 1.0 as casters
//! still speak it): the request for a mountpoint, the caster's answer, NTRIP 2.0's chunked
//! transfer coding, and the NMEA `GGA` sentence a network RTK caster needs to compute
//! corrections for where the rovers are (a virtual reference station).
//!
//! A caster answers:
//! - `ICY 200 OK` (NTRIP 1.0): the data follows the status line at once, with no headers;
//! - `HTTP/1.1 200 OK` (NTRIP 2.0, or 1.0 casters behind HTTP servers): headers, a blank
//!   line, then the data, chunked when `Transfer-Encoding: chunked`;
//! - `SOURCETABLE 200 OK`, or a `200` with `Content-Type: gnss/sourcetable`: the mountpoint
//!   is unknown, and the caster lists those it has;
//! - `401`: wrong or missing credentials; anything else is refused with its status line.

use crate::source::{NtripSource, NtripVersion};
use base64::Engine;
use skein_model::geo::GeoPoint;
use std::time::{SystemTime, UNIX_EPOCH};

/// The largest answer head skein reads before giving up (a source table included).
pub const MAX_HEAD_BYTES: usize = 64 * 1024;

/// The request for `src`'s mountpoint (with `User-Agent: NTRIP ...`, which NTRIP 1.0
/// casters such as RTKLIB's require).
pub fn request(src: &NtripSource) -> String {
    let auth = src.user.as_ref().map(|u| {
        let pair = format!("{u}:{}", src.password.as_deref().unwrap_or(""));
        format!(
            "Authorization: Basic {}\r\n",
            base64::engine::general_purpose::STANDARD.encode(pair)
        )
    });
    let auth = auth.unwrap_or_default();
    let agent = concat!(
        "User-Agent: NTRIP skein/",
        env!("CARGO_PKG_VERSION"),
        "\r\n"
    );
    match src.version {
        NtripVersion::V2 => format!(
            "GET /{} HTTP/1.1\r\nHost: {}:{}\r\nNtrip-Version: Ntrip/2.0\r\n{agent}{auth}Connection: close\r\n\r\n",
            src.mountpoint, src.host, src.port
        ),
        NtripVersion::V1 => format!("GET /{} HTTP/1.0\r\n{agent}{auth}\r\n", src.mountpoint),
    }
}

/// How the corrections arrive after a good answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Framing {
    /// Raw bytes until the connection closes.
    Raw,
    /// HTTP/1.1 chunked transfer coding ([`Dechunker`]).
    Chunked,
}

/// The caster's answer, once its head is complete.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Answer {
    /// Corrections follow: `body_start` bytes of the buffer were the head.
    Streaming {
        /// How the data is framed.
        framing: Framing,
        /// Where the data starts in the buffer given.
        body_start: usize,
    },
    /// The head is not complete yet: read more.
    Incomplete,
}

/// Reads the caster's answer from the first bytes received (`buf`).
///
/// # Errors
/// A refusal, in words an operator acts on: unknown mountpoint (with the mountpoints the
/// caster lists), bad credentials, a web page or another status, or an answer head over
/// [`MAX_HEAD_BYTES`].
pub fn answer(buf: &[u8], mountpoint: &str) -> Result<Answer, String> {
    let Some(line_end) = find(buf, b"\r\n") else {
        return incomplete(buf);
    };
    let status = String::from_utf8_lossy(&buf[..line_end]).to_string();
    if status.starts_with("ICY 200") {
        return Ok(Answer::Streaming {
            framing: Framing::Raw,
            body_start: line_end + 2,
        });
    }
    if status.starts_with("SOURCETABLE") {
        return table_or_wait(buf, mountpoint);
    }
    if !status.starts_with("HTTP/1.") {
        return Err(format!(
            "the caster answered `{}`, not NTRIP",
            printable(&status)
        ));
    }
    let Some(head_end) = find(buf, b"\r\n\r\n") else {
        return incomplete(buf);
    };
    let head = String::from_utf8_lossy(&buf[..head_end]).to_ascii_lowercase();
    let code = status.split_whitespace().nth(1).unwrap_or("");
    let content_type = header(&head, "content-type").unwrap_or_default();
    match code {
        "200" if content_type.contains("sourcetable") => table_or_wait(buf, mountpoint),
        "200" if content_type.starts_with("text/html") => Err(format!(
            "the caster sent a web page (text/html), not corrections: is /{mountpoint} a mountpoint?"
        )),
        "200" => Ok(Answer::Streaming {
            framing: if header(&head, "transfer-encoding").is_some_and(|t| t.contains("chunked")) {
                Framing::Chunked
            } else {
                Framing::Raw
            },
            body_start: head_end + 4,
        }),
        "401" => Err("the caster refused the credentials (401 Unauthorized)".into()),
        "404" => Err(format!("the caster has no mountpoint /{mountpoint} (404)")),
        _ => Err(format!("the caster answered `{}`", printable(&status))),
    }
}

fn incomplete(buf: &[u8]) -> Result<Answer, String> {
    if buf.len() > MAX_HEAD_BYTES {
        Err(format!(
            "the caster's answer has no end of head in {MAX_HEAD_BYTES} bytes"
        ))
    } else {
        Ok(Answer::Incomplete)
    }
}

/// A source table: the mountpoint is not streaming. Waits for `ENDSOURCETABLE` (or the
/// connection's end) to list the mountpoints the caster has.
fn table_or_wait(buf: &[u8], mountpoint: &str) -> Result<Answer, String> {
    if find(buf, b"ENDSOURCETABLE").is_none() && buf.len() <= MAX_HEAD_BYTES {
        return Ok(Answer::Incomplete);
    }
    Err(unknown_mountpoint(buf, mountpoint))
}

/// The refusal for an unknown mountpoint, naming those `table` lists (`STR;NAME;...`).
pub fn unknown_mountpoint(table: &[u8], mountpoint: &str) -> String {
    let text = String::from_utf8_lossy(table);
    let names: Vec<&str> = text
        .lines()
        .filter_map(|l| l.strip_prefix("STR;"))
        .filter_map(|l| l.split(';').next())
        .collect();
    format!(
        "the caster has no mountpoint /{mountpoint}; it lists: {}",
        if names.is_empty() {
            "none".to_string()
        } else {
            names.join(", ")
        }
    )
}

fn header(head: &str, name: &str) -> Option<String> {
    head.lines().find_map(|l| {
        let (k, v) = l.split_once(':')?;
        (k.trim() == name).then(|| v.trim().to_string())
    })
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

fn printable(s: &str) -> String {
    s.chars()
        .take(80)
        .map(|c| {
            if c.is_ascii_graphic() || c == ' ' {
                c
            } else {
                '?'
            }
        })
        .collect()
}

/// Decodes HTTP/1.1's chunked transfer coding as bytes arrive (NTRIP 2.0's data).
#[derive(Debug, Default)]
pub struct Dechunker {
    /// Bytes left in the current chunk, then its CRLF.
    remaining: usize,
    /// A chunk-size line being read.
    line: Vec<u8>,
    /// Expecting the CRLF after a chunk's data.
    after_data: u8,
    done: bool,
}

impl Dechunker {
    /// Appends the data carried in `input` to `out`.
    ///
    /// # Errors
    /// A chunk-size line that is not hexadecimal (a broken stream: reconnect).
    pub fn feed(&mut self, mut input: &[u8], out: &mut Vec<u8>) -> Result<(), String> {
        while !input.is_empty() && !self.done {
            if self.remaining > 0 {
                let n = self.remaining.min(input.len());
                out.extend_from_slice(&input[..n]);
                self.remaining -= n;
                input = &input[n..];
                if self.remaining == 0 {
                    self.after_data = 2;
                }
            } else if self.after_data > 0 {
                input = &input[1..];
                self.after_data -= 1;
            } else {
                let b = input[0];
                input = &input[1..];
                if b != b'\n' {
                    self.line.push(b);
                    if self.line.len() > 64 {
                        return Err("a chunk-size line over 64 bytes".into());
                    }
                    continue;
                }
                let line = String::from_utf8_lossy(&self.line).trim().to_string();
                self.line.clear();
                let size = line.split(';').next().unwrap_or("");
                let size = usize::from_str_radix(size, 16).map_err(|_| {
                    format!("a chunk size `{}` is not hexadecimal", printable(size))
                })?;
                self.remaining = size;
                self.done = size == 0;
            }
        }
        Ok(())
    }

    /// The last chunk (size 0) arrived: the caster ended the stream.
    pub fn is_done(&self) -> bool {
        self.done
    }
}

/// NMEA 0183 `$GPGGA` for `p` at `when` (fix quality 1, 12 satellites, HDOP 1.0: a
/// position a network RTK caster uses to place its virtual reference station), with its
/// checksum and CRLF.
pub fn gga(p: &GeoPoint, when: SystemTime) -> String {
    let secs = when.duration_since(UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let (h, m, s) = ((secs / 3600) % 24, (secs / 60) % 60, secs % 60);
    let (lat, ns) = nmea_angle(p.lat_deg, 2, 'N', 'S');
    let (lon, ew) = nmea_angle(p.lon_deg, 3, 'E', 'W');
    let body = format!(
        "GPGGA,{h:02}{m:02}{s:02}.00,{lat},{ns},{lon},{ew},1,12,1.0,{:.1},M,0.0,M,,",
        p.alt_amsl_m
    );
    let sum = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{sum:02X}\r\n")
}

/// Degrees as NMEA's `(d)ddmm.mmmmm` with `width` degree digits, and its hemisphere.
fn nmea_angle(deg: f64, width: usize, pos: char, neg: char) -> (String, char) {
    let a = deg.abs();
    let mut d = a.floor();
    let mut minutes = ((a - d) * 60.0 * 1e5).round() / 1e5;
    if minutes >= 60.0 {
        d += 1.0;
        minutes -= 60.0;
    }
    (
        format!("{:0width$}{minutes:08.5}", d as u32),
        if deg < 0.0 { neg } else { pos },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn src(version: NtripVersion) -> NtripSource {
        NtripSource {
            host: "caster".into(),
            port: 2101,
            mountpoint: "MNT".into(),
            user: Some("u".into()),
            password: Some("p".into()),
            version,
        }
    }

    #[test]
    fn requests_carry_the_agent_and_basic_authentication() {
        let v2 = request(&src(NtripVersion::V2));
        assert!(v2.starts_with("GET /MNT HTTP/1.1\r\n"), "{v2}");
        assert!(v2.contains("Ntrip-Version: Ntrip/2.0\r\n"));
        assert!(v2.contains("User-Agent: NTRIP skein/"));
        assert!(v2.contains("Authorization: Basic dTpw\r\n"));
        assert!(v2.ends_with("\r\n\r\n"));
        let v1 = request(&src(NtripVersion::V1));
        assert!(v1.starts_with("GET /MNT HTTP/1.0\r\n") && !v1.contains("Ntrip-Version"));
    }

    #[test]
    fn answers_of_both_versions_start_the_stream() {
        let icy = b"ICY 200 OK\r\n\xd3\x00\x13";
        assert_eq!(
            answer(icy, "MNT"),
            Ok(Answer::Streaming {
                framing: Framing::Raw,
                body_start: 12
            })
        );
        let v2 = b"HTTP/1.1 200 OK\r\nNtrip-Version: Ntrip/2.0\r\nContent-Type: gnss/data\r\nTransfer-Encoding: chunked\r\n\r\n13\r\n";
        assert!(matches!(
            answer(v2, "MNT"),
            Ok(Answer::Streaming {
                framing: Framing::Chunked,
                ..
            })
        ));
        assert_eq!(
            answer(b"HTTP/1.1 200 OK\r\nCont", "MNT"),
            Ok(Answer::Incomplete)
        );
        assert_eq!(answer(b"ICY 20", "MNT"), Ok(Answer::Incomplete));
    }

    #[test]
    fn refusals_say_what_to_fix() {
        let table = b"SOURCETABLE 200 OK\r\nContent-Length: 40\r\n\r\nSTR;BASE1;x\r\nSTR;BASE2;y\r\nENDSOURCETABLE\r\n";
        let e = answer(table, "MNT").unwrap_err();
        assert!(
            e.contains("no mountpoint /MNT") && e.contains("BASE1, BASE2"),
            "{e}"
        );
        let e = answer(b"HTTP/1.0 401 Unauthorized\r\n\r\n", "MNT").unwrap_err();
        assert!(e.contains("credentials"), "{e}");
        let html = b"HTTP/1.1 200 OK\r\nContent-Type: text/html\r\n\r\n<html>";
        assert!(answer(html, "MNT").unwrap_err().contains("web page"));
        let e = answer(b"SSH-2.0-OpenSSH_9.2\r\n", "MNT").unwrap_err();
        assert!(e.contains("not NTRIP"), "{e}");
        let endless = vec![b'x'; MAX_HEAD_BYTES + 1];
        assert!(answer(&endless, "MNT").is_err());
    }

    #[test]
    fn chunks_are_joined_whatever_the_reads() {
        let wire = b"5\r\nhello\r\n7;ext=1\r\n, world\r\n0\r\n\r\n";
        for split in 1..wire.len() {
            let mut d = Dechunker::default();
            let mut out = Vec::new();
            d.feed(&wire[..split], &mut out).unwrap();
            d.feed(&wire[split..], &mut out).unwrap();
            assert_eq!(out, b"hello, world", "split at {split}");
            assert!(d.is_done());
        }
        let mut d = Dechunker::default();
        assert!(d.feed(b"zz\r\n", &mut Vec::new()).is_err());
    }

    #[test]
    fn gga_is_valid_nmea() {
        let p = GeoPoint::new(47.397_742, -8.545_594, 488.0);
        let t = UNIX_EPOCH + std::time::Duration::from_secs(12 * 3600 + 34 * 60 + 56);
        let s = gga(&p, t);
        assert_eq!(
            s,
            "$GPGGA,123456.00,4723.86452,N,00832.73564,W,1,12,1.0,488.0,M,0.0,M,,*4A\r\n"
        );
        let body = &s[1..s.find('*').unwrap()];
        let sum = body.bytes().fold(0u8, |a, b| a ^ b);
        assert_eq!(
            format!("{sum:02X}"),
            &s[s.find('*').unwrap() + 1..s.len() - 2]
        );
    }
}
