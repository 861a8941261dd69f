//! Commands fanned out to vehicles without waiting in the actor: the coordinator sends a
//! [`ToVehicle::Command`] to every target at once and answers the API when every target
//! has acknowledged (accepted, or refused naming its state) or when
//! [`VEHICLE_ACK_TIMEOUT`] has passed, whichever comes first. One stuck vehicle costs
//! the command that timeout and never stalls the formation tick.
//!
//! [`CommandMsg`] is what the coordinator is told about commands; payload requests ride
//! the same fan-out but are told through [`super::payloads`].

use super::CoordinatorState;
use super::messages::{CoordinatorMsg, PayloadMsg};
use crate::protocol::{Command, PayloadCommandError, ToVehicle};
use ractor::{ActorRef, RpcReplyPort};
use serde::Serialize;
use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;

/// How long a vehicle has to acknowledge a command before it counts as refused.
pub const VEHICLE_ACK_TIMEOUT: Duration = Duration::from_secs(2);
/// How long a payload has to answer a command.
pub const PAYLOAD_TIMEOUT: Duration = Duration::from_secs(10);

/// The outcome of a command accepted for processing (HTTP 202).
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct CommandOutcome {
    /// Id of the command; results arrive on the stream as `command_result` events.
    pub command_id: u64,
    /// Vehicles that accepted it.
    pub accepted: Vec<String>,
    /// Vehicles that refused it, with the reason (naming their state).
    pub refused: Vec<Refused>,
}

/// A vehicle's refusal.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct Refused {
    /// Vehicle id.
    pub id: String,
    /// Why.
    pub reason: String,
}

/// Who waits for a command's outcome.
pub enum CommandReply {
    /// `POST /api/v1/swarm/commands`.
    Swarm(RpcReplyPort<CommandOutcome>),
    /// `POST /api/v1/vehicles/{id}/commands`: the refusal as the error.
    Vehicle(RpcReplyPort<Result<CommandOutcome, Option<String>>>),
}

impl CommandReply {
    fn send(self, mut outcome: CommandOutcome) {
        outcome.accepted.sort();
        outcome.refused.sort_by(|a, b| a.id.cmp(&b.id));
        match self {
            CommandReply::Swarm(r) => {
                let _ = r.send(outcome);
            }
            CommandReply::Vehicle(r) => {
                let result = match outcome.refused.first() {
                    Some(refused) => Err(Some(refused.reason.clone())),
                    None => Ok(outcome),
                };
                let _ = r.send(result);
            }
        }
    }
}

/// A command waiting for acknowledgements.
pub struct PendingCommand {
    outcome: CommandOutcome,
    waiting: BTreeSet<String>,
    reply: CommandReply,
}

/// Commands and payload requests in flight.
#[derive(Default)]
pub struct InFlight {
    commands: BTreeMap<u64, PendingCommand>,
    payloads: BTreeMap<u64, RpcReplyPort<Result<serde_json::Value, PayloadCommandError>>>,
    next_command_id: u64,
    next_request_id: u64,
}

/// Commands for the vehicles (inside [`CoordinatorMsg::Command`]).
pub enum CommandMsg {
    /// A command for every vehicle.
    SwarmCommand(Command, RpcReplyPort<CommandOutcome>),
    /// A command for one vehicle; `Err(None)` when the vehicle does not exist.
    VehicleCommand(
        String,
        Command,
        RpcReplyPort<Result<CommandOutcome, Option<String>>>,
    ),
    /// A command's vehicles had their time to answer: the silent ones are refused.
    CommandTimeout(u64),
}

impl CoordinatorState {
    /// Handles a [`CommandMsg`].
    pub(super) fn handle_command(&mut self, myself: &ActorRef<CoordinatorMsg>, msg: CommandMsg) {
        match msg {
            CommandMsg::SwarmCommand(cmd, reply) => {
                if matches!(cmd, Command::Land | Command::Rtl) && self.formation.is_active() {
                    self.formation.deactivate();
                    self.formation_changed();
                }
                let targets = self.vehicles.keys().cloned().collect();
                self.run_command(myself, targets, cmd, CommandReply::Swarm(reply));
            }
            CommandMsg::VehicleCommand(id, cmd, reply) => {
                if !self.vehicles.contains_key(&id) {
                    let _ = reply.send(Err(None));
                } else if cmd == Command::ClearHazard {
                    // The formation's, not the vehicle's: done here, nothing to wait for.
                    let _ = reply.send(self.clear_hazard(&id).map(|()| CommandOutcome {
                        command_id: 0,
                        accepted: vec![id],
                        refused: vec![],
                    }));
                } else {
                    self.run_command(myself, vec![id], cmd, CommandReply::Vehicle(reply));
                }
            }
            CommandMsg::CommandTimeout(command_id) => self.on_command_timeout(command_id),
        }
    }

