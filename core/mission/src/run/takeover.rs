//! A run carried from one coordinator to another. The active coordinator mirrors its
//! flying run whole (it is `serde`); a standby that takes the role converts the run's
//! positions into its own swarm frame ([`MissionRun::reframe`]) and takes it over
//! ([`MissionRun::take_over`]): the mission clock moved on by the mirror's age, every
//! vehicle's current point commanded again from where it is, the step's lanes, laps and
//! clocks as they were, so a finished survey lane is not flown again and an unfinished
//! one is not skipped.

use super::step::Active;
use super::{Action, MissionRun, RunState};
use crate::plan::StepKind;
use skein_model::geo::Ned;

/// The longest mirror age a takeover adds to the mission clock, seconds: a mirror older
/// than this (a coordinator that sat long without one) does not age the steps by more.
pub const MAX_TAKEOVER_AGE_S: f64 = 10.0;

impl MissionRun {
    /// Moves every position of the run (its plan's points, polygons and zones, the
    /// step's routes and waypoints) through `f`: from the mirroring coordinator's swarm
    /// frame into this one's.
    pub fn reframe(&mut self, f: &dyn Fn(Ned) -> Ned) {
        let flat = |p: &mut [f64; 2]| {
            let q = f(Ned::new(p[0], p[1], 0.0));
            *p = [q.north_m, q.east_m];
        };
        for step in &mut self.plan.steps {
            match &mut step.kind {
                StepKind::Transit(t) => t.waypoints.iter_mut().for_each(flat),
                StepKind::Survey(s) => s.polygon.iter_mut().for_each(flat),
                StepKind::Patrol(p) => p.route.iter_mut().for_each(flat),
                StepKind::Station(s) => s.points.iter_mut().for_each(flat),
                StepKind::Takeoff(_) | StepKind::Return(_) | StepKind::Land(_) => {}
            }
        }
        if let Some(zone) = self
            .plan
            .reactions
            .intruder
            .as_mut()
            .and_then(|r| r.zone.as_mut())
        {
            zone.iter_mut().for_each(flat);
        }
        if let Some(intrusions) = &mut self.intrusions {
            intrusions.reframe(&flat);
        }
        let landing = self.aborting.as_mut().and_then(|a| a.landing.as_mut());
        for active in self.active.iter_mut().chain(landing) {
            active.reframe(f);
        }
    }

    /// Every position of the run is finite (a reframed one far off its origin is not).
    pub fn positions_finite(&self) -> bool {
        let finite = std::cell::Cell::new(true);
        self.clone().reframe(&|p| {
            let ok = p.north_m.is_finite() && p.east_m.is_finite() && p.down_m.is_finite();
            finite.set(finite.get() && ok);
            p
        });
        finite.get()
    }

    /// This coordinator flies the run on, mirrored `age_s` ago by the one it replaces
    /// (see the module docs); what to command at once. A running run's clock moves on by
    /// the age (at most [`MAX_TAKEOVER_AGE_S`]); the next tick counts from the caller's
    /// clock then, and commands every vehicle of a route its current point again (the
    /// leader motion of a formation's waypoints is what this returns). Observations of the intruder reaction end (the tracks were the other
    /// coordinator's: this one observes what its own tracker confirms), their observers
    /// flying their routes on.
    pub fn take_over(&mut self, age_s: f64) -> Vec<Action> {
        let mut out = Vec::new();
        self.last_now_s = None;
        if self.status.state != RunState::Running {
            return out;
        }
        self.status.elapsed_s += age_s.clamp(0.0, MAX_TAKEOVER_AGE_S);
        let now_s = self.status.elapsed_s;
        if let (Some(intrusions), Some(active)) = (&mut self.intrusions, &mut self.active) {
            intrusions.hand_over(active, now_s, &mut self.status.reactions);
        }
        let landing = self.aborting.as_mut().and_then(|a| a.landing.as_mut());
        for active in self.active.iter_mut().chain(landing) {
            active.resume(&mut out);
        }
        out
    }
}

/// A kind's name (`survey`, `low_battery`): one of a known few, deserialised back into
/// its `&'static` self (spelt as an alias so that serde does not borrow it from the
/// input).
pub type Name = &'static str;

/// Deserialises a step's kind into its `&'static` name ([`StepKind::name`]).
pub(super) fn step_kind<'de, D: serde::Deserializer<'de>>(d: D) -> Result<&'static str, D::Error> {
    known(
        d,
        &[
            "takeoff", "transit", "survey", "patrol", "station", "return", "land",
        ],
    )
}

/// Deserialises a reaction's kind into its `&'static` name.
pub(super) fn reaction_kind<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> Result<&'static str, D::Error> {
    known(d, &["low_battery", "intruder"])
}

fn known<'de, D: serde::Deserializer<'de>>(
    d: D,
    names: &[&'static str],
) -> Result<&'static str, D::Error> {
    let s = <String as serde::Deserialize>::deserialize(d)?;
    names
        .iter()
        .find(|n| **n == s)
        .copied()
        .ok_or_else(|| serde::de::Error::custom(format!("unknown kind `{s}`")))
}

impl Active {
    /// Moves the step's positions through `f` (see [`MissionRun::reframe`]).
    fn reframe(&mut self, f: &dyn Fn(Ned) -> Ned) {
        match self {
            Active::InTurn { .. } => {}
            Active::Formation { points, .. } => points.iter_mut().for_each(|p| *p = f(*p)),
            Active::Routes { routes, .. } => routes.values_mut().for_each(|r| r.reframe(f)),
        }
    }
}
