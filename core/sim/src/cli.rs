//! `skein sim`: command-line arguments, the run loop, and the line-based TCP stats socket.
//!
//! Stats protocol: a client connects to `--stats ADDR`, sends one command per line and
//! gets one line of JSON back per command (the connection stays open for more):
//! - `stats` → `{"vehicles":[SimVehicleStats…]}`
//! - `reset` → `{"ok":true}` (clears the counters)
//! - `silence <sysid> <ms>` → `{"ok":true}` (cuts the link for that long; 0 restores it)
//! - `reboot <sysid>`, `kill <sysid>` → `{"ok":true}`
//! - `link <sysid|all> <loss 0..1> <latency_ms>` → `{"ok":true}` (simulated link quality,
//!   see [`Simulator::set_link_quality`]; `link 3 0 0` restores a perfect link)
//! - `mission_fault <sysid> <error|no_space|denied|off>` → `{"ok":true}`: every fence and
//!   rally upload to that vehicle ends in `MAV_MISSION_ERROR` / `_NO_SPACE` / `_DENIED`
//!   (see [`Simulator::set_mission_fault`]); `off` clears it
//! - `summary` → [`crate::SimSummary`]: totals over every vehicle and the histogram of
//!   setpoint intervals of all vehicles (what `skein bench` reads)
//! - `vehicles` → `{"vehicles":[SimVehicleInfo…]}`
//! - `intruders` → `{"intruders":[IntruderTruth…]}`: ground truth of the non-cooperative
//!   aircraft (`--intruders M`, see [`crate::intruders`])
//! - `intruders restart` → `{"ok":true}`: their paths start again from their beginning
//!   now ([`Simulator::restart_intruders`]); an error when there are none
//! - `intruders leave` → `{"ok":true}`: they leave the world (no camera sees one) until
//!   the next restart ([`Simulator::intruders_leave`])
//!
//! Commands taking a sysid act on the first vehicle with it (sysids repeat beyond 255
//! vehicles).
//!
//! Errors are `{"error":"…"}`.

use crate::{SimConfig, Simulator, TelemetryProfile, WindConfig};
use skein_model::geo::GeoPoint;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::time::Duration;
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpListener;

