//! A formation change in flight (CAPT, see the module docs of [`super`]): every member on
//! a straight line from its start to its new slot in the pattern frame, all members on
//! one shared time scale `β(t)` with a trapezoidal profile, paced by the slowest member;
//! followers whose line would pass a leader vehicle fly it on a layer above (or below)
//! it ([`Climb`]), reached before and left after the horizontal motion.

pub use super::climb::TRANSIT_CLIMB_M_S;
use super::climb::{Climb, Keepout};
use skein_model::geo::Ned;
use std::collections::BTreeMap;

/// Speed of the longest path of a transition relative to the pattern, m/s (a formation
/// moving at 5 m/s stays within the 8 m/s default vehicle limit).
pub const TRANSIT_SPEED_M_S: f64 = 2.5;
/// Acceleration of a transition's time scale along the longest path, m/s².
pub const TRANSIT_ACCEL_M_S2: f64 = 0.5;
/// A member this far behind its planned place slows the transition's time scale down…
pub const LAG_SLOW_M: f64 = 0.75;
/// … and this far stops it: the plan separates members *at one time scale*, so the
/// time scale waits for the slowest instead of leaving it behind.
pub const LAG_STOP_M: f64 = 1.5;

/// A formation change in progress: every member on a straight line in the pattern frame,
/// all on one time scale (see the module docs).
///
/// When followers must pass a leader vehicle, the change has three phases on that time
/// scale: those followers climb (or descend) to their layer while everyone else holds
/// (`hold_s`), then every member flies its straight line with the layered followers
/// staying at their layer, then they return to the formation's altitude at their slots
/// (`hold_s` again). Horizontal motion happens only in the middle phase, all members on
/// one `β`, so the assignment's separation argument holds throughout.
#[derive(Debug, Clone)]
pub(super) struct Transition {
    /// Where each member starts, pattern frame (unrotated offsets from the anchor).
    pub(super) starts: BTreeMap<String, Ned>,
    /// Where each member ends, pattern frame.
    pub(super) goals: BTreeMap<String, Ned>,
    /// Length of the longest path (vertical legs scaled to their slower speed), metres.
    length_m: f64,
    /// Time along the profile, seconds (advances slower than real time while a member
    /// lags its plan).
    elapsed_s: f64,
    /// Rate of the time scale against real time at the last tick, 0 to 1.
    scale: f64,
    /// Layer of the followers that pass a leader vehicle, by member.
    climbs: BTreeMap<String, Climb>,
    /// Length of the layering phases before and after the straight lines, seconds.
    hold_s: f64,
}

impl Transition {
    /// A transition with no member yet, at its start, on a full-rate time scale.
    pub(super) fn new() -> Self {
        Transition {
            starts: BTreeMap::new(),
            goals: BTreeMap::new(),
            length_m: 0.0,
            elapsed_s: 0.0,
            scale: 1.0,
            climbs: BTreeMap::new(),
            hold_s: 0.0,
        }
    }

    /// Adds member `id` going `start → goal` (pattern frame, metres). With
    /// `leader_separation_m` (a leader vehicle at the pattern's origin), a member whose
    /// straight path would pass closer than that to it flies on a layer ([`Climb`]).
    pub(super) fn add(&mut self, id: &str, start: Ned, goal: Ned, keepouts: &[Keepout]) {
        self.length_m = self.length_m.max(leg_length(goal - start));
        // The assignment's ordering argument does not cover the leader vehicle (it keeps
        // slot 0): a follower whose straight path would pass it flies on a layer above (or
        // below) it, reached before anyone moves horizontally and left after everyone
        // arrived (see `Transition`).
        if keepouts.iter().any(|k| !k.clear(start, goal, None)) {
            let climb = Climb::over(start, goal, keepouts);
            self.hold_s = self.hold_s.max(climb.hold_s());
            self.climbs.insert(id.to_string(), climb);
        }
        self.starts.insert(id.to_string(), start);
        self.goals.insert(id.to_string(), goal);
    }

