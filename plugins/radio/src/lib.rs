//! The radio payload plugin: link metrics of a vehicle's radio (RSSI, loss, latency).
//!
//! - **simulated** backend (the default on a simulated vehicle): a log-distance path-loss
//!   model between the vehicle and the ground station (the swarm origin unless
//!   configured). The received power falls with distance, the packet loss grows as the
//!   link margin above the receiver's sensitivity shrinks (logistic in the margin), and the
//!   latency grows with the retransmissions the loss costs. The plugin tells the simulator
//!   through `set_simulated_link(loss, latency)`, so the vehicle's MAVLink traffic is really
//!   dropped and delayed: a vehicle far out shows a degraded link and a lower telemetry
//!   rate. On shutdown it restores a perfect link.
//! - **mavlink** backend (a real vehicle): RSSI and noise from `RADIO_STATUS` (SiK radio
//!   scale: dBm = value / 1.9 − 127); loss and latency are not measured (`null`).
//!
//! Model: `PL(d) = PL(1 m) + 10 n log10(d / 1 m)` with `PL(1 m)` the free-space loss at
//! `frequency_mhz`; `rssi = tx_power − PL(d)`; `margin = rssi − sensitivity`;
//! `loss = 1 / (1 + exp(margin / loss_slope_db))`; `latency = base_latency_ms +
//! retry_latency_ms · loss / (1 − loss) + d / c`, at most `max_latency_ms`. With the
//! defaults the link is clean within about 200 m, loses 7 % at 300 m and 60 % at 500 m.
//!
//! # Configuration (all optional)
//! `{"mode": "auto" | "simulated" | "mavlink", "tx_power_dbm": 20, "frequency_mhz": 2400,
//! "path_loss_exponent": 2.7, "sensitivity_dbm": -92, "loss_slope_db": 2, "base_latency_ms": 5,
//! "retry_latency_ms": 15, "max_latency_ms": 2000,
//! "ground_station": {"north_m": 0, "east_m": 0, "down_m": 0}, "rate_hz": 2}`.
//!
//! # Commands
//! - `{"command": "status"}`
//! - `{"command": "set_model", <any model field above>}`: change the model at run time
//! - `{"command": "override", "loss_fraction": 0.5, "latency_ms": 200}`: impose a link
//!   condition whatever the distance (simulated backend)
//! - `{"command": "clear_override"}`
//!
//! # Published state
//! ```json
//! {"backend": "simulated", "distance_m": 312.0, "rssi_dbm": -87.4, "link_margin_db": 4.6,
//!  "loss_percent": 9.1, "latency_ms": 6.5, "applied_to_simulator": true, "override": null,
//!  "radio_status": null, "model": {"tx_power_dbm": 20.0, ...}}
//! ```

use skein_plugin_sdk::args::{self, DeviceMode};
use skein_plugin_sdk::dialect::RADIO_STATUS_DATA;
use skein_plugin_sdk::geometry::Ned;
use skein_plugin_sdk::serde::{Deserialize, Serialize};
use skein_plugin_sdk::serde_json::{Map, Value, json};
use skein_plugin_sdk::{Context, MavMessage, MavlinkInterest, MessageData, Plugin, export_plugin};

/// Speed of light, metres per millisecond.
const C_M_PER_MS: f64 = 299_792.458;

/// Link metrics at one distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkMetrics {
    /// Received signal strength, dBm.
    pub rssi_dbm: f64,
    /// RSSI above the receiver's sensitivity, dB.
    pub link_margin_db: f64,
    /// Fraction of packets lost, 0..1.
    pub loss_fraction: f64,
    /// One-way latency, milliseconds.
    pub latency_ms: f64,
}

/// The log-distance radio model (see the crate docs); serialises as the state's `model`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(crate = "skein_plugin_sdk::serde")]
pub struct RadioModel {
    /// Transmit power, dBm.
    pub tx_power_dbm: f64,
    /// Carrier frequency, MHz (sets the free-space loss at 1 m).
    pub frequency_mhz: f64,
    /// Path-loss exponent `n` (2 free space, 2.7–3.5 near the ground).
    pub path_loss_exponent: f64,
    /// Receiver sensitivity, dBm (50 % loss at this RSSI).
    pub sensitivity_dbm: f64,
    /// Width of the loss transition, dB (loss falls by e per this much margin).
    pub loss_slope_db: f64,
    /// Latency of a clean link, ms.
    pub base_latency_ms: f64,
    /// Latency added per expected retransmission, ms.
    pub retry_latency_ms: f64,
    /// Cap on the latency, ms.
    pub max_latency_ms: f64,
}

