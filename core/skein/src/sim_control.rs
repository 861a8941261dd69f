//! The in-process simulator as the swarm reaches it ([`skein_swarm::SimulatorControl`]):
//! the radio payload's link impairment, the intruders the simulated cameras render, and the
//! ground truth of `GET /api/v1/sim/truth`.

use serde_json::{Value, json};
use skein_model::geo::{GeoPoint, NedFrame};
use skein_model::vehicle::Velocity;
use skein_payload::SimAircraft;
use std::sync::{Arc, OnceLock};

/// The controls of a simulator started after the swarm (the simulator needs the swarm's
/// endpoints to know where to send): until it is set, nothing is simulated.
pub struct LateSimControl(pub Arc<OnceLock<skein_sim::Simulator>>);

fn geo(p: &GeoPoint) -> Value {
    json!({"lat_deg": p.lat_deg, "lon_deg": p.lon_deg, "alt_amsl_m": p.alt_amsl_m})
}

fn velocity(v: &skein_model::geo::Ned) -> Velocity {
    Velocity {
        north_m_s: v.north_m,
        east_m_s: v.east_m,
        down_m_s: v.down_m,
    }
}

impl skein_swarm::SimulatorControl for LateSimControl {
    fn set_link_quality(&self, sysid: u8, loss_fraction: f64, latency_ms: f64) -> bool {
        self.0
            .get()
            .is_some_and(|sim| sim.set_link_quality(sysid, loss_fraction, latency_ms))
    }

    fn intruders(&self, frame: &NedFrame) -> Vec<SimAircraft> {
        let Some(sim) = self.0.get() else {
            return Vec::new();
        };
        sim.intruders()
            .into_iter()
            .map(|t| {
                let ned = frame.to_ned(&t.position);
                SimAircraft {
                    id: t.id,
                    north_m: ned.north_m,
                    east_m: ned.east_m,
                    down_m: ned.down_m,
                    velocity: velocity(&t.velocity_ned_m_s),
                    span_m: t.span_m,
                }
            })
            .collect()
    }

    /// `{"vehicles": [{"id", "sysid", "position", "north_m", "east_m", "down_m", "velocity",
    /// "armed", "mode", "gnss": {"fix_type", "corrections_age_s", "error_ned_m"}}],
    /// "intruders": [{"id", "pattern", "position", "north_m", "east_m",
    /// "down_m", "velocity", "span_m", "group"}]}` (`group`: `group-N` for intruders flying
    /// together, else null); swarm-frame fields are `null` until the swarm
    /// frame is anchored.
    fn truth(&self, frame: Option<&NedFrame>) -> Value {
        let Some(sim) = self.0.get() else {
            return Value::Null;
        };
        let ned = |p: &GeoPoint| match frame {
            Some(f) => {
                let n = f.to_ned(p);
                (json!(n.north_m), json!(n.east_m), json!(n.down_m))
            }
            None => (Value::Null, Value::Null, Value::Null),
        };
        let vehicles: Vec<Value> = sim
            .stats()
            .into_iter()
            .filter(|s| !s.killed)
            .map(|s| {
                let t = s.truth;
                let (n, e, d) = ned(&t.position);
                json!({
                    "id": format!("uav-{}", t.sysid), "sysid": t.sysid,
                    "position": geo(&t.position), "north_m": n, "east_m": e, "down_m": d,
                    "velocity": velocity(&t.velocity_ned_m_s), "armed": t.armed,
                    "mode": t.mode_name, "gnss": t.gnss,
                })
            })
            .collect();
        let intruders: Vec<Value> = sim
            .intruders()
            .into_iter()
            .map(|t| {
                let (n, e, d) = ned(&t.position);
                json!({
                    "id": t.id, "pattern": t.pattern, "position": geo(&t.position),
                    "north_m": n, "east_m": e, "down_m": d,
                    "velocity": velocity(&t.velocity_ned_m_s), "span_m": t.span_m,
                    "group": t.group,
                })
            })
            .collect();
        json!({ "vehicles": vehicles, "intruders": intruders })
    }
}
