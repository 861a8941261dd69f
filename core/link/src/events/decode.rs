//! An `EVENT` decoded with its metadata: arguments read by their types, the message and
//! description formatted as libevents' `ParsedEvent::processMessage` does, and as
//! QGroundControl shows them (profile `normal`).
//!
//! Formatting: `\` escapes the next character; `{N}` is argument N (1-based), `{N:.D}`
//! a float with D decimals, a unit after it (`{1m}`, `{2:.1m/s}`) is appended after a
//! space (`m_v` shown as `m`); an enum argument shows its entry's description
//! (`(unknown: V)` for a value it does not list), a bitfield the descriptions of its set
//! bits joined by `|`. Tags: `<param>P</param>` and `<a href="…">T</a>` show their
//! content; `<profile name="dev">…</profile>` shows its content only for that profile,
//! `name="!dev"` for any other; any other tag is removed with its content. The result
//! is trimmed.

use super::metadata::{ArgDef, BaseType, EventDef, EventsMetadata};
use skein_mavlink::dialect::EVENT_DATA;
use skein_mavlink::events::external_level;

/// The profile QGroundControl shows events for.
pub const PROFILE: &str = "normal";

/// One argument's value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ArgValue {
    /// An unsigned integer (or enum).
    Unsigned(u64),
    /// A signed integer.
    Signed(i64),
    /// A float.
    Float(f32),
}

impl ArgValue {
    /// As an unsigned integer (a bitfield, an index); 0 for a float.
    pub fn as_u64(self) -> u64 {
        match self {
            ArgValue::Unsigned(v) => v,
            ArgValue::Signed(v) => v as u64,
            ArgValue::Float(_) => 0,
        }
    }
}

/// An event, decoded.
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedEvent {
    /// `namespace::name` (`px4::commander_armed_by`).
    pub name: String,
    /// Its group (`default`, `arming_check`, `health`).
    pub group: String,
    /// Its type (`summary` or empty).
    pub kind: String,
    /// The message, formatted.
    pub message: String,
    /// The description, formatted (may be empty).
    pub description: String,
    /// External log level (0 emergency … 7 debug, 8 protocol).
    pub log_level: u8,
    /// The arguments' values.
    pub args: Vec<ArgValue>,
}

fn read_arg(bytes: &[u8], base: BaseType) -> ArgValue {
    let mut b = [0u8; 8];
    b[..bytes.len()].copy_from_slice(bytes);
    let u = u64::from_le_bytes(b);
    match base {
        BaseType::U8 | BaseType::U16 | BaseType::U32 | BaseType::U64 => ArgValue::Unsigned(u),
        BaseType::I8 => ArgValue::Signed(i64::from(bytes[0] as i8)),
        BaseType::I16 => ArgValue::Signed(i64::from(i16::from_le_bytes([b[0], b[1]]))),
        BaseType::I32 => ArgValue::Signed(i64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]]))),
        BaseType::I64 => ArgValue::Signed(u as i64),
        BaseType::F32 => ArgValue::Float(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
    }
}

/// The values of `def`'s arguments in `arguments` (little-endian, packed); `None` when
/// they do not fit the 40 bytes.
pub fn read_args(def: &EventDef, arguments: &[u8; 40]) -> Option<Vec<ArgValue>> {
    let mut at = 0;
    let mut out = Vec::with_capacity(def.args.len());
    for a in &def.args {
        let end = at + a.base.size();
        out.push(read_arg(arguments.get(at..end)?, a.base));
        at = end;
    }
    Some(out)
}

/// `e` decoded with `meta`; `None` for an event it does not describe.
pub fn decode(meta: &EventsMetadata, e: &EVENT_DATA) -> Option<DecodedEvent> {
    let def = meta.events.get(&e.id)?;
    let args = read_args(def, &e.arguments)?;
    let f = Formatter {
        meta,
        def,
        args: &args,
    };
    Some(DecodedEvent {
        name: format!("{}::{}", def.namespace, def.name),
        group: def.group.clone(),
        kind: def.kind.clone(),
        message: f.format(&def.message),
        description: f.format(&def.description),
        log_level: external_level(e.log_levels),
        args,
    })
}

struct Formatter<'a> {
    meta: &'a EventsMetadata,
    def: &'a EventDef,
    args: &'a [ArgValue],
}

