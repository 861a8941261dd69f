//! Who leads the formation: the requested vehicle, the first member by id, or the
//! virtual leader; and failover, when a leader vehicle leaves the formation or stays
//! silent past its ride-through ([`Member::ride_through`]: [`LEADER_SILENCE`] for a
//! vehicle of this process): the healthy member nearest to where it was takes over, with
//! a [`LeaderChange`] saying who and why. A requested leader that joins the formation
//! after it started (the others were hovering first) takes the lead it was given, once.

use super::spec::{FormationSpec, VIRTUAL};
use super::status::Member;
use serde::Serialize;
use skein_model::geo::Ned;
use std::collections::BTreeMap;
use std::time::Duration;

/// A vehicle of this process silent this long loses its slot and the lead (PX4's own
/// heartbeat timeout is 1.5 s): its ride-through ([`Member::ride_through`]).
pub const LEADER_SILENCE: Duration = Duration::from_millis(1500);

/// A change of leader.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LeaderChange {
    /// The previous leader (`"virtual"` or a vehicle id), if any.
    pub from: Option<String>,
    /// The new one.
    pub to: String,
    /// Why.
    pub reason: String,
}

/// The members heard from within their ride-through ([`Member::ride_through`]: a silent
/// member flies its slot on its own meanwhile).
pub(super) fn healthy(members: &BTreeMap<String, Member>) -> BTreeMap<String, Member> {
    members
        .iter()
        .filter(|(_, m)| m.silence < m.ride_through)
        .map(|(k, v)| (k.clone(), *v))
        .collect()
}

/// The member nearest to `to` (swarm-frame NED), by id.
fn nearest(members: &BTreeMap<String, Member>, to: Ned) -> Option<String> {
    members
        .iter()
        .min_by(|a, b| {
            (a.1.position - to)
                .norm_squared()
                .total_cmp(&(b.1.position - to).norm_squared())
        })
        .map(|(id, _)| id.clone())
}

/// The leader for this tick, given the one in force (`current`, a vehicle id or
/// [`VIRTUAL`]), where the reference point is (swarm-frame NED), the spec, all members
/// (healthy or not) and whether the requested leader has led since the spec was set
/// (`requested_has_led`); with the change to report when it is a new one. `None` when no
/// member can lead.
///
/// A requested leader that has not led yet takes the lead as soon as it is a healthy
/// member: the members join one by one, and the first tick may find it still on its
/// way. Otherwise a healthy leader vehicle keeps the lead (a failover is not undone when
/// the old leader comes back: that would reshuffle the slots twice). Otherwise: the
/// requested one if healthy; the first healthy member by id when none was requested;
/// failing that (failover) the healthy member nearest to the reference point (or to the
/// requested leader).
pub(super) fn resolve_leader(
    current: Option<&str>,
    reference: Option<Ned>,
    spec: &FormationSpec,
    members: &BTreeMap<String, Member>,
    requested_has_led: bool,
) -> (Option<String>, Option<LeaderChange>) {
    if spec.wants_virtual() {
        return (Some(VIRTUAL.to_string()), None);
    }
    let is_healthy = |id: &str| members.get(id).is_some_and(|m| m.silence < m.ride_through);
    let vehicle = current.filter(|l| *l != VIRTUAL);
    if let Some(requested) = spec.leader.as_deref()
        && !requested_has_led
        && vehicle.is_some_and(|l| l != requested)
        && is_healthy(requested)
    {
        let change = LeaderChange {
            from: current.map(str::to_string),
            to: requested.to_string(),
            reason: "requested leader joined the formation".to_string(),
        };
        return (Some(requested.to_string()), Some(change));
    }
    if let Some(l) = vehicle
        && is_healthy(l)
    {
        return (Some(l.to_string()), None);
    }
    let wanted = spec.leader.clone().filter(|l| is_healthy(l));
    let healthy_members = healthy(members);
    let (new, reason) = match (vehicle, wanted) {
        (None, Some(w)) => (Some(w), "requested leader".to_string()),
        (None, None) if spec.leader.is_none() => (
            healthy_members.keys().next().cloned(),
            "first member".to_string(),
        ),
        (previous, _) => {
            // Failover: the member nearest to where the leader was.
            let near = reference.or_else(|| {
                spec.leader
                    .as_ref()
                    .and_then(|l| members.get(l))
                    .map(|m| m.position)
            });
            let pick = match near {
                Some(p) => nearest(&healthy_members, p),
                None => healthy_members.keys().next().cloned(),
            };
            let why = match previous {
                Some(p) if members.contains_key(p) => format!(
                    "leader {p} silent for {} ms",
                    members[p].silence.as_millis()
                ),
                Some(p) => format!("leader {p} left the formation"),
                None => format!(
                    "requested leader {} is not in the formation",
                    spec.leader.as_deref().unwrap_or("?")
                ),
            };
            (pick, why)
        }
    };
    let change = new
        .as_ref()
        .filter(|n| current != Some(n.as_str()))
        .map(|n| LeaderChange {
            from: current.map(str::to_string),
            to: n.clone(),
            reason,
        });
    (new, change)
}

