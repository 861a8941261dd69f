//! The formation engine's tick, step by step: the formation waiting for the change in
//! flight, the leader, the reference point (paced, fenced, clear of hazards), the slot
//! pattern, the transition in flight (planned again when pacing stalls it), the
//! assignment, and each member's slot command and status.

use super::{FormationEngine, MAX_HAZARD_SHIFT_M, PACE_SILENCE};
use crate::assignment::assign;
use crate::hazard::{Hazard, clearing_shift};
use crate::leader::{healthy, resolve_leader};
use crate::pattern::{spin, turn};
use crate::reference::{Reference, inner_fence, pace};
use crate::spec::{FormationFrame, FormationSpec, LeaderMotion, VIRTUAL};
use crate::status::{Member, MemberStatus, Replan, SlotCommand};
use crate::transition::{LAG_SLOW_M, LAG_STOP_M, Transition};
use skein_model::formation::slot_positions;
use skein_model::geo::Ned;
use skein_model::safety::Geofence;
use skein_protocol::REPORT_EXTRAPOLATION;
use std::collections::BTreeMap;

/// Members that hold the transition's time scale (nearly) still: behind their place on
/// the plan by more than this, metres.
const HELD_M: f64 = LAG_STOP_M - 0.1 * (LAG_STOP_M - LAG_SLOW_M);

/// What one tick flies: the spec in force, its leader, the members heard from and the
/// slots they fill.
struct Tick<'a> {
    spec: &'a FormationSpec,
    /// A vehicle id or [`VIRTUAL`].
    leader: &'a str,
    /// The members heard from within their ride-through.
    live: &'a BTreeMap<String, Member>,
    /// How many slots the formation has for them.
    capacity: usize,
    /// The slots' offsets, pattern frame, metres (slot 0 the leader's).
    offsets: &'a [Ned],
    /// Time since the last tick, seconds.
    dt_s: f64,
}

impl Tick<'_> {
    /// The leader vehicle, `None` for the virtual leader.
    fn leader_vehicle(&self) -> Option<&str> {
        (self.leader != VIRTUAL).then_some(self.leader)
    }
}

/// The slot pattern of one tick, swarm frame.
struct Pattern {
    /// Where the offsets are laid from, metres.
    anchor: Ned,
    /// How fast the anchor moves, m/s.
    anchor_velocity: Ned,
    /// Heading of the pattern, radians clockwise from north.
    heading: f64,
    /// Its rate of turn, rad/s.
    heading_rate: f64,
    /// Each slot's position, metres.
    slots: Vec<Ned>,
}

impl FormationEngine {
    /// Computes this tick's slot for every member. `members` are the vehicles flying the
    /// formation (healthy or not); `dt_s` is the time since the last tick, seconds;
    /// `fence` bounds the reference point.
    pub fn tick(
        &mut self,
        members: &BTreeMap<String, Member>,
        dt_s: f64,
        fence: &Geofence,
    ) -> BTreeMap<String, SlotCommand> {
        if self.transition.is_none()
            && let Some(next) = self.pending.take()
        {
            self.apply(next);
            self.pending_applied = true;
        }
        let Some(spec) = self.spec.clone().filter(|_| self.active) else {
            return BTreeMap::new();
        };
        // Silent members keep no slot (they would hold the others' assignment hostage).
        let live = healthy(members);
        let leader = if live.is_empty() {
            None
        } else {
            self.lead(&spec, members, &live)
        };
        let Some(leader) = leader else {
            self.last.clear();
            self.absences.update(BTreeMap::new());
            return BTreeMap::new();
        };
        let capacity = spec.capacity(live.len());
        let offsets = spec.offsets(capacity);
        let t = Tick {
            spec: &spec,
            leader: &leader,
            live: &live,
            capacity,
            offsets: &offsets,
            dt_s,
        };
        let (reference, pace) = self.move_reference(&t, fence);
        let pattern = self.lay_pattern(&t, &reference, pace);
        let held = self.advance_transition(&t, &pattern);
        self.replan_if_stalled(held, dt_s);
        if self.membership_changed(&t) {
            self.reassign(&t, &pattern);
        }
        let out = self.command_slots(&t, members, &pattern, &reference);
        self.settle(&out, &reference, pattern.heading);
        out
    }

