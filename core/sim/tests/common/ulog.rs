//! [`ULog::parse`]: a small ULog reader for the tests, written from the format's spec
//! (docs.px4.io, "ULog File Format"), nothing shared with the simulator's writer. It
//! walks every message by its size to the file's exact end and panics on anything a
//! reader such as pyulog would refuse: a bad header, flag bits that are not the first
//! message, a definition after the data started, a data sample whose size is not its
//! format's (with or without the trailing `_padding` field).

use std::collections::BTreeMap;

/// One field of a format: type name, array length (0 = scalar), name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ULogField {
    pub ty: String,
    pub len: usize,
    pub name: String,
}

/// A parsed ULog file.
#[derive(Debug, Default)]
pub struct ULog {
    /// The header's timestamp, µs.
    pub timestamp_us: u64,
    /// The message types in file order (`B`, `I`, `F`, `A`, `D` …).
    pub message_types: Vec<u8>,
    /// Info messages: key (`char[3] sys_name`) to value bytes.
    pub infos: BTreeMap<String, Vec<u8>>,
    /// Format messages' texts by message name (`name:type field;…`).
    pub format_texts: BTreeMap<String, String>,
    /// Fields by message name.
    pub formats: BTreeMap<String, Vec<ULogField>>,
    /// Subscriptions: msg_id to message name.
    pub subscriptions: BTreeMap<u16, String>,
    /// Data samples by message name, each as field name (arrays as `q[0]` …) to value.
    pub data: BTreeMap<String, Vec<BTreeMap<String, f64>>>,
}

fn type_size(ty: &str) -> usize {
    match ty {
        "int8_t" | "uint8_t" | "bool" | "char" => 1,
        "int16_t" | "uint16_t" => 2,
        "int32_t" | "uint32_t" | "float" => 4,
        "int64_t" | "uint64_t" | "double" => 8,
        other => panic!("unknown ULog type {other}"),
    }
}

fn decode(ty: &str, b: &[u8]) -> f64 {
    match ty {
        "uint8_t" | "bool" | "char" => f64::from(b[0]),
        "int8_t" => f64::from(b[0] as i8),
        "uint16_t" => f64::from(u16::from_le_bytes([b[0], b[1]])),
        "int16_t" => f64::from(i16::from_le_bytes([b[0], b[1]])),
        "uint32_t" => f64::from(u32::from_le_bytes(b[..4].try_into().unwrap())),
        "int32_t" => f64::from(i32::from_le_bytes(b[..4].try_into().unwrap())),
        "float" => f64::from(f32::from_le_bytes(b[..4].try_into().unwrap())),
        "uint64_t" => u64::from_le_bytes(b[..8].try_into().unwrap()) as f64,
        "int64_t" => i64::from_le_bytes(b[..8].try_into().unwrap()) as f64,
        "double" => f64::from_le_bytes(b[..8].try_into().unwrap()),
        other => panic!("unknown ULog type {other}"),
    }
}

fn parse_fields(text: &str) -> Vec<ULogField> {
    text.split(';')
        .filter(|f| !f.is_empty())
        .map(|f| {
            let (ty, name) = f.split_once(' ').expect("`type name`");
            let (ty, len) = match ty.split_once('[') {
                Some((t, n)) => (t, n.trim_end_matches(']').parse().expect("array length")),
                None => (ty, 0),
            };
            type_size(ty);
            ULogField {
                ty: ty.to_string(),
                len,
                name: name.to_string(),
            }
        })
        .collect()
}

