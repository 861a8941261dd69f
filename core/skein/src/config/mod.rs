//! The `skein up --config FILE` file (TOML).
//!
//! ```toml
//! [swarm]                      # optional, every key optional
//! origin = { lat_deg = 47.397742, lon_deg = 8.545594, alt_amsl_m = 488.0 }
//! stream_rate_hz = 50.0        # offboard setpoints per second per vehicle
//! min_separation_m = 3.0        # guaranteed distance between vehicles
//! separation_margin_m = 0.5     # kept on top between setpoints, for tracking error
//! position_uncertainty_sigmas = 1.0  # formations allow for the members' GNSS accuracy
//! default_takeoff_altitude_m = 10.0
//! geofence = { radius_m = 500.0, max_altitude_m = 120.0, min_altitude_m = 5.0 }
//! # optional polygon in the swarm frame ([north_m, east_m] vertices):
//! # geofence = { ..., polygon = [[-100.0, -100.0], [300.0, -100.0], [300.0, 100.0], [-100.0, 100.0]] }
//! # and: exclusions = [{ circle = { north_m = 50.0, east_m = 0.0, radius_m = 10.0 } }],
//! # rally_points = [{ north_m = -50.0, east_m = 0.0, altitude_m = 20.0 }],
//! # breach_action = "hold"   # PX4's GF_ACTION: none, warn, hold, rtl, land
//!
//! [link]                       # our MAVLink identity, and what we ask of vehicles
//! mav_type = "gcs"             # or "onboard_controller" on a companion computer
//! sysid = 255
//! compid = 190
//! telemetry = "swarm"          # reduced rates for big swarms; default "px4_default"
//! params = { COM_OF_LOSS_T = 1.0, COM_OBL_RC_ACT = 5, NAV_DLL_ACT = 0 }  # set at connect
//!
//! [http]
//! listen = "127.0.0.1:8080"   # a non-loopback address needs tokens (or --insecure-no-auth)
//! [[http.tokens]]              # one per holder, from `skein token create --role operator`
//! name = "ops"
//! role = "operator"            # viewer | operator | admin
//! hash = "sha256$<salt>$<digest>"
//! # tls_cert = "cert.pem"      # [http] keys: serve HTTPS (PEM files, both or neither)
//! # tls_key = "key.pem"
//!
//! [plugins]                    # payload plugins (cdylibs built with plugins/sdk)
//! dir = "/var/lib/skein/plugins"  # loads every lib*.so at start; default: the directory
//!                              # of the skein executable; `--plugin-dir` overrides it
//!
//! [supervision]                # restart policies (vehicle, px4link, payload, api)
//! vehicle_escalation = "hold"  # or "land": what a vehicle whose actor keeps failing does
//! watchdog_deadline_ms = 2000  # a child not answering a ping this long is hung (unless
//!                              # the whole process ran late meanwhile: then it is late)
//! max_restarts_per_s = 10.0    # the whole tree's restart rate, and the burst it may make
//! restart_burst = 20           # at once; restarts over that are delayed, never dropped
//! payload = { policy = "on-failure", max_restarts = 5, window_s = 60.0,
//!             backoff_initial_ms = 100, backoff_max_ms = 5000 }
//!
//! [hazards]                    # vehicles lost in the air, planned around
//! drift_m_s = 1.0              # assumed drift of an unseen vehicle; its radius grows so
//! max_radius_m = 10.0          # … up to this
//! max_unseen_s = 300.0         # unseen this long: no longer a hazard
//! replan_after_s = 10.0        # a formation change held this long is planned again
//!
//! [models.observation]         # vehicle models: limits and payload slots
//! payloads = [{ slot = "gimbal", kind = "gimbal" }, { slot = "camera", kind = "camera" }]
//! limits = { max_speed_m_s = 8.0, max_climb_m_s = 3.0, max_descent_m_s = 1.5, max_accel_m_s2 = 3.0 }
//!
//! [map]                        # the map under the plan view (docs/map-and-fence.md)
//! tiles = "field.mbtiles"      # an MBTiles file or a z/x/y folder; --map-tiles overrides
//! # online_url = "https://tile.example.org/{z}/{x}/{y}.png"  # opt in, the browser fetches
//! # online_attribution = "© …"  # what the online tiles must credit
//!
//! [rtk]                        # RTK corrections to every vehicle (docs/field-day.md)
//! source = "ntrip://user:password@caster.example:2101/MOUNT"  # or tcp://, udp://, serial:
//! max_bytes_s = 2000           # cap per vehicle, MAVLink framing included
//! stall_timeout_s = 10.0       # no RTCM frame this long: reconnect
//! send_gga = true              # tell a network RTK caster where the fleet is
//!
//! [logs]                       # the vehicles' flight logs (docs/field-day.md)
//! max_bytes_s = 50000          # one cap over every download at once
//! fetch_after_landing = true   # fetch each vehicle's newest log once it landed
//!
//! [gcs]                        # forward every vehicle's MAVLink to QGroundControl and
//! forward = "udpout:127.0.0.1:14550"  # its commands back (setpoints refused); or udpin:
//!
//! [agent]                      # `skein agent` only
//! coordinator_timeout_s = 1.5  # no coordinator heard this long: hold (offboard)
//! coordinator_lost_action = "land"  # then, after coordinator_lost_action_s: hold|land|rtl
//! coordinator_lost_action_s = 30.0
//! shutdown_action = "land"     # on SIGTERM / Ctrl-C, before exiting: land|hold|rtl
//! shutdown_timeout_s = 60.0    # the longest wait for it
//!
//! [[vehicles]]                 # one table per vehicle (or per shared endpoint)
//! connection = "udpin:0.0.0.0:14540"
//! id = "uav-1"                 # optional, default uav-<sysid>
//! model = "generic"            # optional
//! sysid = 1                    # optional: only this sysid on the endpoint gets this id
//! signing_key_file = "uav-1.key"  # optional: MAVLink 2 signing, 64 hex characters
//!                              # (`skein key create`); unsigned frames then dropped
//! signing_link_id = 0          # optional link id of our signed frames (default 0)
//! ```
//!
//! Unknown keys, wrong types and bad values are refused with the TOML parser's message,
//! which names the key and shows the line.

