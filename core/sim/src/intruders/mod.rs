//! Intruders: non-cooperative aircraft flying in the simulator's world with no MAVLink link.
//!
//! An intruder has no socket, no sysid and no telemetry: the simulated radio never hears
//! it and skein's links never see it. It exists only as a path through the world that the
//! simulated cameras render (through the payload host's `sim_aircraft` service) and as
//! ground truth for evaluation (`GET /api/v1/sim/truth`, the stats socket's `intruders`).
//!
//! Paths are pure functions of the time since the intruders were started, so they are
//! deterministic for a seed and need no simulation tick. Positions are in the NED frame of
//! the simulator's home (the first vehicle's spawn point), heights above it:
//! - **straight**: a straight pass of `2 × range_m` along `heading_deg` (seeded when not
//!   given), whose closest point of approach lies `cpa_m` from home on its left, then the
//!   same pass back, and so on;
//! - **loiter**: a circle of 15–40 m radius around a seeded centre 30–80 % of `range_m`
//!   from home;
//! - **zigzag**: a straight pass with a ±15 m triangular weave every 40 m along the track;
//! - **formation**: every intruder flies the straight pass of the first one in a V behind
//!   it, 6 m apart;
//! - **formation_zigzag**: the same V on a zig-zag pass (the whole V weaves);
//! - **crossing**: two Vs (the first half of the intruders, and the rest) whose passes
//!   cross at right angles [`CROSSING_BEFORE_CPA_M`] before the first pass's closest point
//!   of approach, the second leader 15 m behind the first;
//! - **split**: a V whose members on its right arm (intruders 2, 4, …) break away
//!   [`SPLIT_TURN_DEG`] to the right [`SPLIT_BEFORE_CPA_M`] before the closest point of
//!   approach, and fly on straight.
//!
//! Intruders flying together carry a `group` in their truth (`group-1`, `group-2`: the
//! second V of a crossing, a split's breakaway once it turned), for scoring swarm
//! recognition; lone intruders have none.
//!
//! `mixed` (the default) gives intruder i the pattern straight, loiter, zigzag by turns.

use rand::SeedableRng;
use rand::rngs::SmallRng;
use serde::Serialize;
use skein_model::geo::{GeoPoint, Ned, NedFrame};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// The flight pattern of an intruder.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum IntruderPattern {
    /// Straight passes back and forth.
    Straight,
    /// A circle.
    Loiter,
    /// A weaving pass back and forth.
    Zigzag,
    /// A V of intruders on one straight pass.
    Formation,
    /// A V of intruders on one zig-zag pass.
    FormationZigzag,
    /// Two Vs whose passes cross.
    Crossing,
    /// A V that splits in two.
    Split,
}

/// Two crossing swarms cross this far along the first pass before its closest point of
/// approach (so that the second does not fly over home), metres.
pub const CROSSING_BEFORE_CPA_M: f64 = 40.0;
/// A split's breakaway turns this far to the right, degrees.
pub const SPLIT_TURN_DEG: f64 = 40.0;
/// … this far along the pass before its closest point of approach, metres.
pub const SPLIT_BEFORE_CPA_M: f64 = 30.0;

impl IntruderPattern {
    /// The pattern named `s` (`straight`, `loiter`, `zigzag`, `formation`); `mixed` is
    /// `None` (each intruder its own pattern).
    ///
    /// # Errors
    /// Any other name.
    pub fn parse(s: &str) -> Result<Option<IntruderPattern>, String> {
        match s.to_ascii_lowercase().as_str() {
            "straight" => Ok(Some(IntruderPattern::Straight)),
            "loiter" => Ok(Some(IntruderPattern::Loiter)),
            "zigzag" | "zig-zag" => Ok(Some(IntruderPattern::Zigzag)),
            "formation" => Ok(Some(IntruderPattern::Formation)),
            "formation_zigzag" | "formation-zigzag" => Ok(Some(IntruderPattern::FormationZigzag)),
            "crossing" => Ok(Some(IntruderPattern::Crossing)),
            "split" => Ok(Some(IntruderPattern::Split)),
            "mixed" => Ok(None),
            other => Err(format!(
                "unknown intruder pattern {other:?} (straight, loiter, zigzag, formation, \
                 formation_zigzag, crossing, split, mixed)"
            )),
        }
    }
}

/// How many intruders fly, and how.
#[derive(Debug, Clone, PartialEq)]
pub struct IntruderConfig {
    /// Number of intruders (ids `intruder-1` …).
    pub count: usize,
    /// Pattern of every intruder; `None` = mixed.
    pub pattern: Option<IntruderPattern>,
    /// Ground speed along the path, m/s.
    pub speed_m_s: f64,
    /// Height above home, m.
    pub altitude_m: f64,
    /// Half the length of a pass and the scale of the loiter placement, m.
    pub range_m: f64,
    /// Heading of the (first) straight pass, degrees from north; `None` = seeded.
    pub heading_deg: Option<f64>,
    /// Distance from home to the pass's closest point of approach (on the pass's left), m;
    /// `None` = seeded in 10–50 m.
    pub cpa_m: Option<f64>,
    /// Rotor-tip to rotor-tip span the cameras draw, m.
    pub span_m: f64,
    /// Seed of the paths.
    pub seed: u64,
}