impl ULog {
    /// Parses `file`; panics with the reason on anything malformed.
    pub fn parse(file: &[u8]) -> ULog {
        assert!(file.len() >= 16, "no header");
        assert_eq!(&file[..7], b"ULog\x01\x12\x35", "magic");
        assert_eq!(file[7], 1, "version");
        let mut log = ULog {
            timestamp_us: u64::from_le_bytes(file[8..16].try_into().unwrap()),
            ..ULog::default()
        };
        let mut pos = 16;
        while pos < file.len() {
            assert!(pos + 3 <= file.len(), "truncated message header at {pos}");
            let size = usize::from(u16::from_le_bytes([file[pos], file[pos + 1]]));
            let msg_type = file[pos + 2];
            let body = &file[pos + 3..];
            assert!(size <= body.len(), "message at {pos} overruns the file");
            log.message(msg_type, &body[..size]);
            pos += 3 + size;
        }
        assert_eq!(pos, file.len(), "messages do not end with the file");
        log
    }

    fn message(&mut self, msg_type: u8, body: &[u8]) {
        let in_data = self.message_types.iter().any(|t| matches!(t, b'A' | b'D'));
        if msg_type == b'B' {
            assert!(self.message_types.is_empty(), "flag bits not first");
            assert_eq!(body.len(), 40, "flag bits size");
            assert!(
                body[8..16].iter().all(|b| *b == 0),
                "incompatible flags set"
            );
        } else {
            assert_eq!(
                self.message_types.first(),
                Some(&b'B'),
                "no flag bits first"
            );
        }
        self.message_types.push(msg_type);
        match msg_type {
            b'B' => {}
            b'I' => {
                let key_len = usize::from(body[0]);
                let key = String::from_utf8(body[1..1 + key_len].to_vec()).expect("key");
                self.infos.insert(key, body[1 + key_len..].to_vec());
            }
            b'F' => {
                assert!(!in_data, "format after the data started");
                let text = String::from_utf8(body.to_vec()).expect("format text");
                let (name, fields) = text.split_once(':').expect("name:fields");
                self.formats.insert(name.to_string(), parse_fields(fields));
                self.format_texts.insert(name.to_string(), text.clone());
            }
            b'A' => {
                let msg_id = u16::from_le_bytes([body[1], body[2]]);
                let name = String::from_utf8(body[3..].to_vec()).expect("name");
                assert!(self.formats.contains_key(&name), "no format for {name}");
                self.subscriptions.insert(msg_id, name);
            }
            b'D' => self.sample(body),
            other => panic!("unexpected message type {}", other as char),
        }
    }

    fn sample(&mut self, body: &[u8]) {
        let msg_id = u16::from_le_bytes([body[0], body[1]]);
        let name = self
            .subscriptions
            .get(&msg_id)
            .expect("subscribed msg_id")
            .clone();
        let fields = &self.formats[&name];
        let size = |f: &ULogField| type_size(&f.ty) * f.len.max(1);
        let full: usize = fields.iter().map(size).sum();
        let unpadded: usize = fields
            .iter()
            .filter(|f| !f.name.starts_with("_padding"))
            .map(size)
            .sum();
        let data = &body[2..];
        assert!(
            data.len() == full || data.len() == unpadded,
            "{name}: sample of {} bytes, format {unpadded} ({full} padded)",
            data.len()
        );
        let mut values = BTreeMap::new();
        let mut at = 0;
        for f in fields {
            if f.name.starts_with("_padding") {
                at += size(f);
                continue;
            }
            let n = type_size(&f.ty);
            for i in 0..f.len.max(1) {
                let key = if f.len == 0 {
                    f.name.clone()
                } else {
                    format!("{}[{i}]", f.name)
                };
                values.insert(key, decode(&f.ty, &data[at..at + n]));
                at += n;
            }
        }
        self.data.entry(name).or_default().push(values);
    }

    /// The values of `field` of every `topic` sample, in file order.
    pub fn series(&self, topic: &str, field: &str) -> Vec<f64> {
        self.data
            .get(topic)
            .map(|s| s.iter().map(|v| v[field]).collect())
            .unwrap_or_default()
    }

    /// An info message's value as text.
    pub fn info_str(&self, key: &str) -> Option<String> {
        self.infos
            .get(key)
            .map(|v| String::from_utf8_lossy(v).into_owned())
    }
}
