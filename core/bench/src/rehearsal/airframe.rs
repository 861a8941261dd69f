//! The aircraft a rehearsal flies.
//!
//! - [`AirframeKind::Px4`]: skein's PX4-faithful simulated multicopter
//!   ([`skein_sim::VirtualVehicle`]: PX4 v1.16's position-control cascade on SIH-like
//!   physics, checked against PX4 SITL recordings), flown through its own MAVLink
//!   handling, taking off in OFFBOARD like any vehicle, and measured from its own
//!   LOCAL_POSITION_NED as skein measures it. This is what `skein bench formation`
//!   reports.
//! - [`AirframeKind::PointMass`]: a point mass with a PX4-like position and velocity
//!   loop (position P `MPC_XY_P` 0.95 / `MPC_Z_P` 1.0 plus velocity feed-forward,
//!   velocity setpoint smoothed at `MPC_ACC_HOR` 3 m/s², velocity P 1.8, no drag):
//!   kinder than PX4 and a thousand times cheaper, for the seeded sweeps of formation
//!   changes whose subject is the separation logic, not the tracking.

use skein_model::geo::Ned;
use skein_sim::client;
use skein_sim::{SimConfig, VirtualVehicle};

/// Position P gain, horizontal (PX4 `MPC_XY_P`), 1/s.
const POS_P_XY: f64 = 0.95;
/// Position P gain, vertical (PX4 `MPC_Z_P`), 1/s.
const POS_P_Z: f64 = 1.0;
/// Velocity P gain, 1/s.
const VEL_P: f64 = 1.8;
/// Acceleration of the velocity setpoint (PX4 `MPC_ACC_HOR`), m/s².
const ACC_HOR_M_S2: f64 = 3.0;
/// Largest acceleration the point mass delivers, m/s².
const ACC_MAX_M_S2: f64 = 5.0;
/// How long a simulated vehicle takes off and settles before the rehearsal starts, s.
const TAKEOFF_S: f64 = 20.0;
/// Longest a measured position is moved on by the estimate's age, s (as skein does).
const EXTRAPOLATION_S: f64 = 0.2;

/// Which aircraft a rehearsal flies (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AirframeKind {
    /// The point mass.
    #[default]
    PointMass,
    /// The PX4-faithful simulated multicopter.
    Px4 {
        /// PX4's hover wander (seeded estimator noise), as `skein sim --estimator-noise`.
        estimator_noise: bool,
    },
}

/// One aircraft.
#[derive(Debug)]
pub(super) enum Airframe {
    PointMass(PointMass),
    Px4(Box<Px4Airframe>),
}

/// The point mass's state (rehearsal frame, NED).
#[derive(Debug, Clone)]
pub(super) struct PointMass {
    position: Ned,
    velocity: Ned,
    velocity_sp: Ned,
}

/// A simulated PX4 multicopter: its local frame is the rehearsal frame moved by `offset`
/// (where it took off).
pub(super) struct Px4Airframe {
    vehicle: VirtualVehicle,
    offset: Ned,
    /// Last LOCAL_POSITION_NED: (vehicle time s, position, velocity), local frame.
    estimate: (f64, Ned, Ned),
    next_heartbeat_s: f64,
}

impl std::fmt::Debug for Px4Airframe {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Px4Airframe")
            .field("offset", &self.offset)
            .finish_non_exhaustive()
    }
}

impl Airframe {
    /// An aircraft of `kind` hovering at `at` (rehearsal frame); `seed` seeds a simulated
    /// vehicle's noise.
    ///
    /// # Panics
    /// When a simulated vehicle fails to take off (a simulator bug, not a rehearsal
    /// outcome).
    pub(super) fn new(kind: AirframeKind, at: Ned, seed: u64) -> Self {
        match kind {
            AirframeKind::PointMass => Airframe::PointMass(PointMass {
                position: at,
                velocity: Ned::ZERO,
                velocity_sp: Ned::ZERO,
            }),
            AirframeKind::Px4 { estimator_noise } => {
                let cfg = SimConfig {
                    estimator_noise,
                    seed,
                    // A lost vehicle holds where it is (PX4's offboard-loss action Hold).
                    params: vec![("COM_OBL_RC_ACT".into(), 5.0)],
                    ..SimConfig::default()
                };
                let mut vehicle = VirtualVehicle::new(&cfg);
                assert!(
                    vehicle.take_off_offboard(-at.down_m, TAKEOFF_S),
                    "simulated vehicle {seed} did not take off"
                );
                let offset = Ned::new(at.north_m, at.east_m, 0.0);
                let p = vehicle.true_position_ned_m();
                let next_heartbeat_s = vehicle.time_s() + 1.0;
                Airframe::Px4(Box::new(Px4Airframe {
                    estimate: (vehicle.time_s(), Ned::new(p[0], p[1], p[2]), Ned::ZERO),
                    vehicle,
                    offset,
                    next_heartbeat_s,
                }))
            }
        }
    }