impl Formatter<'_> {
    fn format(&self, template: &str) -> String {
        let chars: Vec<char> = template.chars().collect();
        let mut out = String::new();
        let mut i = 0;
        while i < chars.len() {
            match chars[i] {
                '\\' if i + 1 < chars.len() => {
                    out.push(chars[i + 1]);
                    i += 2;
                }
                '<' => match self.tag(&chars, i) {
                    Some((shown, next)) => {
                        out.push_str(&shown);
                        i = next;
                    }
                    None => {
                        out.push('<');
                        i += 1;
                    }
                },
                '{' => match chars[i..].iter().position(|&c| c == '}') {
                    Some(len) => {
                        let spec: String = chars[i + 1..i + len].iter().collect();
                        match self.argument(&spec) {
                            Some(v) => out.push_str(&v),
                            None => out.push_str(&format!("{{{spec}}}")),
                        }
                        i += len + 1;
                    }
                    None => {
                        out.push('{');
                        i += 1;
                    }
                },
                c => {
                    out.push(c);
                    i += 1;
                }
            }
        }
        out.trim().to_string()
    }

    /// The tag opening at `chars[start]`: what it shows and where the text goes on.
    fn tag(&self, chars: &[char], start: usize) -> Option<(String, usize)> {
        let rest: String = chars[start + 1..].iter().collect();
        let open_end = rest.find('>')?;
        let head = &rest[..open_end];
        let (name, attrs) = head.split_once(' ').unwrap_or((head, ""));
        let close = format!("</{name}>");
        let body_start = open_end + 1;
        let close_at = rest[body_start..].find(&close)? + body_start;
        let body = &rest[body_start..close_at];
        let attr = attrs
            .split_once("=\"")
            .and_then(|(k, v)| v.split_once('"').map(|(v, _)| (k.trim(), v)));
        let shown = match name {
            "param" | "a" => self.format(body),
            "profile" => match attr {
                Some(("name", p)) if p.strip_prefix('!').is_some_and(|p| p == PROFILE) => {
                    String::new()
                }
                Some(("name", p)) if !p.starts_with('!') && p != PROFILE => String::new(),
                _ => self.format(body),
            },
            _ => String::new(),
        };
        let consumed: usize = rest[..close_at + close.len()].chars().count();
        Some((shown, start + 1 + consumed))
    }

    /// `{N[:.D][UNIT]}`.
    fn argument(&self, spec: &str) -> Option<String> {
        let digits_end = spec
            .find(|c: char| !c.is_ascii_digit())
            .unwrap_or(spec.len());
        let index: usize = spec[..digits_end].parse().ok()?;
        let def = self.def.args.get(index.checked_sub(1)?)?;
        let value = *self.args.get(index - 1)?;
        let mut rest = &spec[digits_end..];
        let mut decimals = None;
        if let Some(r) = rest.strip_prefix(":.") {
            let end = r.find(|c: char| !c.is_ascii_digit()).unwrap_or(r.len());
            decimals = r[..end].parse::<usize>().ok();
            rest = &r[end..];
        } else if let Some(r) = rest.strip_prefix(':') {
            rest = r;
        }
        if def.enum_key.is_some() {
            return Some(self.enum_text(def, value.as_u64()));
        }
        let mut s = match (value, decimals) {
            (ArgValue::Float(f), Some(d)) => format!("{f:.d$}"),
            (ArgValue::Float(f), None) => format!("{f}"),
            (ArgValue::Unsigned(v), _) => v.to_string(),
            (ArgValue::Signed(v), _) => v.to_string(),
        };
        if !rest.is_empty() {
            s.push(' ');
            s.push_str(if rest == "m_v" { "m" } else { rest });
        }
        Some(s)
    }

    fn enum_text(&self, def: &ArgDef, value: u64) -> String {
        let Some(e) = def.enum_key.as_ref().and_then(|k| self.meta.enums.get(k)) else {
            return value.to_string();
        };
        let one = |v: u64| {
            e.entries
                .get(&v)
                .map_or_else(|| format!("(unknown: {value})"), |(_, d)| d.clone())
        };
        if !e.is_bitfield {
            return one(value);
        }
        (0..e.base.size() * 8)
            .map(|b| 1u64 << b)
            .filter(|bit| value & bit != 0)
            .map(one)
            .collect::<Vec<_>>()
            .join("|")
    }
}
