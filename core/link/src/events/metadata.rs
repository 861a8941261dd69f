//! libevents' metadata (PX4's `all_events.json`, fetched from the vehicle): the events
//! by id, the enums their arguments use, and the navigation mode groups.
//!
//! The format, as libevents' `parser.cpp` and PX4's `src/lib/events/enums.json` have it:
//! `{"version", "components": {"<component id>": {"namespace", "enums": {"<name>":
//! {"type", "is_bitfield", "separator", "entries": {"<value>": {"name",
//! "description"}}}}, "event_groups": {"<group>": {"events": {"<sub id>": {"name",
//! "message", "description", "type", "arguments": [{"type", "name"}]}}}},
//! "navigation_mode_groups": {"groups": {"<group>": [custom_mode, …]}}}}}`. An event's
//! id is its component id in the top byte and its 24-bit sub id. An argument's type is
//! a base type (`uint8_t` … `int64_t`, `float`) or an enum, named within the event's
//! namespace or as `namespace::name`. An event whose argument type is unknown is left
//! out (counted in [`EventsMetadata::skipped`]).

use serde_json::Value;
use std::collections::{BTreeMap, HashMap};

/// An argument's storage type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BaseType {
    /// `uint8_t`.
    U8,
    /// `int8_t`.
    I8,
    /// `uint16_t`.
    U16,
    /// `int16_t`.
    I16,
    /// `uint32_t`.
    U32,
    /// `int32_t`.
    I32,
    /// `uint64_t`.
    U64,
    /// `int64_t`.
    I64,
    /// `float` (32 bits).
    F32,
}

impl BaseType {
    /// From libevents' type name.
    pub fn parse(name: &str) -> Option<BaseType> {
        Some(match name {
            "uint8_t" => BaseType::U8,
            "int8_t" => BaseType::I8,
            "uint16_t" => BaseType::U16,
            "int16_t" => BaseType::I16,
            "uint32_t" => BaseType::U32,
            "int32_t" => BaseType::I32,
            "uint64_t" => BaseType::U64,
            "int64_t" => BaseType::I64,
            "float" => BaseType::F32,
            _ => return None,
        })
    }

    /// Bytes it takes in `EVENT.arguments`.
    pub fn size(self) -> usize {
        match self {
            BaseType::U8 | BaseType::I8 => 1,
            BaseType::U16 | BaseType::I16 => 2,
            BaseType::U32 | BaseType::I32 | BaseType::F32 => 4,
            BaseType::U64 | BaseType::I64 => 8,
        }
    }
}

/// An enum (or bitfield) of the metadata.
#[derive(Debug, Clone, PartialEq)]
pub struct EnumDef {
    /// Its storage type.
    pub base: BaseType,
    /// Values are bits, combined.
    pub is_bitfield: bool,
    /// Entries by value: (name, description).
    pub entries: BTreeMap<u64, (String, String)>,
}

/// One argument of an event.
#[derive(Debug, Clone, PartialEq)]
pub struct ArgDef {
    /// Its name.
    pub name: String,
    /// Its storage type.
    pub base: BaseType,
    /// Its enum's key (`namespace::name`), for an enum argument.
    pub enum_key: Option<String>,
}

/// One event of the metadata.
#[derive(Debug, Clone, PartialEq)]
pub struct EventDef {
    /// Its id (component id << 24 | sub id).
    pub id: u32,
    /// Its namespace (`px4`, `common`).
    pub namespace: String,
    /// Its name (`commander_armed_by`).
    pub name: String,
    /// Its group (`default`, `arming_check`, `health`, `calibration`).
    pub group: String,
    /// Its type (`summary` for the health protocol's summaries; else empty).
    pub kind: String,
    /// The message template.
    pub message: String,
    /// The description template (may be empty).
    pub description: String,
    /// The arguments, in order.
    pub args: Vec<ArgDef>,
}

/// Parsed events metadata.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct EventsMetadata {
    /// Events by id.
    pub events: HashMap<u32, EventDef>,
    /// Enums by `namespace::name`.
    pub enums: HashMap<String, EnumDef>,
    /// The navigation mode group of each `custom_mode`.
    pub mode_groups: HashMap<u32, u8>,
    /// Events left out (an argument of an unknown type).
    pub skipped: usize,
}