use serde::Deserialize;
use skein_link::{ConnectionAddress, Identity};
use skein_mavlink::dialect::MavType;
use skein_model::geo::GeoPoint;
use skein_model::safety::Geofence;
use skein_swarm::{EndpointSpec, SwarmConfig, VehicleSpec};
use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::path::Path;

/// A connection string, validated while parsing so the error points at its line.
#[derive(Debug, Clone, PartialEq)]
pub struct Connection(pub ConnectionAddress);

impl<'de> Deserialize<'de> for Connection {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse()
            .map(Connection)
            .map_err(|e: skein_link::address::AddressError| serde::de::Error::custom(e.0))
    }
}

/// `[swarm]`.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SwarmSection {
    /// Swarm frame anchor.
    pub origin: Option<GeoPoint>,
    /// Setpoint stream rate, Hz.
    pub stream_rate_hz: Option<f64>,
    /// Minimum separation, metres.
    pub min_separation_m: Option<f64>,
    /// Tracking margin kept between setpoints on top of the separation, metres.
    pub separation_margin_m: Option<f64>,
    /// Standard deviations of the members' position uncertainty a formation's spacing
    /// allows for (0 to 5; 0 ignores it).
    pub position_uncertainty_sigmas: Option<f64>,
    /// Default takeoff altitude, metres above home.
    pub default_takeoff_altitude_m: Option<f64>,
    /// Geofence.
    pub geofence: Option<Geofence>,
}

/// `[link]`.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinkSection {
    /// Telemetry profile asked of every vehicle: `"px4_default"` or `"swarm"`.
    pub telemetry: Option<skein_link::TelemetryProfile>,
    /// PX4 parameters set at connect, e.g. `{ COM_OF_LOSS_T = 1.0, COM_OBL_RC_ACT = 5 }`.
    pub params: Option<BTreeMap<String, f64>>,
    /// `"gcs"` or `"onboard_controller"`.
    pub mav_type: Option<MavTypeName>,
    /// Our system id.
    pub sysid: Option<u8>,
    /// Our component id.
    pub compid: Option<u8>,
}

/// The MAV_TYPE of our heartbeat.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MavTypeName {
    /// `MAV_TYPE_GCS`: a ground station.
    Gcs,
    /// `MAV_TYPE_ONBOARD_CONTROLLER`: a companion computer.
    OnboardController,
}

