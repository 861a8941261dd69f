//! The mission protocol, vehicle side (PX4 `mavlink_mission`), for the plans a swarm
//! ground station uploads: the geofence (`MAV_MISSION_TYPE_FENCE`) and the rally points
//! (`MAV_MISSION_TYPE_RALLY`). Flight plans (`MAV_MISSION_TYPE_MISSION`) are not
//! simulated: their list is empty and an upload is answered `MAV_MISSION_UNSUPPORTED`.
//!
//! As PX4: the vehicle asks for each item with `MISSION_REQUEST_INT`, asks again after
//! 250 ms of silence (`MAVLINK_MISSION_RETRY_TIMEOUT_DEFAULT`), gives up after 5 s
//! (`MAVLINK_MISSION_PROTOCOL_TIMEOUT_DEFAULT`) with `MAV_MISSION_OPERATION_CANCELLED`,
//! and keeps a plan only once it is complete and valid; a plan larger than PX4's storage
//! (64 fence items, 8 rally points: `DM_KEY_FENCE_POINTS_MAX`, `DM_KEY_SAFE_POINTS_MAX`)
//! is refused with `MAV_MISSION_NO_SPACE`, an item of the wrong kind or frame with
//! `MAV_MISSION_UNSUPPORTED` / `MAV_MISSION_UNSUPPORTED_FRAME`, a polygon whose vertex
//! count does not add up with `MAV_MISSION_INVALID_PARAM1`. Plans live in PX4's dataman
//! and survive a reboot; so do they here.
//!
//! A test fault ([`MissionStore::fault`], the stats socket's `mission_fault`) makes every
//! fence and rally upload end in the given error, as a vehicle that cannot store it.

use super::*;
use std::time::Duration;

/// Fence items PX4 stores (`DM_KEY_FENCE_POINTS_MAX`).
pub(crate) const FENCE_CAPACITY: usize = 64;
/// Rally points PX4 stores (`DM_KEY_SAFE_POINTS_MAX`).
pub(crate) const RALLY_CAPACITY: usize = 8;
/// Silence before an item is asked for again.
const RETRY: Duration = Duration::from_millis(250);
/// Silence before an upload is given up.
const GIVE_UP: Duration = Duration::from_secs(5);

/// An upload in progress.
#[derive(Debug, Clone)]
pub(crate) struct Upload {
    mission_type: MavMissionType,
    count: u16,
    items: Vec<MISSION_ITEM_INT_DATA>,
    from: (u8, u8),
    last_request: Instant,
    last_progress: Instant,
}

/// The plans a vehicle holds (kept across reboots, as PX4's dataman).
#[derive(Debug, Clone, Default)]
pub(crate) struct MissionStore {
    pub fence: Vec<MISSION_ITEM_INT_DATA>,
    pub rally: Vec<MISSION_ITEM_INT_DATA>,
    upload: Option<Upload>,
    /// Test fault: every fence and rally upload is answered with this error.
    pub fault: Option<MavMissionResult>,
    /// Plans accepted so far (`opaque_id` of the ACK).
    pub accepted: u32,
}

fn is_plan(t: MavMissionType) -> bool {
    matches!(
        t,
        MavMissionType::MAV_MISSION_TYPE_FENCE | MavMissionType::MAV_MISSION_TYPE_RALLY
    )
}

