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

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use serde::Serialize;
use skein_model::geo::{GeoPoint, Ned, NedFrame};
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

/// One intruder's path, in the home frame.
#[derive(Debug, Clone, PartialEq)]
enum Path {
    /// Back and forth from `start` along `dir` for `length_m`, weaving `weave_m` either
    /// side every `wavelength_m` (0: straight), shifted by `offset` (formation slots).
    Pass {
        start: Ned,
        dir: Ned,
        length_m: f64,
        weave_m: f64,
        wavelength_m: f64,
        offset_back_m: f64,
        offset_left_m: f64,
    },
    /// Circle around `centre`, `clockwise` seen from above.
    Circle {
        centre: Ned,
        radius_m: f64,
        phase_rad: f64,
        clockwise: bool,
    },
    /// `base` until `at_s`, then straight on along its direction then turned `turn_rad`
    /// (clockwise seen from above).
    Breakaway {
        base: Box<Path>,
        at_s: f64,
        turn_rad: f64,
    },
}

/// Triangle wave of period 1 in [-1, 1], 0 at 0.
fn triangle(x: f64) -> f64 {
    let f = (x + 0.25).rem_euclid(1.0);
    if f < 0.5 {
        4.0 * f - 1.0
    } else {
        3.0 - 4.0 * f
    }
}

/// Unit horizontal vector along `heading_deg`.
fn heading(heading_deg: f64) -> Ned {
    let (s, c) = heading_deg.to_radians().sin_cos();
    Ned::new(c, s, 0.0)
}

impl Path {
    fn position(&self, t_s: f64, speed_m_s: f64) -> Ned {
        match *self {
            Path::Pass {
                start,
                dir,
                length_m,
                weave_m,
                wavelength_m,
                offset_back_m,
                offset_left_m,
            } => {
                // Along-track speed such that the path speed is `speed_m_s`.
                let slope = if wavelength_m > 0.0 {
                    4.0 * weave_m / wavelength_m
                } else {
                    0.0
                };
                let along_speed = speed_m_s / (1.0 + slope * slope).sqrt();
                // Back and forth: the distance flown folded into [0, length].
                let flown = (along_speed * t_s).rem_euclid(2.0 * length_m);
                let (s, forward) = if flown <= length_m {
                    (flown, 1.0)
                } else {
                    (2.0 * length_m - flown, -1.0)
                };
                let left = Ned::new(dir.east_m, -dir.north_m, 0.0);
                let weave = if wavelength_m > 0.0 {
                    weave_m * triangle(s / wavelength_m)
                } else {
                    0.0
                };
                // Formation slots keep behind the leader in the current direction.
                start + dir * (s - forward * offset_back_m) + left * (weave + offset_left_m)
            }
            Path::Circle {
                centre,
                radius_m,
                phase_rad,
                clockwise,
            } => {
                let w = speed_m_s / radius_m * if clockwise { 1.0 } else { -1.0 };
                let a = phase_rad + w * t_s;
                centre + Ned::new(radius_m * a.cos(), radius_m * a.sin(), 0.0)
            }
            Path::Breakaway {
                ref base,
                at_s,
                turn_rad,
            } => {
                if t_s <= at_s {
                    return base.position(t_s, speed_m_s);
                }
                let p0 = base.position(at_s, speed_m_s);
                let d = base.position(at_s, speed_m_s) - base.position(at_s - 0.01, speed_m_s);
                let h = d.east_m.atan2(d.north_m) + turn_rad;
                p0 + heading(h.to_degrees()) * (speed_m_s * (t_s - at_s))
            }
        }
    }
}

/// The intruders of one simulation run.
#[derive(Debug, Clone)]
pub struct Intruders {
    frame: NedFrame,
    start: Instant,
    config: IntruderConfig,
    paths: Vec<(IntruderPattern, Path, Group)>,
}

