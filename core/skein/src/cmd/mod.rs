//! The commands of the `skein` binary, one module each. Roles and where they live:
//!
//! | command | what runs | module |
//! |---|---|---|
//! | `skein up` | one process: coordinator, its vehicles, API, dashboard (+ simulator, plugins, DDS) | [`up`] |
//! | `skein coordinator` | a coordinator candidate: coordinator actor, API, DDS, election; no vehicles | [`candidate`] |
//! | `skein agent` | one companion computer's vehicles, steered over DDS | [`agent`] |
//! | `skein bench` | runs the `skein-bench` executable (crate `skein-bench`) | [`bench`] |
//! | `skein mission rehearse` | a mission plan flown in virtual time, its figures printed | [`mission`] |
//! | `skein replay` | a recording played back into a read-only dashboard | [`replay`] |
//! | `skein fault` | a fault injected through a running skein's API | [`fault`] |
//! | `skein health` | the health check of a container or a monitor | [`health`] |
//! | `skein token create` | an API token and its config lines | [`token`] |
//! | `skein key create` | a MAVLink 2 signing key file | [`keys`] |
//! | `skein dds keystore create`, `skein dds enclave create` | an SROS 2 keystore, a participant's enclave | [`dds`] |
//! | `skein plugin new` | a payload plugin crate that builds | [`plugin_new`] |
//!
//! `up`, `coordinator` and `agent` are one composition in three roles ([`crate::compose`]):
//! each turns its flags into a role and its options; none imports another.
//!
//! `skein sim` is `skein_sim::cli`; `skein plugin-host` is `skein_plugin_host`'s child
//! entry point. The actors these commands start are in `skein_swarm` (the `Coordinator`
//! actor, `Vehicle` actors) and `skein_dds` (the DDS roles).

pub mod agent;
pub mod bench;
pub mod coordinator;
pub mod dds;
pub mod fault;
pub mod health;
pub mod keys;
pub mod mission;
pub mod plugin_new;
pub mod replay;
pub mod token;
pub mod up;
