//! The parameter protocol, client side: `PARAM_REQUEST_READ` / `PARAM_SET` answered by
//! `PARAM_VALUE`.
//!
//! One request per parameter name is in flight (others wait). A set given as a number
//! first reads the parameter to learn its type, then writes it in that type (PX4's
//! bytewise encoding for integers, see [`skein_mavlink::param`]), and completes when a
//! `PARAM_VALUE` shows the new value. PX4 answers a `PARAM_SET` twice, and a stale or
//! duplicate `PARAM_VALUE` may arrive while a later request is pending: a value that does
//! not match is ignored, not taken as a refusal; only after every resend does a mismatch
//! become [`LinkError::Rejected`].

use crate::command::LinkError;
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::{PARAM_REQUEST_READ_DATA, PARAM_SET_DATA};
use skein_mavlink::param::{ParamValue, param_id};
use std::collections::{HashMap, VecDeque};

/// Where a parameter request's outcome goes.
pub type ParamReply = ractor::RpcReplyPort<Result<ParamValue, LinkError>>;

/// What to do with a parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ParamOp {
    /// Read it.
    Get,
    /// Write this number in the parameter's own type.
    Set(f64),
}

struct Pending {
    op: ParamOp,
    reply: Option<ParamReply>,
    /// The typed value being written, once the type is known.
    writing: Option<ParamValue>,
    attempts: u32,
    generation: u64,
    last_seen: Option<ParamValue>,
}

/// Something to send, and when to check back.
#[derive(Debug, Clone, PartialEq)]
pub struct Transmit {
    /// The message.
    pub msg: MavMessage,
    /// Parameter name (deadline key).
    pub name: String,
    /// Generation of the request (deadline check).
    pub generation: u64,
}

/// Client-side parameter state of one vehicle.
#[derive(Default)]
pub struct ParamClient {
    pending: HashMap<String, Pending>,
    queued: HashMap<String, VecDeque<(ParamOp, Option<ParamReply>)>>,
    cache: HashMap<String, ParamValue>,
    generation: u64,
}

/// Transmissions of one stage (read or write) before the request fails.
pub const PARAM_ATTEMPTS: u32 = 5;

impl ParamClient {
    /// Values seen so far, by name.
    pub fn cache(&self) -> &HashMap<String, ParamValue> {
        &self.cache
    }

