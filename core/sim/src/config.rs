//! Simulator configuration: vehicles and their UDP endpoints, spawn geometry, environment
//! (wind, GPS noise, the GNSS receiver's RTK timing and error model), telemetry profile
//! and parameter overrides.

use crate::vehicle::gnss::RtkTiming;
use serde::{Deserialize, Serialize};
use skein_model::geo::GeoPoint;
use std::net::{IpAddr, SocketAddr};

/// PX4 SITL's default home (Zurich, as in PX4's `PX4_HOME_LAT/LON/ALT` defaults).
pub const PX4_SITL_HOME: GeoPoint = GeoPoint::new(47.397_742, 8.545_594, 488.0);
/// First UDP port a PX4 SITL instance listens on for its onboard/API link (instance i: +i).
pub const PX4_LISTEN_BASE_PORT: u16 = 14580;
/// First UDP port a PX4 SITL instance sends its onboard/API link to (instance i: +i).
pub const PX4_TARGET_BASE_PORT: u16 = 14540;
/// PX4 SITL instances from this index on all send to `target base + 9` (14549).
pub const PX4_SHARED_TARGET_FROM_INSTANCE: usize = 10;

/// With more than 255 vehicles, system ids repeat every this many vehicles: ids 1..=250,
/// leaving 251..=255 to ground stations (skein itself is 255).
pub const MAX_SHARED_SYSIDS: usize = 250;

/// System id of vehicle `index` (0-based) in a run of `n`: `index + 1` up to 255 vehicles
/// (PX4 SITL's convention), `index % 250 + 1` beyond (identity is then (endpoint, sysid):
/// each vehicle needs its own port pair).
pub fn instance_sysid(index: usize, n: usize) -> u8 {
    if n <= 255 {
        (index + 1).min(255) as u8
    } else {
        (index % MAX_SHARED_SYSIDS + 1) as u8
    }
}

/// One simulated vehicle's identity and UDP endpoints.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SimVehicleConfig {
    /// MAVLink system id (1..=255); the autopilot component id is always 1.
    pub sysid: u8,
    /// Local address the vehicle's UDP socket binds (port 0 picks an ephemeral port).
    pub bind: SocketAddr,
    /// Where the vehicle sends until it has heard from a client (then it locks onto the
    /// first sender, as PX4 does).
    pub target: SocketAddr,
}

/// Which telemetry set each vehicle streams by default.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum TelemetryProfile {
    /// PX4's onboard-mode set at PX4's rates (about 400 messages/s per vehicle); the
    /// simulator ticks at 100 Hz.
    #[default]
    Px4Onboard,
    /// A reduced set for large swarms (about 30 messages/s per vehicle: positions at 10 Hz,
    /// attitude at 5 Hz, status at 1 Hz); the simulator ticks at 50 Hz.
    Swarm,
}

impl TelemetryProfile {
    /// Simulation tick rate for this profile, Hz (physics step and telemetry scheduling).
    pub fn tick_rate_hz(self) -> f64 {
        match self {
            TelemetryProfile::Px4Onboard => 100.0,
            TelemetryProfile::Swarm => 50.0,
        }
    }
}

/// Wind acting on every vehicle: a constant air-mass velocity plus random gusts.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct WindConfig {
    /// Air-mass velocity towards north, m/s.
    pub north_m_s: f64,
    /// Air-mass velocity towards east, m/s.
    pub east_m_s: f64,
    /// Standard deviation of the gust component (per horizontal axis, first-order
    /// Gauss-Markov with a 2 s time constant), m/s.
    pub gust_m_s: f64,
}

impl WindConfig {
    /// Wind of `speed_m_s` blowing *from* `from_deg` (meteorological convention: 270 =
    /// westerly wind, air moving east), with gusts of `gust_m_s`.
    pub fn from_direction(speed_m_s: f64, from_deg: f64, gust_m_s: f64) -> Self {
        let towards = (from_deg + 180.0).to_radians();
        WindConfig {
            north_m_s: speed_m_s * towards.cos(),
            east_m_s: speed_m_s * towards.sin(),
            gust_m_s,
        }
    }
}