/// New values for some fields of the [`RadioModel`] (the config's model fields, and the
/// `set_model` command); a field left out keeps its value.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(crate = "skein_plugin_sdk::serde", deny_unknown_fields)]
struct ModelUpdate {
    /// [`RadioModel::tx_power_dbm`], -30..60 dBm.
    tx_power_dbm: Option<f64>,
    /// [`RadioModel::frequency_mhz`], 1..100 000 MHz.
    frequency_mhz: Option<f64>,
    /// [`RadioModel::path_loss_exponent`], 1.5..6.
    path_loss_exponent: Option<f64>,
    /// [`RadioModel::sensitivity_dbm`], -150..0 dBm.
    sensitivity_dbm: Option<f64>,
    /// [`RadioModel::loss_slope_db`], 0.1..20 dB.
    loss_slope_db: Option<f64>,
    /// [`RadioModel::base_latency_ms`], 0..10 000 ms.
    base_latency_ms: Option<f64>,
    /// [`RadioModel::retry_latency_ms`], 0..10 000 ms.
    retry_latency_ms: Option<f64>,
    /// [`RadioModel::max_latency_ms`], `base_latency_ms`..60 000 ms.
    max_latency_ms: Option<f64>,
}

impl Default for RadioModel {
    fn default() -> Self {
        RadioModel {
            tx_power_dbm: 20.0,
            frequency_mhz: 2400.0,
            path_loss_exponent: 2.7,
            sensitivity_dbm: -92.0,
            loss_slope_db: 2.0,
            base_latency_ms: 5.0,
            retry_latency_ms: 15.0,
            max_latency_ms: 2000.0,
        }
    }
}

impl RadioModel {
    /// Takes the fields `u` gives, keeping the others; every field is range-checked.
    ///
    /// # Errors
    /// A field out of range, named (`path_loss_exponent: 9 is outside [1.5, 6]`).
    fn update(&mut self, u: &ModelUpdate) -> Result<(), String> {
        let set = |field, current: f64, new: Option<f64>, min, max| {
            args::in_range(field, new.unwrap_or(current), min, max)
        };
        self.tx_power_dbm = set(
            "tx_power_dbm",
            self.tx_power_dbm,
            u.tx_power_dbm,
            -30.0,
            60.0,
        )?;
        self.frequency_mhz = set(
            "frequency_mhz",
            self.frequency_mhz,
            u.frequency_mhz,
            1.0,
            100_000.0,
        )?;
        self.path_loss_exponent = set(
            "path_loss_exponent",
            self.path_loss_exponent,
            u.path_loss_exponent,
            1.5,
            6.0,
        )?;
        self.sensitivity_dbm = set(
            "sensitivity_dbm",
            self.sensitivity_dbm,
            u.sensitivity_dbm,
            -150.0,
            0.0,
        )?;
        self.loss_slope_db = set(
            "loss_slope_db",
            self.loss_slope_db,
            u.loss_slope_db,
            0.1,
            20.0,
        )?;
        self.base_latency_ms = set(
            "base_latency_ms",
            self.base_latency_ms,
            u.base_latency_ms,
            0.0,
            10_000.0,
        )?;
        self.retry_latency_ms = set(
            "retry_latency_ms",
            self.retry_latency_ms,
            u.retry_latency_ms,
            0.0,
            10_000.0,
        )?;
        self.max_latency_ms = set(
            "max_latency_ms",
            self.max_latency_ms,
            u.max_latency_ms,
            self.base_latency_ms,
            60_000.0,
        )?;
        Ok(())
    }

    /// Free-space path loss at 1 m, dB: `20 log10(f_MHz) − 27.55`.
    pub fn reference_loss_db(&self) -> f64 {
        20.0 * self.frequency_mhz.log10() - 27.55
    }

    /// Path loss at `distance_m` (at least 1 m), dB.
    pub fn path_loss_db(&self, distance_m: f64) -> f64 {
        self.reference_loss_db() + 10.0 * self.path_loss_exponent * distance_m.max(1.0).log10()
    }

    /// The link at `distance_m`.
    pub fn metrics(&self, distance_m: f64) -> LinkMetrics {
        let rssi_dbm = self.tx_power_dbm - self.path_loss_db(distance_m);
        let link_margin_db = rssi_dbm - self.sensitivity_dbm;
        let loss_fraction = 1.0 / (1.0 + (link_margin_db / self.loss_slope_db).exp());
        let retries = loss_fraction / (1.0 - loss_fraction).max(1e-6);
        let latency_ms =
            (self.base_latency_ms + self.retry_latency_ms * retries + distance_m / C_M_PER_MS)
                .min(self.max_latency_ms);
        LinkMetrics {
            rssi_dbm,
            link_margin_db,
            loss_fraction,
            latency_ms,
        }
    }
}