/// `[http]`.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HttpSection {
    /// Listen address.
    pub listen: Option<SocketAddr>,
    /// API tokens (`[[http.tokens]]`, made by `skein token create`); none: no
    /// authentication, allowed on loopback only (or with `--insecure-no-auth`).
    #[serde(default)]
    pub tokens: Vec<skein_api::auth::TokenConfig>,
    /// PEM certificate chain: serve HTTPS (with `tls_key`; relative to the config file).
    pub tls_cert: Option<std::path::PathBuf>,
    /// PEM private key of `tls_cert`.
    pub tls_key: Option<std::path::PathBuf>,
}

/// `[plugins]`.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PluginsSection {
    /// The plugin directory (relative paths are relative to the config file's directory).
    pub dir: Option<std::path::PathBuf>,
}

/// One `[models.NAME]` table.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelEntry {
    /// Motion limits (default: PX4 multicopter defaults).
    pub limits: Option<skein_model::safety::MotionLimits>,
    /// Payload slots.
    #[serde(default)]
    pub payloads: Vec<skein_payload::PayloadSpec>,
}

/// One `[[vehicles]]` table.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VehicleEntry {
    /// Connection string.
    pub connection: Connection,
    /// Vehicle id.
    pub id: Option<String>,
    /// Model name.
    pub model: Option<String>,
    /// Restrict to this sysid.
    pub sysid: Option<u8>,
    /// MAVLink 2 signing key file (64 hex characters; relative to the config file).
    pub signing_key_file: Option<std::path::PathBuf>,
    /// Link id of our signed frames (default 0); needs `signing_key_file`.
    pub signing_link_id: Option<u8>,
}

/// `[recording]`.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordingSection {
    /// Where `POST /api/v1/recording/start` writes its MCAP files (relative paths are
    /// relative to the config file's directory); default `recordings` in the working
    /// directory.
    pub dir: Option<std::path::PathBuf>,
}

/// `[logs]`: bringing the vehicles' flight logs home.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LogsSection {
    /// One byte-rate cap over every log download at once, bytes/s (none by default).
    pub max_bytes_s: Option<f64>,
    /// Fetch each vehicle's newest log by itself once the vehicle has landed and
    /// disarmed (default false: on request, `POST /api/v1/logs/fetch_latest`).
    #[serde(default)]
    pub fetch_after_landing: bool,
}

/// `[gcs]`.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GcsSection {
    /// Where to forward every vehicle's frames (`udpout:HOST:PORT`, QGroundControl
    /// listens on 14550; or `udpin:ADDR:PORT` to wait for the ground station).
    pub forward: Option<Connection>,
}

/// `[dds]`: the swarm on ROS 2 topics (`skein up --dds`, see `skein_dds::topics`).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DdsSection {
    /// Publish the topics (as `--dds`).
    #[serde(default)]
    pub enabled: bool,
    /// DDS domain, 0 to 232 (`--domain-id` wins; default `ROS_DOMAIN_ID`, else 0).
    pub domain_id: Option<u16>,
    /// Pose, navsat and state publications per second (default 10, at most 100).
    pub publish_rate_hz: Option<f64>,
    /// Obey `skein_msgs/Command`s from the domain (as `--dds-commands`). DDS has no
    /// authentication: turn this on only on a trusted network.
    #[serde(default)]
    pub accept_commands: bool,
    /// Addresses of the local interfaces DDS uses (`["192.168.1.20"]` for the swarm's
    /// WLAN; `["127.0.0.1"]` keeps it on this host); default every interface.
    #[serde(default)]
    pub networks: Vec<std::net::IpAddr>,
    /// The parent of the swarm frame `skein_swarm` on `/tf_static`, as an identity
    /// (`"map"`; as `--dds-tf-parent`); default `earth`, the swarm origin's ECEF place.
    pub tf_parent_frame: Option<String>,
    /// DDS Security: the SROS 2 keystore whose enclave this participant presents (as
    /// `--dds-keystore`; with `enclave`).
    pub keystore: Option<std::path::PathBuf>,
    /// DDS Security: the enclave presented (`"/skein/agent/a1"`, as `--dds-enclave`).
    pub enclave: Option<String>,
}

