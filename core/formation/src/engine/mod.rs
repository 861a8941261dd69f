//! The formation engine's state between ticks ([`FormationEngine`]): setting and
//! stopping a formation, and what it tells the coordinator between ticks. The tick that
//! turns the members' state into slot commands (leader, reference point, pattern,
//! assignment, transition) is in `tick`, step by step; the status it shows in `view`;
//! the mirror a standby keeps of it in [`mirror`].

use super::absence::Absences;
use super::hazard::{Hazard, HazardConfig};
use super::leader::LeaderChange;
use super::reference::Reference;
use super::spec::{FormationSpec, LeaderMotion};
use super::status::{MemberStatus, Replan};
use super::transition::Transition;
use skein_model::geo::Ned;
use std::collections::BTreeMap;
use std::time::Duration;

/// Separation of [`FormationEngine::default`] (3 m plus the default 0.5 m margin), metres.
pub const DEFAULT_SEPARATION_M: f64 = 3.5;
/// Largest shift of the slot pattern that clears it of hazards, metres; beyond it the
/// formation holds and says it is blocked.
pub const MAX_HAZARD_SHIFT_M: f64 = 100.0;

/// Formation state between ticks.
#[derive(Debug)]
pub struct FormationEngine {
    spec: Option<FormationSpec>,
    active: bool,
    leader: Option<String>,
    /// The requested leader has led since the spec was set (see `resolve_leader`).
    requested_led: bool,
    reference: Option<Reference>,
    assignment: BTreeMap<String, usize>,
    last: Vec<MemberStatus>,
    changes: Vec<LeaderChange>,
    transition: Option<Transition>,
    /// Where each member was sent at the last tick: its offset from the anchor (swarm
    /// frame axes, i.e. already turned by the heading of that tick).
    commanded: BTreeMap<String, Ned>,
    /// Where each member was sent at the last tick and how fast that place moved, swarm
    /// frame (metres, m/s), for the pace of the formation.
    sent: BTreeMap<String, (Ned, Ned)>,
    /// Heading of the slot pattern at the last tick, radians.
    pattern_heading: Option<f64>,
    /// Its rate of turn, rad/s.
    pattern_rate: f64,
    /// A formation requested during a transition, applied when it ends.
    pending: Option<FormationSpec>,
    /// The last tick put `pending` in force.
    pending_applied: bool,
    /// Distance followers keep from a leader vehicle on their transition paths, metres.
    separation_m: f64,
    /// Vehicles that may still fly where the formation is not steering them.
    hazards: Vec<Hazard>,
    /// How long pacing may hold a member before the change is planned again.
    replan_after_s: f64,
    /// How long pacing has been holding a member, seconds.
    stalled_s: f64,
    /// Changes planned again since the last call of `take_replans`.
    replans: Vec<Replan>,
    /// Why the formation cannot be flown clear of the hazards, if it cannot.
    blocked: Option<String>,
    /// `blocked` changed since the last call of `take_blocked_change`.
    blocked_changed: bool,
    /// Members that dropped out without being asked.
    absences: Absences,
    /// Seconds left of [`RESUME_PACE_GRACE`] after a resumed formation.
    pace_grace_s: f64,
}

/// After this coordinator resumes another's formation (a failover or a handover,
/// [`FormationEngine::resume`]), how long the members' distance from where it sent them
/// does not slow the formation: their agents fly on from their own mirror until they
/// obey the new coordinator, so that distance says nothing of a member lagging yet, and
/// a formation slowed for it falls ever further behind where the members fly (the pace
/// stops it, and the members then have metres to make up).
pub const RESUME_PACE_GRACE: Duration = Duration::from_secs(3);

/// A member silent for longer than this (six of its reports at 20 Hz) neither slows
/// the formation nor anchors it: its position is stale, and it flies its slot on its own
/// (its ride-through) until it is heard again or its ride-through ends.
pub const PACE_SILENCE: Duration = Duration::from_millis(300);

impl Default for FormationEngine {
    fn default() -> Self {
        FormationEngine {
            spec: None,
            active: false,
            leader: None,
            requested_led: false,
            reference: None,
            assignment: BTreeMap::new(),
            last: Vec::new(),
            changes: Vec::new(),
            transition: None,
            commanded: BTreeMap::new(),
            sent: BTreeMap::new(),
            pattern_heading: None,
            pattern_rate: 0.0,
            pending: None,
            pending_applied: false,
            separation_m: DEFAULT_SEPARATION_M,
            hazards: Vec::new(),
            replan_after_s: HazardConfig::default().replan_after_s,
            stalled_s: 0.0,
            replans: Vec::new(),
            blocked: None,
            blocked_changed: false,
            absences: Absences::default(),
            pace_grace_s: 0.0,
        }
    }
}