/// Configuration of a whole simulator run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SimConfig {
    /// Home of the first vehicle; the others spawn on a grid around it.
    pub home: GeoPoint,
    /// Distance between neighbouring spawn points on the grid, metres. The grid has
    /// `ceil(sqrt(n))` columns going east and rows going north from `home`.
    pub spacing_m: f64,
    /// A fixed grid: this many columns, each vehicle at grid index `sysid - 1`, so that
    /// simulators of several processes (`skein agent --first-sysid K`) never spawn two
    /// vehicles on one point; `None` = the `ceil(sqrt(n))` grid in configuration order.
    #[serde(default)]
    pub grid_columns: Option<usize>,
    /// Seed of every random process (gusts, GPS noise); same seed + same inputs → same
    /// physics.
    pub seed: u64,
    /// Wind.
    pub wind: WindConfig,
    /// Standard deviation of the GPS noise on reported positions, metres (0 = none).
    pub gps_noise_m: f64,
    /// Seconds after boot until the simulated EKF has a 3D fix and a global position
    /// (before it: no GLOBAL_POSITION_INT / HOME_POSITION, arming denied).
    pub ekf_fix_delay_s: f64,
    /// Telemetry profile.
    pub telemetry: TelemetryProfile,
    /// Minimum age of the setpoint stream (at > 2 Hz) before OFFBOARD is accepted, s.
    /// 0 (default) is PX4 v1.16: a single setpoint younger than `COM_OF_LOSS_T` is enough
    /// (`offboardCheck.cpp`; MAVSDK's documented start relies on it). 1.0 enforces the
    /// "> 1 s at > 2 Hz" advice of PX4's documentation, stricter than PX4.
    pub offboard_min_stream_s: f64,
    /// Seeded estimator noise reproducing PX4 SIH's hover wander (about 0.2 m and
    /// 0.2 m/s); the seed is [`SimConfig::seed`]. Off by default.
    pub estimator_noise: bool,
    /// The GNSS receiver's RTK timing: how long corrections take to give RTK float and
    /// fixed, how long fixed and float outlive them (see `docs/simulator.md`, "GNSS and
    /// RTK").
    #[serde(default)]
    pub rtk: RtkTiming,
    /// The GNSS receiver's position error (`--gnss-wander`): metres of slow wander with a
    /// 3D fix, decimetres in RTK float, centimetres in RTK fixed, seeded by
    /// [`SimConfig::seed`]; PX4's EKF follows it, so the estimate carries it and a
    /// hovering vehicle's true position wanders by it. Off by default: positions are
    /// then exact (the fix type and the reported accuracy still follow the RTK state).
    #[serde(default)]
    pub gnss_wander: bool,
    /// Parameter overrides applied to every vehicle at boot (`("MIS_TAKEOFF_ALT", 5.0)`);
    /// integer parameters are rounded.
    pub params: Vec<(String, f64)>,
    /// The vehicles.
    pub vehicles: Vec<SimVehicleConfig>,
    /// MAVLink 2 signing key installed on every vehicle at boot (PX4's key file); with
    /// `MAV_SIGN_CFG` non-zero they then require signed frames (see the `signing` module
    /// docs). `skein sim --signing-key-file` sets both. Never serialised (a secret).
    #[serde(skip)]
    pub signing_key: Option<skein_mavlink::signing::SigningKey>,
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig {
            home: PX4_SITL_HOME,
            spacing_m: 3.0,
            grid_columns: None,
            seed: 0,
            wind: WindConfig::default(),
            gps_noise_m: 0.0,
            ekf_fix_delay_s: 1.0,
            telemetry: TelemetryProfile::Px4Onboard,
            offboard_min_stream_s: 0.0,
            estimator_noise: false,
            rtk: RtkTiming::default(),
            gnss_wander: false,
            params: Vec::new(),
            vehicles: Vec::new(),
            signing_key: None,
        }
    }
}