/// `[agent]`: what `skein agent` does without a coordinator (`skein_dds::agent`), and
/// before it exits.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AgentSection {
    /// No coordinator heard for this long past when its next lease was due: the agent's
    /// vehicles hold (default 1.5 s), unless they ride through for longer.
    pub coordinator_timeout_s: Option<f64>,
    /// How long a vehicle flies its slot on from the formation's mirror when its slot
    /// targets stop, before it holds (default 4 s; 0: never).
    pub coordinator_ride_through_s: Option<f64>,
    /// `hold` | `land` | `rtl`: what they do after `coordinator_lost_action_s` more
    /// (default `hold`).
    pub coordinator_lost_action: Option<String>,
    /// Seconds of holding before the lost action (default 30).
    pub coordinator_lost_action_s: Option<f64>,
    /// `land` | `hold` | `rtl`: what the airborne vehicles do before the agent exits on
    /// SIGTERM or Ctrl-C (default `land`; see `crate::shutdown`).
    pub shutdown_action: Option<String>,
    /// The longest wait for that at shutdown, seconds (default 60).
    pub shutdown_timeout_s: Option<f64>,
}

/// The whole file.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConfigFile {
    /// `[swarm]`.
    #[serde(default)]
    pub swarm: SwarmSection,
    /// `[link]`.
    #[serde(default)]
    pub link: LinkSection,
    /// `[http]`.
    #[serde(default)]
    pub http: HttpSection,
    /// `[plugins]`.
    #[serde(default)]
    pub plugins: PluginsSection,
    /// `[gcs]`.
    #[serde(default)]
    pub gcs: GcsSection,
    /// `[recording]`.
    #[serde(default)]
    pub recording: RecordingSection,
    /// `[logs]`.
    #[serde(default)]
    pub logs: LogsSection,
    /// `[dds]`.
    #[serde(default)]
    pub dds: DdsSection,
    /// `[agent]`.
    #[serde(default)]
    pub agent: AgentSection,
    /// `[map]`.
    #[serde(default)]
    pub map: skein_api::map::MapConfig,
    /// `[supervision]`.
    pub supervision: Option<skein_swarm::supervision::SupervisionConfig>,
    /// `[hazards]`.
    pub hazards: Option<skein_swarm::formation::HazardConfig>,
    /// `[remote_id]`: the operator's identity and location sent to every vehicle's
    /// Remote ID transmitter (see `skein_link::remote_id`).
    pub remote_id: Option<skein_link::remote_id::RemoteIdConfig>,
    /// `[rtk]`: RTK corrections sent to every vehicle from this source at start
    /// (`PUT /api/v1/rtk` changes it; see `skein_rtk`).
    pub rtk: Option<skein_rtk::RtkConfig>,
    /// `[models.NAME]`.
    #[serde(default)]
    pub models: BTreeMap<String, ModelEntry>,
    /// `[[vehicles]]`.
    #[serde(default)]
    pub vehicles: Vec<VehicleEntry>,
}

impl ConfigFile {
    /// Reads and parses `path`.
    ///
    /// # Errors
    /// A message naming the file, and the parser's message naming the key and line.
    pub fn load(path: &Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
        let mut cfg = Self::parse(&text).map_err(|e| format!("{}: {e}", path.display()))?;
        if let Some(dir) = &cfg.plugins.dir
            && dir.is_relative()
            && let Some(base) = path.parent()
        {
            cfg.plugins.dir = Some(base.join(dir));
        }
        if let Some(base) = path.parent() {
            let keys = cfg.vehicles.iter_mut().map(|v| &mut v.signing_key_file);
            for p in [
                &mut cfg.http.tls_cert,
                &mut cfg.http.tls_key,
                &mut cfg.recording.dir,
                &mut cfg.map.tiles,
            ]
            .into_iter()
            .chain(keys)
            {
                if let Some(f) = p.as_mut()
                    && f.is_relative()
                {
                    *f = base.join(&*f);
                }
            }
        }
        // Read every key now: a bad key file stops the start, naming the file.
        cfg.endpoints()?;
        Ok(cfg)
    }

    /// Parses TOML text.
    ///
    /// # Errors
    /// The parser's message (line, column, key) or a validation message naming the key.
    pub fn parse(text: &str) -> Result<Self, String> {
        let cfg: ConfigFile = toml::from_str(text).map_err(|e| e.to_string())?;
        cfg.validate()?;
        Ok(cfg)
    }