/// Which radio the instance reports on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Backend {
    /// The log-distance model, applied to the simulator.
    Simulated,
    /// A real radio's `RADIO_STATUS`.
    Mavlink,
}

/// The link as last computed or reported.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Current {
    distance_m: Option<f64>,
    metrics: Option<LinkMetrics>,
}

/// The swarm-frame position of the ground station (each part optional, default 0).
#[derive(Debug, Clone, Copy, Default, Deserialize)]
#[serde(crate = "skein_plugin_sdk::serde", deny_unknown_fields)]
struct GroundStation {
    north_m: Option<f64>,
    east_m: Option<f64>,
    down_m: Option<f64>,
}

/// The configuration's own fields; the model's are a [`ModelUpdate`].
#[derive(Debug, Default, Deserialize)]
#[serde(crate = "skein_plugin_sdk::serde", deny_unknown_fields)]
struct StationConfig {
    #[serde(default)]
    mode: DeviceMode,
    ground_station: Option<GroundStation>,
    rate_hz: Option<f64>,
}

impl StationConfig {
    /// The fields of [`StationConfig`], which a config holds beside a [`ModelUpdate`]'s.
    const FIELDS: [&'static str; 3] = ["mode", "ground_station", "rate_hz"];

    /// Splits a configuration into its own fields and the model's, each read with the SDK
    /// (a field neither knows is refused by the model's).
    fn parse(config: Value) -> Result<(StationConfig, ModelUpdate), String> {
        let mut model = match config {
            Value::Null => Map::new(),
            Value::Object(m) => m,
            other => return Err(format!("a radio config is a JSON object, got {other}")),
        };
        let own: Map<String, Value> = Self::FIELDS
            .iter()
            .filter_map(|k| model.remove_entry(*k))
            .collect();
        Ok((
            args::config(Value::Object(own))?,
            args::config(Value::Object(model))?,
        ))
    }

    /// The ground station's position, range-checked.
    fn ground_station(&self) -> Result<Ned, String> {
        let g = self.ground_station.unwrap_or_default();
        Ok(Ned::new(
            args::in_range(
                "ground_station.north_m",
                g.north_m.unwrap_or(0.0),
                -1e6,
                1e6,
            )?,
            args::in_range("ground_station.east_m", g.east_m.unwrap_or(0.0), -1e6, 1e6)?,
            args::in_range("ground_station.down_m", g.down_m.unwrap_or(0.0), -1e5, 1e5)?,
        ))
    }
}

/// The radio's commands (see the crate docs); `set_model` takes any model field.
#[derive(Deserialize)]
#[serde(crate = "skein_plugin_sdk::serde")]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
enum Command {
    Status,
    SetModel(ModelUpdate),
    Override {
        loss_fraction: f64,
        latency_ms: Option<f64>,
    },
    ClearOverride,
}

/// One radio instance.
pub struct Radio {
    backend: Backend,
    model: RadioModel,
    ground_station: Ned,
    rate_hz: f64,
    current: Current,
    /// `(loss_fraction, latency_ms)` imposed by the operator.
    override_link: Option<(f64, f64)>,
    /// What was last sent to the simulator, and when (instance clock, s).
    applied: Option<(f64, f64, f64)>,
    applied_ok: bool,
    time_s: f64,
    radio_status: Option<Value>,
}

/// The simulator is re-told an unchanged link at least this often (s), in case it
/// restarted.
const REFRESH_S: f64 = 5.0;

impl Radio {
    fn state(&self) -> Value {
        let m = self.current.metrics;
        json!({
            "backend": match self.backend { Backend::Simulated => "simulated", Backend::Mavlink => "mavlink" },
            "distance_m": self.current.distance_m,
            "rssi_dbm": m.map(|m| m.rssi_dbm),
            "link_margin_db": m.map(|m| m.link_margin_db),
            "loss_percent": m.map(|m| m.loss_fraction * 100.0),
            "latency_ms": m.map(|m| m.latency_ms),
            "applied_to_simulator": self.applied_ok,
            "override": self.override_link.map(|(l, t)| json!({"loss_fraction": l, "latency_ms": t})),
            "radio_status": self.radio_status,
            "model": self.model,
            "ground_station": {"north_m": self.ground_station.north_m, "east_m": self.ground_station.east_m, "down_m": self.ground_station.down_m},
        })
    }