/// Arguments of `skein sim`.
#[derive(clap::Args, Debug, Clone)]
pub struct SimArgs {
    /// Number of vehicles (sysid i+1; beyond 255 vehicles sysids repeat, i % 250 + 1, and
    /// --per-vehicle-targets is required).
    #[arg(long, default_value_t = 1)]
    pub vehicles: usize,
    /// Vehicle i sends to target base port + i, for every i (instead of PX4's shared
    /// port + 9 from instance 10 on): one port pair per vehicle, any number of vehicles.
    #[arg(long)]
    pub per_vehicle_targets: bool,
    /// With --per-vehicle-targets: this many vehicles share each target port (vehicle i
    /// sends to target base port + i / K), as PX4's instances from the 10th on share
    /// one; 1 to 250.
    #[arg(long, default_value_t = 1, requires = "per_vehicle_targets")]
    pub vehicles_per_target_port: usize,
    /// Address the vehicles' sockets bind to.
    #[arg(long, default_value_t = IpAddr::V4(Ipv4Addr::LOCALHOST))]
    pub bind_ip: IpAddr,
    /// Address the vehicles send to until a client talks to them.
    #[arg(long, default_value_t = IpAddr::V4(Ipv4Addr::LOCALHOST))]
    pub target_ip: IpAddr,
    /// Vehicle i binds this port + i (0: ephemeral ports).
    #[arg(long, default_value_t = crate::PX4_LISTEN_BASE_PORT)]
    pub listen_base_port: u16,
    /// Vehicle i sends to this port + i (instances >= 10 share port + 9, as PX4 does,
    /// unless --per-vehicle-targets).
    #[arg(long, default_value_t = crate::PX4_TARGET_BASE_PORT)]
    pub target_base_port: u16,
    /// Home of the first vehicle: LAT,LON,ALT (degrees, degrees, metres AMSL).
    #[arg(long, value_parser = parse_home, default_value = "47.397742,8.545594,488.0")]
    pub home: GeoPoint,
    /// Distance between spawn points on the grid, metres.
    #[arg(long, default_value_t = 3.0)]
    pub spacing_m: f64,
    /// Seed of the random processes (gusts, GPS noise).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Mean wind speed, m/s.
    #[arg(long, default_value_t = 0.0)]
    pub wind_m_s: f64,
    /// Direction the wind blows from, degrees (meteorological: 270 = from the west).
    #[arg(long, default_value_t = 270.0)]
    pub wind_from_deg: f64,
    /// Gust standard deviation, m/s.
    #[arg(long, default_value_t = 0.0)]
    pub gust_m_s: f64,
    /// GPS noise standard deviation on reported positions, metres.
    #[arg(long, default_value_t = 0.0)]
    pub gps_noise_m: f64,
    /// Seconds after boot until the simulated EKF has a global position.
    #[arg(long, default_value_t = 1.0)]
    pub ekf_fix_delay_s: f64,
    /// Telemetry profile: `px4` (PX4's onboard rates) or `swarm` (reduced, for big swarms).
    #[arg(long, value_parser = parse_profile, default_value = "px4")]
    pub profile: TelemetryProfile,
    /// Minimum setpoint-stream age before OFFBOARD is accepted, s (0 = PX4 v1.16: a single
    /// setpoint younger than COM_OF_LOSS_T is enough, the default; 1 = the stricter
    /// "> 1 s at > 2 Hz" advice of PX4's documentation).
    #[arg(long, default_value_t = 0.0)]
    pub offboard_min_stream_s: f64,
    /// Seeded estimator noise (PX4 SIH's hover wander, about 0.2 m / 0.2 m/s; seed from
    /// --seed). Off by default.
    #[arg(long)]
    pub estimator_noise: bool,
    /// The GNSS receiver's position error: metres of slow wander with a 3D fix,
    /// decimetres in RTK float, centimetres in RTK fixed (seed from --seed); PX4's EKF
    /// follows it, so a hovering vehicle's true position wanders by it. Off by default:
    /// exact positions, the fix type and accuracy still following the RTK corrections.
    #[arg(long)]
    pub gnss_wander: bool,
    /// Parameter override for every vehicle, NAME=VALUE (repeatable).
    #[arg(long = "param", value_parser = parse_param)]
    pub params: Vec<(String, f64)>,
    /// MAVLink 2 signing: install the key of this file (64 hex characters, from `skein key
    /// create`) on every vehicle and require signed frames (PX4 `MAV_SIGN_CFG` 2), unless
    /// `--param MAV_SIGN_CFG=0` says otherwise. Unsigned frames are then counted and
    /// dropped; `SETUP_SIGNING` signed with the key replaces it.
    #[arg(long)]
    pub signing_key_file: Option<std::path::PathBuf>,
    /// Open the stats socket on this TCP address (port 0 allowed; the bound address is
    /// printed).
    #[arg(long)]
    pub stats: Option<SocketAddr>,
    /// Intruders (non-cooperative aircraft).
    #[command(flatten)]
    pub intruders: crate::intruders::IntruderArgs,
}

fn parse_home(s: &str) -> Result<GeoPoint, String> {
    let parts: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>().map_err(|e| format!("{p:?}: {e}")))
        .collect::<Result<_, _>>()?;
    match parts.as_slice() {
        [lat, lon, alt] if lat.abs() <= 90.0 && lon.abs() <= 180.0 && alt.is_finite() => {
            Ok(GeoPoint::new(*lat, *lon, *alt))
        }
        _ => Err("expected LAT,LON,ALT with |LAT| <= 90 and |LON| <= 180".into()),
    }
}

fn parse_profile(s: &str) -> Result<TelemetryProfile, String> {
    match s.to_ascii_lowercase().as_str() {
        "px4" | "px4-onboard" | "onboard" => Ok(TelemetryProfile::Px4Onboard),
        "swarm" => Ok(TelemetryProfile::Swarm),
        _ => Err("expected px4 or swarm".into()),
    }
}

fn parse_param(s: &str) -> Result<(String, f64), String> {
    let (name, value) = s.split_once('=').ok_or("expected NAME=VALUE")?;
    let value: f64 = value
        .trim()
        .parse()
        .map_err(|e| format!("{value:?}: {e}"))?;
    if crate::px4_params::Params::index_of(name.trim()).is_none() {
        return Err(format!("unknown parameter {name:?}"));
    }
    Ok((name.trim().to_string(), value))
}

