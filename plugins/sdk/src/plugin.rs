//! [`Plugin`]: the safe trait a plugin author implements.

use crate::context::Context;
use serde_json::Value;
use skein_mavlink::MavMessage;

/// Which MAVLink messages from its vehicle an instance wants in [`Plugin::on_mavlink`].
/// The host filters before encoding, so an instance pays only for what it asked.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum MavlinkInterest {
    /// None (the default).
    #[default]
    None,
    /// Every message of the vehicle's system.
    All,
    /// These message ids only (e.g. `[285]` for `GIMBAL_DEVICE_ATTITUDE_STATUS`).
    Ids(Vec<u32>),
}

impl MavlinkInterest {
    /// The JSON form of the ABI's instance info: `"none"`, `"all"` or an array of ids.
    pub fn to_json(&self) -> Value {
        match self {
            MavlinkInterest::None => Value::from("none"),
            MavlinkInterest::All => Value::from("all"),
            MavlinkInterest::Ids(ids) => Value::from(ids.clone()),
        }
    }

    /// Parses the JSON form (see [`MavlinkInterest::to_json`]).
    ///
    /// # Errors
    /// Any other shape, naming it.
    pub fn from_json(v: &Value) -> Result<MavlinkInterest, String> {
        match v {
            Value::Null => Ok(MavlinkInterest::None),
            Value::String(s) if s == "none" => Ok(MavlinkInterest::None),
            Value::String(s) if s == "all" => Ok(MavlinkInterest::All),
            Value::Array(items) => items
                .iter()
                .map(|i| {
                    i.as_u64()
                        .and_then(|n| u32::try_from(n).ok())
                        .ok_or_else(|| format!("`mavlink`: {i} is not a message id"))
                })
                .collect::<Result<Vec<u32>, String>>()
                .map(MavlinkInterest::Ids),
            other => Err(format!(
                "`mavlink`: expected \"none\", \"all\" or an array of message ids, got {other}"
            )),
        }
    }

    /// True when a message with this id should be delivered.
    pub fn wants(&self, message_id: u32) -> bool {
        match self {
            MavlinkInterest::None => false,
            MavlinkInterest::All => true,
            MavlinkInterest::Ids(ids) => ids.contains(&message_id),
        }
    }
}

/// A payload plugin: one value of the implementing type is one payload instance (one slot
/// of one vehicle). Export it with [`crate::export_plugin!`].
///
/// Every method runs inside `catch_unwind`: a panic becomes an error for the host, and the
/// instance is poisoned (every later call fails) so its supervisor re-creates it. Errors
/// are strings shown to the operator as they are: name the offending field or value.
///
/// An instance is called by one thread at a time; it must not block for long (tick at
/// tens of Hz). Host services are reached through the [`Context`] lent to each call.
pub trait Plugin: Send + Sized + 'static {
    /// The plugin's name, unique among the loaded plugins (`"gimbal"`).
    const NAME: &'static str;
    /// The plugin's version (`env!("CARGO_PKG_VERSION")`).
    const VERSION: &'static str;
    /// The payload kinds it provides (`&["gimbal"]`), at least one.
    const KINDS: &'static [&'static str];

    /// Creates an instance of `kind` (one of [`Plugin::KINDS`]) with its configuration
    /// (`PayloadSpec.config`, `Value::Null` when none was given).
    ///
    /// # Errors
    /// A configuration the plugin cannot use, naming the field.
    fn create(kind: &str, config: Value, ctx: &Context) -> Result<Self, String>;

    /// Ticks per second the instance wants (0 = never ticked). Read by the host after
    /// every call, so it may change (a camera's frame rate).
    fn tick_rate_hz(&self) -> f64 {
        0.0
    }

    /// Periodic work, `dt_s` seconds after the previous tick.
    ///
    /// # Errors
    /// A failure the supervisor should see (the payload actor fails and is restarted).
    fn tick(&mut self, _ctx: &Context, _dt_s: f64) -> Result<(), String> {
        Ok(())
    }

    /// An operator command (the JSON body of `POST /api/v1/vehicles/{id}/payloads/{slot}`);
    /// the returned JSON is the reply.
    ///
    /// # Errors
    /// A command the plugin refuses (unknown `command`, wrong field), returned to the
    /// operator as a 4xx.
    fn handle(&mut self, ctx: &Context, command: Value) -> Result<Value, String>;

    /// Which MAVLink messages the instance wants in [`Plugin::on_mavlink`]; read once,
    /// right after [`Plugin::create`].
    fn mavlink_interest(&self) -> MavlinkInterest {
        MavlinkInterest::None
    }

    /// A MAVLink message from the vehicle's component `compid` (e.g.
    /// `GIMBAL_DEVICE_ATTITUDE_STATUS` from the gimbal device).
    ///
    /// # Errors
    /// As for [`Plugin::tick`].
    fn on_mavlink(&mut self, _ctx: &Context, _compid: u8, _msg: &MavMessage) -> Result<(), String> {
        Ok(())
    }

    /// Called once before the instance is dropped (e.g. to restore a simulated link or
    /// release a gimbal). Panics here are caught and reported.
    fn shutdown(&mut self, _ctx: &Context) {}
}