#[cfg(test)]
mod tests {
    use super::super::engine::FormationEngine;
    use super::super::engine::tests::{fence, member};
    use super::super::spec::tests::line;
    use super::*;

    fn members(list: &[(&str, f64)]) -> BTreeMap<String, Member> {
        list.iter()
            .map(|(id, east)| (id.to_string(), member(0.0, *east, -10.0)))
            .collect()
    }

    fn silence(members: &mut BTreeMap<String, Member>, id: &str) {
        members.get_mut(id).unwrap().silence = LEADER_SILENCE;
    }

    #[test]
    fn the_requested_leader_leads() {
        let m = members(&[("uav-1", 0.0), ("uav-2", 5.0)]);
        let (l, change) = resolve_leader(None, None, &line(), &m, false);
        assert_eq!(l.as_deref(), Some("uav-2"));
        let change = change.unwrap();
        assert_eq!((change.from, change.to.as_str()), (None, "uav-2"));
        assert_eq!(change.reason, "requested leader");
        // Once in force, no new change.
        assert_eq!(
            resolve_leader(Some("uav-2"), None, &line(), &m, true),
            (Some("uav-2".into()), None)
        );
    }

    #[test]
    fn without_a_request_the_first_healthy_member_leads() {
        let spec = FormationSpec {
            leader: None,
            ..line()
        };
        let mut m = members(&[("b", 0.0), ("a", 5.0), ("c", 9.0)]);
        let (l, change) = resolve_leader(None, None, &spec, &m, false);
        assert_eq!(l.as_deref(), Some("a"));
        assert_eq!(change.unwrap().reason, "first member");
        silence(&mut m, "a");
        assert_eq!(
            resolve_leader(None, None, &spec, &m, false).0.as_deref(),
            Some("b")
        );
    }

    #[test]
    fn the_virtual_leader_needs_no_member_and_no_event() {
        let spec = FormationSpec {
            leader: Some(VIRTUAL.into()),
            ..line()
        };
        let (l, change) = resolve_leader(Some("uav-2"), None, &spec, &BTreeMap::new(), false);
        assert_eq!((l.as_deref(), change), (Some(VIRTUAL), None));
    }

    #[test]
    fn a_silent_leader_hands_over_to_the_member_nearest_the_reference() {
        let mut m = members(&[("uav-1", -5.0), ("uav-2", 0.0), ("uav-3", 7.0)]);
        silence(&mut m, "uav-2");
        // Nearest to the reference point, not to the silent leader.
        let r = Some(Ned::new(0.0, 4.0, -10.0));
        let (l, change) = resolve_leader(Some("uav-2"), r, &line(), &m, true);
        assert_eq!(l.as_deref(), Some("uav-3"));
        let change = change.unwrap();
        assert_eq!(change.from.as_deref(), Some("uav-2"));
        assert_eq!(change.reason, "leader uav-2 silent for 1500 ms");
        // Just under the silence limit it keeps the lead.
        m.get_mut("uav-2").unwrap().silence = LEADER_SILENCE - Duration::from_millis(1);
        assert_eq!(
            resolve_leader(Some("uav-2"), r, &line(), &m, true)
                .0
                .as_deref(),
            Some("uav-2")
        );
    }

    #[test]
    fn a_leader_that_left_is_replaced_and_the_event_says_so() {
        let m = members(&[("uav-1", -5.0), ("uav-3", 7.0)]);
        let r = Some(Ned::new(0.0, -1.0, -10.0));
        let (l, change) = resolve_leader(Some("uav-2"), r, &line(), &m, true);
        assert_eq!(l.as_deref(), Some("uav-1"));
        assert_eq!(change.unwrap().reason, "leader uav-2 left the formation");
    }

