//! The MAVLink mission protocol, client side (mavlink.io, "Mission Protocol"), for any
//! `mission_type` (skein uses `MAV_MISSION_TYPE_FENCE` and `MAV_MISSION_TYPE_RALLY`):
//!
//! - upload: `MISSION_COUNT` → the vehicle asks for each item with `MISSION_REQUEST_INT`
//!   (or the older `MISSION_REQUEST`) → `MISSION_ITEM_INT` → the vehicle's `MISSION_ACK`
//!   ends it (`MAV_MISSION_ACCEPTED`, or the error such as `MAV_MISSION_NO_SPACE`). A count
//!   of 0 clears the plan.
//! - download: `MISSION_REQUEST_LIST` → `MISSION_COUNT` → `MISSION_REQUEST_INT` for each
//!   item → `MISSION_ITEM_INT`; our `MISSION_ACK` ends it.
//!
//! Time-outs and retries as the protocol says: whatever we sent last is sent again when
//! nothing answered within [`MISSION_TIMEOUT`], up to [`MISSION_ATTEMPTS`] transmissions,
//! then the operation fails with [`LinkError::Timeout`]; an error `MISSION_ACK` fails it
//! with [`LinkError::Rejected`] naming the `MAV_MISSION_RESULT`. One operation per
//! mission type is in flight; others wait their turn. Answers addressed to another
//! ground station (a QGroundControl behind the forwarder) are not ours and are ignored.
//!
//! The state machine has no I/O: the `Px4Link` actor sends what it returns and calls
//! back with what arrives and when a deadline passes.

use crate::command::LinkError;
use ractor::RpcReplyPort;
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::{
    MISSION_ACK_DATA, MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA, MISSION_REQUEST_INT_DATA,
    MISSION_REQUEST_LIST_DATA, MavCmd, MavFrame, MavMissionResult, MavMissionType,
};
use std::collections::{HashMap, VecDeque};
use std::time::Duration;

/// Wait for the vehicle's next message before sending ours again (the protocol's
/// default, as QGroundControl uses it).
pub const MISSION_TIMEOUT: Duration = Duration::from_millis(1500);
/// Transmissions of one message before the operation fails.
pub const MISSION_ATTEMPTS: u32 = 5;

/// One mission item as `MISSION_ITEM_INT` carries it (positions in degE7 for global
/// frames).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MissionItem {
    /// The command (`MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION` …).
    pub command: MavCmd,
    /// Coordinate frame of `x`, `y`, `z`.
    pub frame: MavFrame,
    /// `param1` to `param4`.
    pub params: [f32; 4],
    /// Latitude, degE7 (global frames).
    pub x: i32,
    /// Longitude, degE7 (global frames).
    pub y: i32,
    /// Altitude, metres in `frame`.
    pub z: f32,
}

impl MissionItem {
    /// The `MISSION_ITEM_INT` for item `seq` of a plan of `mission_type`.
    pub fn to_message(
        &self,
        seq: u16,
        target: (u8, u8),
        mission_type: MavMissionType,
    ) -> MavMessage {
        MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
            param1: self.params[0],
            param2: self.params[1],
            param3: self.params[2],
            param4: self.params[3],
            x: self.x,
            y: self.y,
            z: self.z,
            seq,
            command: self.command,
            target_system: target.0,
            target_component: target.1,
            frame: self.frame,
            current: 0,
            autocontinue: 1,
            mission_type,
        })
    }

    /// The item a `MISSION_ITEM_INT` carries.
    pub fn from_message(m: &MISSION_ITEM_INT_DATA) -> Self {
        MissionItem {
            command: m.command,
            frame: m.frame,
            params: [m.param1, m.param2, m.param3, m.param4],
            x: m.x,
            y: m.y,
            z: m.z,
        }
    }
}

/// The name of a `MAV_MISSION_TYPE` for messages (`"fence"`).
pub fn type_name(t: MavMissionType) -> &'static str {
    match t {
        MavMissionType::MAV_MISSION_TYPE_MISSION => "mission",
        MavMissionType::MAV_MISSION_TYPE_FENCE => "fence",
        MavMissionType::MAV_MISSION_TYPE_RALLY => "rally",
        _ => "plan",
    }
}

/// The `MAV_MISSION_RESULT` name without its prefix's noise (`"MAV_MISSION_NO_SPACE"`).
pub fn result_name(r: MavMissionResult) -> String {
    format!("{r:?}")
}

/// Where an upload's outcome goes.
pub type UploadReply = RpcReplyPort<Result<(), LinkError>>;
/// Where a download's items go.
pub type DownloadReply = RpcReplyPort<Result<Vec<MissionItem>, LinkError>>;

/// An operation on one mission type.
pub enum MissionOp {
    /// Replace the vehicle's plan with these items (none: clear it).
    Upload(Vec<MissionItem>, Option<UploadReply>),
    /// Read the vehicle's plan.
    Download(Option<DownloadReply>),
}

