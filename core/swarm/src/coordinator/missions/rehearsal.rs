//! What a rehearsal of a stored mission needs from the coordinator
//! (`POST /api/v1/missions/{id}/rehearse`): the plan, its groups resolved against the
//! vehicles now, and the swarm as it is (each vehicle's home, model limits, battery and
//! gimbal; the geofence in force; the separation and loop rates of the configuration).
//! The rehearsal itself runs outside the coordinator (`skein_rehearse`, on a thread of
//! its own): the coordinator only answers what it knows.

use super::{MissionError, refused};
use crate::SwarmConfig;
use crate::coordinator::CoordinatorState;
use skein_mission::resolve;
use skein_mission::swarm::{RehearsalSetup, SwarmSetup, VehicleSetup};
use skein_model::geo::GeoPoint;
use skein_model::geofence::Geofence;

impl CoordinatorState {
    /// The rehearsal of mission `id` (see the module docs).
    pub(super) fn rehearsal_setup(&self, id: &str) -> Result<RehearsalSetup, MissionError> {
        let m = self
            .missions
            .get(id)
            .ok_or_else(|| MissionError::NotFound(id.to_string()))?;
        let plan = m.plan.clone();
        let frame = self.context.frame().ok_or_else(|| {
            MissionError::Conflict("no swarm frame yet: no vehicle has reported a home".into())
        })?;
        let config = &self.context.config;
        let vehicles: Vec<VehicleSetup> = self
            .vehicles
            .iter()
            .map(|(vid, v)| {
                let s = v.snapshot();
                let home = s
                    .home
                    .or(s.position)
                    .map_or(skein_model::geo::Ned::ZERO, |p| {
                        let n = p.ned();
                        skein_model::geo::Ned::new(n.north_m, n.east_m, 0.0)
                    });
                VehicleSetup {
                    id: vid.clone(),
                    limits: config.model(&s.model).limits,
                    model: s.model,
                    home,
                    battery_percent: s.battery.map(|b| b.percent).filter(|p| p.is_finite()),
                    // Asked of the vehicle by whoever rehearses (a parameter read).
                    battery_capacity_mah: None,
                    observer: self.gimbal_slot(vid).is_some(),
                }
            })
            .collect();
        let members = skein_mission::swarm::members(&vehicles);
        let groups =
            resolve::groups(&plan, &members).map_err(|e| MissionError::Refused(refused(e)))?;
        Ok(RehearsalSetup {
            plan,
            groups,
            swarm: rehearsal_swarm(
                config,
                self.context.geofence().fence.clone(),
                frame.origin,
                vehicles,
            ),
        })
    }
}

/// The swarm of a rehearsal: `vehicles` around `origin` (the swarm frame's), inside
/// `fence`, under `config`'s separation and loop rates.
pub fn rehearsal_swarm(
    config: &SwarmConfig,
    fence: Geofence,
    origin: GeoPoint,
    vehicles: Vec<VehicleSetup>,
) -> SwarmSetup {
    SwarmSetup {
        origin,
        vehicles,
        fence,
        min_separation_m: config.min_separation_m,
        separation_margin_m: config.separation_margin_m,
        control_rate_hz: config.control_rate_hz,
        formation_rate_hz: config.formation_rate_hz,
    }
}
