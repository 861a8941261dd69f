//! Battery (PX4 `battery_status`): a LiPo pack draining with the flight state.

#![allow(deprecated)]

use super::*;

/// A simple LiPo pack.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Battery {
    pub consumed_mah: f64,
    pub current_a: f64,
    pub voltage_v: f64,
    pub remaining: f64,
}

impl Vehicle {
    pub(super) fn update_battery(&mut self, dt: f64) {
        let current = if !self.armed {
            0.4
        } else if self.landed {
            2.0
        } else {
            12.0 + 0.6 * self.vel.horizontal_norm() + 2.0 * self.vel.down_m.abs()
        };
        let capacity = self.params.get(Param::BAT1_CAPACITY).max(1.0);
        self.battery.current_a = current;
        self.battery.consumed_mah += current * dt / 3.6;
        let remaining = (1.0 - self.battery.consumed_mah / capacity).clamp(0.0, 1.0);
        self.battery.remaining = remaining;
        let cells = self.params.get(Param::BAT1_N_CELLS).max(1.0);
        let full = self.params.get(Param::BAT1_V_CHARGED);
        let empty = self.params.get(Param::BAT1_V_EMPTY);
        let internal_resistance_ohm = 0.005 * cells;
        self.battery.voltage_v =
            cells * (empty + (full - empty) * remaining) - internal_resistance_ohm * current;
    }
}