    /// Recomputes the simulated link and tells the simulator when it changed.
    fn update_simulated(&mut self, ctx: &Context, force: bool) -> Result<(), String> {
        let vehicle = ctx.vehicle()?;
        self.current.distance_m = vehicle.ned().map(|p| (p - self.ground_station).norm());
        let metrics = match (self.override_link, self.current.distance_m) {
            (Some((loss, latency)), _) => Some(LinkMetrics {
                loss_fraction: loss,
                latency_ms: latency,
                ..self
                    .current
                    .distance_m
                    .map(|d| self.model.metrics(d))
                    .unwrap_or(LinkMetrics {
                        rssi_dbm: f64::NAN,
                        link_margin_db: f64::NAN,
                        loss_fraction: loss,
                        latency_ms: latency,
                    })
            }),
            (None, Some(d)) => Some(self.model.metrics(d)),
            // Position unknown: say nothing rather than guess.
            (None, None) => None,
        };
        self.current.metrics = metrics;
        let Some(m) = metrics else { return Ok(()) };
        // Negligible loss is no loss: the simulator need not roll dice for 1e-6.
        let loss = if m.loss_fraction < 1e-4 {
            0.0
        } else {
            m.loss_fraction
        };
        let due = force
            || match self.applied {
                None => true,
                Some((l, t, at)) => {
                    (loss - l).abs() > 1e-9
                        || (m.latency_ms - t).abs() > 1e-9
                        || self.time_s - at >= REFRESH_S
                }
            };
        if due {
            self.applied_ok = ctx.set_simulated_link(loss, m.latency_ms);
            self.applied = Some((loss, m.latency_ms, self.time_s));
        }
        Ok(())
    }

    fn on_radio_status(&mut self, s: &RADIO_STATUS_DATA) {
        // SiK radios report RSSI and noise as value ≈ (dBm + 127) × 1.9.
        let dbm = |v: u8| f64::from(v) / 1.9 - 127.0;
        let rssi = dbm(s.rssi);
        let noise = dbm(s.noise);
        self.current.metrics = Some(LinkMetrics {
            rssi_dbm: rssi,
            link_margin_db: rssi - noise,
            loss_fraction: f64::NAN,
            latency_ms: f64::NAN,
        });
        self.radio_status = Some(json!({
            "rssi": s.rssi, "remrssi": s.remrssi, "noise": s.noise, "remnoise": s.remnoise,
            "rxerrors": s.rxerrors, "fixed": s.fixed, "txbuf": s.txbuf,
            "remote_rssi_dbm": dbm(s.remrssi),
        }));
    }
}

/// `null` instead of NaN (JSON has no NaN).
fn finite(v: &mut Value) {
    if let Some(obj) = v.as_object_mut() {
        for val in obj.values_mut() {
            if val.as_f64().is_some_and(|f| !f.is_finite()) {
                *val = Value::Null;
            }
        }
    }
}

impl Plugin for Radio {
    const NAME: &'static str = "radio";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const KINDS: &'static [&'static str] = &["radio"];

    fn create(_kind: &str, config: Value, ctx: &Context) -> Result<Self, String> {
        let (cfg, model_update) = StationConfig::parse(config)?;
        let backend = if cfg.mode.simulated(ctx.simulated()) {
            Backend::Simulated
        } else {
            Backend::Mavlink
        };
        let mut model = RadioModel::default();
        model.update(&model_update)?;
        Ok(Radio {
            backend,
            model,
            ground_station: cfg.ground_station()?,
            rate_hz: args::in_range("rate_hz", cfg.rate_hz.unwrap_or(2.0), 0.1, 50.0)?,
            current: Current::default(),
            override_link: None,
            applied: None,
            applied_ok: false,
            time_s: 0.0,
            radio_status: None,
        })
    }

    fn tick_rate_hz(&self) -> f64 {
        self.rate_hz
    }

    fn tick(&mut self, ctx: &Context, dt_s: f64) -> Result<(), String> {
        self.time_s += dt_s.max(0.0);
        if self.backend == Backend::Simulated {
            self.update_simulated(ctx, false)?;
        }
        let mut s = self.state();
        finite(&mut s);
        ctx.publish_state(&s)
    }

    fn handle(&mut self, ctx: &Context, command: Value) -> Result<Value, String> {
        let command: Command = args::command(command)?;
        match &command {
            Command::SetModel(update) => {
                let mut model = self.model;
                model.update(update)?;
                self.model = model;
            }
            Command::Override {
                loss_fraction,
                latency_ms,
            } => {
                if self.backend != Backend::Simulated {
                    return Err(
                        "command `override`: only a simulated radio link can be degraded".into(),
                    );
                }
                self.override_link = Some((
                    args::in_range("loss_fraction", *loss_fraction, 0.0, 1.0)?,
                    args::in_range(
                        "latency_ms",
                        latency_ms.unwrap_or(self.model.base_latency_ms),
                        0.0,
                        60_000.0,
                    )?,
                ));
            }
            Command::ClearOverride => self.override_link = None,
            Command::Status => {}
        }
        if self.backend == Backend::Simulated && !matches!(command, Command::Status) {
            self.update_simulated(ctx, true)?;
        }
        let mut s = self.state();
        finite(&mut s);
        ctx.publish_state(&s)?;
        Ok(s)
    }

    fn mavlink_interest(&self) -> MavlinkInterest {
        match self.backend {
            Backend::Simulated => MavlinkInterest::None,
            Backend::Mavlink => MavlinkInterest::Ids(vec![RADIO_STATUS_DATA::ID]),
        }
    }

    fn on_mavlink(&mut self, _ctx: &Context, _compid: u8, msg: &MavMessage) -> Result<(), String> {
        if let MavMessage::RADIO_STATUS(s) = msg {
            self.on_radio_status(s);
        }
        Ok(())
    }

    fn shutdown(&mut self, ctx: &Context) {
        if self.backend == Backend::Simulated && self.applied.is_some() {
            ctx.set_simulated_link(0.0, 0.0);
        }
    }
}

export_plugin!(Radio);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loss_and_latency_grow_with_distance() {
        let m = RadioModel::default();
        let mut last = m.metrics(1.0);
        for d in [50.0, 100.0, 200.0, 300.0, 400.0, 500.0, 800.0, 2000.0] {
            let x = m.metrics(d);
            assert!(x.rssi_dbm < last.rssi_dbm, "{d}");
            assert!(x.loss_fraction > last.loss_fraction, "{d}");
            assert!(x.latency_ms > last.latency_ms, "{d}");
            last = x;
        }
    }

