//! The vehicle's state as the formation engine needs it ([`VehicleReport`]), published at
//! the control rate and read keep-last, and where it is now given the report's age.

use crate::stamp::age_of;
use serde::{Deserialize, Serialize};
use skein_model::fsm::VehicleState;
use skein_model::geo::Ned;
use std::time::Duration;

/// What the formation engine needs of a vehicle, published by the vehicle at its control
/// rate (keep-last: only the newest matters).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct VehicleReport {
    /// FSM state.
    pub state: VehicleState,
    /// Swarm-frame position, NED metres, at `stamp_us`; `None` before position and home
    /// are known.
    pub position: Option<Ned>,
    /// Velocity, NED m/s.
    pub velocity: Ned,
    /// Heading, radians clockwise from north (`ATTITUDE.yaw`).
    pub heading_rad: f64,
    /// Time since the autopilot was last heard, seconds; `None` if never heard.
    pub link_silence_s: Option<f64>,
    /// Where skein is sending the vehicle (swarm frame), if it steers it.
    pub target: Option<Ned>,
    /// When this report was made, wall-clock µs ([`wall_us`](crate::wall_us)).
    pub stamp_us: u64,
    /// How long its agent flies it on its slot without hearing a coordinator, seconds
    /// (`skein agent`'s `coordinator_ride_through_s`); `None` for a vehicle of the
    /// reader's own process. A coordinator keeps a silent member's slot that long.
    #[serde(default)]
    pub ride_through_s: Option<f64>,
}

impl VehicleReport {
    /// A vehicle never heard from.
    pub fn disconnected() -> Self {
        VehicleReport {
            state: VehicleState::Disconnected,
            position: None,
            velocity: Ned::ZERO,
            heading_rad: 0.0,
            link_silence_s: None,
            target: None,
            stamp_us: 0,
            ride_through_s: None,
        }
    }

    /// The position moved on by the report's age (at most `cap`): where the vehicle is
    /// now if it kept its velocity.
    pub fn position_now(&self, cap: Duration) -> Option<Ned> {
        let age = age_of(self.stamp_us).min(cap).as_secs_f64();
        self.position.map(|p| p + self.velocity * age)
    }

    /// Link silence now (the report's value plus its age); `Duration::MAX` if never
    /// heard.
    pub fn silence_now(&self) -> Duration {
        match self.link_silence_s {
            Some(s) => Duration::from_secs_f64(s.max(0.0)) + age_of(self.stamp_us),
            None => Duration::MAX,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stamp::wall_us;

    #[test]
    fn a_report_moves_on_by_its_age_up_to_the_cap() {
        let mut r = VehicleReport::disconnected();
        r.position = Some(Ned::new(0.0, 0.0, -10.0));
        r.velocity = Ned::new(5.0, 0.0, 0.0);
        r.stamp_us = wall_us() - 100_000; // 100 ms old
        let p = r.position_now(Duration::from_millis(200)).unwrap();
        assert!((0.5..0.6).contains(&p.north_m), "{p:?}");
        r.stamp_us = wall_us() - 2_000_000; // 2 s old: capped at 200 ms
        let p = r.position_now(Duration::from_millis(200)).unwrap();
        assert!((p.north_m - 1.0).abs() < 1e-9, "{p:?}");
        r.stamp_us = wall_us() + 1_000_000; // from the future: no extrapolation
        assert_eq!(r.position_now(Duration::from_millis(200)), r.position);
        assert_eq!(VehicleReport::disconnected().silence_now(), Duration::MAX);
    }
}
