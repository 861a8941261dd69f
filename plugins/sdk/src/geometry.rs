//! Geometry for payloads: NED vectors, geodetic points and tangent-plane frames (WGS84),
//! look angles (azimuth/elevation/range) from one point to another, angle wrapping.
//!
//! This is skein's own geodesy, the `skein-geo` crate (the one the swarm model uses),
//! re-exported: a plugin converts exactly as skein does. Conventions: NED = north, east,
//! down, metres; azimuth = degrees clockwise from north; elevation = degrees above the
//! horizontal (negative looks down), which is also the gimbal pitch convention of
//! MAVLink's Gimbal Protocol v2 (pitch positive up).
//!
//! ```
//! use skein_plugin_sdk::geometry::{GeoPoint, Ned, NedFrame, look_angles};
//! let here = NedFrame::new(GeoPoint::new(47.3977, 8.5456, 488.0));
//! let roi = here.to_ned(&GeoPoint::new(47.3986, 8.5456, 488.0)); // ~100 m north
//! let look = look_angles(Ned::ZERO, roi).unwrap();
//! assert!(look.azimuth_deg < 0.1 && (look.range_m - 100.0).abs() < 1.0);
//! ```

pub use skein_geo::{
    GeoPoint, LookAngles, Ned, NedFrame, direction, look_angles, wrap_deg_180, wrap_deg_360,
    wrap_pi,
};
