//! An agent's ride-through: its vehicles fly their slots on while no coordinator is
//! heard, and its silent neighbours are predicted on theirs, from the last formation the
//! active coordinator mirrored (`/skein/formation`).
//!
//! A WLAN fades for a second or two far more often than it fails. Without a
//! ride-through, an agent whose coordinator fell silent held its vehicles after
//! `coordinator_timeout_s`, and the formation waited for them. With it, for
//! [`Riding::ride_through`] after a vehicle's last slot target:
//!
//! - each local vehicle that was flying a slot gets its slot target from this agent at
//!   the formation's rate, computed from the mirror exactly as the coordinator computes
//!   it ([`RideThrough`]): the reference point moved on by its motion, the vehicle's
//!   offset from it (taken from its last target) turned with the pattern;
//! - each other agent's vehicle that was a member and fell silent is predicted the same
//!   way from its last report, so that the separation check of this agent's vehicles
//!   sees where it flies, not where it was last heard.
//!
//! Why this is safe: every member flies the same plan from the same mirror, and the
//! plan keeps them apart (slots are the separation apart, a formation change's paths
//! were planned apart); every setpoint still passes the vehicle's geofence, speed and
//! separation checks. What the plan cannot know (a member lagging, a hazard, a command
//! sent meanwhile) is why the ride-through lasts seconds: after it, the agent holds its
//! vehicles as before, and the coordinator gives their slots up.

use skein_model::geo::Ned;
use skein_model::safety::Geofence;
use skein_swarm::formation::{FormationMirror, RideThrough};
use skein_swarm::protocol::{SlotTarget, VehicleReport};
use std::collections::BTreeMap;
use std::time::Duration;

/// A vehicle rides once its last slot target is this old: three of the formation's
/// targets (10 Hz) missed, or a coordinator gone.
pub const RIDE_AFTER: Duration = Duration::from_millis(300);

/// A local vehicle's last slot target (this process's frame and clock) and its place in
/// the pattern.
#[derive(Debug, Clone)]
struct Slot {
    target: SlotTarget,
    /// Offset of `target.position` from the reference at its stamp, pattern frame.
    offset: Option<Ned>,
}

/// Another agent's vehicle, as last reported (this process's frame and clock).
#[derive(Debug, Clone)]
struct Neighbour {
    report: VehicleReport,
    /// Offset of its position from the reference at the report's stamp, pattern frame,
    /// when it was a member flying a slot.
    offset: Option<Ned>,
}

/// The ride-through state of one agent (see the module docs). Times are wall-clock µs
/// of this process.
#[derive(Debug)]
pub struct Riding {
    ride_through: Duration,
    ride: Option<RideThrough>,
    slots: BTreeMap<String, Slot>,
    neighbours: BTreeMap<String, Neighbour>,
    /// The local vehicles riding as of the last tick.
    riding: std::collections::BTreeSet<String>,
    /// The other agents' vehicles predicted as of the last tick.
    predicted: std::collections::BTreeSet<String>,
}

impl Riding {
    /// Rides through for `ride_through` after a vehicle's last target (zero: never).
    pub fn new(ride_through: Duration) -> Self {
        Riding {
            ride_through,
            ride: None,
            slots: BTreeMap::new(),
            neighbours: BTreeMap::new(),
            riding: Default::default(),
            predicted: Default::default(),
        }
    }

    /// How long it rides through.
    pub fn ride_through(&self) -> Duration {
        self.ride_through
    }

    /// The active coordinator's formation (this process's frame and clock), inside this
    /// agent's `geofence`; `None`: it flies none.
    pub fn on_mirror(&mut self, mirror: Option<FormationMirror>, geofence: &Geofence) {
        self.ride = mirror.map(|m| RideThrough::new(m, geofence));
        if self.ride.is_none() {
            self.slots.clear();
        }
        for s in self.slots.values_mut() {
            s.offset = None;
        }
    }

    /// The offset of `p` at `stamp_us` from the current mirror, if any.
    fn offset_at(&self, p: Ned, stamp_us: u64) -> Option<Ned> {
        let ride = self.ride.as_ref()?;
        Some(ride.at(stamp_us).offset_of(p))
    }

    /// Local vehicle `id` was sent `target` by the active coordinator.
    pub fn on_target(&mut self, id: &str, target: SlotTarget) {
        let offset = self.offset_at(target.position, target.stamp_us);
        self.slots.insert(id.to_string(), Slot { target, offset });
    }