impl SimConfig {
    /// PX4 SITL convention: instance i has sysid i+1, binds `bind_ip:14580+i`, sends to
    /// `target_ip:14540+i` (instances >= 10 all send to `target_ip:14549`, as PX4 does).
    pub fn px4_sitl(n: usize, bind_ip: IpAddr, target_ip: IpAddr) -> Self {
        Self::px4_sitl_ports(
            n,
            bind_ip,
            target_ip,
            PX4_LISTEN_BASE_PORT,
            PX4_TARGET_BASE_PORT,
        )
    }

    /// [`SimConfig::px4_sitl`] with other base ports (instance i binds `listen_base + i`
    /// and sends to `target_base + min(i, 9)`). A `listen_base` of 0 binds every vehicle
    /// to an ephemeral port.
    ///
    /// # Panics
    /// When `n` exceeds 255 (MAVLink system ids are one byte).
    pub fn px4_sitl_ports(
        n: usize,
        bind_ip: IpAddr,
        target_ip: IpAddr,
        listen_base: u16,
        target_base: u16,
    ) -> Self {
        assert!(n <= 255, "at most 255 vehicles (MAVLink system ids)");
        let vehicles = (0..n)
            .map(|i| {
                let listen = if listen_base == 0 {
                    0
                } else {
                    listen_base.saturating_add(i as u16)
                };
                let target_offset = i.min(PX4_SHARED_TARGET_FROM_INSTANCE - 1) as u16;
                SimVehicleConfig {
                    sysid: (i + 1) as u8,
                    bind: SocketAddr::new(bind_ip, listen),
                    target: SocketAddr::new(target_ip, target_base.saturating_add(target_offset)),
                }
            })
            .collect();
        SimConfig {
            vehicles,
            ..SimConfig::default()
        }
    }

    /// One port pair per vehicle, for any number of vehicles: vehicle i (sysid
    /// [`instance_sysid`]`(i, n)`) binds `bind_ip:listen_base + i` (any free port when
    /// `listen_base` is 0) and sends to `target_ip:target_base + i`.
    ///
    /// # Errors
    /// No vehicles, a target base of 0, or ports running past 65535.
    pub fn per_vehicle_ports(
        n: usize,
        bind_ip: IpAddr,
        target_ip: IpAddr,
        listen_base: u16,
        target_base: u16,
    ) -> Result<Self, String> {
        Self::grouped_target_ports(n, bind_ip, target_ip, listen_base, target_base, 1)
    }

    /// As [`SimConfig::per_vehicle_ports`], but `per_port` vehicles share each target
    /// port: vehicle i sends to `target_ip:target_base + i / per_port`, as PX4 instances
    /// from the 10th on share one port (a client demultiplexes them by sysid, which
    /// [`instance_sysid`] keeps unique within a group of at most 250).
    ///
    /// # Errors
    /// As [`SimConfig::per_vehicle_ports`], and a `per_port` of 0 or over 250.
    pub fn grouped_target_ports(
        n: usize,
        bind_ip: IpAddr,
        target_ip: IpAddr,
        listen_base: u16,
        target_base: u16,
        per_port: usize,
    ) -> Result<Self, String> {
        if n == 0 {
            return Err("no vehicles".into());
        }
        if target_base == 0 {
            return Err("per-vehicle targets need a target base port".into());
        }
        if !(1..=MAX_SHARED_SYSIDS).contains(&per_port) {
            return Err(format!(
                "{per_port} vehicles per target port: 1 to {MAX_SHARED_SYSIDS} (their sysids \
                 must differ)"
            ));
        }
        let port = |base: u16, i: usize, what: &str| -> Result<u16, String> {
            u16::try_from(usize::from(base) + i)
                .map_err(|_| format!("{what} base port {base} + {n} vehicles runs past port 65535"))
        };
        let vehicles = (0..n)
            .map(|i| {
                let listen = if listen_base == 0 {
                    0
                } else {
                    port(listen_base, i, "listen")?
                };
                Ok(SimVehicleConfig {
                    sysid: instance_sysid(i, n),
                    bind: SocketAddr::new(bind_ip, listen),
                    target: SocketAddr::new(target_ip, port(target_base, i / per_port, "target")?),
                })
            })
            .collect::<Result<Vec<_>, String>>()?;
        Ok(SimConfig {
            vehicles,
            ..SimConfig::default()
        })
    }

