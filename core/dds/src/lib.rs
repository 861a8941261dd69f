//! The DDS link: skein's swarm on ROS 2 topics, through `ros2-client` on RustDDS (no ROS
//! installation needed; any ROS 2 node, `ros2 topic echo` or a plain DDS peer such as
//! CycloneDDS sees it).
//!
//! - [`topics`]: names and QoS of every topic (the table there is the contract);
//! - [`msgs`]: the message types, standard ROS 2 ones and skein's own (the ROS 2
//!   interface package `ros2/skein_msgs`), with [`msg_samples`], one of each for the
//!   checks against the `.msg` files;
//! - [`carrier`]: what carries the samples: DDS ([`carrier::ros2`]) or, in unit tests, an
//!   in-memory bus ([`carrier::memory`]);
//! - the roles, each with its own topics and a small context trait: [`vehicles`] (the
//!   vehicles' topics and commands of `skein up --dds`), [`tf`] (the vehicles as TF
//!   frames on `/tf`, the swarm frame's anchor on `/tf_static`), [`lease`] (the coordinator
//!   election on `/skein/coordinator`, `skein coordinator`), [`remote`] (a coordinator's
//!   remote vehicles), [`mirror`] (the formation a standby resumes) and [`agent`] (an
//!   agent's vehicles obeying the active coordinator, `skein agent`, riding through its
//!   silences with [`ride`]), [`rtcm`] (RTK corrections relayed from the active
//!   coordinator to the agents on `/skein/rtcm`);
//! - [`clocks`]: the clock exchange, so that stamps from another host are aged in this
//!   process's clock;
//! - [`envelope`] and [`reframe`]: the swarm protocol's envelope between coordinators
//!   and agents (`/skein/swarm/*`) and positions between two processes' swarm frames;
//! - [`swarm_adapter`]: the roles' contexts on `skein_swarm`'s coordinator actor, the
//!   one module that speaks to it;
//! - [`link`]: composes the roles ([`DdsRoles`]) and runs them as the supervised
//!   `DdsLink` service, on a new participant after a change of the network
//!   [`interfaces`];
//! - [`convert`]: skein's NED swarm frame to the ENU of REP 103, commands back;
//! - [`probe`]: a listener of the pose topics (`skein bench dds`);
//! - [`security`]: DDS Security (SROS 2 keystores and enclaves, permissions by role).
//!
//! The roles' scenario tests (`src/role_tests/`, test scaffolding) wire several processes together on the
//! in-memory carrier, on tokio's paused clock.
//!
//! The domain is `--domain-id`, else `ROS_DOMAIN_ID`, else 0 ([`domain_id_from_env`]).
#![warn(missing_docs)]

pub mod agent;
pub mod carrier;
mod clock;
pub mod clocks;
pub mod convert;
pub mod counters;
pub mod envelope;
pub mod error;
pub mod interfaces;
pub mod lease;
pub mod link;
pub mod mirror;
#[cfg(test)]
mod msg_files;
pub mod msg_samples;
pub mod msgs;
pub mod probe;
pub mod reframe;
pub mod remote;
pub mod ride;
#[cfg(test)]
mod role_tests;
pub mod rtcm;
pub mod security;
pub mod swarm_adapter;
pub mod tf;
pub mod topics;
pub mod vehicles;

pub use counters::DdsCounters;
pub use error::DdsError;
pub use link::{DdsConfig, DdsLink, DdsRoles};

/// The frame of positions on skein's topics: ENU about the swarm origin (its geodetic
/// point is the `[swarm] origin` of the config, or the first vehicle's home).
pub const FRAME_ID: &str = "skein_swarm";

/// The highest DDS domain id RTPS port mapping allows with default port parameters.
pub const MAX_DOMAIN_ID: u16 = 232;

/// The domain given by `ROS_DOMAIN_ID`, if set.
///
/// # Errors
/// `ROS_DOMAIN_ID` is set but not an integer in `0..=232`.
pub fn domain_id_from_env() -> Result<Option<u16>, String> {
    match std::env::var("ROS_DOMAIN_ID") {
        Ok(s) if s.trim().is_empty() => Ok(None),
        Ok(s) => parse_domain_id(s.trim())
            .map(Some)
            .map_err(|e| format!("ROS_DOMAIN_ID: {e}")),
        Err(_) => Ok(None),
    }
}

/// A domain id from text.
///
/// # Errors
/// Not an integer in `0..=232`.
pub fn parse_domain_id(s: &str) -> Result<u16, String> {
    match s.parse::<u16>() {
        Ok(d) if d <= MAX_DOMAIN_ID => Ok(d),
        _ => Err(format!(
            "`{s}` is not a DDS domain id (0 to {MAX_DOMAIN_ID})"
        )),
    }
}