/// The group of an intruder: `group-<n>` from `from_s` on, `before` until then.
#[derive(Debug, Clone, PartialEq)]
struct Group {
    before: Option<u32>,
    from_s: f64,
    after: Option<u32>,
}

impl Group {
    fn alone() -> Self {
        Self::always(None)
    }

    fn always(g: Option<u32>) -> Self {
        Group {
            before: g,
            from_s: 0.0,
            after: g,
        }
    }

    fn at(&self, t_s: f64) -> Option<String> {
        let g = if t_s < self.from_s {
            self.before
        } else {
            self.after
        };
        g.map(|n| format!("group-{n}"))
    }
}

fn pass(rng: &mut SmallRng, cfg: &IntruderConfig, down_m: f64, first: bool) -> Path {
    let heading_deg = match cfg.heading_deg {
        Some(h) if first => h,
        _ => rng.random_range(0.0..360.0),
    };
    let cpa_m = match cfg.cpa_m {
        Some(c) if first => c,
        _ => rng.random_range(10.0..50.0),
    };
    let dir = heading(heading_deg);
    let left = Ned::new(dir.east_m, -dir.north_m, 0.0);
    let cpa = left * cpa_m + Ned::new(0.0, 0.0, down_m);
    Path::Pass {
        start: cpa - dir * cfg.range_m,
        dir,
        length_m: 2.0 * cfg.range_m,
        weave_m: 0.0,
        wavelength_m: 0.0,
        offset_back_m: 0.0,
        offset_left_m: 0.0,
    }
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
            start,
            config,
            paths,
        })
    }
}

/// `pass` weaving ±15 m every 40 m (the zig-zag).
fn weaving(pass: &Path) -> Path {
    match pass {
        Path::Pass {
            start,
            dir,
            length_m,
            ..
        } => Path::Pass {
            start: *start,
            dir: *dir,
            length_m: *length_m,
            weave_m: 15.0,
            wavelength_m: 40.0,
            offset_back_m: 0.0,
            offset_left_m: 0.0,
        },
        other => other.clone(),
    }
}

/// The pass crossing `pass` at right angles (turned to its right)
/// [`CROSSING_BEFORE_CPA_M`] before its closest point of approach, its leader 15 m behind
/// `pass`'s there.
fn crossing(pass: &Path, range_m: f64) -> Path {
    match pass {
        Path::Pass {
            start,
            dir,
            length_m,
            ..
        } => {
            let along = (range_m - CROSSING_BEFORE_CPA_M).max(0.0);
            let cross = *start + *dir * along;
            let d = Ned::new(-dir.east_m, dir.north_m, 0.0);
            Path::Pass {
                start: cross - d * (along + 15.0),
                dir: d,
                length_m: *length_m,
                weave_m: 0.0,
                wavelength_m: 0.0,
                offset_back_m: 0.0,
                offset_left_m: 0.0,
            }
        }
        other => other.clone(),
    }
}