    /// Local vehicle `id` was commanded, or its slot dropped: it does not ride.
    pub fn forget(&mut self, id: &str) {
        self.slots.remove(id);
    }

    /// Another agent's vehicle `id` reported `report`.
    pub fn on_neighbour(&mut self, id: &str, report: VehicleReport) {
        let member = self
            .ride
            .as_ref()
            .is_some_and(|r| r.mirror().assignment.contains_key(id));
        let offset = match report.position {
            Some(p) if member && report.state == skein_model::fsm::VehicleState::InFormation => {
                self.offset_at(p, report.stamp_us)
            }
            _ => None,
        };
        self.neighbours
            .insert(id.to_string(), Neighbour { report, offset });
    }

    /// The ride at `now_us`: the slot targets of the local vehicles that ride (their last
    /// target between [`RIDE_AFTER`] and the ride-through old), and the predicted reports
    /// of the silent neighbours that were members (silent for [`RIDE_AFTER`] or more,
    /// predicted up to the ride-through after they were last heard: then their agents
    /// hold them).
    pub fn tick(&mut self, now_us: u64) -> RideTick {
        let mut out = self.tick_rides(now_us);
        let now: std::collections::BTreeSet<String> =
            out.targets.iter().map(|(id, _)| id.clone()).collect();
        out.started = now.difference(&self.riding).cloned().collect();
        out.ended = self.riding.difference(&now).cloned().collect();
        self.riding = now;
        let predicted: std::collections::BTreeSet<String> =
            out.neighbours.iter().map(|(id, _)| id.clone()).collect();
        out.predicting = predicted.difference(&self.predicted).cloned().collect();
        self.predicted = predicted;
        out
    }

    /// What a ride of local vehicle `id` flies at `now_us`, for the log: its offset from
    /// the reference (pattern frame, forward/right/down m) once taken, and the age of the
    /// mirror it rides from, ms (this process's clock).
    pub fn describe_slot(&self, id: &str, now_us: u64) -> String {
        let offset = self.slots.get(id).and_then(|s| s.offset);
        let age_ms = self
            .ride
            .as_ref()
            .map(|r| now_us.saturating_sub(r.mirror().stamp_us) as f64 / 1e3);
        match (offset, age_ms) {
            (Some(o), Some(a)) => format!(
                "offset ({:.2}, {:.2}, {:.2}) m, mirror {a:.0} ms old",
                o.north_m, o.east_m, o.down_m
            ),
            (None, Some(a)) => format!("no offset, mirror {a:.0} ms old"),
            _ => "no mirror".into(),
        }
    }

    /// How long other agent's vehicle `id` has been silent at `now_us` (its last report's
    /// age, this process's clock), ms, and its offset (pattern frame), for the log.
    pub fn describe_neighbour(&self, id: &str, now_us: u64) -> String {
        match self.neighbours.get(id) {
            Some(n) => {
                let silent_ms = now_us.saturating_sub(n.report.stamp_us) as f64 / 1e3;
                match n.offset {
                    Some(o) => format!(
                        "silent {silent_ms:.0} ms, offset ({:.2}, {:.2}) m",
                        o.north_m, o.east_m
                    ),
                    None => format!("silent {silent_ms:.0} ms, no offset"),
                }
            }
            None => "never heard".into(),
        }
    }

    fn tick_rides(&mut self, now_us: u64) -> RideTick {
        let mut out = RideTick::default();
        let Some(ride) = self.ride.as_mut() else {
            return out;
        };
        ride.advance_to(now_us);
        let ride = &*ride;
        let limit_us = self.ride_through.as_micros() as u64;
        let after_us = RIDE_AFTER.as_micros() as u64;
        for (id, s) in &mut self.slots {
            let age = now_us.saturating_sub(s.target.stamp_us);
            if age < after_us || age >= limit_us {
                continue;
            }
            if s.offset.is_none() {
                s.offset = Some(ride.at(s.target.stamp_us).offset_of(s.target.position));
            }
            let Some(offset) = s.offset else { continue };
            let (position, velocity) = ride.place(offset);
            out.targets.push((
                id.clone(),
                SlotTarget {
                    position,
                    goal: position,
                    velocity,
                    yaw_rad: ride.heading_rad(),
                    stamp_us: now_us,
                    ..s.target
                },
            ));
        }
        for (id, n) in &self.neighbours {
            let Some(offset) = n.offset else { continue };
            let silent = now_us.saturating_sub(n.report.stamp_us);
            if silent < after_us {
                continue;
            }
            // Predicted where it flies now, or where its agent held it.
            let until = now_us.min(n.report.stamp_us + limit_us);
            let at = ride.at(until);
            let (position, velocity) = at.place(offset);
            let moving = until == now_us;
            // Where it is and where it is sent are both its slot: its last reported
            // target would be a ghost the others keep clear of.
            out.neighbours.push((
                id.clone(),
                VehicleReport {
                    position: Some(position),
                    velocity: if moving { velocity } else { Ned::ZERO },
                    target: Some(position),
                    stamp_us: now_us,
                    ..n.report
                },
            ));
        }
        out
    }