    fn validate(&self) -> Result<(), String> {
        let positive = |key: &str, v: Option<f64>| match v {
            Some(x) if !(x.is_finite() && x > 0.0) => {
                Err(format!("{key} must be a positive number, got {x}"))
            }
            _ => Ok(()),
        };
        positive("swarm.stream_rate_hz", self.swarm.stream_rate_hz)?;
        positive("logs.max_bytes_s", self.logs.max_bytes_s)?;
        if let Some(rtk) = &self.rtk {
            rtk.settings()
                .map_err(|e| format!("rtk.{}: {}", e.field, e.error))?;
        }
        if let Some(r) = self.swarm.stream_rate_hz
            && r <= 2.0
        {
            return Err(format!(
                "swarm.stream_rate_hz must be above 2 Hz (PX4 refuses OFFBOARD below), got {r}"
            ));
        }
        positive("swarm.min_separation_m", self.swarm.min_separation_m)?;
        if let Some(m) = self.swarm.separation_margin_m
            && !(m.is_finite() && m >= 0.0)
        {
            return Err(format!(
                "swarm.separation_margin_m must be 0 or more, got {m}"
            ));
        }
        if let Some(k) = self.swarm.position_uncertainty_sigmas
            && !(0.0..=5.0).contains(&k)
        {
            return Err(format!(
                "swarm.position_uncertainty_sigmas must be 0 to 5, got {k}"
            ));
        }
        positive(
            "swarm.default_takeoff_altitude_m",
            self.swarm.default_takeoff_altitude_m,
        )?;
        for (name, v) in self.link.params.iter().flatten() {
            if name.is_empty() || name.len() > 16 || !name.is_ascii() {
                return Err(format!(
                    "link.params.{name}: a PX4 parameter name is 1 to 16 ASCII characters"
                ));
            }
            if !v.is_finite() {
                return Err(format!("link.params.{name}: {v} is not a number"));
            }
        }
        if let Some(g) = &self.swarm.geofence {
            g.validate()
                .map_err(|(field, why)| format!("swarm.geofence.{field}: {why}"))?;
        }
        for (name, m) in &self.models {
            let mut slots = std::collections::BTreeSet::new();
            for (i, p) in m.payloads.iter().enumerate() {
                if p.slot.is_empty() || p.slot.contains('/') {
                    return Err(format!(
                        "models.{name}.payloads[{i}].slot `{}` must be non-empty and contain no `/`",
                        p.slot
                    ));
                }
                if !slots.insert(p.slot.clone()) {
                    return Err(format!(
                        "models.{name}.payloads[{i}].slot `{}` is used twice",
                        p.slot
                    ));
                }
            }
        }
        let known_model =
            |m: &str| self.models.contains_key(m) || m == "generic" || m == "observation";
        for (i, v) in self.vehicles.iter().enumerate() {
            if v.signing_link_id.is_some() && v.signing_key_file.is_none() {
                return Err(format!(
                    "vehicles[{i}].signing_link_id needs vehicles[{i}].signing_key_file"
                ));
            }
            if let Some(m) = &v.model
                && !known_model(m)
            {
                return Err(format!(
                    "vehicles[{i}].model `{m}`: no such model (generic, observation, or a [models.NAME] table)"
                ));
            }
        }
        let mut ids = std::collections::BTreeSet::new();
        for (i, v) in self.vehicles.iter().enumerate() {
            if let Some(id) = &v.id {
                if id.is_empty() || id.contains('/') {
                    return Err(format!(
                        "vehicles[{i}].id `{id}` must be non-empty and contain no `/`"
                    ));
                }
                if !ids.insert(id.clone()) {
                    return Err(format!("vehicles[{i}].id `{id}` is used twice"));
                }
            }
        }
        Ok(())
    }

