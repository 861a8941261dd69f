//! MAVLink FTP's payload (`FILE_TRANSFER_PROTOCOL.payload[251]`), shared by the
//! simulator's server and the link's client.
//!
//! Verified against the MAVLink FTP service description and PX4's `MavlinkFTP`
//! (`src/modules/mavlink/mavlink_ftp.{h,cpp}`): a 12-byte little-endian header
//! (`seq_number` u16, `session` u8, `opcode` u8, `size` u8, `req_opcode` u8,
//! `burst_complete` u8, padding u8, `offset` u32) and up to [`MAX_DATA`] bytes of data.
//! A reply carries the request's `seq_number + 1`, `opcode` [`Opcode::Ack`] or
//! [`Opcode::Nak`], the request's opcode in `req_opcode`; a NAK's data is the
//! [`NakError`] (and errno for [`NakError::FailErrno`]).

use crate::dialect::FILE_TRANSFER_PROTOCOL_DATA;

/// Bytes of `FILE_TRANSFER_PROTOCOL.payload`.
pub const PAYLOAD_LEN: usize = 251;
/// Bytes of the header before the data.
pub const HEADER_LEN: usize = 12;
/// Data bytes one message carries (PX4's `kMaxDataLength`): 239.
pub const MAX_DATA: usize = PAYLOAD_LEN - HEADER_LEN;

/// FTP opcodes (`MAV_FTP_OPCODE`), the ones skein uses and their replies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Opcode {
    /// 0: nothing, always ACKed.
    None,
    /// 1: close the session in `session`.
    TerminateSession,
    /// 2: close every session.
    ResetSessions,
    /// 3: list a directory.
    ListDirectory,
    /// 4: open the file named in the data for reading; the ACK's data is its size (u32).
    OpenFileRO,
    /// 5: read up to 239 bytes from `offset` of the session.
    ReadFile,
    /// 15: stream the session's file from `offset` to its end (ACKs with data, a NAK
    /// [`NakError::Eof`] at the end; `burst_complete` on the last of a 35 kB chunk).
    BurstReadFile,
    /// 14: the file's CRC32.
    CalcFileCrc32,
    /// 128: positive reply.
    Ack,
    /// 129: negative reply, with a [`NakError`].
    Nak,
    /// Any other opcode (create, write, remove …), kept as its number.
    Other(u8),
}

impl Opcode {
    /// The wire value.
    pub fn to_u8(self) -> u8 {
        match self {
            Opcode::None => 0,
            Opcode::TerminateSession => 1,
            Opcode::ResetSessions => 2,
            Opcode::ListDirectory => 3,
            Opcode::OpenFileRO => 4,
            Opcode::ReadFile => 5,
            Opcode::CalcFileCrc32 => 14,
            Opcode::BurstReadFile => 15,
            Opcode::Ack => 128,
            Opcode::Nak => 129,
            Opcode::Other(v) => v,
        }
    }

    /// From the wire value.
    pub fn from_u8(v: u8) -> Opcode {
        match v {
            0 => Opcode::None,
            1 => Opcode::TerminateSession,
            2 => Opcode::ResetSessions,
            3 => Opcode::ListDirectory,
            4 => Opcode::OpenFileRO,
            5 => Opcode::ReadFile,
            14 => Opcode::CalcFileCrc32,
            15 => Opcode::BurstReadFile,
            128 => Opcode::Ack,
            129 => Opcode::Nak,
            v => Opcode::Other(v),
        }
    }
}

/// NAK error codes (`MAV_FTP_ERR`, PX4's `ErrorCode`), `data[0]` of a NAK.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NakError {
    /// 1: unknown failure.
    Fail,
    /// 2: a system call failed; `data[1]` holds errno.
    FailErrno,
    /// 3: `size` out of range.
    InvalidDataSize,
    /// 4: no such open session.
    InvalidSession,
    /// 5: every session is in use (PX4 has one).
    NoSessionsAvailable,
    /// 6: offset past the end of the file.
    Eof,
    /// 7: opcode not handled.
    UnknownCommand,
    /// 8: file exists.
    FileExists,
    /// 9: file protected.
    FileProtected,
    /// 10: no such file.
    FileNotFound,
    /// Any other code.
    Other(u8),
}

impl NakError {
    /// The wire value.
    pub fn to_u8(self) -> u8 {
        match self {
            NakError::Fail => 1,
            NakError::FailErrno => 2,
            NakError::InvalidDataSize => 3,
            NakError::InvalidSession => 4,
            NakError::NoSessionsAvailable => 5,
            NakError::Eof => 6,
            NakError::UnknownCommand => 7,
            NakError::FileExists => 8,
            NakError::FileProtected => 9,
            NakError::FileNotFound => 10,
            NakError::Other(v) => v,
        }
    }