    /// True for the simulated PX4, whose lag the slot correction cancels (as the
    /// Vehicle actor does for a member flying its slot).
    pub(super) fn is_px4(&self) -> bool {
        matches!(self, Airframe::Px4(_))
    }

    /// Where skein measures it: position and velocity (rehearsal frame).
    pub(super) fn measured(&self) -> (Ned, Ned) {
        match self {
            Airframe::PointMass(m) => (m.position, m.velocity),
            Airframe::Px4(p) => {
                let (at, pos, vel) = p.estimate;
                let age = (p.vehicle.time_s() - at).clamp(0.0, EXTRAPOLATION_S);
                (pos + vel * age + p.offset, vel)
            }
        }
    }

    /// Where it really is (rehearsal frame).
    pub(super) fn truth(&self) -> Ned {
        match self {
            Airframe::PointMass(m) => m.position,
            Airframe::Px4(p) => {
                let t = p.vehicle.true_position_ned_m();
                Ned::new(t[0], t[1], t[2]) + p.offset
            }
        }
    }

    /// Flies `dt_s` seconds towards `setpoint` (position, velocity and acceleration
    /// feed-forward, rehearsal frame); `None` sends nothing (a lost link: the simulated
    /// PX4 fails safe and holds; the point mass holds where it was sent last).
    pub(super) fn fly(&mut self, setpoint: Option<(Ned, Ned, Ned)>, dt_s: f64) {
        match self {
            Airframe::PointMass(m) => {
                if let Some((sp, ff, _)) = setpoint {
                    m.fly(sp, ff, dt_s);
                } else {
                    m.fly(m.position, Ned::ZERO, dt_s);
                }
            }
            Airframe::Px4(p) => p.fly(setpoint, dt_s),
        }
    }
}

impl PointMass {
    fn fly(&mut self, sp: Ned, ff: Ned, dt: f64) {
        let e = sp - self.position;
        let mut vel_sp = Ned::new(
            POS_P_XY * e.north_m,
            POS_P_XY * e.east_m,
            POS_P_Z * e.down_m,
        ) + ff;
        let h = vel_sp.horizontal_norm();
        if h > 12.0 {
            vel_sp.north_m *= 12.0 / h;
            vel_sp.east_m *= 12.0 / h;
        }
        let dv = (vel_sp - self.velocity_sp).clamped_norm(ACC_HOR_M_S2 * dt);
        self.velocity_sp = self.velocity_sp + dv;
        let acc = ((self.velocity_sp - self.velocity) * VEL_P + dv * (1.0 / dt))
            .clamped_norm(ACC_MAX_M_S2);
        self.velocity = self.velocity + acc * dt;
        self.position = self.position + self.velocity * dt;
    }
}

impl Px4Airframe {
    fn fly(&mut self, setpoint: Option<(Ned, Ned, Ned)>, dt_s: f64) {
        let v = &mut self.vehicle;
        if let Some((p, vel, acc)) = setpoint {
            let yaw = if vel.horizontal_norm() > 0.5 {
                vel.east_m.atan2(vel.north_m)
            } else {
                0.0
            };
            v.send(&client::setpoint(
                client::POSITION_VELOCITY_ACCELERATION_YAW,
                p - self.offset,
                vel,
                acc,
                yaw,
            ));
        }
        if v.time_s() >= self.next_heartbeat_s {
            v.send(&client::gcs_heartbeat());
            self.next_heartbeat_s += 1.0;
        }
        let sent = v.run_until(v.time_s() + dt_s);
        if let Some(e) = client::last_estimate(&sent) {
            self.estimate = e;
        }
    }
}
