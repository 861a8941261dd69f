//! One vehicle flying its points in order, one `goto` at a time: the next point is
//! commanded once the vehicle is within [`ARRIVED_M`] of the current one, and the current
//! one again when the vehicle is neither flying to it nor there after [`RESEND_S`] (a
//! command lost or refused in passing). A cyclic route starts over after its last point;
//! a station's route holds its point: the vehicle found away from it (back from an
//! observation) is flown to it again.

use super::{Action, VehicleView};
use skein_model::command::{Command, GoTo};
use skein_model::fsm::VehicleState;
use skein_model::geo::Ned;

/// Within this of a point (horizontally and vertically), metres, a vehicle has reached it.
pub const ARRIVED_M: f64 = 1.5;

/// Across a survey lane, metres, a vehicle at the lane's start must be within this of
/// its line to have reached it: the lane is flown on a line from where the vehicle
/// starts it, so an offset across the lane is carried, shrinking, all along it (with
/// [`ARRIVED_M`] alone, a rehearsal saw a vehicle start a lane 2 m off it, and 9 % of an
/// 8 m-lane survey unseen).
pub const LANE_START_M: f64 = 0.5;

/// Across a survey lane, m/s, a vehicle at its start must move slower than this: one
/// that passes the start at speed from the side (from a transit) carries on off the lane
/// (a rehearsal saw 7 m).
pub const LANE_START_CROSS_M_S: f64 = 0.5;

/// A point not reached this long after its `goto`, seconds, with the vehicle not flying to
/// it, is commanded again.
pub const RESEND_S: f64 = 5.0;

/// A vehicle's points and how far along them it is.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Route {
    points: Vec<Ned>,
    next: usize,
    /// Points reached so far (a cyclic route goes on counting).
    reached: usize,
    cyclic: bool,
    sent_at: Option<f64>,
    /// Survey lanes (points in start/end pairs): a lane's start is reached within
    /// [`LANE_START_M`], not [`ARRIVED_M`].
    lanes: bool,
    /// A point flown first, before the route's next (where the vehicle whose place this
    /// one took left the route), counted as reached.
    #[serde(default)]
    join: Option<Ned>,
    /// A station: once reached, the last point is held, flown to again whenever the
    /// vehicle is found farther than [`ARRIVED_M`] from it.
    #[serde(default)]
    hold: bool,
}

impl Route {
    /// A route through `points` (swarm-frame NED), once or for ever (`cyclic`).
    pub fn new(points: Vec<Ned>, cyclic: bool) -> Self {
        Route {
            points,
            next: 0,
            reached: 0,
            cyclic,
            sent_at: None,
            lanes: false,
            join: None,
            hold: false,
        }
    }

    /// A station at `point` (swarm-frame NED): flown to once, then held (the vehicle
    /// flown back whenever it is found away, as after an observation).
    pub fn station(point: Ned) -> Self {
        Route {
            hold: true,
            ..Route::new(vec![point], false)
        }
    }

    /// A survey's lanes, `points` in start/end pairs, flown once.
    pub fn lanes(points: Vec<Ned>) -> Self {
        Route {
            lanes: true,
            ..Route::new(points, false)
        }
    }

    /// A vehicle at `pos` moving at `velocity` has reached point `i`: within
    /// [`ARRIVED_M`]; a survey lane's start only once on the lane's line (within
    /// [`LANE_START_M`] across it) and not drifting off it (under
    /// [`LANE_START_CROSS_M_S`] across it), so the lane is flown on its line.
    fn reached_point(&self, i: usize, pos: Ned, velocity: Option<Ned>) -> bool {
        let target = self.points[i];
        let end = self.points.get(i + 1).copied();
        let Some(end) = end.filter(|_| self.lanes && i.is_multiple_of(2)) else {
            return arrived(pos, target);
        };
        let along = end - target;
        let length = along.horizontal_norm();
        if length < 1e-6 {
            return arrived(pos, target);
        }
        let u = Ned::new(along.north_m / length, along.east_m / length, 0.0);
        let across = |d: Ned| (d.north_m * u.east_m - d.east_m * u.north_m).abs();
        let d = pos - target;
        arrived(pos, target)
            && across(d) < LANE_START_M
            && velocity.is_none_or(|v| across(v) < LANE_START_CROSS_M_S)
    }

    /// A cyclic route starting at point `first`.
    pub fn starting_at(points: Vec<Ned>, first: usize) -> Self {
        let next = first % points.len().max(1);
        Route {
            next,
            ..Route::new(points, true)
        }
    }

    /// The last point was reached (never, for a cyclic route).
    pub fn finished(&self) -> bool {
        !self.cyclic && self.next >= self.points.len()
    }

    /// Points reached so far.
    pub fn reached(&self) -> usize {
        self.reached
    }

    /// The points not reached yet, in order (for a cyclic route: the rest of the lap).
    pub fn remaining(&self) -> &[Ned] {
        &self.points[self.next.min(self.points.len())..]
    }

    /// The route starts over after its last point.
    pub fn is_cyclic(&self) -> bool {
        self.cyclic
    }