    /// Explicit endpoints (tests and `skein up --sim` use ephemeral ports: bind port 0 is
    /// allowed).
    pub fn with_vehicles(vehicles: Vec<SimVehicleConfig>) -> Self {
        SimConfig {
            vehicles,
            ..SimConfig::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::Ipv4Addr;

    #[test]
    fn px4_sitl_ports_follow_the_px4_convention() {
        let ip = IpAddr::V4(Ipv4Addr::LOCALHOST);
        let cfg = SimConfig::px4_sitl(12, ip, ip);
        assert_eq!(cfg.vehicles[0].sysid, 1);
        assert_eq!(cfg.vehicles[0].bind.port(), 14580);
        assert_eq!(cfg.vehicles[0].target.port(), 14540);
        assert_eq!(cfg.vehicles[9].target.port(), 14549);
        assert_eq!(cfg.vehicles[10].bind.port(), 14590);
        assert_eq!(cfg.vehicles[10].target.port(), 14549);
        assert_eq!(cfg.vehicles[11].sysid, 12);
    }

    #[test]
    fn per_vehicle_ports_repeat_sysids_beyond_255() {
        let ip = IpAddr::V4(Ipv4Addr::LOCALHOST);
        let cfg = SimConfig::per_vehicle_ports(1000, ip, ip, 0, 20_000).expect("config");
        assert_eq!(cfg.vehicles.len(), 1000);
        assert_eq!(cfg.vehicles[0].sysid, 1);
        assert_eq!(cfg.vehicles[249].sysid, 250);
        assert_eq!(cfg.vehicles[250].sysid, 1);
        assert_eq!(cfg.vehicles[999].sysid, 250);
        assert_eq!(cfg.vehicles[999].target.port(), 20_999);
        assert_eq!(cfg.vehicles[999].bind.port(), 0);
        let pairs: std::collections::HashSet<_> =
            cfg.vehicles.iter().map(|v| (v.sysid, v.target)).collect();
        assert_eq!(pairs.len(), 1000, "(sysid, target) unique");
        // Up to 255 vehicles the PX4 SITL numbering holds.
        assert_eq!(instance_sysid(254, 255), 255);
        assert!(SimConfig::per_vehicle_ports(1000, ip, ip, 0, 65_000).is_err());
        assert!(SimConfig::per_vehicle_ports(10, ip, ip, 65_530, 20_000).is_err());
        assert!(SimConfig::per_vehicle_ports(10, ip, ip, 0, 0).is_err());
    }

    #[test]
    fn grouped_target_ports_share_a_port_per_group_with_distinct_sysids() {
        let ip = IpAddr::V4(Ipv4Addr::LOCALHOST);
        let cfg = SimConfig::grouped_target_ports(1000, ip, ip, 0, 20_000, 250).expect("config");
        assert_eq!(cfg.vehicles[0].target.port(), 20_000);
        assert_eq!(cfg.vehicles[249].target.port(), 20_000);
        assert_eq!(cfg.vehicles[250].target.port(), 20_001);
        assert_eq!(cfg.vehicles[999].target.port(), 20_003);
        let pairs: std::collections::HashSet<_> =
            cfg.vehicles.iter().map(|v| (v.sysid, v.target)).collect();
        assert_eq!(pairs.len(), 1000, "(sysid, target) unique");
        for bad in [0, 251] {
            let err = SimConfig::grouped_target_ports(10, ip, ip, 0, 20_000, bad).unwrap_err();
            assert!(err.contains("vehicles per target port"), "{err}");
        }
    }

    #[test]
    fn wind_direction_is_meteorological() {
        let w = WindConfig::from_direction(5.0, 270.0, 0.0);
        assert!((w.east_m_s - 5.0).abs() < 1e-9 && w.north_m_s.abs() < 1e-9);
    }
}