    /// The ride's reference point and motion, for the log.
    pub fn describe(&self) -> (String, String) {
        match &self.ride {
            Some(r) => {
                let p = r.reference().position;
                let v = r.reference().velocity;
                (
                    format!(
                        "({:.1}, {:.1}, {:.1}) m moving {:.1} m/s",
                        p.north_m,
                        p.east_m,
                        p.down_m,
                        v.horizontal_norm()
                    ),
                    format!("{:?}", r.reference().motion)
                        .split_whitespace()
                        .next()
                        .unwrap_or("?")
                        .to_string(),
                )
            }
            None => ("none".into(), "no formation".into()),
        }
    }

    /// True while some local vehicle rides through at `now_us`.
    pub fn riding(&self, now_us: u64) -> bool {
        let (after, limit) = (
            RIDE_AFTER.as_micros() as u64,
            self.ride_through.as_micros() as u64,
        );
        self.ride.is_some()
            && self.slots.values().any(|s| {
                let age = now_us.saturating_sub(s.target.stamp_us);
                age >= after && age < limit
            })
    }
}

/// What a [`Riding::tick`] asks the agent to do.
#[derive(Debug, Default)]
pub struct RideTick {
    /// Slot targets for local vehicles, by id.
    pub targets: Vec<(String, SlotTarget)>,
    /// Predicted reports of other agents' silent vehicles, by id.
    pub neighbours: Vec<(String, VehicleReport)>,
    /// Local vehicles that started riding at this tick, and that stopped.
    pub started: Vec<String>,
    /// Local vehicles that stopped riding at this tick (heard again, commanded, or
    /// their ride-through over).
    pub ended: Vec<String>,
    /// Other agents' vehicles predicted from this tick on (not at the one before).
    pub predicting: Vec<String>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use skein_model::fsm::VehicleState;
    use skein_swarm::formation::{FormationSpec, LeaderMotion, Reference};

    const T0: u64 = 1_000_000_000;

    /// A wedge behind the virtual leader at (`north`, 0) at T0, cruising north at 5 m/s.
    fn mirror() -> FormationMirror {
        let spec: FormationSpec = serde_json::from_value(serde_json::json!({
            "shape": "wedge", "spacing_m": 6.0, "leader": "virtual", "altitude_m": 12.0,
            "heading_deg": 0.0, "frame": "leader", "offsets": []
        }))
        .unwrap();
        FormationMirror {
            spec,
            reference: Reference {
                position: Ned::new(100.0, 0.0, -12.0),
                velocity: Ned::new(5.0, 0.0, 0.0),
                heading_rad: 0.0,
                heading_rate_rad_s: 0.0,
                motion: LeaderMotion::GoTo {
                    target: Ned::new(1000.0, 0.0, -12.0),
                    speed_m_s: 5.0,
                },
            },
            leader: None,
            pattern_heading_rad: Some(0.0),
            assignment: [("uav-1", 0), ("uav-2", 1), ("uav-3", 2)]
                .into_iter()
                .map(|(id, s)| (id.to_string(), s))
                .collect(),
            stamp_us: T0,
        }
    }

    fn target(position: Ned, stamp_us: u64) -> SlotTarget {
        SlotTarget {
            slot: 1,
            leader: false,
            position,
            goal: position,
            velocity: Ned::new(5.0, 0.0, 0.0),
            yaw_rad: 0.0,
            stamp_us,
        }
    }