    /// Sends `cmd` to every vehicle of `targets` that exists and answers `reply` once
    /// all have acknowledged or the timeout passed.
    pub(super) fn run_command(
        &mut self,
        myself: &ActorRef<CoordinatorMsg>,
        targets: Vec<String>,
        cmd: Command,
        reply: CommandReply,
    ) {
        self.in_flight.next_command_id += 1;
        let command_id = self.in_flight.next_command_id;
        let mut pending = PendingCommand {
            outcome: CommandOutcome {
                command_id,
                accepted: vec![],
                refused: vec![],
            },
            waiting: BTreeSet::new(),
            reply,
        };
        for id in targets {
            if !self.vehicles.contains_key(&id) {
                continue;
            }
            self.released_from_formation(&id, &cmd);
            let Some(v) = self.vehicles.get(&id) else {
                continue;
            };
            let sent = if v.failed {
                Err(format!(
                    "{} refused: vehicle {id} has failed (its actor kept failing and it was commanded to {:?})",
                    cmd.name(),
                    self.context.config.supervision.vehicle_escalation
                ))
            } else {
                v.send(ToVehicle::Command {
                    command_id,
                    command: cmd.clone(),
                })
                .map_err(|e| format!("{} refused: vehicle {id}: {e}", cmd.name()))
            };
            match sent {
                Ok(()) => {
                    pending.waiting.insert(id);
                }
                Err(reason) => pending.outcome.refused.push(Refused { id, reason }),
            }
        }
        if pending.waiting.is_empty() {
            pending.reply.send(pending.outcome);
            return;
        }
        self.in_flight.commands.insert(command_id, pending);
        myself.send_after(VEHICLE_ACK_TIMEOUT, move || {
            CommandMsg::CommandTimeout(command_id).into()
        });
    }

    /// Sends one of the coordinator's own commands (formation joins and leaves): no
    /// command id, no outcome event; a refusal is only logged.
    pub(super) fn internal_command(&self, id: &str, cmd: Command) {
        if let Some(v) = self.vehicles.get(id).filter(|v| !v.failed)
            && let Err(e) = v.send(ToVehicle::Command {
                command_id: 0,
                command: cmd,
            })
        {
            tracing::debug!("{id}: {e}");
        }
    }

    /// A vehicle acknowledged command `command_id`.
    pub(super) fn on_ack(&mut self, id: String, command_id: u64, result: Result<(), String>) {
        if command_id == 0 {
            if let Err(e) = result {
                tracing::debug!("{id}: {e}");
            }
            return;
        }
        let Some(p) = self.in_flight.commands.get_mut(&command_id) else {
            return; // answered after the timeout: it was reported as silent
        };
        if !p.waiting.remove(&id) {
            return;
        }
        match result {
            Ok(()) => p.outcome.accepted.push(id),
            Err(reason) => p.outcome.refused.push(Refused { id, reason }),
        }
        if p.waiting.is_empty() {
            let p = self
                .in_flight
                .commands
                .remove(&command_id)
                .expect("present");
            p.reply.send(p.outcome);
        }
    }

    /// The time to acknowledge command `command_id` has passed.
    pub(super) fn on_command_timeout(&mut self, command_id: u64) {
        let Some(mut p) = self.in_flight.commands.remove(&command_id) else {
            return;
        };
        for id in std::mem::take(&mut p.waiting) {
            p.outcome.refused.push(Refused {
                reason: format!(
                    "vehicle {id} did not answer within {} s",
                    VEHICLE_ACK_TIMEOUT.as_secs_f64()
                ),
                id,
            });
        }
        p.reply.send(p.outcome);
    }

    /// Sends a payload request (command, attach, detach: `make` builds it from its
    /// request id) to vehicle `id`; the answer comes back as a
    /// [`crate::protocol::FromVehicle::PayloadResult`], or the request times out after
    /// [`PAYLOAD_TIMEOUT`].
    pub(super) fn payload_request(
        &mut self,
        myself: &ActorRef<CoordinatorMsg>,
        id: String,
        make: impl FnOnce(u64) -> ToVehicle,
        reply: RpcReplyPort<Result<serde_json::Value, PayloadCommandError>>,
    ) {
        let Some(v) = self.vehicles.get(&id) else {
            let _ = reply.send(Err(PayloadCommandError::NotFound(format!(
                "no vehicle `{id}`"
            ))));
            return;
        };
        self.in_flight.next_request_id += 1;
        let request_id = self.in_flight.next_request_id;
        let sent = v.send(make(request_id));
        if let Err(e) = sent {
            let _ = reply.send(Err(PayloadCommandError::Unavailable(format!(
                "vehicle {id} is not running: {e}"
            ))));
            return;
        }
        self.in_flight.payloads.insert(request_id, reply);
        myself.send_after(PAYLOAD_TIMEOUT, move || {
            PayloadMsg::PayloadTimeout(request_id).into()
        });
    }

    /// A payload command was answered (`result`) or timed out (`None`).
    pub(super) fn on_payload_result(
        &mut self,
        request_id: u64,
        result: Option<Result<serde_json::Value, PayloadCommandError>>,
    ) {
        if let Some(reply) = self.in_flight.payloads.remove(&request_id) {
            let _ = reply.send(result.unwrap_or_else(|| {
                Err(PayloadCommandError::Unavailable(
                    "the vehicle did not answer".into(),
                ))
            }));
        }
    }
}
