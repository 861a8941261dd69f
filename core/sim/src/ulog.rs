//! A ULog writer: the file format of PX4's flight logs (PX4's `logger` module writes it;
//! spec: docs.px4.io, "ULog File Format"; `pyulog` is PX4's reference reader).
//!
//! A file is a 16-byte header (the magic `ULog\x01\x12\x35`, version 1, then a `uint64_t`
//! timestamp: µs of the writer's clock when the log starts), the definitions (the flag
//! bits message `B` first, then info `I` and formats `F`) and the data (subscriptions `A`,
//! then samples `D`). Every message is `uint16_t msg_size`, `uint8_t msg_type`, then
//! `msg_size` bytes. Everything is little endian.
//!
//! Formats are laid out as PX4's uORB structs: the fields in the order given, biggest
//! types first (PX4's generator sorts them so, which leaves no padding between fields),
//! the struct padded to a multiple of 8 bytes by a last `uint8_t[N] _padding0` field that
//! the format names but data messages leave out (PX4 writes `o_size_no_padding` bytes;
//! readers accept a sample with or without it).

/// The file magic (`ULog`, 0x01, 0x12, 0x35).
pub(crate) const MAGIC: [u8; 7] = *b"ULog\x01\x12\x35";
/// The file format version this writer writes.
pub(crate) const VERSION: u8 = 1;
/// Bytes of the file header: magic, version, `uint64_t` timestamp.
pub(crate) const HEADER_LEN: usize = 16;
/// Bytes of every message's header: `uint16_t msg_size`, `uint8_t msg_type`.
pub(crate) const MSG_HEADER_LEN: usize = 3;
/// Bytes of the flag bits message's body: `compat_flags[8]`, `incompat_flags[8]`,
/// `appended_offsets[3]` (`uint64_t`).
pub(crate) const FLAG_BITS_LEN: usize = 40;

/// A field's type, as a ULog format names it (C types).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum FieldType {
    /// `uint8_t`, 1 byte.
    Uint8,
    /// `bool`, 1 byte (0 or 1).
    Bool,
    /// `float`, 4 bytes (IEEE 754 single).
    Float,
    /// `uint64_t`, 8 bytes.
    Uint64,
}

impl FieldType {
    /// The C name a format uses (`uint8_t`, `bool`, `float`, `uint64_t`).
    pub(crate) fn c_name(self) -> &'static str {
        match self {
            FieldType::Uint8 => "uint8_t",
            FieldType::Bool => "bool",
            FieldType::Float => "float",
            FieldType::Uint64 => "uint64_t",
        }
    }

    /// Size, bytes.
    pub(crate) fn size(self) -> usize {
        match self {
            FieldType::Uint8 | FieldType::Bool => 1,
            FieldType::Float => 4,
            FieldType::Uint64 => 8,
        }
    }
}

/// One field of a format: `type name`, or `type[len] name` for an array.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Field {
    /// Element type.
    pub ty: FieldType,
    /// Array length; 0 for a scalar.
    pub len: usize,
    /// Field name (PX4's `msg/` name).
    pub name: &'static str,
}

impl Field {
    /// A scalar field.
    pub(crate) const fn scalar(ty: FieldType, name: &'static str) -> Field {
        Field { ty, len: 0, name }
    }

    /// An array field of `len` elements.
    pub(crate) const fn array(ty: FieldType, len: usize, name: &'static str) -> Field {
        Field { ty, len, name }
    }

    /// Size, bytes.
    pub(crate) fn size(&self) -> usize {
        self.ty.size() * self.len.max(1)
    }

    /// `type name;` or `type[len] name;`.
    fn definition(&self) -> String {
        if self.len == 0 {
            format!("{} {};", self.ty.c_name(), self.name)
        } else {
            format!("{}[{}] {};", self.ty.c_name(), self.len, self.name)
        }
    }
}

/// A logged message's format (a uORB topic's definition): its name and fields.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Format {
    /// Message (topic) name, e.g. `vehicle_local_position`.
    pub name: &'static str,
    /// Fields in struct order, `uint64_t timestamp` first.
    pub fields: &'static [Field],
}

impl Format {
    /// Bytes of one data sample: the fields, without the trailing padding.
    pub(crate) fn data_size(&self) -> usize {
        self.fields.iter().map(Field::size).sum()
    }

    /// Trailing padding of the struct to 8-byte alignment, bytes.
    pub(crate) fn padding(&self) -> usize {
        (8 - self.data_size() % 8) % 8
    }