/// Why a complete plan is refused, if it is.
fn check_plan(t: MavMissionType, items: &[MISSION_ITEM_INT_DATA]) -> Option<MavMissionResult> {
    use MavCmd::*;
    let global = |f: MavFrame| {
        matches!(
            f,
            MavFrame::MAV_FRAME_GLOBAL
                | MavFrame::MAV_FRAME_GLOBAL_INT
                | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT
                | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
        )
    };
    let mut i = 0;
    while i < items.len() {
        let it = &items[i];
        if !global(it.frame) {
            return Some(MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME);
        }
        match (t, it.command) {
            (MavMissionType::MAV_MISSION_TYPE_RALLY, MAV_CMD_NAV_RALLY_POINT) => i += 1,
            (
                MavMissionType::MAV_MISSION_TYPE_FENCE,
                MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION | MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION,
            ) => {
                if !(it.param1.is_finite() && it.param1 > 0.0) {
                    return Some(MavMissionResult::MAV_MISSION_INVALID_PARAM1);
                }
                i += 1;
            }
            (
                MavMissionType::MAV_MISSION_TYPE_FENCE,
                MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
                | MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
            ) => {
                // `param1` vertices of the same command follow, each saying the same count.
                let n = it.param1 as usize;
                let ok = n >= 3
                    && i + n <= items.len()
                    && items[i..i + n]
                        .iter()
                        .all(|v| v.command == it.command && v.param1 == it.param1);
                if !ok {
                    return Some(MavMissionResult::MAV_MISSION_INVALID_PARAM1);
                }
                i += n;
            }
            _ => return Some(MavMissionResult::MAV_MISSION_UNSUPPORTED),
        }
    }
    None
}

