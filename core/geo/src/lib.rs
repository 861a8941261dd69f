//! WGS84 geodesy for skein, in one place: geodetic points, north-east-down vectors,
//! local tangent-plane frames and look angles.
//!
//! Every PX4 has its own local NED origin (where its EKF started), so raw
//! `LOCAL_POSITION_NED` values of two vehicles cannot be compared. skein works in one
//! *swarm frame*, a NED tangent plane anchored at a swarm origin, and converts each
//! vehicle's positions and setpoints through geodetic coordinates: swarm NED → geodetic →
//! vehicle local NED ([`NedFrame`]). The ellipsoid maths are the `map_3d` crate's (WGS84,
//! exact geodetic ↔ ECEF ↔ NED), not a flat-earth approximation.
//!
//! - [`GeoPoint`]: latitude, longitude (degrees) and altitude AMSL (metres), with the
//!   MAVLink integer encoding (degE7, millimetres).
//! - [`Ned`]: a north-east-down vector and its arithmetic.
//! - [`NedFrame`]: a tangent plane anchored at a geodetic origin, and the recovery of a
//!   PX4 local origin from `HOME_POSITION`; [`FrameTransform`], the map between two of
//!   them worked out once for a control loop's many conversions.
//! - [`look_angles`], [`direction`]: azimuth / elevation / range between two NED points
//!   (the gimbal and camera conventions), and angle wrapping.
//! - [`Position`], [`Velocity`]: a vehicle's position (swarm-frame NED plus geodetic) and
//!   NED velocity, as the vehicle snapshot carries them to the API and to plugins.
//!
//! Why a crate of its own: the swarm's model (`skein-model`) and the payload plugins both
//! need this geodesy, and the plugin SDK (`plugins/sdk`), the only crate a plugin links, is
//! built outside skein's workspace by third-party plugins. This leaf crate costs them
//! `serde` and `map_3d` (no dependencies of its own); depending on `skein-model` instead
//! would drag in `pathfinding` and `utoipa`'s derive macros, which a plugin never uses.
//! `skein-model` re-exports it as `skein_model::geo`, the SDK as
//! `skein_plugin_sdk::geometry`; the `openapi` feature (on in the workspace, through
//! `skein-model`) derives `utoipa::ToSchema` for the API's OpenAPI document.
#![warn(missing_docs)]

mod angles;
mod frame;
mod ned;
mod point;
mod position;

pub use angles::{LookAngles, direction, look_angles, wrap_deg_180, wrap_deg_360, wrap_pi};
pub use frame::{FrameTransform, NedFrame};
pub use ned::Ned;
pub use point::GeoPoint;
pub use position::{Position, Velocity};