    /// From the wire value.
    pub fn from_u8(v: u8) -> NakError {
        match v {
            1 => NakError::Fail,
            2 => NakError::FailErrno,
            3 => NakError::InvalidDataSize,
            4 => NakError::InvalidSession,
            5 => NakError::NoSessionsAvailable,
            6 => NakError::Eof,
            7 => NakError::UnknownCommand,
            8 => NakError::FileExists,
            9 => NakError::FileProtected,
            10 => NakError::FileNotFound,
            v => NakError::Other(v),
        }
    }
}

/// One FTP message's payload, decoded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FtpPayload {
    /// Sequence number: a request's own, a reply's is the request's + 1.
    pub seq: u16,
    /// Session id.
    pub session: u8,
    /// Operation, or [`Opcode::Ack`] / [`Opcode::Nak`] in a reply.
    pub opcode: Opcode,
    /// The request's opcode, in a reply.
    pub req_opcode: Opcode,
    /// Last message of a burst.
    pub burst_complete: bool,
    /// File offset, bytes.
    pub offset: u32,
    /// Data (`size` bytes, at most [`MAX_DATA`]).
    pub data: Vec<u8>,
}

impl FtpPayload {
    /// A request of `opcode` with `data` (a path, or nothing).
    pub fn request(seq: u16, session: u8, opcode: Opcode, offset: u32, data: &[u8]) -> Self {
        FtpPayload {
            seq,
            session,
            opcode,
            req_opcode: Opcode::None,
            burst_complete: false,
            offset,
            data: data[..data.len().min(MAX_DATA)].to_vec(),
        }
    }

    /// The NAK's error, for a NAK with one.
    pub fn nak_error(&self) -> Option<NakError> {
        (self.opcode == Opcode::Nak)
            .then(|| self.data.first().map(|&e| NakError::from_u8(e)))
            .flatten()
    }

    /// The 251 bytes of `FILE_TRANSFER_PROTOCOL.payload`.
    pub fn encode(&self) -> [u8; PAYLOAD_LEN] {
        let mut p = [0u8; PAYLOAD_LEN];
        let size = self.data.len().min(MAX_DATA);
        p[0..2].copy_from_slice(&self.seq.to_le_bytes());
        p[2] = self.session;
        p[3] = self.opcode.to_u8();
        p[4] = size as u8;
        p[5] = self.req_opcode.to_u8();
        p[6] = u8::from(self.burst_complete);
        p[8..12].copy_from_slice(&self.offset.to_le_bytes());
        p[HEADER_LEN..HEADER_LEN + size].copy_from_slice(&self.data[..size]);
        p
    }

    /// Decodes a payload; `Err` names what is wrong (a `size` past [`MAX_DATA`]).
    pub fn decode(p: &[u8; PAYLOAD_LEN]) -> Result<Self, String> {
        let size = usize::from(p[4]);
        if size > MAX_DATA {
            return Err(format!("FTP size {size} > {MAX_DATA}"));
        }
        Ok(FtpPayload {
            seq: u16::from_le_bytes([p[0], p[1]]),
            session: p[2],
            opcode: Opcode::from_u8(p[3]),
            req_opcode: Opcode::from_u8(p[5]),
            burst_complete: p[6] != 0,
            offset: u32::from_le_bytes([p[8], p[9], p[10], p[11]]),
            data: p[HEADER_LEN..HEADER_LEN + size].to_vec(),
        })
    }

    /// This payload as a `FILE_TRANSFER_PROTOCOL` to `(target_system, target_component)`.
    pub fn to_message(&self, target_system: u8, target_component: u8) -> crate::MavMessage {
        crate::MavMessage::FILE_TRANSFER_PROTOCOL(FILE_TRANSFER_PROTOCOL_DATA {
            target_network: 0,
            target_system,
            target_component,
            payload: self.encode(),
        })
    }
}

/// MAVLink's CRC32 as PX4 computes a component metadata file's `fileCrc` and
/// `COMPONENT_METADATA.file_crc` (`component_information/generate_crc.py`, PX4's
/// `crc32part`): the reflected polynomial 0xEDB88320, started at 0, no final inversion.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = 0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    crc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_payload_survives_encoding_and_names_an_oversized_one() {
        let p = FtpPayload {
            seq: 513,
            session: 0,
            opcode: Opcode::Ack,
            req_opcode: Opcode::BurstReadFile,
            burst_complete: true,
            offset: 70_000,
            data: (0..239).map(|i| i as u8).collect(),
        };
        let bytes = p.encode();
        assert_eq!(&bytes[0..2], &[1, 2], "seq little-endian");
        assert_eq!(bytes[3], 128);
        assert_eq!(bytes[5], 15);
        assert_eq!(FtpPayload::decode(&bytes).unwrap(), p);
        let mut bad = bytes;
        bad[4] = 240;
        assert!(FtpPayload::decode(&bad).unwrap_err().contains("240"));
    }

    #[test]
    fn the_crc_is_px4s_uninverted_crc32() {
        // generate_crc.py's table-driven loop over b"123456789", started at 0.
        assert_eq!(crc32(b""), 0);
        assert_eq!(crc32(b"123456789"), 0x2DFD_2D88);
    }
}