impl Vehicle {
    fn mission_ack(
        &self,
        to: (u8, u8),
        mission_type: MavMissionType,
        result: MavMissionResult,
        out: &mut Outbox,
    ) {
        out.push(&MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            target_system: to.0,
            target_component: to.1,
            mavtype: result,
            mission_type,
            opaque_id: self.missions.accepted,
        }));
    }

    fn mission_request(&mut self, now: Instant, out: &mut Outbox) {
        let Some(u) = self.missions.upload.as_mut() else {
            return;
        };
        u.last_request = now;
        out.push(&MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq: u.items.len() as u16,
            target_system: u.from.0,
            target_component: u.from.1,
            mission_type: u.mission_type,
        }));
    }

    /// `MISSION_COUNT`: an upload starts (or a plan is cleared with 0).
    pub(super) fn on_mission_count(
        &mut self,
        now: Instant,
        from: (u8, u8),
        c: &MISSION_COUNT_DATA,
        out: &mut Outbox,
    ) {
        let t = c.mission_type;
        if !is_plan(t) {
            self.mission_ack(from, t, MavMissionResult::MAV_MISSION_UNSUPPORTED, out);
            return;
        }
        let capacity = if t == MavMissionType::MAV_MISSION_TYPE_FENCE {
            FENCE_CAPACITY
        } else {
            RALLY_CAPACITY
        };
        if let Some(fault) = self.missions.fault {
            self.missions.upload = None;
            self.mission_ack(from, t, fault, out);
            return;
        }
        if usize::from(c.count) > capacity {
            self.missions.upload = None;
            self.statustext(
                now,
                MavSeverity::MAV_SEVERITY_CRITICAL,
                "Plan is too large!",
                out,
            );
            self.mission_ack(from, t, MavMissionResult::MAV_MISSION_NO_SPACE, out);
            return;
        }
        if c.count == 0 {
            self.missions.upload = None;
            self.store_plan(t, vec![]);
            self.mission_ack(from, t, MavMissionResult::MAV_MISSION_ACCEPTED, out);
            return;
        }
        self.missions.upload = Some(Upload {
            mission_type: t,
            count: c.count,
            items: vec![],
            from,
            last_request: now,
            last_progress: now,
        });
        self.mission_request(now, out);
    }

    /// `MISSION_ITEM_INT` of the upload in progress.
    pub(super) fn on_mission_item(
        &mut self,
        now: Instant,
        from: (u8, u8),
        item: &MISSION_ITEM_INT_DATA,
        out: &mut Outbox,
    ) {
        let Some(u) = self.missions.upload.as_mut() else {
            return;
        };
        if item.mission_type != u.mission_type || from != u.from {
            return;
        }
        let expected = u.items.len() as u16;
        if item.seq + 1 == expected {
            return; // a resend of the item before: the request for this one stands
        }
        if item.seq != expected {
            let (to, t) = (u.from, u.mission_type);
            self.missions.upload = None;
            self.mission_ack(to, t, MavMissionResult::MAV_MISSION_INVALID_SEQUENCE, out);
            return;
        }
        u.items.push(item.clone());
        u.last_progress = now;
        if u.items.len() < usize::from(u.count) {
            self.mission_request(now, out);
            return;
        }
        let u = self.missions.upload.take().expect("in progress");
        match check_plan(u.mission_type, &u.items) {
            Some(err) => self.mission_ack(u.from, u.mission_type, err, out),
            None => {
                self.store_plan(u.mission_type, u.items);
                self.mission_ack(
                    u.from,
                    u.mission_type,
                    MavMissionResult::MAV_MISSION_ACCEPTED,
                    out,
                );
            }
        }
    }

    fn store_plan(&mut self, t: MavMissionType, items: Vec<MISSION_ITEM_INT_DATA>) {
        self.missions.accepted += 1;
        if t == MavMissionType::MAV_MISSION_TYPE_FENCE {
            self.missions.fence = items;
            self.load_fence();
        } else {
            self.missions.rally = items;
        }
    }

    fn plan(&self, t: MavMissionType) -> Option<&[MISSION_ITEM_INT_DATA]> {
        match t {
            MavMissionType::MAV_MISSION_TYPE_FENCE => Some(&self.missions.fence),
            MavMissionType::MAV_MISSION_TYPE_RALLY => Some(&self.missions.rally),
            _ => None,
        }
    }

    /// `MISSION_REQUEST_LIST`: a download starts with the count.
    pub(super) fn on_mission_request_list(
        &mut self,
        from: (u8, u8),
        mission_type: MavMissionType,
        out: &mut Outbox,
    ) {
        let count = self.plan(mission_type).map_or(0, <[_]>::len);
        out.push(&MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: count as u16,
            target_system: from.0,
            target_component: from.1,
            mission_type,
            opaque_id: self.missions.accepted,
        }));
    }

    /// `MISSION_REQUEST_INT` of a download: the item.
    pub(super) fn on_mission_request(
        &mut self,
        from: (u8, u8),
        mission_type: MavMissionType,
        seq: u16,
        out: &mut Outbox,
    ) {
        let item = self
            .plan(mission_type)
            .and_then(|p| p.get(usize::from(seq)))
            .cloned();
        match item {
            Some(mut it) => {
                it.seq = seq;
                it.target_system = from.0;
                it.target_component = from.1;
                it.mission_type = mission_type;
                out.push(&MavMessage::MISSION_ITEM_INT(it));
            }
            None => self.mission_ack(
                from,
                mission_type,
                MavMissionResult::MAV_MISSION_INVALID_SEQUENCE,
                out,
            ),
        }
    }

    /// `MISSION_CLEAR_ALL`.
    pub(super) fn on_mission_clear(
        &mut self,
        from: (u8, u8),
        mission_type: MavMissionType,
        out: &mut Outbox,
    ) {
        let types: &[MavMissionType] = match mission_type {
            MavMissionType::MAV_MISSION_TYPE_ALL => &[
                MavMissionType::MAV_MISSION_TYPE_FENCE,
                MavMissionType::MAV_MISSION_TYPE_RALLY,
            ],
            t if is_plan(t) => &[t],
            _ => &[],
        };
        for t in types {
            self.store_plan(*t, vec![]);
        }
        self.mission_ack(
            from,
            mission_type,
            MavMissionResult::MAV_MISSION_ACCEPTED,
            out,
        );
    }

    /// Every step: ask again for an item not received, give up a stalled upload.
    pub(super) fn mission_timers(&mut self, now: Instant, out: &mut Outbox) {
        let Some(u) = self.missions.upload.as_ref() else {
            return;
        };
        if now.saturating_duration_since(u.last_progress) >= GIVE_UP {
            let (to, t) = (u.from, u.mission_type);
            self.missions.upload = None;
            self.mission_ack(
                to,
                t,
                MavMissionResult::MAV_MISSION_OPERATION_CANCELLED,
                out,
            );
        } else if now.saturating_duration_since(u.last_request) >= RETRY {
            self.mission_request(now, out);
        }
    }
}