    /// The swarm configuration, defaults filled in.
    ///
    /// # Errors
    /// None today beyond what [`ConfigFile::parse`] checked; kept fallible for models
    /// that need the plugin host.
    pub fn swarm_config(&self) -> Result<SwarmConfig, String> {
        let mut c = SwarmConfig {
            swarm_origin: self.swarm.origin,
            ..SwarmConfig::default()
        };
        if let Some(v) = self.swarm.stream_rate_hz {
            c.stream_rate_hz = v;
        }
        if let Some(v) = self.swarm.min_separation_m {
            c.min_separation_m = v;
        }
        if let Some(v) = self.swarm.separation_margin_m {
            c.separation_margin_m = v;
        }
        if let Some(v) = self.swarm.position_uncertainty_sigmas {
            c.position_uncertainty_sigmas = v;
        }
        if let Some(v) = self.swarm.default_takeoff_altitude_m {
            c.default_takeoff_altitude_m = v;
        }
        if let Some(g) = &self.swarm.geofence {
            c.geofence = g.clone();
        }
        c.link_setup = skein_link::LinkSetup {
            telemetry: self.link.telemetry.unwrap_or_default(),
            params: self
                .link
                .params
                .iter()
                .flatten()
                .map(|(k, v)| (k.clone(), *v))
                .collect(),
            remote_id: self.remote_id.clone(),
            // The reader is started with the process (`compose::remote_id`).
            operator_gnss: None,
            metadata_cache_dir: Some(self.metadata_cache_dir()),
            log_bandwidth: skein_link::log_bandwidth::LogBandwidth::new(self.logs.max_bytes_s),
        };
        c.missions_dir = Some(self.missions_dir());
        if let Some(sup) = &self.supervision {
            c.supervision = sup.clone();
        }
        if let Some(h) = self.hazards {
            c.hazards = h;
        }
        for (name, m) in &self.models {
            c.models.insert(
                name.clone(),
                skein_swarm::VehicleModel {
                    name: name.clone(),
                    limits: m.limits.unwrap_or_default(),
                    payloads: m.payloads.clone(),
                },
            );
        }
        Ok(c)
    }

    /// The recordings' directory (`[recording] dir`, default `recordings`), where skein
    /// keeps what it brings home and what it must remember.
    fn data_dir(&self) -> std::path::PathBuf {
        self.recording
            .dir
            .clone()
            .unwrap_or_else(|| "recordings".into())
    }

    /// Where PX4's component metadata is cached: `px4-metadata` in the recordings'
    /// directory.
    pub fn metadata_cache_dir(&self) -> std::path::PathBuf {
        self.data_dir().join("px4-metadata")
    }

    /// Where mission plans are stored: `missions` in the recordings' directory.
    pub fn missions_dir(&self) -> std::path::PathBuf {
        self.data_dir().join("missions")
    }

    /// Our MAVLink identity.
    pub fn identity(&self) -> Identity {
        let d = Identity::default();
        Identity {
            sysid: self.link.sysid.unwrap_or(d.sysid),
            compid: self.link.compid.unwrap_or(d.compid),
            mav_type: match self.link.mav_type {
                Some(MavTypeName::OnboardController) => MavType::MAV_TYPE_ONBOARD_CONTROLLER,
                _ => MavType::MAV_TYPE_GCS,
            },
        }
    }

    /// The endpoints to open: vehicles sharing a connection string share the endpoint.
    ///
    /// # Errors
    /// A signing key file that cannot be read or is not 64 hex characters (named).
    pub fn endpoints(&self) -> Result<Vec<EndpointSpec>, String> {
        let mut by_conn: BTreeMap<String, EndpointSpec> = BTreeMap::new();
        let mut order = Vec::new();
        for v in &self.vehicles {
            let key = v.connection.0.to_string();
            let e = by_conn.entry(key.clone()).or_insert_with(|| {
                order.push(key.clone());
                EndpointSpec {
                    connection: v.connection.0.clone(),
                    vehicles: vec![],
                    simulated: false,
                }
            });
            let signing = match &v.signing_key_file {
                Some(f) => Some(skein_link::SigningSpec {
                    key: skein_mavlink::signing::SigningKey::load(f).map_err(|e| e.to_string())?,
                    link_id: v.signing_link_id.unwrap_or(0),
                }),
                None => None,
            };
            e.vehicles.push(VehicleSpec {
                id: v.id.clone(),
                sysid: v.sysid,
                model: v.model.clone(),
                signing,
            });
        }
        Ok(order
            .into_iter()
            .map(|k| by_conn.remove(&k).expect("inserted"))
            .collect())
    }
}

#[cfg(test)]
mod tests;
