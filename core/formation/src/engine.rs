//! The formation engine's state between ticks ([`FormationEngine`]): setting and
//! stopping a formation, the tick that turns the members' state into slot commands
//! (leader, reference point, pattern, assignment, transition), and the status it shows.

use super::absence::Absences;
use super::assignment::assign;
use super::hazard::{Hazard, HazardConfig, clearing_shift};
use super::leader::{LeaderChange, healthy, resolve_leader};
use super::pattern::{spin, turn};
use super::reference::{Reference, inner_fence, pace};
use super::spec::{FormationFrame, FormationSpec, LeaderMotion, VIRTUAL};
use super::status::{Member, MemberStatus, Replan, SlotCommand};
use super::transition::{LAG_SLOW_M, LAG_STOP_M, Transition};
use skein_model::formation::slot_positions;
use skein_model::geo::Ned;
use skein_model::safety::Geofence;
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

    /// Computes this tick's slot for every member. `members` are the vehicles flying the
    /// formation (healthy or not); `dt_s` is the time since the last tick, seconds;
    /// `fence` bounds the reference point.
    pub fn tick(
        &mut self,
        members: &BTreeMap<String, Member>,
        dt_s: f64,
        fence: &Geofence,
    ) -> BTreeMap<String, SlotCommand> {
        let mut out = BTreeMap::new();
        if self.transition.is_none()
            && let Some(next) = self.pending.take()
        {
            self.apply(next);
            self.pending_applied = true;
        }
        let Some(spec) = self.spec.clone().filter(|_| self.active) else {
            return out;
        };
        // Silent members keep no slot (they would hold the others' assignment hostage).
        let live = healthy(members);
        if live.is_empty() {
            self.last.clear();
            self.absences.update(BTreeMap::new());
            return out;
        }
        let (leader, change) = resolve_leader(
            self.leader.as_deref(),
            self.reference.as_ref().map(|r| r.position),
            &spec,
            members,
            self.requested_led,
        );
        self.changes.extend(change);
        let Some(leader) = leader else {
            self.last.clear();
            self.absences.update(BTreeMap::new());
            return out;
        };
        self.requested_led |= spec.leader.as_ref() == Some(&leader);
        if self.leader.as_ref() != Some(&leader) {
            let failover = self.leader.as_ref().is_some_and(|l| l != VIRTUAL);
            self.leader = Some(leader.clone());
            self.assignment.clear();
            // Offsets from the old anchor mean nothing around the new one.
            self.commanded.clear();
            self.sent.clear();
            // A new leader vehicle takes the formation from where it is: the old leader's
            // spot may still be occupied (a silent vehicle may hover on there).
            if failover
                && leader != VIRTUAL
                && let (Some(r), Some(m)) = (self.reference.as_mut(), live.get(&leader))
            {
                let mut p = m.target.unwrap_or(m.position);
                p.down_m = r.position.down_m;
                r.position = p;
            }
        }
        let virtual_leader = leader == VIRTUAL;
        let capacity = spec.capacity(live.len());
        let offsets = spec.offsets(capacity);
        // The reference point: created where the leader is held (or the members' centroid
        // for a virtual leader), at the formation altitude.
        let reference = self.reference.get_or_insert_with(|| {
            let mut p = if virtual_leader {
                let n = live.len() as f64;
                live.values().fold(Ned::ZERO, |a, m| a + m.position) * (1.0 / n)
            } else {
                let m = &live[&leader];
                m.target.unwrap_or(m.position)
            };
            if let Some(alt) = spec.altitude_m {
                p.down_m = -alt;
            }
            Reference::at(p, spec.heading_deg.to_radians())
        });
        // The reference stays far enough inside the fence for every slot to be inside, and
        // every place on a transition in flight or about to start: paths are straight
        // between start and goal (plus a climb), so their ends bound their reach.
        let mut extents: Vec<Ned> = offsets.clone();
        extents.extend(self.commanded.values().copied());
        if let Some(t) = &self.transition {
            extents.extend(t.extents());
        }
        let inner = inner_fence(fence, &extents);
        // The pace: how far the farthest member is from where it was sent (extrapolated
        // to now), against PACE_SLOW_M … PACE_STOP_M. A silent member's position is
        // stale: it rides through on its slot and does not hold the others back.
        let behind = self
            .sent
            .iter()
            .filter_map(|(id, (p, v))| {
                let m = live.get(id).filter(|m| m.silence <= PACE_SILENCE)?;
                Some((m.position - (*p + *v * dt_s)).norm())
            })
            .fold(0.0, f64::max);
        let pace = if self.pace_grace_s > 0.0 {
            self.pace_grace_s -= dt_s;
            1.0
        } else {
            pace(behind)
        };
        reference.step_paced(dt_s, &inner, pace);
        // Hazards: the slots, laid around where the leader is sent, keep clear of them by
        // the smallest horizontal shift of the reference; failing that, it holds.
        let mut blocked = None;
        if !self.hazards.is_empty() {
            let plan_heading = match spec.frame {
                FormationFrame::World => spec.heading_deg.to_radians(),
                FormationFrame::Leader => self.pattern_heading.unwrap_or(reference.heading_rad),
            };
            let plan = slot_positions(&offsets, reference.position, plan_heading);
            let shift = clearing_shift(&plan, &self.hazards, self.separation_m, MAX_HAZARD_SHIFT_M)
                .filter(|s| inner.contains(reference.position + *s));
            match shift {
                Some(s) => reference.position = reference.position + s,
                None => {
                    reference.motion = LeaderMotion::Hold;
                    let ids: Vec<&str> = self.hazards.iter().map(|h| h.id.as_str()).collect();
                    blocked = Some(format!(
                        "no shift of up to {MAX_HAZARD_SHIFT_M} m inside the geofence keeps every slot {} m plus their radius from the hazards ({}): holding",
                        self.separation_m,
                        ids.join(", ")
                    ));
                }
            }
        }
        let reference = reference.clone();
        self.set_blocked(blocked);
        // Anchor and heading of the slot pattern.
        let (anchor, anchor_velocity, wanted_heading) = if virtual_leader {
            let h = match spec.frame {
                FormationFrame::World => spec.heading_deg.to_radians(),
                FormationFrame::Leader => reference.heading_rad,
            };
            (reference.position, reference.velocity, h)
        } else if live[&leader].silence > PACE_SILENCE {
            // A silent leader vehicle rides through on the reference point (its slot):
            // the pattern is laid around that, not around its stale position.
            let h = match spec.frame {
                FormationFrame::World => spec.heading_deg.to_radians(),
                FormationFrame::Leader => reference.heading_rad,
            };
            (reference.position, reference.velocity, h)
        } else {
            let m = &live[&leader];
            let h = match spec.frame {
                FormationFrame::World => spec.heading_deg.to_radians(),
                FormationFrame::Leader => m.heading_rad,
            };
            let mut a = m.position;
            // Followers keep the formation altitude, not the leader's transient one.
            a.down_m = reference.position.down_m;
            (a, m.velocity, h)
        };
        // A `leader`-frame pattern turns as a rigid body, its outermost slot at no more
        // than TURN_SPEED_M_S (the leader's heading may jump, e.g. when it sets off); a
        // `world` heading changes only with the spec, and the transition covers that.
        let (heading, heading_rate) = match (spec.frame, self.pattern_heading) {
            (FormationFrame::Leader, Some(h)) if dt_s > 0.0 => {
                turn(h, self.pattern_rate, wanted_heading, &offsets, pace, dt_s)
            }
            _ => (wanted_heading, 0.0),
        };
        self.pattern_rate = heading_rate;
        self.pattern_heading = Some(heading);
        let slots = slot_positions(&offsets, anchor, heading);
        // Members that hold the transition's time scale (nearly) still: behind their place
        // on the plan by more than this.
        const HELD_M: f64 = LAG_STOP_M - 0.1 * (LAG_STOP_M - LAG_SLOW_M);
        let mut held: Vec<(String, f64)> = Vec::new();
        if let Some(t) = self.transition.as_mut() {
            // How far the slowest member is behind its place on the plan.
            let lags: Vec<(String, f64)> = t
                .starts
                .keys()
                .filter_map(|id| {
                    let (offset, _) = t.planned(id)?;
                    let d =
                        (live.get(id)?.position - (anchor + offset.rotated_yaw(heading))).norm();
                    Some((id.clone(), d))
                })
                .collect();
            let lag = lags.iter().map(|(_, d)| *d).fold(0.0, f64::max);
            t.advance(dt_s, lag);
            held.extend(lags.into_iter().filter(|(_, d)| *d >= HELD_M));
        }
        self.stalled_s = if held.is_empty() {
            0.0
        } else {
            self.stalled_s + dt_s
        };
        if self.stalled_s >= self.replan_after_s && !self.assignment.is_empty() {
            // No deadlock: plan the change again from where the members are.
            let reason = held
                .iter()
                .map(|(id, d)| format!("{id} held {d:.1} m from its place"))
                .collect::<Vec<_>>()
                .join(", ");
            self.replans.push(Replan {
                stuck: held.into_iter().map(|(id, _)| id).collect(),
                reason: format!(
                    "{reason} for {:.0} s: planned again from where the members are",
                    self.stalled_s
                ),
            });
            self.stalled_s = 0.0;
            self.assignment.clear();
            self.commanded.clear();
            self.transition = None;
        }

        // Assignment when the shape, leader or membership changed, then a transition.
        let membership_changed = self.assignment.len() != capacity
            || self.assignment.keys().any(|k| !live.contains_key(k));
        if membership_changed {
            // Where each member starts, pattern frame: where it was being sent (its slot,
            // or its place on the plan in flight: the plan is what keeps the separation),
            // relative to the anchor so that a moving formation does not jump; a newcomer
            // from where it is.
            let starts: BTreeMap<String, Ned> = live
                .iter()
                .map(|(id, m)| {
                    let arm = self
                        .commanded
                        .get(id)
                        .copied()
                        .unwrap_or(m.position - anchor);
                    (id.clone(), arm.rotated_yaw(-heading))
                })
                .collect();
            let leader_vehicle = (!virtual_leader).then_some(leader.as_str());
            // Hazards in the pattern frame, like the starts and the slots.
            let hazards: Vec<Hazard> = self
                .hazards
                .iter()
                .map(|h| Hazard {
                    position: (h.position - anchor).rotated_yaw(-heading),
                    ..h.clone()
                })
                .collect();
            let (assignment, transition) = assign(
                &starts,
                &offsets,
                leader_vehicle,
                self.separation_m,
                &hazards,
            );
            self.assignment = assignment;
            self.transition = Some(transition);
        }

        self.last.clear();
        self.commanded.clear();
        self.sent.clear();
        for (id, &slot) in &self.assignment {
            let is_leader_vehicle = !virtual_leader && *id == leader;
            let planned = self.transition.as_ref().and_then(|t| t.planned(id));
            let (position, velocity) = if is_leader_vehicle {
                // The leader vehicle flies the reference point itself.
                (reference.position, reference.velocity)
            } else if let Some((offset, rate)) = planned {
                let arm = offset.rotated_yaw(heading);
                self.commanded.insert(id.clone(), arm);
                (
                    anchor + arm,
                    anchor_velocity + rate.rotated_yaw(heading) + spin(heading_rate, arm),
                )
            } else {
                let arm = slots[slot] - anchor;
                self.commanded.insert(id.clone(), arm);
                (slots[slot], anchor_velocity + spin(heading_rate, arm))
            };
            // The slot itself: errors are measured to it, not to the transition's plan.
            let goal = if is_leader_vehicle {
                position
            } else {
                slots[slot]
            };
            self.sent.insert(id.clone(), (position, velocity));
            out.insert(
                id.clone(),
                SlotCommand {
                    slot,
                    leader: is_leader_vehicle,
                    position,
                    goal,
                    velocity,
                    yaw_rad: heading,
                },
            );
            if let Some(m) = members.get(id) {
                // A silent member: its error when last heard (its position is frozen
                // while its slot moves on).
                let silent = m.silence > PACE_SILENCE;
                let unseen_s = m
                    .silence
                    .saturating_sub(skein_protocol::REPORT_EXTRAPOLATION)
                    .as_secs_f64();
                let at = if silent {
                    m.position + velocity * unseen_s
                } else {
                    m.position
                };
                self.last.push(MemberStatus {
                    id: id.clone(),
                    slot,
                    target: goal,
                    error_m: (at - goal).norm(),
                    silent_s: silent.then_some(m.silence.as_secs_f64()),
                });
            }
        }
        if self.transition.as_ref().is_some_and(Transition::done) {
            self.transition = None;
        }
        self.last.sort_by_key(|m| m.slot);
        let offsets = out
            .iter()
            .map(|(id, c)| {
                let offset = (c.goal - reference.position).rotated_yaw(-heading);
                (id.clone(), (c.slot, offset))
            })
            .collect();
        self.absences.update(offsets);
        out
    }
}

pub mod mirror;
mod view;

#[cfg(test)]
mod silence_tests;
#[cfg(test)]
pub(super) mod tests;