    fn request(&self, name: &str, target: (u8, u8), writing: Option<ParamValue>) -> MavMessage {
        match writing {
            None => MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
                param_index: -1,
                target_system: target.0,
                target_component: target.1,
                param_id: param_id(name),
            }),
            Some(v) => {
                let (raw, ty) = v.to_wire();
                MavMessage::PARAM_SET(PARAM_SET_DATA {
                    param_value: raw,
                    target_system: target.0,
                    target_component: target.1,
                    param_id: param_id(name),
                    param_type: ty,
                })
            }
        }
    }

    /// Starts (or queues) a request; returns what to send now.
    pub fn start(
        &mut self,
        name: &str,
        op: ParamOp,
        reply: Option<ParamReply>,
        target: (u8, u8),
    ) -> Option<Transmit> {
        if self.pending.contains_key(name) {
            self.queued
                .entry(name.to_string())
                .or_default()
                .push_back((op, reply));
            return None;
        }
        self.generation += 1;
        let writing = match op {
            ParamOp::Set(v) => self.cache.get(name).map(|known| known.with_f64(v)),
            ParamOp::Get => None,
        };
        self.pending.insert(
            name.to_string(),
            Pending {
                op,
                reply,
                writing,
                attempts: 1,
                generation: self.generation,
                last_seen: None,
            },
        );
        Some(Transmit {
            msg: self.request(name, target, writing),
            name: name.to_string(),
            generation: self.generation,
        })
    }

    fn finish(
        &mut self,
        name: &str,
        result: Result<ParamValue, LinkError>,
        target: (u8, u8),
    ) -> Option<Transmit> {
        if let Some(p) = self.pending.remove(name)
            && let Some(r) = p.reply
        {
            let _ = r.send(result);
        }
        let next = self.queued.get_mut(name).and_then(VecDeque::pop_front);
        next.and_then(|(op, reply)| self.start(name, op, reply, target))
    }

    /// A `PARAM_VALUE` arrived; returns what to send next, if anything.
    pub fn on_value(
        &mut self,
        name: &str,
        value: ParamValue,
        target: (u8, u8),
    ) -> Option<Transmit> {
        self.cache.insert(name.to_string(), value);
        let p = self.pending.get_mut(name)?;
        p.last_seen = Some(value);
        match (p.op, p.writing) {
            (ParamOp::Get, _) => self.finish(name, Ok(value), target),
            (ParamOp::Set(v), None) => {
                // The read told us the type: now write.
                let typed = value.with_f64(v);
                p.writing = Some(typed);
                p.attempts = 1;
                self.generation += 1;
                p.generation = self.generation;
                let generation = p.generation;
                Some(Transmit {
                    msg: self.request(name, target, Some(typed)),
                    name: name.to_string(),
                    generation,
                })
            }
            (ParamOp::Set(_), Some(w)) if w == value => self.finish(name, Ok(value), target),
            (ParamOp::Set(_), Some(_)) => None, // stale or duplicate: keep waiting
        }
    }

    /// The deadline of a transmission passed: resend, or fail the request.
    pub fn on_deadline(
        &mut self,
        name: &str,
        generation: u64,
        target: (u8, u8),
    ) -> Option<Transmit> {
        let p = self.pending.get_mut(name)?;
        if p.generation != generation {
            return None;
        }
        if p.attempts >= PARAM_ATTEMPTS {
            let err = match (p.writing, p.last_seen) {
                (Some(w), Some(seen)) => LinkError::Rejected {
                    command: format!("param_set {name}"),
                    result: format!("the vehicle keeps reporting {seen:?}, not {w:?}"),
                    statustexts: Vec::new(),
                },
                _ => LinkError::Timeout {
                    command: format!(
                        "{} {name}",
                        if p.writing.is_some() {
                            "param_set"
                        } else {
                            "param_get"
                        }
                    ),
                    attempts: p.attempts,
                },
            };
            return self.finish(name, Err(err), target);
        }
        p.attempts += 1;
        let writing = p.writing;
        Some(Transmit {
            msg: self.request(name, target, writing),
            name: name.to_string(),
            generation,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: (u8, u8) = (1, 1);

    fn kind(t: &Option<Transmit>) -> &'static str {
        match t.as_ref().map(|t| &t.msg) {
            Some(MavMessage::PARAM_REQUEST_READ(_)) => "read",
            Some(MavMessage::PARAM_SET(_)) => "set",
            None => "none",
            _ => "other",
        }
    }

    #[test]
    fn set_by_number_reads_the_type_then_writes_bytewise() {
        let mut c = ParamClient::default();
        let t = c.start("COM_OBL_RC_ACT", ParamOp::Set(5.0), None, T);
        assert_eq!(kind(&t), "read");
        let t = c.on_value("COM_OBL_RC_ACT", ParamValue::Int32(0), T);
        assert_eq!(kind(&t), "set");
        let Some(MavMessage::PARAM_SET(s)) = t.map(|t| t.msg) else {
            panic!()
        };
        assert_eq!(s.param_value.to_bits(), 5, "bytewise");
        // PX4's two answers: the first completes, the duplicate is harmless.
        assert_eq!(
            kind(&c.on_value("COM_OBL_RC_ACT", ParamValue::Int32(5), T)),
            "none"
        );
        assert_eq!(
            kind(&c.on_value("COM_OBL_RC_ACT", ParamValue::Int32(5), T)),
            "none"
        );
        assert!(c.pending.is_empty());
        assert_eq!(c.cache()["COM_OBL_RC_ACT"], ParamValue::Int32(5));
    }

    #[test]
    fn a_stale_value_does_not_fail_a_set_and_retries_end_in_rejection() {
        let mut c = ParamClient::default();
        c.cache.insert("X".into(), ParamValue::Real32(1.0));
        let t = c.start("X", ParamOp::Set(2.0), None, T).unwrap();
        assert_eq!(kind(&c.on_value("X", ParamValue::Real32(1.0), T)), "none");
        assert!(c.pending.contains_key("X"), "stale value ignored");
        let mut generation = t.generation;
        for _ in 1..PARAM_ATTEMPTS {
            let t = c.on_deadline("X", generation, T).unwrap();
            generation = t.generation;
        }
        assert!(c.on_deadline("X", generation, T).is_none());
        assert!(c.pending.is_empty(), "gave up");
    }

    #[test]
    fn requests_for_one_name_are_serialised() {
        let mut c = ParamClient::default();
        assert_eq!(kind(&c.start("A", ParamOp::Get, None, T)), "read");
        assert_eq!(kind(&c.start("A", ParamOp::Get, None, T)), "none");
        assert_eq!(kind(&c.start("B", ParamOp::Get, None, T)), "read");
        // A's answer completes the first and starts the queued one.
        assert_eq!(kind(&c.on_value("A", ParamValue::Int32(1), T)), "read");
    }
}