    /// The `F` message's text: `name:type field;…;`, ending with PX4's
    /// `uint8_t[N] _padding0;` when the struct is padded.
    pub(crate) fn definition(&self) -> String {
        let mut s = format!("{}:", self.name);
        for f in self.fields {
            s.push_str(&f.definition());
        }
        let pad = self.padding();
        if pad > 0 {
            s.push_str(&Field::array(FieldType::Uint8, pad, "_padding0").definition());
        }
        s
    }
}

/// One data sample being encoded, field by field in the format's order (little endian).
#[derive(Debug, Default)]
pub(crate) struct Sample {
    bytes: Vec<u8>,
}

impl Sample {
    /// An empty sample.
    pub(crate) fn new() -> Sample {
        Sample::default()
    }

    /// Appends a `uint64_t`.
    pub(crate) fn u64(&mut self, v: u64) -> &mut Sample {
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// Appends a `float` (from an `f64`, rounded to single precision).
    pub(crate) fn f32(&mut self, v: f64) -> &mut Sample {
        self.bytes.extend_from_slice(&(v as f32).to_le_bytes());
        self
    }

    /// Appends a `float[N]`.
    pub(crate) fn f32s(&mut self, v: &[f32]) -> &mut Sample {
        for x in v {
            self.bytes.extend_from_slice(&x.to_le_bytes());
        }
        self
    }

    /// Appends a `bool`.
    pub(crate) fn bool(&mut self, v: bool) -> &mut Sample {
        self.bytes.push(u8::from(v));
        self
    }

    /// Appends a `uint8_t`.
    pub(crate) fn u8(&mut self, v: u8) -> &mut Sample {
        self.bytes.push(v);
        self
    }

    /// The encoded fields.
    pub(crate) fn bytes(&self) -> &[u8] {
        &self.bytes
    }
}

/// Writes one ULog file into memory.
#[derive(Debug, Clone)]
pub(crate) struct Writer {
    bytes: Vec<u8>,
}

impl Writer {
    /// A file starting at `timestamp_us` (µs of the logging clock): the header and the
    /// flag bits message (no compatibility or incompatibility flag, nothing appended).
    pub(crate) fn new(timestamp_us: u64) -> Writer {
        let mut bytes = Vec::with_capacity(4096);
        bytes.extend_from_slice(&MAGIC);
        bytes.push(VERSION);
        bytes.extend_from_slice(&timestamp_us.to_le_bytes());
        debug_assert_eq!(bytes.len(), HEADER_LEN);
        let mut w = Writer { bytes };
        w.message(b'B', &[&[0u8; FLAG_BITS_LEN]]);
        w
    }

    /// Appends a message of `msg_type` whose body is `parts` one after the other; a body
    /// longer than `msg_size` can say (64 KiB) is not written (false).
    fn message(&mut self, msg_type: u8, parts: &[&[u8]]) -> bool {
        let len: usize = parts.iter().map(|p| p.len()).sum();
        let Ok(msg_size) = u16::try_from(len) else {
            return false;
        };
        self.bytes.extend_from_slice(&msg_size.to_le_bytes());
        self.bytes.push(msg_type);
        for p in parts {
            self.bytes.extend_from_slice(p);
        }
        true
    }

    /// An info message `I`: `key` is `type name` (e.g. `char[3] sys_name`), `value` its
    /// bytes. A key longer than 255 bytes is not written.
    pub(crate) fn info(&mut self, key: &str, value: &[u8]) {
        let Ok(key_len) = u8::try_from(key.len()) else {
            return;
        };
        self.message(b'I', &[&[key_len], key.as_bytes(), value]);
    }

    /// An info message with a string value (`char[len] name`, no terminating NUL).
    pub(crate) fn info_str(&mut self, name: &str, value: &str) {
        self.info(&format!("char[{}] {name}", value.len()), value.as_bytes());
    }

    /// An info message with a `uint32_t` value.
    pub(crate) fn info_u32(&mut self, name: &str, value: u32) {
        self.info(&format!("uint32_t {name}"), &value.to_le_bytes());
    }

    /// A format message `F` for `format`.
    pub(crate) fn format(&mut self, format: &Format) {
        self.message(b'F', &[format.definition().as_bytes()]);
    }

    /// A subscription `A`: data messages with `msg_id` are samples of `format` (instance
    /// 0, PX4's `multi_id`).
    pub(crate) fn subscribe(&mut self, msg_id: u16, format: &Format) {
        self.message(
            b'A',
            &[&[0u8], &msg_id.to_le_bytes(), format.name.as_bytes()],
        );
    }