fn text(v: &Value, key: &str) -> String {
    v.get(key)
        .and_then(Value::as_str)
        .unwrap_or_default()
        .to_string()
}

fn parse_enum(e: &Value) -> Option<EnumDef> {
    let base = BaseType::parse(e.get("type")?.as_str()?)?;
    let mut entries = BTreeMap::new();
    for (value, entry) in e
        .get("entries")
        .and_then(Value::as_object)
        .into_iter()
        .flatten()
    {
        if let Ok(v) = value.parse::<u64>() {
            entries.insert(v, (text(entry, "name"), text(entry, "description")));
        }
    }
    Some(EnumDef {
        base,
        is_bitfield: e
            .get("is_bitfield")
            .and_then(Value::as_bool)
            .unwrap_or(false),
        entries,
    })
}

impl EventsMetadata {
    /// Parses the JSON; `Err` says what is wrong with it.
    pub fn parse(json: &[u8]) -> Result<Self, String> {
        let root: Value =
            serde_json::from_slice(json).map_err(|e| format!("events metadata: {e}"))?;
        let version = root.get("version").and_then(Value::as_u64).unwrap_or(0);
        if version < 1 {
            return Err(format!(
                "events metadata: version {version} (need 1 or later)"
            ));
        }
        let components = root
            .get("components")
            .and_then(Value::as_object)
            .ok_or("events metadata: no \"components\"")?;
        let mut meta = EventsMetadata::default();
        for c in components.values() {
            let ns = text(c, "namespace");
            for (name, e) in c
                .get("enums")
                .and_then(Value::as_object)
                .into_iter()
                .flatten()
            {
                if let Some(def) = parse_enum(e) {
                    meta.enums.insert(format!("{ns}::{name}"), def);
                }
            }
        }
        for (id, c) in components {
            let component: u32 = id
                .parse()
                .map_err(|_| format!("events metadata: component id {id:?}"))?;
            meta.add_component(component & 0xff, c);
        }
        Ok(meta)
    }

    fn add_component(&mut self, component: u32, c: &Value) {
        let ns = text(c, "namespace");
        for (group, g) in c
            .get("event_groups")
            .and_then(Value::as_object)
            .into_iter()
            .flatten()
        {
            for (sub, e) in g
                .get("events")
                .and_then(Value::as_object)
                .into_iter()
                .flatten()
            {
                let Ok(sub) = sub.parse::<u32>() else {
                    self.skipped += 1;
                    continue;
                };
                match self.event_def(&ns, group, e) {
                    Some(mut def) => {
                        def.id = (component << 24) | (sub & 0x00ff_ffff);
                        self.events.insert(def.id, def);
                    }
                    None => self.skipped += 1,
                }
            }
        }
        let groups = c
            .pointer("/navigation_mode_groups/groups")
            .and_then(Value::as_object);
        for (group, modes) in groups.into_iter().flatten() {
            let Ok(group) = group.parse::<u8>() else {
                continue;
            };
            for m in modes
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(Value::as_u64)
            {
                self.mode_groups.insert(m as u32, group);
            }
        }
    }

    fn event_def(&self, ns: &str, group: &str, e: &Value) -> Option<EventDef> {
        let mut args = Vec::new();
        for a in e
            .get("arguments")
            .and_then(Value::as_array)
            .into_iter()
            .flatten()
        {
            let ty = a.get("type")?.as_str()?;
            let (base, enum_key) = match BaseType::parse(ty) {
                Some(b) => (b, None),
                None => {
                    let key = if ty.contains("::") {
                        ty.to_string()
                    } else {
                        format!("{ns}::{ty}")
                    };
                    (self.enums.get(&key)?.base, Some(key))
                }
            };
            args.push(ArgDef {
                name: text(a, "name"),
                base,
                enum_key,
            });
        }
        Some(EventDef {
            id: 0,
            namespace: ns.to_string(),
            name: text(e, "name"),
            group: group.to_string(),
            kind: text(e, "type"),
            message: text(e, "message"),
            description: text(e, "description"),
            args,
        })
    }
}