impl SimArgs {
    /// The simulator configuration these arguments describe.
    pub fn config(&self) -> Result<SimConfig, String> {
        if self.vehicles == 0 {
            return Err("--vehicles must be at least 1".into());
        }
        let mut cfg = if self.per_vehicle_targets {
            SimConfig::grouped_target_ports(
                self.vehicles,
                self.bind_ip,
                self.target_ip,
                self.listen_base_port,
                self.target_base_port,
                self.vehicles_per_target_port,
            )?
        } else if self.vehicles > 255 {
            return Err(format!(
                "--vehicles {}: more than 255 vehicles repeat system ids, so each needs its own \
                 target port: add --per-vehicle-targets",
                self.vehicles
            ));
        } else {
            SimConfig::px4_sitl_ports(
                self.vehicles,
                self.bind_ip,
                self.target_ip,
                self.listen_base_port,
                self.target_base_port,
            )
        };
        cfg.home = self.home;
        cfg.spacing_m = self.spacing_m;
        cfg.seed = self.seed;
        cfg.wind = WindConfig::from_direction(self.wind_m_s, self.wind_from_deg, self.gust_m_s);
        cfg.gps_noise_m = self.gps_noise_m;
        cfg.ekf_fix_delay_s = self.ekf_fix_delay_s;
        cfg.telemetry = self.profile;
        cfg.offboard_min_stream_s = self.offboard_min_stream_s;
        cfg.estimator_noise = self.estimator_noise;
        cfg.gnss_wander = self.gnss_wander;
        cfg.params = self.params.clone();
        if let Some(path) = &self.signing_key_file {
            cfg.signing_key =
                Some(skein_mavlink::signing::SigningKey::load(path).map_err(|e| e.to_string())?);
            if !cfg.params.iter().any(|(n, _)| n == "MAV_SIGN_CFG") {
                cfg.params.push(("MAV_SIGN_CFG".into(), 2.0));
            }
        }
        Ok(cfg)
    }
}

/// Runs one stats-socket command against `sim`; returns one line of JSON (no newline).
pub fn stats_command(sim: &Simulator, line: &str) -> String {
    let mut words = line.split_whitespace();
    let cmd = words.next().unwrap_or("");
    let sysid = |w: Option<&str>| -> Result<u8, String> {
        w.ok_or("missing sysid")?
            .parse::<u8>()
            .map_err(|e| format!("bad sysid: {e}"))
    };
    let result: Result<serde_json::Value, String> = match cmd {
        "stats" => Ok(serde_json::json!({ "vehicles": sim.stats() })),
        "vehicles" => Ok(serde_json::json!({ "vehicles": sim.vehicles() })),
        "reset" => {
            sim.reset_stats();
            Ok(serde_json::json!({ "ok": true }))
        }
        "silence" => sysid(words.next()).and_then(|id| {
            let ms: u64 = words
                .next()
                .ok_or("missing duration (ms)")?
                .parse()
                .map_err(|e| format!("bad duration: {e}"))?;
            if ms == 0 {
                sim.set_silent(id, false);
            } else {
                sim.silence_for(id, Duration::from_millis(ms));
            }
            Ok(serde_json::json!({ "ok": true }))
        }),
        "reboot" => sysid(words.next()).map(|id| {
            sim.reboot(id);
            serde_json::json!({ "ok": true })
        }),
        "kill" => sysid(words.next()).map(|id| {
            sim.kill(id);
            serde_json::json!({ "ok": true })
        }),
        "summary" => serde_json::to_value(sim.summary()).map_err(|e| e.to_string()),
        "intruders" => match words.next() {
            None => Ok(serde_json::json!({ "intruders": sim.intruders() })),
            Some("restart") => sim
                .restart_intruders()
                .map(|()| serde_json::json!({ "ok": true })),
            Some("leave") => sim
                .intruders_leave()
                .map(|()| serde_json::json!({ "ok": true })),
            Some(other) => Err(format!(
                "intruders: nothing, restart or leave, got {other:?}"
            )),
        },
        "link" => link_command(sim, &mut words),
        "mission_fault" => sysid(words.next()).and_then(|id| {
            use skein_mavlink::dialect::MavMissionResult as R;
            let fault = match words.next() {
                Some("error") => Some(R::MAV_MISSION_ERROR),
                Some("no_space") => Some(R::MAV_MISSION_NO_SPACE),
                Some("denied") => Some(R::MAV_MISSION_DENIED),
                Some("off") => None,
                other => {
                    return Err(format!(
                        "mission_fault: error, no_space, denied or off, got {other:?}"
                    ));
                }
            };
            if sim.set_mission_fault(id, fault) {
                Ok(serde_json::json!({ "ok": true }))
            } else {
                Err(format!("no vehicle with sysid {id}"))
            }
        }),
        "" => Err("empty command".into()),
        other => Err(format!("unknown command {other:?}")),
    };
    match result {
        Ok(v) => v.to_string(),
        Err(e) => serde_json::json!({ "error": e }).to_string(),
    }
}