    /// A data message `D`: one sample of the subscription `msg_id`.
    pub(crate) fn data(&mut self, msg_id: u16, sample: &[u8]) {
        self.message(b'D', &[&msg_id.to_le_bytes(), sample]);
    }

    /// Bytes written so far.
    pub(crate) fn len(&self) -> usize {
        self.bytes.len()
    }

    /// The file so far.
    pub(crate) fn bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// The file.
    pub(crate) fn into_bytes(self) -> Vec<u8> {
        self.bytes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const POINT: Format = Format {
        name: "point",
        fields: &[
            Field::scalar(FieldType::Uint64, "timestamp"),
            Field::array(FieldType::Float, 2, "xy"),
            Field::scalar(FieldType::Bool, "valid"),
        ],
    };

    /// Every message of `file` after the header as (type, body); panics unless the sizes
    /// walk the file exactly to its end.
    fn messages(file: &[u8]) -> Vec<(u8, &[u8])> {
        let mut out = Vec::new();
        let mut pos = HEADER_LEN;
        while pos < file.len() {
            assert!(
                pos + MSG_HEADER_LEN <= file.len(),
                "truncated header at {pos}"
            );
            let size = usize::from(u16::from_le_bytes([file[pos], file[pos + 1]]));
            let body = pos + MSG_HEADER_LEN;
            assert!(
                body + size <= file.len(),
                "message at {pos} overruns the file"
            );
            out.push((file[pos + 2], &file[body..body + size]));
            pos = body + size;
        }
        assert_eq!(pos, file.len());
        out
    }

    #[test]
    fn format_pads_to_eight_bytes_with_px4_padding_field() {
        assert_eq!(POINT.data_size(), 17);
        assert_eq!(POINT.padding(), 7);
        assert_eq!(
            POINT.definition(),
            "point:uint64_t timestamp;float[2] xy;bool valid;uint8_t[7] _padding0;"
        );
        const ALIGNED: Format = Format {
            name: "t",
            fields: &[Field::scalar(FieldType::Uint64, "timestamp")],
        };
        let aligned = ALIGNED;
        assert_eq!(aligned.padding(), 0);
        assert_eq!(aligned.definition(), "t:uint64_t timestamp;");
    }

    #[test]
    fn writer_lays_out_header_flag_bits_definitions_and_data() {
        let mut w = Writer::new(1_234_567);
        w.info_str("sys_name", "PX4");
        w.info_u32("ver_sw_release", 0x0110_00FF);
        w.format(&POINT);
        w.subscribe(3, &POINT);
        let mut s = Sample::new();
        s.u64(42).f32s(&[1.0, -2.0]).bool(true);
        assert_eq!(s.bytes().len(), POINT.data_size());
        w.data(3, s.bytes());
        let file = w.into_bytes();

        assert_eq!(&file[..7], b"ULog\x01\x12\x35");
        assert_eq!(file[7], 1);
        assert_eq!(
            u64::from_le_bytes(file[8..16].try_into().unwrap()),
            1_234_567
        );
        let msgs = messages(&file);
        let types: Vec<u8> = msgs.iter().map(|m| m.0).collect();
        assert_eq!(types, b"BIIFAD".to_vec());
        assert_eq!(msgs[0].1, &[0u8; FLAG_BITS_LEN][..]);
        assert_eq!(msgs[1].1, b"\x10char[3] sys_namePX4");
        assert_eq!(msgs[2].1, b"\x17uint32_t ver_sw_release\xFF\x00\x10\x01");
        assert_eq!(msgs[3].1, POINT.definition().as_bytes());
        assert_eq!(msgs[4].1, b"\x00\x03\x00point");
        let d = msgs[5].1;
        assert_eq!(d.len(), 2 + 17);
        assert_eq!(&d[..2], &3u16.to_le_bytes());
        assert_eq!(&d[2..10], &42u64.to_le_bytes());
        assert_eq!(&d[10..14], &1.0f32.to_le_bytes());
        assert_eq!(&d[14..18], &(-2.0f32).to_le_bytes());
        assert_eq!(d[18], 1);
    }

    #[test]
    fn an_oversized_message_is_left_out() {
        let mut w = Writer::new(0);
        let before = w.len();
        w.data(0, &vec![0u8; 70_000]);
        assert_eq!(w.len(), before);
        w.info(&"k".repeat(300), b"v");
        assert_eq!(w.len(), before);
        assert_eq!(messages(w.bytes()).len(), 1);
    }
}