    /// Every place a member may be sent on this plan (pattern frame, metres): the ends of
    /// each straight line and of each layer (the paths between them are straight).
    pub(super) fn extents(&self) -> Vec<Ned> {
        let mut out = Vec::new();
        for (id, start) in &self.starts {
            let up = Ned::new(0.0, 0.0, -self.climbs.get(id).map_or(0.0, |c| c.height_m));
            out.push(*start);
            out.push(*start + up);
            if let Some(goal) = self.goals.get(id) {
                out.push(*goal);
                out.push(*goal + up);
            }
        }
        out
    }

    /// Advances the time scale by `dt_s` real seconds when the slowest member is `lag_m`
    /// metres behind its planned place: full rate up to [`LAG_SLOW_M`], stopped from
    /// [`LAG_STOP_M`].
    pub(super) fn advance(&mut self, dt_s: f64, lag_m: f64) {
        self.scale = ((LAG_STOP_M - lag_m) / (LAG_STOP_M - LAG_SLOW_M)).clamp(0.0, 1.0);
        self.elapsed_s += dt_s * self.scale;
    }

    /// Duration of the straight-line phase, seconds: a trapezoidal speed profile over
    /// `length_m` (peak speed, its acceleration time, and the cruise time).
    fn profile(&self) -> (f64, f64, f64) {
        let (l, v, a) = (self.length_m, TRANSIT_SPEED_M_S, TRANSIT_ACCEL_M_S2);
        let vp = v.min((a * l).sqrt());
        let ta = vp / a;
        let tc = ((l - vp * ta) / vp).max(0.0);
        (vp, ta, tc)
    }

    /// Total duration on the time scale, seconds.
    fn duration_s(&self) -> f64 {
        if self.length_m < 1e-6 {
            return 2.0 * self.hold_s;
        }
        let (_, ta, tc) = self.profile();
        2.0 * self.hold_s + 2.0 * ta + tc
    }

    /// Progress `β` in [0, 1] of the straight lines and its rate (1/s) at `elapsed_s`.
    pub(super) fn progress(&self) -> (f64, f64) {
        let l = self.length_m;
        if l < 1e-6 {
            return (
                if self.elapsed_s >= self.hold_s {
                    1.0
                } else {
                    0.0
                },
                0.0,
            );
        }
        let (vp, ta, tc) = self.profile();
        let a = TRANSIT_ACCEL_M_S2;
        let da = 0.5 * a * ta * ta;
        let t = self.elapsed_s - self.hold_s;
        let (s, ds) = if t <= 0.0 {
            (0.0, 0.0)
        } else if t < ta {
            (0.5 * a * t * t, a * t)
        } else if t < ta + tc {
            (da + vp * (t - ta), vp)
        } else if t < 2.0 * ta + tc {
            let u = 2.0 * ta + tc - t;
            (l - 0.5 * a * u * u, a * u)
        } else {
            (l, 0.0)
        };
        ((s / l).clamp(0.0, 1.0), ds / l)
    }

    /// True once the time scale has run through every phase.
    pub(super) fn done(&self) -> bool {
        self.elapsed_s >= self.duration_s()
    }

    /// How far the layered followers are on their way to their layer (0 to 1) at
    /// `elapsed_s`, smoothstep, and its rate (1/s).
    fn layering(&self) -> (f64, f64) {
        if self.hold_s <= 0.0 {
            return (0.0, 0.0);
        }
        let e = self.elapsed_s;
        let end = self.duration_s();
        let (x, dx) = if e < self.hold_s {
            (e / self.hold_s, 1.0 / self.hold_s)
        } else if e > end - self.hold_s {
            ((end - e) / self.hold_s, -1.0 / self.hold_s)
        } else {
            (1.0, 0.0)
        };
        let x = x.clamp(0.0, 1.0);
        (x * x * (3.0 - 2.0 * x), 6.0 * x * (1.0 - x) * dx)
    }

    /// Planned offset of `id` now, pattern frame (metres), and its rate of change (m/s,
    /// real time).
    pub(super) fn planned(&self, id: &str) -> Option<(Ned, Ned)> {
        let (beta, rate) = self.progress();
        let a = *self.starts.get(id)?;
        let b = *self.goals.get(id)?;
        let rate = rate * self.scale;
        let h = self.climbs.get(id).map_or(0.0, |c| c.height_m);
        let (f, df) = self.layering();
        let climb = Ned::new(0.0, 0.0, -h * f);
        let climb_rate = Ned::new(0.0, 0.0, -h * df * self.scale);
        Some((a + (b - a) * beta + climb, (b - a) * rate + climb_rate))
    }
}