impl Default for IntruderConfig {
    fn default() -> Self {
        IntruderConfig {
            count: 0,
            pattern: None,
            speed_m_s: 5.0,
            altitude_m: 20.0,
            range_m: 120.0,
            heading_deg: None,
            cpa_m: None,
            span_m: 0.8,
            seed: 0,
        }
    }
}

/// Ground truth of one intruder.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IntruderTruth {
    /// `intruder-<n>`, n from 1.
    pub id: String,
    /// Its pattern.
    pub pattern: IntruderPattern,
    /// True geodetic position.
    pub position: GeoPoint,
    /// Position in the NED frame of the simulator's home, m.
    pub home_ned_m: Ned,
    /// Velocity, NED, m/s.
    pub velocity_ned_m_s: Ned,
    /// Span, m.
    pub span_m: f64,
    /// The group it flies with (`group-1`, …), for scoring; `None` alone.
    pub group: Option<String>,
}

mod paths;
#[cfg(test)]
mod tests;

use paths::{Group, Path, crossing, pass, single_path, weaving};

/// The intruders of one simulation run.
#[derive(Debug)]
pub struct Intruders {
    frame: NedFrame,
    /// When their paths started (t = 0); [`Intruders::restart`] moves it.
    start: Mutex<Instant>,
    /// They left the world ([`Intruders::leave`]) until the next restart.
    away: AtomicBool,
    config: IntruderConfig,
    paths: Vec<(IntruderPattern, Path, Group)>,
}

impl Intruders {
    /// The intruders of `config` around `home` (the simulator's home), starting their
    /// paths at `start`.
    ///
    /// # Errors
    /// A speed, range or span that is not positive and finite, or an altitude that is not
    /// finite.
    pub fn new(home: GeoPoint, config: IntruderConfig, start: Instant) -> Result<Self, String> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !positive(config.speed_m_s) {
            return Err(format!(
                "intruder speed {} m/s must be > 0",
                config.speed_m_s
            ));
        }
        if !positive(config.range_m) || !positive(config.span_m) {
            return Err("intruder range and span must be > 0".into());
        }
        if !config.altitude_m.is_finite() {
            return Err("intruder altitude must be finite".into());
        }
        let down_m = -config.altitude_m;
        let mut rng = SmallRng::seed_from_u64(config.seed ^ 0x1A7D_0DE5_0000_0000);
        let mut paths = Vec::with_capacity(config.count);
        let leader = pass(&mut rng, &config, down_m, true);
        for i in 0..config.count {
            let pattern = config.pattern.unwrap_or(match i % 3 {
                0 => IntruderPattern::Straight,
                1 => IntruderPattern::Loiter,
                _ => IntruderPattern::Zigzag,
            });
            let v_slot = |lead: &Path, slot: usize| match lead {
                Path::Pass {
                    start,
                    dir,
                    length_m,
                    weave_m,
                    wavelength_m,
                    ..
                } => {
                    // Slots of a V: 0 leads, then pairs behind on either side.
                    let rank = slot.div_ceil(2) as f64;
                    let side = if slot % 2 == 1 { 1.0 } else { -1.0 };
                    Path::Pass {
                        start: *start,
                        dir: *dir,
                        length_m: *length_m,
                        weave_m: *weave_m,
                        wavelength_m: *wavelength_m,
                        offset_back_m: 6.0 * rank,
                        offset_left_m: side * 6.0 * rank,
                    }
                }
                other => other.clone(),
            };
            let (path, group) = match pattern {
                IntruderPattern::Formation => (v_slot(&leader, i), Group::always(Some(1))),
                IntruderPattern::FormationZigzag => {
                    (v_slot(&weaving(&leader), i), Group::always(Some(1)))
                }
                IntruderPattern::Crossing => {
                    let first = config.count.div_ceil(2);
                    if i < first {
                        (v_slot(&leader, i), Group::always(Some(1)))
                    } else {
                        (
                            v_slot(&crossing(&leader, config.range_m), i - first),
                            Group::always(Some(2)),
                        )
                    }
                }
                IntruderPattern::Split => {
                    let at_s = (config.range_m - SPLIT_BEFORE_CPA_M).max(0.0) / config.speed_m_s;
                    if i % 2 == 1 {
                        let path = Path::Breakaway {
                            base: Box::new(v_slot(&leader, i)),
                            at_s,
                            turn_rad: SPLIT_TURN_DEG.to_radians(),
                        };
                        let g = Group {
                            before: Some(1),
                            from_s: at_s,
                            after: Some(2),
                        };
                        (path, g)
                    } else {
                        (v_slot(&leader, i), Group::always(Some(1)))
                    }
                }
                single => (
                    single_path(single, i, &leader, &mut rng, &config, down_m),
                    Group::alone(),
                ),
            };
            paths.push((pattern, path, group));
        }
        Ok(Intruders {
            frame: NedFrame::new(home),
            start: Mutex::new(start),
            away: AtomicBool::new(false),
            config,
            paths,
        })
    }
}