impl FormationEngine {
    /// An engine whose transitions keep followers `separation_m` from a leader vehicle
    /// (the swarm's setpoint separation).
    pub fn new(separation_m: f64) -> Self {
        FormationEngine {
            separation_m,
            ..FormationEngine::default()
        }
    }

    /// How long pacing may hold a member before a change is planned again from where
    /// the members are, seconds.
    pub fn set_replan_after_s(&mut self, seconds: f64) {
        self.replan_after_s = seconds.max(0.0);
    }

    /// The hazards to plan around from the next tick on (swarm frame).
    pub fn set_hazards(&mut self, hazards: Vec<Hazard>) {
        self.hazards = hazards;
    }

    /// How long pacing has been holding a member, seconds (0 while nobody is held).
    pub fn stalled_s(&self) -> f64 {
        self.stalled_s
    }

    /// The hazards planned around.
    pub fn hazards(&self) -> &[Hazard] {
        &self.hazards
    }

    /// Changes planned again because pacing held a member too long, since the last call
    /// (for the event stream).
    pub fn take_replans(&mut self) -> Vec<Replan> {
        std::mem::take(&mut self.replans)
    }

    /// `Some(why)` when the formation became blocked by hazards, `Some(None)` when it no
    /// longer is, once per change (for the event stream).
    pub fn take_blocked_change(&mut self) -> Option<Option<String>> {
        std::mem::take(&mut self.blocked_changed).then(|| self.blocked.clone())
    }

    fn set_blocked(&mut self, why: Option<String>) {
        if self.blocked != why {
            self.blocked = why;
            self.blocked_changed = true;
        }
    }

    /// The spec in force.
    pub fn spec(&self) -> Option<&FormationSpec> {
        self.spec.as_ref()
    }

    /// True while the formation is flown.
    pub fn is_active(&self) -> bool {
        self.active && self.spec.is_some()
    }

    /// The leader in force (vehicle id or `"virtual"`).
    pub fn leader(&self) -> Option<&str> {
        self.leader.as_deref()
    }

    /// Sets a new formation. The reference point stays where it is (a shape change in
    /// flight reshapes around the same point) unless there is none yet. While a change is
    /// being flown, the new one waits for it to end (the latest request wins): the
    /// separation the transition keeps holds between settled formations.
    pub fn set(&mut self, spec: FormationSpec) {
        if self.active && self.transition.is_some() {
            self.pending = Some(spec);
            return;
        }
        self.apply(spec);
    }

    fn apply(&mut self, spec: FormationSpec) {
        let leader_changes = self
            .spec
            .as_ref()
            .is_none_or(|old| old.leader != spec.leader);
        if leader_changes {
            self.leader = None;
            self.requested_led = false;
            self.reference = None;
        }
        self.spec = Some(spec);
        self.active = true;
        self.pending = None;
        self.assignment.clear();
    }

    /// The formation waiting for the change in flight to end, if any.
    pub fn pending(&self) -> Option<&FormationSpec> {
        self.pending.as_ref()
    }

    /// Stops flying the formation (the spec is kept for the next `set`).
    pub fn deactivate(&mut self) {
        self.active = false;
        self.leader = None;
        self.requested_led = false;
        self.reference = None;
        self.assignment.clear();
        self.last.clear();
        self.transition = None;
        self.commanded.clear();
        self.sent.clear();
        self.pattern_heading = None;
        self.pattern_rate = 0.0;
        self.pending = None;
        self.stalled_s = 0.0;
        self.set_blocked(None);
        self.absences.clear();
        self.pace_grace_s = 0.0;
    }

    /// `id` leaves the formation because it was asked to (an operator's command, an
    /// observation station): when it drops out it is not listed as absent, and it no
    /// longer is if it was.
    pub fn release(&mut self, id: &str) {
        self.absences.release(id);
    }

    /// The members that dropped out without being released (see
    /// [`FormationEngine::status_with`]).
    pub fn absent_ids(&self) -> impl Iterator<Item = &str> {
        self.absences.ids()
    }

    /// Gives the reference point a new motion (leader go-to, waypoints, orbit).
    ///
    /// # Errors
    /// When no formation is flown yet.
    pub fn set_motion(&mut self, motion: LeaderMotion) -> Result<(), String> {
        match self.reference.as_mut().filter(|_| self.active) {
            Some(r) => {
                r.motion = motion;
                Ok(())
            }
            None => Err("no formation is being flown: PUT /api/v1/formation first".into()),
        }
    }

    /// Leader changes since the last call (for the event stream).
    pub fn take_leader_changes(&mut self) -> Vec<LeaderChange> {
        std::mem::take(&mut self.changes)
    }

    /// True once after a tick that put a pending formation (requested during a
    /// transition) in force (for the event stream).
    pub fn take_pending_applied(&mut self) -> bool {
        std::mem::take(&mut self.pending_applied)
    }
}

pub mod mirror;
mod tick;
mod view;

#[cfg(test)]
mod silence_tests;
#[cfg(test)]
pub(super) mod tests;