    /// The leader for this tick (see `resolve_leader`), its change kept for the event
    /// stream; `None` when no member can lead. A new leader takes over (`take_over`).
    fn lead(
        &mut self,
        spec: &FormationSpec,
        members: &BTreeMap<String, Member>,
        live: &BTreeMap<String, Member>,
    ) -> Option<String> {
        let (leader, change) = resolve_leader(
            self.leader.as_deref(),
            self.reference.as_ref().map(|r| r.position),
            spec,
            members,
            self.requested_led,
        );
        self.changes.extend(change);
        let leader = leader?;
        self.requested_led |= spec.leader.as_ref() == Some(&leader);
        if self.leader.as_ref() != Some(&leader) {
            self.take_over(&leader, live);
        }
        Some(leader)
    }

    /// `leader` leads from now on: the slots are assigned afresh (offsets from the old
    /// anchor mean nothing around the new one), and a leader vehicle that replaces another
    /// takes the formation from where it is (the old leader's spot may still be occupied:
    /// a silent vehicle may hover on there).
    fn take_over(&mut self, leader: &str, live: &BTreeMap<String, Member>) {
        let failover = self.leader.as_ref().is_some_and(|l| l != VIRTUAL);
        self.leader = Some(leader.to_string());
        self.assignment.clear();
        self.commanded.clear();
        self.sent.clear();
        if failover
            && leader != VIRTUAL
            && let (Some(r), Some(m)) = (self.reference.as_mut(), live.get(leader))
        {
            let mut p = m.target.unwrap_or(m.position);
            p.down_m = r.position.down_m;
            r.position = p;
        }
    }

    /// Moves the reference point one tick along its motion, at the members' pace, inside
    /// the fence shrunk so that every slot stays inside, and clear of the hazards (or
    /// held there, the formation blocked). Returns the reference and the pace.
    fn move_reference(&mut self, t: &Tick, fence: &Geofence) -> (Reference, f64) {
        let inner = inner_fence(fence, &self.extents(t.offsets));
        let pace = self.pace(t);
        let mut reference = self
            .reference
            .take()
            .unwrap_or_else(|| initial_reference(t));
        reference.step_paced(t.dt_s, &inner, pace);
        let blocked = self.clear_hazards(t, &mut reference, &inner);
        self.set_blocked(blocked);
        self.reference = Some(reference.clone());
        (reference, pace)
    }

    /// Where the slots and every place on a transition in flight or about to start lie
    /// from the anchor: paths are straight between start and goal (plus a climb), so
    /// their ends bound their reach.
    fn extents(&self, offsets: &[Ned]) -> Vec<Ned> {
        let mut extents = offsets.to_vec();
        extents.extend(self.commanded.values().copied());
        if let Some(t) = &self.transition {
            extents.extend(t.extents());
        }
        extents
    }

    /// The pace of this tick: how far the farthest member is from where it was sent
    /// (extrapolated to now), against PACE_SLOW_M … PACE_STOP_M; full pace during the
    /// grace after a resumed formation. A silent member's position is stale: it rides
    /// through on its slot and does not hold the others back.
    fn pace(&mut self, t: &Tick) -> f64 {
        let behind = self
            .sent
            .iter()
            .filter_map(|(id, (p, v))| {
                let m = t.live.get(id).filter(|m| m.silence <= PACE_SILENCE)?;
                Some((m.position - (*p + *v * t.dt_s)).norm())
            })
            .fold(0.0, f64::max);
        if self.pace_grace_s > 0.0 {
            self.pace_grace_s -= t.dt_s;
            1.0
        } else {
            pace(behind)
        }
    }

    /// Keeps the slots, laid around where the leader is sent, clear of the hazards by the
    /// smallest horizontal shift of `reference` that stays inside `inner`; failing that,
    /// the reference holds and the answer says why (the formation is blocked).
    fn clear_hazards(
        &self,
        t: &Tick,
        reference: &mut Reference,
        inner: &Geofence,
    ) -> Option<String> {
        if self.hazards.is_empty() {
            return None;
        }
        let plan_heading = match t.spec.frame {
            FormationFrame::World => t.spec.heading_deg.to_radians(),
            FormationFrame::Leader => self.pattern_heading.unwrap_or(reference.heading_rad),
        };
        let plan = slot_positions(t.offsets, reference.position, plan_heading);
        let shift = clearing_shift(&plan, &self.hazards, self.separation_m, MAX_HAZARD_SHIFT_M)
            .filter(|s| inner.contains(reference.position + *s));
        if let Some(s) = shift {
            reference.position = reference.position + s;
            return None;
        }
        reference.motion = LeaderMotion::Hold;
        let ids: Vec<&str> = self.hazards.iter().map(|h| h.id.as_str()).collect();
        Some(format!(
            "no shift of up to {MAX_HAZARD_SHIFT_M} m inside the geofence keeps every slot {} m plus their radius from the hazards ({}): holding",
            self.separation_m,
            ids.join(", ")
        ))
    }