    #[test]
    fn a_vehicle_rides_its_slot_from_the_mirror_then_stops_riding() {
        let mut r = Riding::new(Duration::from_secs(4));
        r.on_mirror(Some(mirror()), &Geofence::default());
        // Its last target: 4.24 m behind and right of the reference, 0.1 s after the
        // mirror (the reference 0.5 m further north by then).
        r.on_target("uav-2", target(Ned::new(96.26, 4.24, -12.0), T0 + 100_000));
        assert!(
            r.tick(T0 + 300_000).targets.is_empty(),
            "not yet: heard 0.2 s ago"
        );
        assert!(!r.riding(T0 + 300_000));
        // 2 s after the mirror: 10 m on, at 5 m/s.
        let t = r.tick(T0 + 2_000_000);
        assert!(r.riding(T0 + 2_000_000));
        assert_eq!(t.targets.len(), 1);
        let (id, s) = &t.targets[0];
        assert_eq!(id, "uav-2");
        assert!(
            (s.position - Ned::new(105.76, 4.24, -12.0)).norm() < 0.01,
            "{s:?}"
        );
        assert!((s.velocity - Ned::new(5.0, 0.0, 0.0)).norm() < 1e-6);
        assert_eq!(s.slot, 1);
        assert_eq!(s.stamp_us, T0 + 2_000_000);
        assert_eq!(
            r.describe_slot("uav-2", T0 + 2_000_000),
            "offset (-4.24, 4.24, 0.00) m, mirror 2000 ms old"
        );
        // Past the ride-through after its last target: no more.
        assert!(r.tick(T0 + 4_100_000).targets.is_empty());
        // A command (or a dropped slot) ends it at once.
        r.on_target("uav-2", target(Ned::new(96.26, 4.24, -12.0), T0 + 100_000));
        r.forget("uav-2");
        assert!(r.tick(T0 + 2_000_000).targets.is_empty());
    }

    #[test]
    fn without_a_formation_or_with_no_ride_through_nothing_rides() {
        let mut r = Riding::new(Duration::from_secs(4));
        r.on_target("uav-2", target(Ned::new(96.26, 4.24, -12.0), T0 + 100_000));
        assert!(r.tick(T0 + 2_000_000).targets.is_empty());
        let mut r = Riding::new(Duration::ZERO);
        r.on_mirror(Some(mirror()), &Geofence::default());
        r.on_target("uav-2", target(Ned::new(96.26, 4.24, -12.0), T0 + 100_000));
        assert!(r.tick(T0 + 2_000_000).targets.is_empty());
        // The formation stopped: its slots are forgotten.
        let mut r = Riding::new(Duration::from_secs(4));
        r.on_mirror(Some(mirror()), &Geofence::default());
        r.on_target("uav-2", target(Ned::new(96.26, 4.24, -12.0), T0 + 100_000));
        r.on_mirror(None, &Geofence::default());
        assert!(r.tick(T0 + 2_000_000).targets.is_empty());
    }

    #[test]
    fn a_silent_member_neighbour_is_predicted_on_its_slot_until_its_agent_holds_it() {
        let mut r = Riding::new(Duration::from_secs(4));
        r.on_mirror(Some(mirror()), &Geofence::default());
        let report = VehicleReport {
            state: VehicleState::InFormation,
            position: Some(Ned::new(96.26, -4.24, -12.0)),
            velocity: Ned::new(5.0, 0.0, 0.0),
            target: Some(Ned::new(96.26, -4.24, -12.0)),
            stamp_us: T0,
            ..VehicleReport::disconnected()
        };
        r.on_neighbour("uav-3", report);
        // A vehicle that is no member is not predicted.
        r.on_neighbour(
            "uav-9",
            VehicleReport {
                stamp_us: T0,
                ..report
            },
        );
        assert!(
            r.tick(T0 + 200_000).neighbours.is_empty(),
            "heard 0.2 s ago"
        );
        let t = r.tick(T0 + 3_000_000);
        assert_eq!(t.neighbours.len(), 1, "{t:?}");
        assert_eq!(
            t.predicting,
            vec!["uav-3".to_string()],
            "first predicted now"
        );
        assert!(
            r.describe_neighbour("uav-3", T0 + 3_000_000)
                .starts_with("silent 3000 ms")
        );
        let (id, p) = &t.neighbours[0];
        assert_eq!(id, "uav-3");
        assert!((p.position.unwrap() - Ned::new(111.26, -4.24, -12.0)).norm() < 0.01);
        assert_eq!(
            p.target, p.position,
            "sent where it is predicted, not where it was"
        );
        assert_eq!(p.stamp_us, T0 + 3_000_000);
        // Past its ride-through its agent held it: it stays there, at rest.
        let t = r.tick(T0 + 6_000_000);
        assert!(t.predicting.is_empty(), "already predicted: {t:?}");
        let (_, p) = &t.neighbours[0];
        assert!((p.position.unwrap() - Ned::new(116.26, -4.24, -12.0)).norm() < 0.01);
        assert_eq!(p.velocity, Ned::ZERO);
    }
}
