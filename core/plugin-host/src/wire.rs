//! The process-isolation protocol between skein (the parent) and a `skein plugin-host`
//! child, over a Unix stream socket.
//!
//! # Framing
//! Every message is one frame: `u32` little-endian length `n` (≤ 64 MiB), then `n` bytes:
//! one tag byte and the body. Numbers in bodies are little-endian.
//!
//! # Session
//! 1. The parent binds a socket in its private directory, spawns
//!    `<program> <args…> --socket <path> --library <shadow copy>`, and accepts one
//!    connection.
//! 2. The child maps and validates the library exactly as the parent did, then sends
//!    `HELLO` (JSON `{"ok": true, "pid": 123, "name": "gimbal", "version": "0.1.0"}` or
//!    `{"ok": false, "error": "…"}`).
//! 3. The parent sends requests one at a time and reads until the matching `DONE_OK` /
//!    `DONE_ERR`, answering the child's host-service calls in between:
//!
//! | tag | direction | body |
//! |---|---|---|
//! | `CREATE` 0x01 | → child | JSON `{"kind", "config", "vehicle_id", "slot"}` |
//! | `TICK` 0x02 | → child | `f64` dt_s |
//! | `HANDLE` 0x03 | → child | command JSON |
//! | `MAVLINK` 0x04 | → child | `u8` compid, MAVLink 2 frame |
//! | `DESTROY` 0x05 | → child | empty; the child destroys the instance, answers, exits |
//! | `HOST_REPLY` 0x10 | → child | `u8` status, result bytes |
//! | `HELLO` 0x7F | → parent | JSON (above) |
//! | `DONE_OK` 0x80 | → parent | `f64` tick_rate_hz, result bytes (create: instance info JSON; handle: reply JSON) |
//! | `DONE_ERR` 0x81 | → parent | `f64` tick_rate_hz, `u8` status (1 error, 2 panic), UTF-8 message |
//! | `HOST_CALL` 0x90 | → parent | `u8` service, arguments; the parent answers `HOST_REPLY` |
//! | `HOST_NOTIFY` 0x91 | → parent | `u8` service, arguments; no answer (fire and forget) |
//!
//! Services (arguments): `VEHICLE` 2, `SWARM` 3, `SIMULATED` 4 (reply: one byte 0/1),
//! `SEND_MAVLINK` 5 (frame), `PAYLOAD_STATE` 6 (slot), `SET_SIMULATED_LINK` 7 (`f64` loss,
//! `f64` latency; reply: one byte) are calls; `EMIT_EVENT` 8 (`u32` kind length, kind, data
//! JSON), `PUBLISH_STATE` 9 (JSON), `PUBLISH_FRAME` 10 (JPEG), `LOG` 11 (`u32` level,
//! message) are notifications: their errors are logged by the parent, not returned to the
//! plugin; `SIM_AIRCRAFT` 12 (reply: JSON array) and `PAYLOAD_FRAME` 13 (slot; reply: JPEG,
//! empty when none) are calls too. The vehicle id is sent in `CREATE` and answered by the child itself.
//!
//! The parent gives every request a deadline (the call timeout); a child that misses it is
//! killed. A child whose socket closes (it died) makes the driver fail every later call.
//! A child whose parent dies exits (it watches its parent process id).

use std::io::{self, Read, Write};

/// Largest frame accepted, bytes.
pub const MAX_FRAME: usize = 64 << 20;

/// Frame tags.
pub mod tag {
    /// Create the instance.
    pub const CREATE: u8 = 0x01;
    /// Tick.
    pub const TICK: u8 = 0x02;
    /// Operator command.
    pub const HANDLE: u8 = 0x03;
    /// MAVLink message.
    pub const MAVLINK: u8 = 0x04;
    /// Destroy and exit.
    pub const DESTROY: u8 = 0x05;
    /// Answer to a host-service call.
    pub const HOST_REPLY: u8 = 0x10;
    /// The child's greeting.
    pub const HELLO: u8 = 0x7F;
    /// Request done.
    pub const DONE_OK: u8 = 0x80;
    /// Request failed.
    pub const DONE_ERR: u8 = 0x81;
    /// Host-service call (answered).
    pub const HOST_CALL: u8 = 0x90;
    /// Host-service notification (not answered).
    pub const HOST_NOTIFY: u8 = 0x91;
}

