//! Each vehicle's consumption, measured at every mission tick whether or not a mission
//! flies (an operator's flights count too): its battery percent and horizontal speed
//! while airborne (armed, `EXTENDED_SYS_STATE` in air), fitted by
//! [`skein_mission::consumption`]. A mission's energy check at start uses a vehicle's
//! measured rates once it has flown enough, the model's defaults before.

use super::super::CoordinatorState;
use skein_mission::energy::EnergyModel;

impl CoordinatorState {
    /// One sample of every vehicle (at the mission tick).
    pub(super) fn measure_consumption(&mut self) {
        let now_s = self.started.elapsed().as_secs_f64();
        for (id, v) in &self.vehicles {
            let s = v.snapshot();
            let airborne = s.armed && s.landed_state.is_airborne();
            let speed_m_s = s.velocity.north_m_s.hypot(s.velocity.east_m_s);
            self.missions
                .consumption
                .entry(id.clone())
                .or_default()
                .sample(now_s, s.battery.map(|b| b.percent), speed_m_s, airborne);
        }
    }

    /// Vehicle `id`'s measured consumption, once it has flown enough.
    pub(super) fn measured_consumption(&self, id: &str) -> Option<EnergyModel> {
        self.missions
            .consumption
            .get(id)
            .and_then(|f| f.model(&EnergyModel::default()))
    }
}