    #[test]
    fn a_missing_requested_leader_falls_back() {
        // Silent from the start: the member nearest to it.
        let mut m = members(&[("uav-1", -5.0), ("uav-2", 0.0), ("uav-3", 3.0)]);
        silence(&mut m, "uav-2");
        let (l, change) = resolve_leader(None, None, &line(), &m, false);
        assert_eq!(l.as_deref(), Some("uav-3"));
        let change = change.unwrap();
        assert_eq!(
            change.reason,
            "requested leader uav-2 is not in the formation"
        );
        // Absent and nothing to be near: the first by id.
        m.remove("uav-2");
        assert_eq!(
            resolve_leader(None, None, &line(), &m, false).0.as_deref(),
            Some("uav-1")
        );
        // Nobody healthy: nobody leads, nothing to report.
        silence(&mut m, "uav-1");
        silence(&mut m, "uav-3");
        assert_eq!(resolve_leader(None, None, &line(), &m, false), (None, None));
    }

    #[test]
    fn a_requested_leader_that_joins_late_takes_the_lead_once() {
        let mut e = FormationEngine::default();
        e.set(line());
        let mut m = members(&[("uav-1", -5.0), ("uav-3", 12.0)]);
        // uav-2, the requested leader, is still on its way: someone leads meanwhile.
        e.tick(&m, 0.1, &fence());
        let first = e.take_leader_changes();
        assert_eq!(first.len(), 1, "{first:?}");
        assert_ne!(first[0].to, "uav-2");
        // It joins: it takes the lead it was given.
        m.insert("uav-2".to_string(), member(0.0, 0.0, -10.0));
        let slots = e.tick(&m, 0.1, &fence());
        let joined = e.take_leader_changes();
        assert_eq!(joined.len(), 1, "{joined:?}");
        assert_eq!(joined[0].to, "uav-2");
        assert_eq!(joined[0].from, Some(first[0].to.clone()));
        assert_eq!(joined[0].reason, "requested leader joined the formation");
        assert_eq!(slots["uav-2"].slot, 0);
        // Silent, it hands over; back, it does not take the lead again.
        silence(&mut m, "uav-2");
        e.tick(&m, 0.1, &fence());
        let over = e.take_leader_changes();
        assert_eq!(over.len(), 1, "{over:?}");
        assert_eq!(over[0].from.as_deref(), Some("uav-2"));
        m.get_mut("uav-2").unwrap().silence = Duration::ZERO;
        e.tick(&m, 0.1, &fence());
        assert!(e.take_leader_changes().is_empty());
        assert_eq!(e.leader(), Some(over[0].to.as_str()));
        // A new spec naming it again: it leads again.
        e.deactivate();
        e.set(line());
        e.tick(&m, 0.1, &fence());
        assert_eq!(e.leader(), Some("uav-2"));
    }

    #[test]
    fn leaving_the_virtual_leader_reports_it() {
        let m = members(&[("uav-1", -5.0), ("uav-2", 0.0)]);
        let (l, change) = resolve_leader(Some(VIRTUAL), None, &line(), &m, false);
        assert_eq!(l.as_deref(), Some("uav-2"));
        assert_eq!(change.unwrap().from.as_deref(), Some(VIRTUAL));
    }

    #[test]
    fn a_silent_leader_is_replaced_by_the_nearest_member() {
        let mut e = FormationEngine::default();
        e.set(line());
        let mut members = BTreeMap::new();
        members.insert("uav-1".to_string(), member(0.0, -5.0, -10.0));
        members.insert("uav-2".to_string(), member(0.0, 0.0, -10.0));
        members.insert("uav-3".to_string(), member(0.0, 12.0, -10.0));
        e.tick(&members, 0.1, &fence());
        assert_eq!(e.take_leader_changes()[0].to, "uav-2");
        members.get_mut("uav-2").unwrap().silence = Duration::from_secs(2);
        let slots = e.tick(&members, 0.1, &fence());
        let change = e.take_leader_changes();
        assert_eq!(change.len(), 1);
        assert_eq!(
            (change[0].from.as_deref(), change[0].to.as_str()),
            (Some("uav-2"), "uav-1")
        );
        assert!(change[0].reason.contains("silent"), "{change:?}");
        assert_eq!(slots["uav-1"].slot, 0);
        assert!(
            !slots.contains_key("uav-2"),
            "a silent member keeps no slot"
        );
        assert_eq!(slots.len(), 2);
        // The formation re-anchors on the new leader, not on the silent one's spot.
        assert!((slots["uav-1"].position - Ned::new(0.0, -5.0, -10.0)).norm() < 1e-9);
        assert!((slots["uav-3"].goal - Ned::new(0.0, 0.0, -10.0)).norm() < 1e-9);
    }
}