    /// The points ahead of a vehicle at `from` flying this route, for `laps` laps of a
    /// cyclic one (the rest of it for another): how many points ahead (0: the next), the
    /// point, and the way to it along the route from `from`, metres.
    pub fn ahead(&self, from: Ned, laps: usize) -> Vec<(usize, Ned, f64)> {
        let n = self.points.len();
        let count = if self.cyclic {
            n * laps
        } else {
            n.saturating_sub(self.next)
        };
        let (mut at, mut along_m) = (from, 0.0);
        (0..count)
            .map(|i| {
                let p = self.points[(self.next + i) % n];
                along_m += (p - at).norm();
                at = p;
                (i, p, along_m)
            })
            .collect()
    }

    /// The route's last point; `None` for an empty one.
    pub fn last(&self) -> Option<&Ned> {
        self.points.last()
    }

    /// Takes the points of the lanes not flown yet (pairs of lane start and end; a lane
    /// begun but not ended is taken whole, its start again) and ends this route.
    pub fn take_rest_of_lanes(&mut self) -> Vec<Ned> {
        let from = if self.next % 2 == 1 {
            self.next - 1
        } else {
            self.next
        };
        let rest = self.points.split_off(from.min(self.points.len()));
        self.next = self.points.len();
        rest
    }

    /// What another vehicle flies to take this one's place: from `at` (where this one
    /// leaves it), a lap from the same point (cyclic), or the lanes not flown yet (this
    /// route ends there; a lane begun is flown whole, `at` not used; a station's point,
    /// held as this one held it).
    pub fn handover(&mut self, at: Option<Ned>) -> Route {
        if self.cyclic {
            Route {
                reached: 0,
                sent_at: None,
                join: at,
                ..self.clone()
            }
        } else {
            Route {
                lanes: self.lanes,
                hold: self.hold,
                ..Route::new(self.take_rest_of_lanes(), false)
            }
        }
    }

    /// Appends `points` (another vehicle's share) after this route's own.
    pub fn extend(&mut self, points: &[Ned]) {
        self.points.extend_from_slice(points);
    }

    /// Moves the route's points through `f` (into another swarm frame).
    pub(super) fn reframe(&mut self, f: &dyn Fn(Ned) -> Ned) {
        self.points.iter_mut().for_each(|p| *p = f(*p));
        self.join = self.join.map(f);
    }

    /// The next `goto` to command again at once (after a pause, say).
    pub fn resend(&mut self) {
        self.sent_at = None;
    }

    /// What vehicle `v` must be told at mission time `now_s`; counts what it reached.
    pub fn tick(&mut self, v: &VehicleView, now_s: f64, out: &mut Vec<Action>) {
        let Some(pos) = v.position else {
            return;
        };
        if self.join.is_some_and(|j| arrived(pos, j)) {
            self.join = None;
            self.reached += 1;
            self.sent_at = None;
        }
        while self.join.is_none() && self.next < self.points.len() {
            if !self.reached_point(self.next, pos, v.velocity) {
                break;
            }
            self.reached += 1;
            self.next += 1;
            self.sent_at = None;
            if self.cyclic && self.next == self.points.len() {
                self.next = 0;
            }
            if self.points.len() <= 1 {
                break;
            }
        }
        let held = || {
            self.last()
                .copied()
                .filter(|p| self.hold && !arrived(pos, *p))
        };
        let Some(target) = self
            .join
            .or_else(|| self.points.get(self.next).copied())
            .or_else(held)
        else {
            return;
        };
        let stale = self
            .sent_at
            .is_none_or(|t| now_s - t >= RESEND_S && v.state != VehicleState::GoTo);
        if stale {
            self.sent_at = Some(now_s);
            out.push(Action::Command {
                vehicle: v.id.clone(),
                command: Command::GoTo(GoTo::from(target)),
            });
        }
    }
}