/// The path of a lone intruder `i` of pattern `pattern` (straight, loiter, zigzag).
fn single_path(
    pattern: IntruderPattern,
    i: usize,
    leader: &Path,
    rng: &mut SmallRng,
    config: &IntruderConfig,
    down_m: f64,
) -> Path {
    match pattern {
        IntruderPattern::Straight if i == 0 => leader.clone(),
        IntruderPattern::Straight => pass(rng, config, down_m, false),
        IntruderPattern::Zigzag => match pass(rng, config, down_m, i == 0) {
            Path::Pass {
                start,
                dir,
                length_m,
                ..
            } => Path::Pass {
                start,
                dir,
                length_m,
                weave_m: 15.0,
                wavelength_m: 40.0,
                offset_back_m: 0.0,
                offset_left_m: 0.0,
            },
            circle => circle,
        },
        IntruderPattern::Loiter => {
            let bearing: f64 = rng.random_range(0.0..360.0);
            let distance = config.range_m * rng.random_range(0.3..0.8);
            Path::Circle {
                centre: heading(bearing) * distance + Ned::new(0.0, 0.0, down_m),
                radius_m: rng.random_range(15.0..40.0),
                phase_rad: rng.random_range(0.0..std::f64::consts::TAU),
                clockwise: rng.random_bool(0.5),
            }
        }
        _ => leader.clone(),
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

    /// Ground truth now.
    pub fn truth(&self) -> Vec<IntruderTruth> {
        self.truth_at(
            Instant::now()
                .saturating_duration_since(self.start)
                .as_secs_f64(),
        )
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PX4_SITL_HOME;

    fn intruders(cfg: IntruderConfig) -> Intruders {
        Intruders::new(PX4_SITL_HOME, cfg, Instant::now()).expect("valid config")
    }

    #[test]
    fn straight_pass_crosses_at_its_closest_point_at_speed() {
        let cfg = IntruderConfig {
            count: 1,
            pattern: Some(IntruderPattern::Straight),
            heading_deg: Some(90.0),
            cpa_m: Some(60.0),
            range_m: 100.0,
            speed_m_s: 5.0,
            altitude_m: 20.0,
            ..IntruderConfig::default()
        };
        let ints = intruders(cfg);
        let at_start = &ints.truth_at(0.0)[0];
        assert!((at_start.home_ned_m.north_m - 60.0).abs() < 1e-9);
        assert!((at_start.home_ned_m.east_m + 100.0).abs() < 1e-9);
        assert!((at_start.home_ned_m.down_m + 20.0).abs() < 1e-9);
        // 20 s later: at the closest point of approach, flying east at 5 m/s.
        let mid = &ints.truth_at(20.0)[0];
        assert!(mid.home_ned_m.east_m.abs() < 1e-6, "{mid:?}");
        assert!((mid.velocity_ned_m_s.east_m - 5.0).abs() < 1e-6);
        // After the pass it comes back.
        let back = &ints.truth_at(45.0)[0];
        assert!(
            (back.velocity_ned_m_s.east_m + 5.0).abs() < 1e-6,
            "{back:?}"
        );
        assert_eq!(at_start.id, "intruder-1");
    }

    #[test]
    fn every_pattern_flies_at_its_speed_and_seeds_repeat() {
        let cfg = IntruderConfig {
            count: 3,
            seed: 7,
            speed_m_s: 6.0,
            ..IntruderConfig::default()
        };
        let a = intruders(cfg.clone());
        let b = intruders(cfg.clone());
        let pats: Vec<_> = a.truth_at(0.0).iter().map(|t| t.pattern).collect();
        assert_eq!(
            pats,
            [
                IntruderPattern::Straight,
                IntruderPattern::Loiter,
                IntruderPattern::Zigzag
            ]
        );
        for t in [1.0, 13.3, 77.0] {
            assert_eq!(a.truth_at(t), b.truth_at(t));
            for tr in a.truth_at(t) {
                let speed = tr.velocity_ned_m_s.norm();
                assert!((speed - 6.0).abs() < 0.05, "{} at {t}: {speed}", tr.id);
                assert!((tr.home_ned_m.down_m + 20.0).abs() < 1e-9);
            }
        }
        let other = intruders(IntruderConfig { seed: 8, ..cfg });
        assert_ne!(a.truth_at(5.0), other.truth_at(5.0));
    }

    #[test]
    fn formation_flies_a_v_behind_its_leader() {
        let ints = intruders(IntruderConfig {
            count: 3,
            pattern: Some(IntruderPattern::Formation),
            heading_deg: Some(0.0),
            cpa_m: Some(0.0),
            ..IntruderConfig::default()
        });
        let t = ints.truth_at(10.0);
        // Flying north: members 2 and 3 are 6 m behind, 6 m to either side.
        let d1 = t[1].home_ned_m - t[0].home_ned_m;
        let d2 = t[2].home_ned_m - t[0].home_ned_m;
        assert!((d1.north_m + 6.0).abs() < 1e-9 && (d1.east_m.abs() - 6.0).abs() < 1e-9);
        assert!((d2.north_m + 6.0).abs() < 1e-9 && (d2.east_m + d1.east_m).abs() < 1e-9);
    }

    #[test]
    fn crossing_swarms_and_a_split_fly_in_their_groups() {
        let cfg = |pattern| IntruderConfig {
            count: 5,
            pattern: Some(pattern),
            heading_deg: Some(0.0),
            cpa_m: Some(40.0),
            range_m: 100.0,
            ..IntruderConfig::default()
        };
        // Crossing: three fly north, two east, their leaders over the same point 3 s apart.
        let x = intruders(cfg(IntruderPattern::Crossing));
        let t = x.truth_at(20.0);
        let groups: Vec<_> = t.iter().map(|i| i.group.clone().unwrap()).collect();
        assert_eq!(
            groups,
            ["group-1", "group-1", "group-1", "group-2", "group-2"]
        );
        assert!((t[0].velocity_ned_m_s.north_m - 5.0).abs() < 1e-6);
        assert!(
            (t[3].velocity_ned_m_s.east_m - 5.0).abs() < 1e-6,
            "{:?}",
            t[3]
        );
        let meet = (100.0 - CROSSING_BEFORE_CPA_M) / 5.0;
        let (a, b) = (x.truth_at(meet), x.truth_at(meet + 3.0));
        assert!((b[3].home_ned_m - a[0].home_ned_m).horizontal_norm() < 1e-6);
        // Split: 30 m before the closest point the right arm turns 40° right and is group 2.
        let s = intruders(cfg(IntruderPattern::Split));
        let at = (100.0 - SPLIT_BEFORE_CPA_M) / 5.0;
        let before = s.truth_at(at - 1.0);
        assert!(before.iter().all(|i| i.group.as_deref() == Some("group-1")));
        let after = s.truth_at(at + 5.0);
        for (i, tr) in after.iter().enumerate() {
            let v = tr.velocity_ned_m_s;
            let course = v.east_m.atan2(v.north_m).to_degrees();
            if i % 2 == 1 {
                assert_eq!(tr.group.as_deref(), Some("group-2"));
                assert!((course - SPLIT_TURN_DEG).abs() < 0.5, "{course}");
            } else {
                assert_eq!(tr.group.as_deref(), Some("group-1"));
                assert!(course.abs() < 0.5, "{course}");
            }
            assert!((v.norm() - 5.0).abs() < 0.05);
        }
        // The zig-zag V weaves together: its slots keep their offsets.
        let z = intruders(cfg(IntruderPattern::FormationZigzag));
        let (a, b) = (z.truth_at(7.0), z.truth_at(13.0));
        let d = |t: &[IntruderTruth]| t[1].home_ned_m - t[0].home_ned_m;
        assert!((d(&a) - d(&b)).norm() < 1e-9);
        assert!(
            (a[0].velocity_ned_m_s.east_m - b[0].velocity_ned_m_s.east_m).abs() > 1.0,
            "it weaves"
        );
        assert_eq!(
            IntruderPattern::parse("formation-zigzag"),
            Ok(Some(IntruderPattern::FormationZigzag))
        );
        // Lone intruders belong to no group.
        let lone = intruders(IntruderConfig {
            count: 3,
            ..IntruderConfig::default()
        });
        assert!(lone.truth_at(1.0).iter().all(|i| i.group.is_none()));
    }

    #[test]
    fn bad_configs_are_refused() {
        let bad = IntruderConfig {
            count: 1,
            speed_m_s: 0.0,
            ..IntruderConfig::default()
        };
        assert!(Intruders::new(PX4_SITL_HOME, bad, Instant::now()).is_err());
        assert!(IntruderPattern::parse("spiral").is_err());
        assert_eq!(IntruderPattern::parse("mixed"), Ok(None));
    }
}