/// Path length of a transition leg for the time scale: horizontal metres, or vertical
/// metres scaled to the slower vertical speed.
fn leg_length(d: Ned) -> f64 {
    d.horizontal_norm()
        .max(d.down_m.abs() * TRANSIT_SPEED_M_S / TRANSIT_CLIMB_M_S)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-9
    }

    fn near(a: Ned, b: Ned) -> bool {
        (a - b).norm() < 1e-9
    }

    /// One member going 20 m east: a trapezoid (5 s up to 2.5 m/s, 3 s cruise, 5 s down).
    fn twenty_metres() -> Transition {
        let mut t = Transition::new();
        t.add("a", Ned::ZERO, Ned::new(0.0, 20.0, 0.0), &[]);
        t
    }

    fn at(mut t: Transition, elapsed_s: f64) -> Transition {
        t.elapsed_s = elapsed_s;
        t
    }

    #[test]
    fn progress_follows_a_trapezoid_on_the_longest_path() {
        let t = twenty_metres();
        assert!(close(t.duration_s(), 13.0));
        let p = |e: f64| at(t.clone(), e).progress();
        assert_eq!(p(0.0), (0.0, 0.0));
        // Accelerating: s = a t²/2 = 1 m of 20 after 2 s, at 1 m/s.
        let (b, r) = p(2.0);
        assert!(close(b, 0.05) && close(r, 0.05), "{b} {r}");
        // Cruising at 2.5 m/s: half way after 6.5 s.
        let (b, r) = p(6.5);
        assert!(close(b, 0.5) && close(r, 0.125), "{b} {r}");
        // Braking: 1 m left 2 s before the end.
        let (b, r) = p(11.0);
        assert!(close(b, 0.95) && close(r, 0.05), "{b} {r}");
        assert_eq!(p(13.0), (1.0, 0.0));
        assert_eq!(p(100.0), (1.0, 0.0));
        assert!(!at(t.clone(), 12.99).done());
        assert!(at(t, 13.0).done());
    }

    #[test]
    fn a_short_path_never_reaches_cruise_speed() {
        let mut t = Transition::new();
        t.add("a", Ned::ZERO, Ned::new(4.0, 0.0, 0.0), &[]);
        t.add("b", Ned::ZERO, Ned::new(1.0, 0.0, 0.0), &[]);
        // Triangle: peak √(a·l) = √2 m/s after 2√2 s, 4√2 s in all.
        let half = 2.0 * 2f64.sqrt();
        assert!(close(t.duration_s(), 2.0 * half));
        let (b, r) = at(t.clone(), half).progress();
        assert!(close(b, 0.5) && close(r, 2f64.sqrt() / 4.0), "{b} {r}");
        // All members share β: the shorter path is half done too.
        let (pa, _) = at(t.clone(), half).planned("a").unwrap();
        let (pb, vb) = at(t, half).planned("b").unwrap();
        assert!(near(pa, Ned::new(2.0, 0.0, 0.0)) && near(pb, Ned::new(0.5, 0.0, 0.0)));
        assert!(near(vb, Ned::new(2f64.sqrt() / 4.0, 0.0, 0.0)), "{vb:?}");
    }

    #[test]
    fn an_empty_transition_is_done_at_once() {
        let t = Transition::new();
        assert_eq!(t.duration_s(), 0.0);
        assert!(t.done());
        assert_eq!(t.progress(), (1.0, 0.0));
        assert_eq!(t.layering(), (0.0, 0.0));
        assert!(t.planned("a").is_none());
        assert!(t.extents().is_empty());
    }

    #[test]
    fn the_time_scale_waits_for_a_lagging_member() {
        let mut t = twenty_metres();
        t.advance(2.0, 0.0);
        assert!(close(t.elapsed_s, 2.0) && close(t.scale, 1.0));
        // Half way between LAG_SLOW_M and LAG_STOP_M: half rate, half the plan's speed.
        t.advance(2.0, (LAG_SLOW_M + LAG_STOP_M) / 2.0);
        assert!(close(t.elapsed_s, 3.0) && close(t.scale, 0.5));
        let (_, v) = t.planned("a").unwrap();
        assert!(near(v, Ned::new(0.0, 0.5 * 1.5, 0.0)), "{v:?}");
        t.advance(2.0, LAG_STOP_M);
        assert!(close(t.elapsed_s, 3.0) && t.scale == 0.0);
        assert_eq!(t.planned("a").unwrap().1, Ned::ZERO);
    }

    #[test]
    fn a_follower_passing_the_leader_climbs_first_and_lands_last() {
        let (a, b) = (Ned::new(0.0, -5.0, 0.0), Ned::new(0.0, 5.0, 0.0));
        let mut t = Transition::new();
        t.add("f", a, b, &[Keepout::leader(3.5)]);
        assert_eq!(t.climbs["f"].height_m, 3.5);
        assert!(close(t.hold_s, 5.25));
        // Layers, then a 10 m triangle (4 · √5 s), then back down.
        let line_s = 4.0 * 5f64.sqrt();
        assert!(close(t.duration_s(), 2.0 * 5.25 + line_s));
        assert_eq!(at(t.clone(), 0.0).planned("f").unwrap(), (a, Ned::ZERO));
        // Half way up, nobody moves horizontally, climbing at TRANSIT_CLIMB_M_S.
        let (p, v) = at(t.clone(), 5.25 / 2.0).planned("f").unwrap();
        assert!(near(p, a + Ned::new(0.0, 0.0, -1.75)), "{p:?}");
        assert!(near(v, Ned::new(0.0, 0.0, -TRANSIT_CLIMB_M_S)), "{v:?}");
        // Over the leader at the middle of the line, on the layer.
        let (p, v) = at(t.clone(), 5.25 + line_s / 2.0).planned("f").unwrap();
        assert!(near(p, Ned::new(0.0, 0.0, -3.5)), "{p:?}");
        assert!(near(v, Ned::new(0.0, 5f64.sqrt(), 0.0)), "{v:?}");
        let end = at(t.clone(), t.duration_s());
        assert!(end.done());
        assert!(near(end.planned("f").unwrap().0, b));
        let up = Ned::new(0.0, 0.0, -3.5);
        assert_eq!(t.extents(), vec![a, a + up, b, b + up]);
    }

    #[test]
    fn layering_is_a_smoothstep_up_and_down() {
        let mut t = Transition::new();
        t.add(
            "f",
            Ned::new(0.0, -5.0, 0.0),
            Ned::new(0.0, 5.0, 0.0),
            &[Keepout::leader(3.5)],
        );
        let l = |e: f64| at(t.clone(), e).layering();
        assert_eq!(l(0.0).0, 0.0);
        let (f, df) = l(5.25 / 2.0);
        assert!(close(f, 0.5) && close(df, 1.5 / 5.25), "{f} {df}");
        assert_eq!(l(5.25).0, 1.0);
        assert_eq!(l(8.0), (1.0, 0.0));
        let end = t.duration_s();
        let (f, df) = l(end - 5.25 / 2.0);
        assert!(close(f, 0.5) && close(df, -1.5 / 5.25), "{f} {df}");
        assert_eq!(l(end).0, 0.0);
    }

    #[test]
    fn no_layer_without_a_leader_vehicle_or_away_from_it() {
        let (a, b) = (Ned::new(0.0, -5.0, 0.0), Ned::new(0.0, 5.0, 0.0));
        let mut t = Transition::new();
        t.add("virtual-follower", a, b, &[]);
        t.add(
            "beside",
            Ned::new(0.0, 5.0, 0.0),
            Ned::new(0.0, 10.0, 0.0),
            &[Keepout::leader(3.5)],
        );
        assert!(t.climbs.is_empty());
        assert_eq!(t.hold_s, 0.0);
        assert!(close(t.length_m, 10.0));
    }

    #[test]
    fn vertical_legs_count_at_the_slower_climb_speed() {
        assert!(close(leg_length(Ned::new(3.0, 4.0, 0.0)), 5.0));
        assert!(close(leg_length(Ned::new(0.0, 0.0, -2.0)), 5.0));
        assert!(close(leg_length(Ned::new(3.0, 4.0, 4.0)), 10.0));
        assert!(close(leg_length(Ned::new(6.0, 8.0, 1.0)), 10.0));
    }
}