/// `link <sysid|all> <loss> <latency_ms>`.
fn link_command<'a>(
    sim: &Simulator,
    words: &mut impl Iterator<Item = &'a str>,
) -> Result<serde_json::Value, String> {
    let who = words.next().ok_or("missing sysid (or `all`)")?;
    let loss: f64 = words
        .next()
        .ok_or("missing loss fraction (0..1)")?
        .parse()
        .map_err(|e| format!("bad loss fraction: {e}"))?;
    let latency_ms: f64 = words
        .next()
        .ok_or("missing latency (ms)")?
        .parse()
        .map_err(|e| format!("bad latency: {e}"))?;
    if !(0.0..=1.0).contains(&loss) {
        return Err(format!("loss fraction {loss} outside 0..1"));
    }
    if !(latency_ms.is_finite() && latency_ms >= 0.0) {
        return Err(format!("latency {latency_ms} ms must be >= 0"));
    }
    if who == "all" {
        sim.set_link_quality_all(loss, latency_ms);
    } else {
        let id = who.parse::<u8>().map_err(|e| format!("bad sysid: {e}"))?;
        if !sim.set_link_quality(id, loss, latency_ms) {
            return Err(format!("no vehicle with sysid {id}"));
        }
    }
    Ok(serde_json::json!({ "ok": true }))
}

/// Serves the stats socket on `listener` until the task is dropped.
pub async fn serve_stats(sim: Simulator, listener: TcpListener) {
    loop {
        let Ok((stream, _)) = listener.accept().await else {
            tokio::time::sleep(Duration::from_millis(10)).await;
            continue;
        };
        let sim = sim.clone();
        tokio::spawn(async move {
            let (read, mut write) = stream.into_split();
            let mut lines = BufReader::new(read).lines();
            while let Ok(Some(line)) = lines.next_line().await {
                let mut reply = stats_command(&sim, line.trim());
                reply.push('\n');
                if write.write_all(reply.as_bytes()).await.is_err() {
                    break;
                }
            }
        });
    }
}