    #[test]
    fn documented_operating_points() {
        let m = RadioModel::default();
        assert!((m.reference_loss_db() - 40.05).abs() < 0.01);
        assert!(m.metrics(100.0).loss_fraction < 0.001);
        let at300 = m.metrics(300.0).loss_fraction;
        assert!((0.05..0.10).contains(&at300), "{at300}");
        let at500 = m.metrics(500.0).loss_fraction;
        assert!((0.5..0.7).contains(&at500), "{at500}");
        // At the sensitivity, half the packets are lost.
        let d50 = 10f64.powf((m.tx_power_dbm - m.sensitivity_dbm - m.reference_loss_db()) / 27.0);
        assert!((m.metrics(d50).loss_fraction - 0.5).abs() < 1e-9);
        assert!(m.metrics(1e7).latency_ms <= m.max_latency_ms);
    }

    #[test]
    fn model_update_checks_ranges() {
        let mut m = RadioModel::default();
        let e = m
            .update(&ModelUpdate {
                path_loss_exponent: Some(9.0),
                ..Default::default()
            })
            .unwrap_err();
        assert_eq!(e, "path_loss_exponent: 9 is outside [1.5, 6]");
        m.update(&ModelUpdate {
            tx_power_dbm: Some(27.0),
            ..Default::default()
        })
        .unwrap();
        assert_eq!(m.tx_power_dbm, 27.0);
        assert_eq!(m.path_loss_exponent, 2.7);
    }

    #[test]
    fn the_config_splits_into_station_and_model_fields() {
        let (cfg, model) = StationConfig::parse(json!({
            "mode": "simulated", "rate_hz": 4, "ground_station": {"east_m": 5}, "tx_power_dbm": 27
        }))
        .unwrap();
        assert_eq!((cfg.mode, cfg.rate_hz), (DeviceMode::Simulated, Some(4.0)));
        assert_eq!(cfg.ground_station().unwrap(), Ned::new(0.0, 5.0, 0.0));
        assert_eq!(model.tx_power_dbm, Some(27.0));
        assert!(StationConfig::parse(Value::Null).is_ok());
        let e = StationConfig::parse(json!({"colour": 1})).unwrap_err();
        assert!(e.starts_with("colour: unknown field `colour`"), "{e}");
        let e = StationConfig::parse(json!({"ground_station": {"north": 1}})).unwrap_err();
        assert!(e.starts_with("ground_station.north: unknown field"), "{e}");
        let e = StationConfig::parse(json!({"mode": "radio"})).unwrap_err();
        assert!(e.starts_with("mode: unknown variant `radio`"), "{e}");
    }
}