    /// Lays this tick's slot pattern around its anchor ([`anchor`]). A `leader`-frame
    /// pattern turns as a rigid body, its outermost slot at no more than TURN_SPEED_M_S
    /// (the leader's heading may jump, e.g. when it sets off); a `world` heading changes
    /// only with the spec, and the transition covers that.
    fn lay_pattern(&mut self, t: &Tick, reference: &Reference, pace: f64) -> Pattern {
        let (anchor, anchor_velocity, wanted_heading) = anchor(t, reference);
        let (heading, heading_rate) = match (t.spec.frame, self.pattern_heading) {
            (FormationFrame::Leader, Some(h)) if t.dt_s > 0.0 => turn(
                h,
                self.pattern_rate,
                wanted_heading,
                t.offsets,
                pace,
                t.dt_s,
            ),
            _ => (wanted_heading, 0.0),
        };
        self.pattern_rate = heading_rate;
        self.pattern_heading = Some(heading);
        Pattern {
            anchor,
            anchor_velocity,
            heading,
            heading_rate,
            slots: slot_positions(t.offsets, anchor, heading),
        }
    }

    /// Moves the transition in flight on along its time scale, as far as the member
    /// farthest behind its place on the plan lets it; returns the members it holds
    /// (nearly) still, with how far behind they are, metres.
    fn advance_transition(&mut self, t: &Tick, p: &Pattern) -> Vec<(String, f64)> {
        let Some(transition) = self.transition.as_mut() else {
            return Vec::new();
        };
        let lags: Vec<(String, f64)> = transition
            .starts
            .keys()
            .filter_map(|id| {
                let (offset, _) = transition.planned(id)?;
                let place = p.anchor + offset.rotated_yaw(p.heading);
                Some((id.clone(), (t.live.get(id)?.position - place).norm()))
            })
            .collect();
        let lag = lags.iter().map(|(_, d)| *d).fold(0.0, f64::max);
        transition.advance(t.dt_s, lag);
        lags.into_iter().filter(|(_, d)| *d >= HELD_M).collect()
    }