/// Runs `skein sim`: starts the simulator, prints one line per vehicle (and the stats
/// address), and runs until Ctrl-C.
pub async fn run(args: SimArgs) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    let cfg = args.config()?;
    let sim = Simulator::start(cfg).await?;
    if args.intruders.intruders > 0 {
        sim.start_intruders(args.intruders.config(args.seed))?;
        println!("intruders {}", args.intruders.intruders);
    }
    for v in sim.vehicles() {
        println!(
            "vehicle sysid={} bound={} target={}",
            v.sysid, v.bound, v.target
        );
    }
    let stats_task = match args.stats {
        Some(addr) => {
            let listener = TcpListener::bind(addr).await?;
            println!("stats {}", listener.local_addr()?);
            Some(tokio::spawn(serve_stats(sim.clone(), listener)))
        }
        None => None,
    };
    println!("ready");
    use std::io::Write;
    std::io::stdout().flush()?;
    tokio::signal::ctrl_c().await?;
    if let Some(t) = stats_task {
        t.abort();
    }
    sim.shutdown().await;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        sim: SimArgs,
    }

    #[test]
    fn parses_flags() {
        let cli = Cli::try_parse_from([
            "sim",
            "--vehicles",
            "3",
            "--home",
            "47.0,8.0,400",
            "--param",
            "MIS_TAKEOFF_ALT=5",
            "--profile",
            "swarm",
            "--stats",
            "127.0.0.1:0",
        ])
        .expect("parse");
        let cfg = cli.sim.config().expect("config");
        assert_eq!(cfg.vehicles.len(), 3);
        assert_eq!(cfg.home.alt_amsl_m, 400.0);
        assert_eq!(cfg.params, vec![("MIS_TAKEOFF_ALT".to_string(), 5.0)]);
        assert_eq!(cfg.telemetry, TelemetryProfile::Swarm);
        assert!(Cli::try_parse_from(["sim", "--param", "NOPE=1"]).is_err());
        let many = |extra: &[&str]| {
            let mut args = vec!["sim", "--vehicles", "1000", "--listen-base-port", "0"];
            args.extend_from_slice(extra);
            Cli::try_parse_from(args).expect("parse").sim.config()
        };
        let err = many(&[]).expect_err("shared target with repeated sysids");
        assert!(err.contains("--per-vehicle-targets"), "{err}");
        let cfg = many(&["--per-vehicle-targets", "--target-base-port", "20000"]).expect("config");
        assert_eq!(cfg.vehicles.len(), 1000);
        assert_eq!(cfg.vehicles[250].sysid, 1);
        assert_eq!(cfg.vehicles[250].target.port(), 20_250);
        assert!(Cli::try_parse_from(["sim", "--home", "95,0,0"]).is_err());
    }

    #[tokio::test]
    async fn intruders_fly_and_answer_on_the_stats_socket() {
        let cli = Cli::try_parse_from([
            "sim",
            "--listen-base-port",
            "0",
            "--target-base-port",
            "9",
            "--intruders",
            "2",
            "--intruder-pattern",
            "straight",
            "--intruder-speed-m-s",
            "7",
        ])
        .expect("parse");
        assert_eq!(
            cli.sim.intruders.intruder_pattern.0,
            Some(crate::intruders::IntruderPattern::Straight)
        );
        let sim = Simulator::start(cli.sim.config().expect("config"))
            .await
            .expect("start");
        assert_eq!(stats_command(&sim, "intruders"), r#"{"intruders":[]}"#);
        assert!(stats_command(&sim, "intruders restart").contains("no intruders"));
        assert!(stats_command(&sim, "intruders leave").contains("no intruders"));
        sim.start_intruders(cli.sim.intruders.config(cli.sim.seed))
            .expect("intruders");
        let reply: serde_json::Value =
            serde_json::from_str(&stats_command(&sim, "intruders")).expect("json");
        let list = reply["intruders"].as_array().expect("list");
        assert_eq!(list.len(), 2);
        assert_eq!(list[1]["id"], "intruder-2");
        let v = &list[0]["velocity_ned_m_s"];
        let speed =
            (v["north_m"].as_f64().unwrap().powi(2) + v["east_m"].as_f64().unwrap().powi(2)).sqrt();
        assert!((speed - 7.0).abs() < 0.1, "{reply}");
        // The radio never hears them: no vehicle was added.
        assert_eq!(sim.vehicles().len(), 1);
        assert!(sim.start_intruders(cli.sim.intruders.config(0)).is_err());
        // A restart puts each back where it started (its truth at t = 0), once it has
        // flown from there.
        let at_start = sim.inner.intruders.get().expect("started").truth_at(0.0);
        let from_start = |sim: &Simulator| -> f64 {
            let reply: serde_json::Value =
                serde_json::from_str(&stats_command(sim, "intruders")).expect("json");
            let list = reply["intruders"].as_array().cloned().unwrap_or_default();
            list.iter()
                .zip(&at_start)
                .map(|(now, start)| {
                    let p = &now["home_ned_m"];
                    let dn = p["north_m"].as_f64().unwrap() - start.home_ned_m.north_m;
                    let de = p["east_m"].as_f64().unwrap() - start.home_ned_m.east_m;
                    dn.hypot(de)
                })
                .fold(0.0, f64::max)
        };
        let deadline = std::time::Instant::now() + Duration::from_secs(10);
        while from_start(&sim) < 3.0 {
            assert!(
                std::time::Instant::now() < deadline,
                "the intruders never left"
            );
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        assert_eq!(stats_command(&sim, "intruders restart"), r#"{"ok":true}"#);
        let d = from_start(&sim);
        assert!(d < 2.0, "{d} m from where they started after a restart");
        assert!(stats_command(&sim, "intruders again").contains("error"));
        // Gone until the next restart.
        assert_eq!(stats_command(&sim, "intruders leave"), r#"{"ok":true}"#);
        assert_eq!(stats_command(&sim, "intruders"), r#"{"intruders":[]}"#);
        assert_eq!(stats_command(&sim, "intruders restart"), r#"{"ok":true}"#);
        assert!(from_start(&sim) < 2.0);
        sim.shutdown().await;
    }
}
