//! The intruders' paths in the home frame: straight and weaving passes (with formation
//! slots), circles and breakaways, as pure functions of time, and how each pattern's paths
//! are built from the first pass; the group an intruder flies with.

use super::{CROSSING_BEFORE_CPA_M, IntruderConfig, IntruderPattern};
use rand::Rng;
use rand::rngs::SmallRng;
use skein_model::geo::Ned;

/// One intruder's path, in the home frame.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Path {
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
pub(super) fn heading(heading_deg: f64) -> Ned {
    let (s, c) = heading_deg.to_radians().sin_cos();
    Ned::new(c, s, 0.0)
}

impl Path {
    pub(super) fn position(&self, t_s: f64, speed_m_s: f64) -> Ned {
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

/// The group of an intruder: `group-<n>` from `from_s` on, `before` until then.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Group {
    pub(super) before: Option<u32>,
    pub(super) from_s: f64,
    pub(super) after: Option<u32>,
}

impl Group {
    pub(super) fn alone() -> Self {
        Self::always(None)
    }

    pub(super) fn always(g: Option<u32>) -> Self {
        Group {
            before: g,
            from_s: 0.0,
            after: g,
        }
    }

    pub(super) fn at(&self, t_s: f64) -> Option<String> {
        let g = if t_s < self.from_s {
            self.before
        } else {
            self.after
        };
        g.map(|n| format!("group-{n}"))
    }
}

pub(super) fn pass(rng: &mut SmallRng, cfg: &IntruderConfig, down_m: f64, first: bool) -> Path {
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

/// `pass` weaving ±15 m every 40 m (the zig-zag).
pub(super) fn weaving(pass: &Path) -> Path {
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
pub(super) fn crossing(pass: &Path, range_m: f64) -> Path {
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
pub(super) fn single_path(
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