/// `pos` is within [`ARRIVED_M`] of `target`, horizontally and vertically.
pub fn arrived(pos: Ned, target: Ned) -> bool {
    let d = pos - target;
    d.horizontal_norm() < ARRIVED_M && d.down_m.abs() < ARRIVED_M
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(at: Ned, state: VehicleState) -> VehicleView {
        VehicleView {
            id: "uav-1".into(),
            state,
            position: Some(at),
            velocity: None,
            relative_alt_m: Some(-at.down_m),
            battery_percent: None,
            observer: false,
        }
    }

    fn gotos(out: &[Action]) -> Vec<Ned> {
        out.iter()
            .filter_map(|a| match a {
                Action::Command {
                    command: Command::GoTo(g),
                    ..
                } => Some(g.target()),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn points_are_flown_in_order_and_a_lost_goto_is_sent_again() {
        let a = Ned::new(10.0, 0.0, -10.0);
        let b = Ned::new(10.0, 20.0, -10.0);
        let mut r = Route::new(vec![a, b], false);
        let mut out = Vec::new();
        r.tick(
            &view(Ned::new(0.0, 0.0, -10.0), VehicleState::Hovering),
            0.0,
            &mut out,
        );
        assert_eq!(gotos(&out), [a]);
        // Flying to it: nothing more.
        out.clear();
        r.tick(
            &view(Ned::new(5.0, 0.0, -10.0), VehicleState::GoTo),
            6.0,
            &mut out,
        );
        assert!(out.is_empty());
        // Hovering short of it for 5 s: commanded again.
        r.tick(
            &view(Ned::new(5.0, 0.0, -10.0), VehicleState::Hovering),
            6.0,
            &mut out,
        );
        assert_eq!(gotos(&out), [a]);
        out.clear();
        r.tick(
            &view(Ned::new(9.5, 0.3, -10.2), VehicleState::GoTo),
            7.0,
            &mut out,
        );
        assert_eq!(gotos(&out), [b]);
        assert_eq!(r.reached(), 1);
        out.clear();
        r.tick(&view(b, VehicleState::Hovering), 9.0, &mut out);
        assert!(out.is_empty() && r.finished() && r.reached() == 2);
    }

    #[test]
    fn a_station_once_reached_is_flown_to_again_when_the_vehicle_is_found_away() {
        let p = Ned::new(10.0, 0.0, -10.0);
        let mut r = Route::station(p);
        let mut out = Vec::new();
        r.tick(
            &view(Ned::new(0.0, 0.0, -10.0), VehicleState::Hovering),
            0.0,
            &mut out,
        );
        assert_eq!(gotos(&out), [p]);
        out.clear();
        r.tick(&view(p, VehicleState::Hovering), 3.0, &mut out);
        assert!(out.is_empty() && r.finished());
        // Back from an observation 4.8 m east of it: sent to it at once, again.
        r.resend();
        let away = Ned::new(10.0, 4.8, -10.0);
        r.tick(&view(away, VehicleState::Hovering), 40.0, &mut out);
        assert_eq!(gotos(&out), [p]);
        assert!(
            r.finished() && r.reached() == 1,
            "still the step's one point"
        );
        // A Hold that overtook that goto: sent again after RESEND_S.
        out.clear();
        r.tick(&view(away, VehicleState::Hovering), 44.0, &mut out);
        assert!(out.is_empty());
        r.tick(&view(away, VehicleState::Hovering), 45.0, &mut out);
        assert_eq!(gotos(&out), [p]);
        // Another route's last point is not held.
        let mut once = Route::new(vec![p], false);
        out.clear();
        once.tick(&view(p, VehicleState::Hovering), 0.0, &mut out);
        once.tick(&view(away, VehicleState::Hovering), 10.0, &mut out);
        assert!(out.is_empty());
    }

    #[test]
    fn a_lane_starts_once_the_vehicle_is_on_its_line_and_not_drifting_off() {
        // A lane east from (10, 0) to (10, 40); the vehicle comes from the south.
        let (start, end) = (Ned::new(10.0, 0.0, -10.0), Ned::new(10.0, 40.0, -10.0));
        let mut r = Route::lanes(vec![start, end]);
        let mut out = Vec::new();
        let at = |north_m: f64, east_m: f64, v_north_m_s: f64, v_east_m_s: f64| VehicleView {
            velocity: Some(Ned::new(v_north_m_s, v_east_m_s, 0.0)),
            ..view(Ned::new(north_m, east_m, -10.0), VehicleState::GoTo)
        };
        // Within 1.5 m but 1 m off the line: not yet.
        r.tick(&at(9.0, 0.2, 0.3, 0.0), 0.0, &mut out);
        // On the line but crossing it at 3 m/s (passing through from the side): not yet.
        r.tick(&at(10.1, 0.0, 3.0, 0.0), 0.5, &mut out);
        assert_eq!(r.reached(), 0);
        // On the line, 1 m short along it, moving along it: the lane is flown.
        out.clear();
        r.tick(&at(10.2, -1.0, 0.2, 2.0), 1.0, &mut out);
        assert_eq!((r.reached(), gotos(&out)), (1, vec![end]));
        // A lane's end is reached as any point is.
        r.tick(&at(11.0, 39.0, 0.5, 0.0), 5.0, &mut out);
        assert!(r.finished());
        // Without a velocity (not reported), the position decides.
        let mut r = Route::lanes(vec![start, end]);
        r.tick(
            &view(Ned::new(10.3, 0.5, -10.0), VehicleState::GoTo),
            0.0,
            &mut out,
        );
        assert_eq!(r.reached(), 1);
    }

    #[test]
    fn a_cyclic_route_goes_round() {
        let pts = vec![
            Ned::new(0.0, 0.0, -10.0),
            Ned::new(0.0, 30.0, -10.0),
            Ned::new(30.0, 30.0, -10.0),
        ];
        let mut r = Route::starting_at(pts.clone(), 2);
        let mut out = Vec::new();
        for (i, p) in [pts[2], pts[0], pts[1], pts[2]].into_iter().enumerate() {
            r.tick(&view(p, VehicleState::Hovering), i as f64, &mut out);
        }
        assert_eq!(r.reached(), 4);
        assert!(!r.finished());
        assert_eq!(gotos(&out).last(), Some(&pts[0]));
    }
}