/// Host-service numbers.
pub mod service {
    /// Vehicle snapshot.
    pub const VEHICLE: u8 = 2;
    /// Swarm snapshots.
    pub const SWARM: u8 = 3;
    /// Simulated?
    pub const SIMULATED: u8 = 4;
    /// Send MAVLink.
    pub const SEND_MAVLINK: u8 = 5;
    /// Another slot's state.
    pub const PAYLOAD_STATE: u8 = 6;
    /// Degrade the simulated link.
    pub const SET_SIMULATED_LINK: u8 = 7;
    /// Event (notification).
    pub const EMIT_EVENT: u8 = 8;
    /// State (notification).
    pub const PUBLISH_STATE: u8 = 9;
    /// Video frame (notification).
    pub const PUBLISH_FRAME: u8 = 10;
    /// Log line (notification).
    pub const LOG: u8 = 11;
    /// Simulated non-cooperative aircraft.
    pub const SIM_AIRCRAFT: u8 = 12;
    /// Another slot's latest frame.
    pub const PAYLOAD_FRAME: u8 = 13;
}

/// Writes one frame made of `tag` and the concatenation of `parts`, in one `write_all`.
///
/// # Errors
/// I/O errors; a frame above [`MAX_FRAME`].
pub fn write_frame(w: &mut impl Write, tag: u8, parts: &[&[u8]]) -> io::Result<()> {
    let len = 1 + parts.iter().map(|p| p.len()).sum::<usize>();
    if len > MAX_FRAME {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("frame of {len} bytes exceeds {MAX_FRAME}"),
        ));
    }
    let mut buf = Vec::with_capacity(4 + len);
    buf.extend_from_slice(&(len as u32).to_le_bytes());
    buf.push(tag);
    for p in parts {
        buf.extend_from_slice(p);
    }
    w.write_all(&buf)
}

/// Reads one frame: `(tag, body)`.
///
/// # Errors
/// I/O errors (`UnexpectedEof` when the peer closed, `WouldBlock`/`TimedOut` on a read
/// timeout), an empty or oversized frame (`InvalidData`).
pub fn read_frame(r: &mut impl Read) -> io::Result<(u8, Vec<u8>)> {
    let mut len = [0u8; 4];
    r.read_exact(&mut len)?;
    let len = u32::from_le_bytes(len) as usize;
    if len == 0 || len > MAX_FRAME {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("bad frame length {len}"),
        ));
    }
    let mut tag = [0u8; 1];
    r.read_exact(&mut tag)?;
    let mut body = vec![0u8; len - 1];
    r.read_exact(&mut body)?;
    Ok((tag[0], body))
}

/// Splits a leading little-endian `f64` off `body`.
///
/// # Errors
/// A body shorter than 8 bytes.
pub fn take_f64(body: &[u8]) -> io::Result<(f64, &[u8])> {
    if body.len() < 8 {
        return Err(io::Error::new(io::ErrorKind::InvalidData, "truncated f64"));
    }
    let (head, rest) = body.split_at(8);
    let mut b = [0u8; 8];
    b.copy_from_slice(head);
    Ok((f64::from_le_bytes(b), rest))
}

/// Splits a leading little-endian `u32` off `body`.
///
/// # Errors
/// A body shorter than 4 bytes.
pub fn take_u32(body: &[u8]) -> io::Result<(u32, &[u8])> {
    if body.len() < 4 {
        return Err(io::Error::new(io::ErrorKind::InvalidData, "truncated u32"));
    }
    let (head, rest) = body.split_at(4);
    let mut b = [0u8; 4];
    b.copy_from_slice(head);
    Ok((u32::from_le_bytes(b), rest))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_round_trip_back_to_back() {
        let mut buf = Vec::new();
        write_frame(&mut buf, tag::HANDLE, &[b"{\"command\":", b"\"ping\"}"]).unwrap();
        write_frame(&mut buf, tag::TICK, &[&0.05f64.to_le_bytes()]).unwrap();
        let mut r = &buf[..];
        let (t, body) = read_frame(&mut r).unwrap();
        assert_eq!(
            (t, body.as_slice()),
            (tag::HANDLE, &b"{\"command\":\"ping\"}"[..])
        );
        let (t, body) = read_frame(&mut r).unwrap();
        assert_eq!(t, tag::TICK);
        assert_eq!(take_f64(&body).unwrap().0, 0.05);
        assert_eq!(
            read_frame(&mut r).unwrap_err().kind(),
            io::ErrorKind::UnexpectedEof
        );
    }

    #[test]
    fn bad_lengths_are_refused() {
        let mut r = &[0u8, 0, 0, 0][..];
        assert_eq!(
            read_frame(&mut r).unwrap_err().kind(),
            io::ErrorKind::InvalidData
        );
        let huge = ((MAX_FRAME + 1) as u32).to_le_bytes();
        let mut r = &huge[..];
        assert_eq!(
            read_frame(&mut r).unwrap_err().kind(),
            io::ErrorKind::InvalidData
        );
        assert!(take_f64(&[1, 2]).is_err());
        assert_eq!(take_u32(&[7, 0, 0, 0, 9]).unwrap(), (7, &[9u8][..]));
    }
}
