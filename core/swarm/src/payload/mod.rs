//! Payloads on a vehicle: one supervised payload actor per running slot, under its
//! Vehicle actor.
//!
//! The actor ([`actor`]) owns a [`PayloadDriver`](skein_payload::PayloadDriver) created
//! by the configured [`PayloadFactory`](skein_payload::PayloadFactory) (plugins, or the
//! built-in fault fixture, [`builtin`]) on an OS thread of its own ([`driver`]): it ticks
//! it at the rate it asks for, forwards operator commands and MAVLink from the vehicle's
//! components to it, and answers the watchdog. A driver error during a tick fails the
//! actor (a crashed process-isolated plugin shows up that way), and the supervisor
//! restarts it, which creates a new driver. Every call has a deadline: a plugin never
//! blocks a tokio worker. When its plugin is reloaded the driver is re-created on the new
//! build ([`PayloadMsg::Refresh`]) without a failure.
//!
//! A slot whose kind no loaded provider offers does not start at all: it waits for a
//! plugin ([`placement`]), and its vehicle creates it when one is loaded.
//!
//! What outlives the actor is [`PayloadShared`] ([`shared`]): the spec, the state and the
//! last video frame the payload published, and which library serves it, so the API keeps
//! showing them across restarts. The driver reaches the world through the
//! [`PayloadHost`](skein_payload::PayloadHost) its vehicle gives it
//! ([`crate::vehicle::payload_host`]).

pub mod actor;
pub mod builtin;
mod driver;
pub mod placement;
pub mod shared;

pub use crate::protocol::PayloadCommandError;
pub use actor::{
    PayloadActor, PayloadActorState, PayloadArgs, PayloadMsg, abandoned_driver_threads,
};
pub use builtin::{BuiltinPayloads, FAULT_FIXTURE, Factories};
pub use placement::{AttachRefusal, Placement, check_attach, placement, provider_for};
pub use shared::PayloadShared;