struct Transfer {
    op: MissionOp,
    /// Download: the count the vehicle announced, and the items so far.
    count: Option<u16>,
    received: Vec<MissionItem>,
    /// What we sent last (resent on the deadline).
    last: MavMessage,
    attempts: u32,
    generation: u64,
}

/// Something to send and, if set, the deadline key to check back with
/// ([`MissionClient::on_deadline`] after [`MISSION_TIMEOUT`]).
#[derive(Debug, Clone, PartialEq)]
pub struct MissionTransmit {
    /// The message.
    pub msg: MavMessage,
    /// `(mission type, generation)` of the transmission awaiting an answer.
    pub deadline: Option<(MavMissionType, u64)>,
}

/// Client-side mission protocol state of one vehicle (see the module docs).
#[derive(Default)]
pub struct MissionClient {
    active: HashMap<u8, (MavMissionType, Transfer)>,
    queued: HashMap<u8, VecDeque<MissionOp>>,
    generation: u64,
}

fn key(t: MavMissionType) -> u8 {
    t as u8
}

impl MissionClient {
    /// Starts (or queues behind the one in flight) an operation on `mission_type`;
    /// returns what to send now.
    pub fn start(
        &mut self,
        mission_type: MavMissionType,
        op: MissionOp,
        target: (u8, u8),
    ) -> Vec<MissionTransmit> {
        if self.active.contains_key(&key(mission_type)) {
            self.queued
                .entry(key(mission_type))
                .or_default()
                .push_back(op);
            return vec![];
        }
        let first = match &op {
            MissionOp::Upload(items, _) => MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                count: items.len() as u16,
                target_system: target.0,
                target_component: target.1,
                mission_type,
                opaque_id: 0,
            }),
            MissionOp::Download(_) => MavMessage::MISSION_REQUEST_LIST(MISSION_REQUEST_LIST_DATA {
                target_system: target.0,
                target_component: target.1,
                mission_type,
            }),
        };
        self.generation += 1;
        let transfer = Transfer {
            op,
            count: None,
            received: vec![],
            last: first.clone(),
            attempts: 1,
            generation: self.generation,
        };
        self.active
            .insert(key(mission_type), (mission_type, transfer));
        vec![MissionTransmit {
            msg: first,
            deadline: Some((mission_type, self.generation)),
        }]
    }

    /// True while an operation on `mission_type` is in flight.
    pub fn busy(&self, mission_type: MavMissionType) -> bool {
        self.active.contains_key(&key(mission_type))
    }

    /// Ends the operation on `mission_type` with `result` and starts the next queued one.
    fn finish(
        &mut self,
        mission_type: MavMissionType,
        result: Result<Vec<MissionItem>, LinkError>,
        target: (u8, u8),
    ) -> Vec<MissionTransmit> {
        if let Some((_, t)) = self.active.remove(&key(mission_type)) {
            match t.op {
                MissionOp::Upload(_, Some(reply)) => {
                    let _ = reply.send(result.map(|_| ()));
                }
                MissionOp::Download(Some(reply)) => {
                    let _ = reply.send(result);
                }
                _ => {}
            }
        }
        match self
            .queued
            .get_mut(&key(mission_type))
            .and_then(VecDeque::pop_front)
        {
            Some(op) => self.start(mission_type, op, target),
            None => vec![],
        }
    }

    /// Sends `msg` as the transfer's next step, awaiting an answer.
    fn step(&mut self, mission_type: MavMissionType, msg: MavMessage) -> Vec<MissionTransmit> {
        self.generation += 1;
        let generation = self.generation;
        let Some((_, t)) = self.active.get_mut(&key(mission_type)) else {
            return vec![];
        };
        t.last = msg.clone();
        t.attempts = 1;
        t.generation = generation;
        vec![MissionTransmit {
            msg,
            deadline: Some((mission_type, generation)),
        }]
    }

    /// A frame from the vehicle; `ours` is our (sysid, compid): answers addressed to
    /// someone else are ignored. Returns what to send next.
    // PX4 still sends the deprecated MISSION_REQUEST at times: it is answered all the same.
    #[allow(deprecated)]
    pub fn on_message(
        &mut self,
        msg: &MavMessage,
        ours: (u8, u8),
        target: (u8, u8),
    ) -> Vec<MissionTransmit> {
        let for_us = |s: u8, c: u8| (s == 0 || s == ours.0) && (c == 0 || c == ours.1);
        match msg {
            MavMessage::MISSION_REQUEST_INT(r) if for_us(r.target_system, r.target_component) => {
                self.on_request(r.mission_type, r.seq, target)
            }
            // PX4 may ask with the float request; it gets the int item all the same.
            MavMessage::MISSION_REQUEST(r) if for_us(r.target_system, r.target_component) => {
                self.on_request(r.mission_type, r.seq, target)
            }
            MavMessage::MISSION_ACK(a) if for_us(a.target_system, a.target_component) => {
                self.on_ack(a, target)
            }
            MavMessage::MISSION_COUNT(c) if for_us(c.target_system, c.target_component) => {
                self.on_count(c.mission_type, c.count, target)
            }
            MavMessage::MISSION_ITEM_INT(i) if for_us(i.target_system, i.target_component) => {
                self.on_item(i, target)
            }
            _ => vec![],
        }
    }

    fn on_request(
        &mut self,
        mission_type: MavMissionType,
        seq: u16,
        target: (u8, u8),
    ) -> Vec<MissionTransmit> {
        let Some((_, t)) = self.active.get(&key(mission_type)) else {
            return vec![];
        };
        let MissionOp::Upload(items, _) = &t.op else {
            return vec![];
        };
        match items.get(usize::from(seq)) {
            Some(item) => {
                let msg = item.to_message(seq, target, mission_type);
                self.step(mission_type, msg)
            }
            None => vec![], // a request beyond the count: the vehicle's error to report
        }
    }

    fn on_ack(&mut self, a: &MISSION_ACK_DATA, target: (u8, u8)) -> Vec<MissionTransmit> {
        let Some((_, t)) = self.active.get(&key(a.mission_type)) else {
            return vec![];
        };
        let what = match &t.op {
            MissionOp::Upload(..) => "upload",
            MissionOp::Download(..) => "download",
        };
        let result = if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED {
            match &t.op {
                MissionOp::Upload(..) => Ok(vec![]),
                // An ACCEPTED ack in the middle of a download is not the end of it.
                MissionOp::Download(..) => return vec![],
            }
        } else {
            Err(LinkError::Rejected {
                command: format!("{} {what}", type_name(a.mission_type)),
                result: result_name(a.mavtype),
                statustexts: Vec::new(),
            })
        };
        self.finish(a.mission_type, result, target)
    }

    fn on_count(
        &mut self,
        mission_type: MavMissionType,
        count: u16,
        target: (u8, u8),
    ) -> Vec<MissionTransmit> {
        let Some((_, t)) = self.active.get_mut(&key(mission_type)) else {
            return vec![];
        };
        if !matches!(t.op, MissionOp::Download(_)) || t.count.is_some() {
            return vec![]; // a repeated count: the request for the next item is pending
        }
        t.count = Some(count);
        if count == 0 {
            let mut out = vec![ack(target, mission_type)];
            out.extend(self.finish(mission_type, Ok(vec![]), target));
            return out;
        }
        self.step(mission_type, request(0, target, mission_type))
    }

    fn on_item(&mut self, i: &MISSION_ITEM_INT_DATA, target: (u8, u8)) -> Vec<MissionTransmit> {
        let mission_type = i.mission_type;
        let Some((_, t)) = self.active.get_mut(&key(mission_type)) else {
            return vec![];
        };
        let (MissionOp::Download(_), Some(count)) = (&t.op, t.count) else {
            return vec![];
        };
        if usize::from(i.seq) != t.received.len() {
            return vec![]; // a duplicate or an item out of turn: the request stands
        }
        t.received.push(MissionItem::from_message(i));
        if t.received.len() < usize::from(count) {
            let next = t.received.len() as u16;
            return self.step(mission_type, request(next, target, mission_type));
        }
        let items = std::mem::take(&mut t.received);
        let mut out = vec![ack(target, mission_type)];
        out.extend(self.finish(mission_type, Ok(items), target));
        out
    }

    /// A deadline passed: resend what was sent last, or fail the operation after
    /// [`MISSION_ATTEMPTS`] transmissions.
    pub fn on_deadline(
        &mut self,
        mission_type: MavMissionType,
        generation: u64,
        target: (u8, u8),
    ) -> Vec<MissionTransmit> {
        let Some((_, t)) = self.active.get_mut(&key(mission_type)) else {
            return vec![];
        };
        if t.generation != generation {
            return vec![];
        }
        if t.attempts >= MISSION_ATTEMPTS {
            let what = match &t.op {
                MissionOp::Upload(..) => "upload",
                MissionOp::Download(..) => "download",
            };
            let err = LinkError::Timeout {
                command: format!("{} {what}", type_name(mission_type)),
                attempts: t.attempts,
            };
            return self.finish(mission_type, Err(err), target);
        }
        t.attempts += 1;
        vec![MissionTransmit {
            msg: t.last.clone(),
            deadline: Some((mission_type, generation)),
        }]
    }
}

fn request(seq: u16, target: (u8, u8), mission_type: MavMissionType) -> MavMessage {
    MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
        seq,
        target_system: target.0,
        target_component: target.1,
        mission_type,
    })
}

fn ack(target: (u8, u8), mission_type: MavMissionType) -> MissionTransmit {
    MissionTransmit {
        msg: MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            target_system: target.0,
            target_component: target.1,
            mavtype: MavMissionResult::MAV_MISSION_ACCEPTED,
            mission_type,
            opaque_id: 0,
        }),
        deadline: None,
    }
}

#[cfg(test)]
mod tests;