    /// Counts how long pacing has held a member (`held`, see `advance_transition`); past
    /// the replan time the change is planned again from where the members are (no
    /// deadlock), with a [`Replan`] saying who was stuck.
    fn replan_if_stalled(&mut self, held: Vec<(String, f64)>, dt_s: f64) {
        self.stalled_s = if held.is_empty() {
            0.0
        } else {
            self.stalled_s + dt_s
        };
        if self.stalled_s >= self.replan_after_s && !self.assignment.is_empty() {
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
    }

    /// True when the shape, the leader or the membership changed since the last
    /// assignment.
    fn membership_changed(&self, t: &Tick) -> bool {
        self.assignment.len() != t.capacity
            || self.assignment.keys().any(|k| !t.live.contains_key(k))
    }

    /// Assigns the slots afresh and plans the transition to them. Each member starts,
    /// pattern frame, from where it was being sent (its slot, or its place on the plan in
    /// flight: the plan is what keeps the separation), relative to the anchor so that a
    /// moving formation does not jump; a newcomer from where it is. The hazards are
    /// turned into the pattern frame too.
    fn reassign(&mut self, t: &Tick, p: &Pattern) {
        let starts: BTreeMap<String, Ned> = t
            .live
            .iter()
            .map(|(id, m)| {
                let arm = self
                    .commanded
                    .get(id)
                    .copied()
                    .unwrap_or(m.position - p.anchor);
                (id.clone(), arm.rotated_yaw(-p.heading))
            })
            .collect();
        let hazards: Vec<Hazard> = self
            .hazards
            .iter()
            .map(|h| Hazard {
                position: (h.position - p.anchor).rotated_yaw(-p.heading),
                ..h.clone()
            })
            .collect();
        let (assignment, transition) = assign(
            &starts,
            t.offsets,
            t.leader_vehicle(),
            self.separation_m,
            &hazards,
        );
        self.assignment = assignment;
        self.transition = Some(transition);
    }

    /// Every assigned member's slot command, and the status of those in `members`;
    /// remembers where each was sent. The leader vehicle flies the reference point
    /// itself; the others their place on the transition's plan, or their slot, moving
    /// with the anchor and the pattern's turn.
    fn command_slots(
        &mut self,
        t: &Tick,
        members: &BTreeMap<String, Member>,
        p: &Pattern,
        reference: &Reference,
    ) -> BTreeMap<String, SlotCommand> {
        self.last.clear();
        self.commanded.clear();
        self.sent.clear();
        let mut out = BTreeMap::new();
        for (id, &slot) in &self.assignment {
            let leads = t.leader_vehicle() == Some(id.as_str());
            let planned = self.transition.as_ref().and_then(|tr| tr.planned(id));
            let (position, velocity) = match (leads, planned) {
                (true, _) => (reference.position, reference.velocity),
                (false, Some((offset, rate))) => {
                    let arm = offset.rotated_yaw(p.heading);
                    self.commanded.insert(id.clone(), arm);
                    let velocity =
                        p.anchor_velocity + rate.rotated_yaw(p.heading) + spin(p.heading_rate, arm);
                    (p.anchor + arm, velocity)
                }
                (false, None) => {
                    let arm = p.slots[slot] - p.anchor;
                    self.commanded.insert(id.clone(), arm);
                    (p.slots[slot], p.anchor_velocity + spin(p.heading_rate, arm))
                }
            };
            self.sent.insert(id.clone(), (position, velocity));
            let command = SlotCommand {
                slot,
                leader: leads,
                position,
                // The slot itself: errors are measured to it, not to the transition's plan.
                goal: if leads { position } else { p.slots[slot] },
                velocity,
                yaw_rad: p.heading,
            };
            if let Some(m) = members.get(id) {
                self.last.push(member_status(id, m, &command));
            }
            out.insert(id.clone(), command);
        }
        out
    }

    /// Ends a transition that is done, orders the members' status by slot, and tells the
    /// absences where each member's slot is (its goal from the reference point, pattern
    /// frame).
    fn settle(&mut self, out: &BTreeMap<String, SlotCommand>, reference: &Reference, heading: f64) {
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
    }
}

/// The reference point of a formation that has none yet: where the leader vehicle is
/// held (or is), or the members' centroid for the virtual leader, at the formation
/// altitude when the spec sets one, heading the spec's heading.
fn initial_reference(t: &Tick) -> Reference {
    let mut p = match t.leader_vehicle() {
        None => {
            let n = t.live.len() as f64;
            t.live.values().fold(Ned::ZERO, |a, m| a + m.position) * (1.0 / n)
        }
        Some(leader) => {
            let m = &t.live[leader];
            m.target.unwrap_or(m.position)
        }
    };
    if let Some(alt) = t.spec.altitude_m {
        p.down_m = -alt;
    }
    Reference::at(p, t.spec.heading_deg.to_radians())
}

/// Where the slot pattern is laid (metres), how fast that moves (m/s), and the heading
/// the pattern wants (radians). The reference point for the virtual leader, and for a
/// silent leader vehicle (it rides through on the reference point, its slot: the pattern
/// is not laid around its stale position); else the leader vehicle, at the formation
/// altitude (followers keep that, not the leader's transient one).
fn anchor(t: &Tick, reference: &Reference) -> (Ned, Ned, f64) {
    let heard = t
        .leader_vehicle()
        .map(|l| &t.live[l])
        .filter(|m| m.silence <= PACE_SILENCE);
    let heading = |own_rad: f64| match t.spec.frame {
        FormationFrame::World => t.spec.heading_deg.to_radians(),
        FormationFrame::Leader => own_rad,
    };
    match heard {
        None => (
            reference.position,
            reference.velocity,
            heading(reference.heading_rad),
        ),
        Some(m) => {
            let mut a = m.position;
            a.down_m = reference.position.down_m;
            (a, m.velocity, heading(m.heading_rad))
        }
    }
}

/// How well `m` flies the slot of `command`: a silent member by its error when last
/// heard (its position is frozen while its slot moves on).
fn member_status(id: &str, m: &Member, command: &SlotCommand) -> MemberStatus {
    let silent = m.silence > PACE_SILENCE;
    let unseen_s = m.silence.saturating_sub(REPORT_EXTRAPOLATION).as_secs_f64();
    let at = if silent {
        m.position + command.velocity * unseen_s
    } else {
        m.position
    };
    MemberStatus {
        id: id.to_string(),
        slot: command.slot,
        target: command.goal,
        error_m: (at - command.goal).norm(),
        silent_s: silent.then_some(m.silence.as_secs_f64()),
    }
}