impl Intruders {
    /// Number of intruders.
    pub fn len(&self) -> usize {
        self.paths.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.paths.is_empty()
    }

    /// The configuration they fly.
    pub fn config(&self) -> &IntruderConfig {
        &self.config
    }

    /// Ground truth `t_s` seconds after the start.
    pub fn truth_at(&self, t_s: f64) -> Vec<IntruderTruth> {
        // Forward difference (paths start at t = 0; a reversal blurs 1 ms of it).
        const DT: f64 = 0.001;
        let v = self.config.speed_m_s;
        self.paths
            .iter()
            .enumerate()
            .map(|(i, (pattern, path, group))| {
                let p = path.position(t_s, v);
                let vel = (path.position(t_s + DT, v) - p) * (1.0 / DT);
                IntruderTruth {
                    id: format!("intruder-{}", i + 1),
                    pattern: *pattern,
                    position: self.frame.to_geo(p),
                    home_ned_m: p,
                    velocity_ned_m_s: vel,
                    span_m: self.config.span_m,
                    group: group.at(t_s),
                }
            })
            .collect()
    }

    /// Ground truth now (none while they are away).
    pub fn truth(&self) -> Vec<IntruderTruth> {
        if self.away.load(Ordering::Relaxed) {
            return Vec::new();
        }
        let start = *self.start.lock().unwrap_or_else(|p| p.into_inner());
        self.truth_at(
            Instant::now()
                .saturating_duration_since(start)
                .as_secs_f64(),
        )
    }

    /// Starts every path again from its beginning at `at` (t = 0 then): each intruder
    /// jumps back to where it started.
    pub fn restart(&self, at: Instant) {
        *self.start.lock().unwrap_or_else(|p| p.into_inner()) = at;
        self.away.store(false, Ordering::Relaxed);
    }

    /// Every intruder leaves the world (lands out of sight): no camera sees one, and the
    /// truth lists none, until [`Intruders::restart`].
    pub fn leave(&self) {
        self.away.store(true, Ordering::Relaxed);
    }
}

/// A pattern given on the command line: one for every intruder, or `None` for mixed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PatternChoice(pub Option<IntruderPattern>);

impl PatternChoice {
    /// See [`IntruderPattern::parse`].
    ///
    /// # Errors
    /// An unknown pattern name.
    pub fn parse(s: &str) -> Result<PatternChoice, String> {
        IntruderPattern::parse(s).map(PatternChoice)
    }
}

/// Command-line options of the intruders (`skein sim` and `skein up --sim`).
#[derive(clap::Args, Debug, Clone, PartialEq)]
pub struct IntruderArgs {
    /// Non-cooperative aircraft (no MAVLink link) flying seeded patterns, seen only by the
    /// simulated cameras.
    #[arg(long, value_name = "M", default_value_t = 0)]
    pub intruders: usize,
    /// Their pattern: straight, loiter, zigzag, formation (a V), formation_zigzag (a
    /// weaving V), crossing (two Vs crossing), split (a V splitting in two), or mixed
    /// (straight, loiter and zigzag by turns).
    #[arg(long, value_name = "PATTERN", default_value = "mixed", value_parser = PatternChoice::parse)]
    pub intruder_pattern: PatternChoice,
    /// Their speed, m/s.
    #[arg(long, default_value_t = 5.0)]
    pub intruder_speed_m_s: f64,
    /// Their height above home, m.
    #[arg(long, default_value_t = 20.0)]
    pub intruder_altitude_m: f64,
    /// Half a pass's length (they start this far before the closest point of approach), m.
    #[arg(long, default_value_t = 120.0)]
    pub intruder_range_m: f64,
    /// Heading of the (first) straight pass, degrees from north (default: seeded).
    #[arg(long)]
    pub intruder_heading_deg: Option<f64>,
    /// Distance from home to the (first) pass's closest point of approach, on the pass's
    /// left, m (default: seeded in 10–50 m).
    #[arg(long)]
    pub intruder_cpa_m: Option<f64>,
}

impl IntruderArgs {
    /// The configuration these options describe, with the simulator's `seed`.
    pub fn config(&self, seed: u64) -> IntruderConfig {
        IntruderConfig {
            count: self.intruders,
            pattern: self.intruder_pattern.0,
            speed_m_s: self.intruder_speed_m_s,
            altitude_m: self.intruder_altitude_m,
            range_m: self.intruder_range_m,
            heading_deg: self.intruder_heading_deg,
            cpa_m: self.intruder_cpa_m,
            seed,
            ..IntruderConfig::default()
        }
    }
}
