//! The `Px4Link` actor: the adapter between one PX4 autopilot and skein.
//!
//! It receives the vehicle's frames from its [`Endpoint`](crate::endpoint::Endpoint)
//! route, folds them into [`Telemetry`](crate::telemetry::Telemetry), reports what the state machine needs as [`LinkEvent`]s, sends a 1 Hz
//! heartbeat, watches liveness (lost after [`LINK_TIMEOUT`] of silence), and runs the
//! command protocol: one command per id in flight, ACK matched by command id, resent with
//! `confirmation + 1` every [`ACK_TIMEOUT`] up to [`MAX_ATTEMPTS`] transmissions,
//! `IN_PROGRESS` waited out, mode changes confirmed from `HEARTBEAT.custom_mode`, a
//! refusal answered with what the vehicle said about it (`statustexts`).
//!
//! It reads the vehicle's component metadata and decodes PX4's events with it
//! (`metadata`, `events`): the health and arming check report, the events as messages.
//!
//! It also runs the mission protocol ([`crate::mission`]) and keeps the autopilot on
//! skein's geofence (`missions`, [`crate::fence_sync`]).
//!
//! Everything that must survive a restart of this actor (the route's socket, telemetry,
//! the setpoint stream, the fence status) lives in the shared [`VehicleLink`]; a
//! restarted actor picks it up and re-registers its route.

mod events;
mod fence_autopilot;
mod logs;
mod metadata;
mod missions;
mod route;
mod statustexts;
mod vehicle_link;

pub use logs::{LOG_TICK, LogDownloadReply, LogListReply};
pub use metadata::META_TICK;
pub use statustexts::REASON_GRACE;
pub use vehicle_link::VehicleLink;

use crate::command::{LinkCommand, LinkError, result_name};
use crate::fence::FencePlan;
use crate::mission::{DownloadReply, MissionClient, MissionItem, UploadReply};
use crate::param_client::{ParamClient, ParamOp, ParamReply, Transmit};
use crate::setup::interval_us;
use crate::statustext::{StatusText, StatusTextAssembler};
use crate::telemetry::Change;
use ractor::{Actor, ActorProcessingErr, ActorRef, RpcReplyPort};
use skein_mavlink::dialect::{
    HEARTBEAT_DATA, MavAutopilot, MavCmd, MavMissionType, MavModeFlag, MavResult, MavState,
};
use skein_mavlink::param::{ParamValue, param_name};
use skein_mavlink::{Frame, MavMessage, MessageData};
use skein_model::fsm::Observed;
use skein_model::geofence::FenceStatus;
use skein_model::px4::Px4Mode;
use std::collections::{HashMap, VecDeque};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// Silence after which a vehicle is Lost.
pub const LINK_TIMEOUT: Duration = Duration::from_secs(3);
/// Wait for a `COMMAND_ACK` before resending.
pub const ACK_TIMEOUT: Duration = Duration::from_millis(400);
/// Transmissions of a command before it fails with [`LinkError::Timeout`].
pub const MAX_ATTEMPTS: u32 = 5;
/// Longest wait for a command PX4 reported `IN_PROGRESS`.
pub const IN_PROGRESS_TIMEOUT: Duration = Duration::from_secs(30);
/// Longest wait for a heartbeat that shows a mode PX4 accepted.
pub const MODE_CONFIRM_TIMEOUT: Duration = Duration::from_millis(3500);
/// Rate of our heartbeat to the vehicle.
pub const HEARTBEAT_PERIOD: Duration = Duration::from_secs(1);

/// Something the vehicle did that its owner (the Vehicle actor) must know.
#[derive(Debug, Clone, PartialEq)]
pub enum LinkEvent {
    /// Armed flag, mode or landed state changed (the first heartbeat included).
    Observed(Observed),
    /// No valid message for [`LINK_TIMEOUT`].
    Lost,
    /// The autopilot's HEARTBEAT again after [`LinkEvent::Lost`] (with what it says).
    Restored(Observed),
    /// The autopilot rebooted (boot time went backwards).
    Rebooted,
    /// A `STATUSTEXT` from the vehicle.
    StatusText {
        /// `MAV_SEVERITY` (0 emergency … 7 debug).
        severity: u8,
        /// The text.
        text: String,
    },
}

/// Receives [`LinkEvent`]s (typically casts them to the Vehicle actor).
pub type EventSink = Arc<dyn Fn(LinkEvent) + Send + Sync>;

/// Sees every frame of the vehicle's system after the link has handled it (the vehicle
/// forwards gimbal and camera traffic to its payloads). Called on the link actor: must be
/// cheap and filter for itself.
pub type FrameSink = Arc<dyn Fn(&Frame) + Send + Sync>;

/// Arguments of [`Px4Link`].
pub struct Px4LinkArgs {
    /// The shared per-vehicle state.
    pub link: Arc<VehicleLink>,
    /// Where events go.
    pub events: EventSink,
    /// Where the vehicle's component traffic goes, if anywhere.
    pub components: Option<FrameSink>,
}

/// Messages of [`Px4Link`].
// ractor boxes every message already; boxing the frame again would add an allocation
// per telemetry message for nothing.
#[allow(clippy::large_enum_variant)]
pub enum Px4LinkMsg {
    /// A frame from the vehicle (from the endpoint route).
    Frame(Frame),
    /// What a message the route applied itself changed (see `route::applies_on_route`);
    /// never [`Change::None`].
    Applied(Change),
    /// Run a command; the reply comes when it is acknowledged (and, for modes, confirmed).
    Command(LinkCommand, RpcReplyPort<Result<(), LinkError>>),
    /// Run a command without waiting for the outcome (fire and forget, still retried).
    CommandNoReply(LinkCommand),
    /// 1 Hz: heartbeat and liveness.
    Tick,
    /// An ACK deadline of the command in flight with this id and generation.
    AckDeadline(u32, u64),
    /// The mode-confirmation deadline of the command in flight with this generation.
    ModeDeadline(u64),
    /// List the vehicle's flight logs (`LOG_REQUEST_LIST`, see
    /// [`crate::log_transfer`]).
    LogList(LogListReply),
    /// Download the vehicle's log of this id, its bytes so far counted into the counter;
    /// the reply holds every byte (a gap is asked for again until filled).
    LogDownload(
        u16,
        std::sync::Arc<std::sync::atomic::AtomicU64>,
        LogDownloadReply,
    ),
    /// A tick of the log transfer of this generation.
    LogTick(u64),
    /// A tick of the component metadata read of this generation.
    MetaTick(u64),
    /// The end of [`REASON_GRACE`] after the vehicle refused the command in flight with
    /// this id and generation.
    ReasonDeadline(u32, u64),
    /// Read a parameter.
    ParamGet(String, ParamReply),
    /// Write a parameter, given as a number, in its own type.
    ParamSet(String, f64, ParamReply),
    /// A parameter request's deadline (name, generation).
    ParamDeadline(String, u64),
    /// The parameter values seen so far.
    Params(RpcReplyPort<Vec<(String, ParamValue)>>),
    /// Liveness probe of the supervisor's watchdog.
    Ping(RpcReplyPort<()>),
    /// Fault injection (see [`crate::fault::inject`]).
    Fault(skein_model::supervision::FaultKind),
    /// Replace the vehicle's plan of this mission type (mission protocol upload).
    MissionUpload(MavMissionType, Vec<MissionItem>, UploadReply),
    /// Read the vehicle's plan of this mission type (mission protocol download).
    MissionDownload(MavMissionType, DownloadReply),
    /// A mission transfer's deadline (mission type, generation).
    MissionDeadline(MavMissionType, u64),
    /// Bring the autopilot to the plan followed (see [`VehicleLink::follow_fence`]);
    /// with `only_if_changed`, not if it holds that version already.
    SyncFence {
        /// Skip a vehicle already synced to the current version.
        only_if_changed: bool,
    },
    /// Bring the autopilot to this candidate plan and answer with the outcome (a fence
    /// not yet committed: `PUT /api/v1/geofence` tries it on every vehicle first).
    TryFence(Arc<FencePlan>, RpcReplyPort<FenceStatus>),
}

/// The `Px4Link` actor (see module docs).
pub struct Px4Link;

/// Where a command's outcome goes.
pub type CommandReply = RpcReplyPort<Result<(), LinkError>>;

struct Pending {
    command: LinkCommand,
    reply: Option<CommandReply>,
    attempts: u32,
    generation: u64,
    in_progress: bool,
    /// For `SetMode`: ACK accepted, waiting for the heartbeat to show the mode.
    awaiting_mode: Option<Px4Mode>,
    /// The `MAV_RESULT` name of the vehicle's refusal, waiting [`REASON_GRACE`] for
    /// what it says about it.
    refused: Option<String>,
    /// The warnings and errors the vehicle sent (`STATUSTEXT`) while this was in flight.
    statustexts: Vec<String>,
}

/// State of [`Px4Link`].
pub struct Px4LinkState {
    link: Arc<VehicleLink>,
    events: EventSink,
    components: Option<FrameSink>,
    pending: HashMap<u32, Pending>,
    queued: HashMap<u32, VecDeque<(LinkCommand, Option<CommandReply>)>>,
    generation: u64,
    greeted: bool,
    params: ParamClient,
    missions: MissionClient,
    statustexts: StatusTextAssembler,
    logs: logs::LogOp,
    log_generation: u64,
    px4_events: events::EventsState,
    metadata: metadata::MetadataFetch,
}

impl Px4LinkState {
    fn target(&self) -> (u8, u8) {
        (self.link.sysid, self.link.compid)
    }

    fn transmit(&self, command: &LinkCommand, confirmation: u8) -> Result<(), LinkError> {
        let (sys, comp) = self.target();
        self.link
            .endpoint
            .send(sys, &command.encode(sys, comp, confirmation))
            .map_err(|e| LinkError::Send(e.to_string()))
    }

    fn start(
        &mut self,
        myself: &ActorRef<Px4LinkMsg>,
        command: LinkCommand,
        reply: Option<CommandReply>,
    ) {
        let id = command.mav_cmd() as u32;
        if self.pending.contains_key(&id) {
            self.queued
                .entry(id)
                .or_default()
                .push_back((command, reply));
            return;
        }
        if let Err(e) = self.transmit(&command, 0) {
            if let Some(r) = reply {
                let _ = r.send(Err(e));
            }
            return;
        }
        self.generation += 1;
        let generation = self.generation;
        self.pending.insert(
            id,
            Pending {
                command,
                reply,
                attempts: 1,
                generation,
                in_progress: false,
                awaiting_mode: None,
                refused: None,
                statustexts: Vec::new(),
            },
        );
        myself.send_after(ACK_TIMEOUT, move || Px4LinkMsg::AckDeadline(id, generation));
    }

    fn finish(&mut self, myself: &ActorRef<Px4LinkMsg>, id: u32, result: Result<(), LinkError>) {
        if let Some(p) = self.pending.remove(&id) {
            if let Err(e) = &result {
                tracing::debug!(sysid = self.link.sysid, "{e}");
            }
            if let Some(r) = p.reply {
                let _ = r.send(result);
            }
        }
        if let Some((cmd, reply)) = self.queued.get_mut(&id).and_then(|q| q.pop_front()) {
            self.start(myself, cmd, reply);
        }
    }

    fn on_ack(&mut self, myself: &ActorRef<Px4LinkMsg>, id: u32, result: MavResult) {
        let Some(p) = self.pending.get_mut(&id) else {
            return; // e.g. PX4's second DO_SET_MODE ACK after confirmation
        };
        if p.refused.is_some() {
            return; // refused already: a resent command's ACK
        }
        match result {
            MavResult::MAV_RESULT_ACCEPTED => {
                if let LinkCommand::SetMode(mode) = p.command {
                    if p.awaiting_mode.is_some() {
                        return; // PX4's second ACK
                    }
                    let current = self.link.with_telemetry(|t| t.heartbeat.map(|h| h.mode));
                    if current == Some(mode) {
                        self.finish(myself, id, Ok(()));
                    } else {
                        p.awaiting_mode = Some(mode);
                        let generation = p.generation;
                        myself.send_after(MODE_CONFIRM_TIMEOUT, move || {
                            Px4LinkMsg::ModeDeadline(generation)
                        });
                    }
                } else {
                    self.finish(myself, id, Ok(()));
                }
            }
            MavResult::MAV_RESULT_IN_PROGRESS => {
                if !p.in_progress {
                    p.in_progress = true;
                    let generation = p.generation;
                    myself.send_after(IN_PROGRESS_TIMEOUT, move || {
                        Px4LinkMsg::AckDeadline(id, generation)
                    });
                }
            }
            other => {
                // PX4 says why in STATUSTEXTs sent about when it acknowledges: wait for
                // them a moment.
                p.refused = Some(result_name(other));
                let generation = p.generation;
                myself.send_after(REASON_GRACE, move || {
                    Px4LinkMsg::ReasonDeadline(id, generation)
                });
            }
        }
    }

    fn on_ack_deadline(&mut self, myself: &ActorRef<Px4LinkMsg>, id: u32, generation: u64) {
        let Some(p) = self.pending.get_mut(&id) else {
            return;
        };
        if p.generation != generation || p.awaiting_mode.is_some() || p.refused.is_some() {
            return;
        }
        if p.in_progress || p.attempts >= MAX_ATTEMPTS {
            let err = LinkError::Timeout {
                command: p.command.describe(),
                attempts: p.attempts,
            };
            self.finish(myself, id, Err(err));
            return;
        }
        let confirmation = p.attempts.min(255) as u8;
        p.attempts += 1;
        let command = p.command.clone();
        if let Err(e) = self.transmit(&command, confirmation) {
            self.finish(myself, id, Err(e));
            return;
        }
        myself.send_after(ACK_TIMEOUT, move || Px4LinkMsg::AckDeadline(id, generation));
    }

    fn check_mode_confirmations(&mut self, myself: &ActorRef<Px4LinkMsg>, mode: Px4Mode) {
        let id = MavCmd::MAV_CMD_DO_SET_MODE as u32;
        if self
            .pending
            .get(&id)
            .is_some_and(|p| p.awaiting_mode == Some(mode))
        {
            self.finish(myself, id, Ok(()));
        }
    }

    /// The operator's part of the vehicle's Remote ID ([`crate::remote_id`]), once the
    /// vehicle has been heard.
    fn send_remote_id(&self) {
        let Some(rid) = &self.link.setup.remote_id else {
            return;
        };
        let Some(home) = self
            .link
            .with_telemetry(|t| t.heartbeat.is_some().then(|| t.home.map(|h| h.geo)))
        else {
            return;
        };
        // The receiver's state is a copy taken under a lock its task never holds across
        // a wait: reading it does not wait on the receiver.
        let gnss = self.link.setup.operator_gnss.as_ref().map(|g| g.state());
        let location = rid.operator_location(gnss.as_ref(), home, Instant::now());
        for m in rid.messages(self.link.sysid, &location, std::time::SystemTime::now()) {
            let _ = self.link.endpoint.send(self.link.sysid, &m);
        }
        self.link.remote_id().sent(location);
    }

    fn send_heartbeat(&self) {
        let identity = self.link.endpoint.identity();
        let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: 0,
            mavtype: identity.mav_type,
            autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
            base_mode: MavModeFlag::empty(),
            system_status: MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        });
        // Before the vehicle has spoken a udpin endpoint has no address: nothing to do.
        let _ = self.link.endpoint.send(self.link.sysid, &hb);
    }

    /// First contact (and after a reboot or a restored link): ask for what we need now
    /// rather than waiting for PX4's slow streams, and apply the [`LinkSetup`](crate::setup::LinkSetup).
    fn greet(&mut self, myself: &ActorRef<Px4LinkMsg>) {
        self.greeted = true;
        self.send_heartbeat();
        self.start(
            myself,
            LinkCommand::RequestMessage {
                message_id: skein_mavlink::dialect::HOME_POSITION_DATA::ID,
            },
            None,
        );
        self.request_component_metadata(myself);
        let setup = self.link.setup.clone();
        for (message_id, rate_hz) in setup.telemetry.rates() {
            self.start(
                myself,
                LinkCommand::SetMessageInterval {
                    message_id,
                    interval_us: interval_us(rate_hz),
                },
                None,
            );
        }
        for (name, value) in setup.params {
            self.param(myself, &name, ParamOp::Set(value), None);
        }
        // The autopilot may have rebooted without its fence, or been given another one
        // while we did not hear it: upload it again.
        let _ = myself.cast(Px4LinkMsg::SyncFence {
            only_if_changed: false,
        });
    }

    fn param(
        &mut self,
        myself: &ActorRef<Px4LinkMsg>,
        name: &str,
        op: ParamOp,
        reply: Option<ParamReply>,
    ) {
        let t = self.params.start(name, op, reply, self.target());
        self.transmit_param(myself, t);
    }

    fn transmit_param(&self, myself: &ActorRef<Px4LinkMsg>, t: Option<Transmit>) {
        if let Some(t) = t {
            let _ = self.link.endpoint.send(self.link.sysid, &t.msg);
            let (name, generation) = (t.name, t.generation);
            myself.send_after(ACK_TIMEOUT, move || {
                Px4LinkMsg::ParamDeadline(name, generation)
            });
        }
    }

    fn on_frame(&mut self, myself: &ActorRef<Px4LinkMsg>, frame: Frame) {
        if frame.sysid != self.link.sysid {
            return;
        }
        if let Some(sink) = &self.components {
            sink(&frame);
        }
        if let MavMessage::COMMAND_ACK(ack) = &frame.msg {
            let ours = self.link.endpoint.identity();
            let for_us = (ack.target_system == 0 || ack.target_system == ours.sysid)
                && (ack.target_component == 0 || ack.target_component == ours.compid);
            if for_us {
                self.on_ack(myself, ack.command as u32, ack.result);
            }
            return;
        }
        if let MavMessage::OPEN_DRONE_ID_ARM_STATUS(_) = &frame.msg {
            // From the Remote ID transmitter, a component of its own.
            self.link.apply(&frame.msg);
            return;
        }
        // MAVLink FTP: from the autopilot, or the component a metadata URI names.
        if let MavMessage::FILE_TRANSFER_PROTOCOL(f) = &frame.msg {
            let ours = self.link.endpoint.identity();
            if f.target_system == ours.sysid
                && let Ok(p) = skein_mavlink::ftp::FtpPayload::decode(&f.payload)
            {
                self.on_ftp_reply(myself, &p);
            }
            return;
        }
        if frame.compid != self.link.compid {
            return; // other components (camera, gimbal) are the payloads' business
        }
        if let MavMessage::STATUSTEXT(t) = &frame.msg {
            self.on_statustext(t, Instant::now());
            return;
        }
        if self.on_events_message(&frame.msg) {
            return;
        }
        if let MavMessage::COMPONENT_METADATA(m) = &frame.msg {
            self.on_component_metadata(myself, m);
            return;
        }
        self.on_mission_message(myself, &frame.msg);
        self.on_log_message(&frame.msg);
        if let MavMessage::PARAM_VALUE(pv) = &frame.msg
            && let Some(value) = ParamValue::from_wire(pv.param_value, pv.param_type)
        {
            let t = self
                .params
                .on_value(&param_name(&pv.param_id), value, self.target());
            self.transmit_param(myself, t);
        }
        let change = self.link.apply(&frame.msg);
        // The link is back with the autopilot's first HEARTBEAT after the loss: what it
        // says (armed, mode) is fresh, where other messages would leave the FSM settling
        // on the state from before the loss.
        if matches!(frame.msg, MavMessage::HEARTBEAT(_))
            && self.link.lost.swap(false, Ordering::Relaxed)
        {
            let observed = self.link.with_telemetry(|t| t.observed());
            if let Some(o) = observed {
                (self.events)(LinkEvent::Restored(o));
            }
            self.greet(myself);
        }
        self.on_change(myself, change);
    }

    /// Acts on what a telemetry message changed: events for the vehicle, and the
    /// greeting (stream rates, fence) once the autopilot is heard or rebooted.
    fn on_change(&mut self, myself: &ActorRef<Px4LinkMsg>, change: Change) {
        match change {
            Change::None => {}
            Change::Observed(o) => {
                if !self.greeted {
                    self.greet(myself);
                }
                self.check_mode_confirmations(myself, o.mode);
                (self.events)(LinkEvent::Observed(o));
            }
            Change::Rebooted => {
                self.events_rebooted();
                (self.events)(LinkEvent::Rebooted);
                self.greet(myself);
            }
        }
    }

    fn on_tick(&mut self, myself: &ActorRef<Px4LinkMsg>) {
        self.send_heartbeat();
        self.send_remote_id();
        self.flush_statustext(Instant::now());
        self.events_tick();
        if self.greeted && self.link.fence().retry_due() {
            let _ = myself.cast(Px4LinkMsg::SyncFence {
                only_if_changed: true,
            });
        }
        let silent = self.link.silence().is_none_or(|s| s > LINK_TIMEOUT);
        let heard_before = self.link.with_telemetry(|t| t.heartbeat.is_some());
        if silent && heard_before && !self.link.lost.swap(true, Ordering::Relaxed) {
            (self.events)(LinkEvent::Lost);
        }
    }
}

impl Actor for Px4Link {
    type Msg = Px4LinkMsg;
    type State = Px4LinkState;
    type Arguments = Px4LinkArgs;

    async fn pre_start(
        &self,
        myself: ActorRef<Self::Msg>,
        args: Px4LinkArgs,
    ) -> Result<Self::State, ActorProcessingErr> {
        args.link.endpoint.route(
            args.link.sysid,
            route::handler(&args.link, args.components.clone(), myself.clone()),
        );
        myself.send_interval(HEARTBEAT_PERIOD, || Px4LinkMsg::Tick);
        missions::watch_plans(&args.link, &myself);
        let greeted = false;
        Ok(Px4LinkState {
            link: args.link,
            events: args.events,
            components: args.components,
            pending: HashMap::new(),
            queued: HashMap::new(),
            generation: 0,
            greeted,
            params: ParamClient::default(),
            missions: MissionClient::default(),
            statustexts: StatusTextAssembler::default(),
            logs: logs::LogOp::Idle,
            log_generation: 0,
            px4_events: events::EventsState::default(),
            metadata: metadata::MetadataFetch::default(),
        })
    }

    async fn post_start(
        &self,
        myself: ActorRef<Self::Msg>,
        state: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        // A restarted actor of a vehicle already heard from greets at once.
        if state.link.with_telemetry(|t| t.heartbeat.is_some()) {
            state.greet(&myself);
        }
        Ok(())
    }

    async fn handle(
        &self,
        myself: ActorRef<Self::Msg>,
        msg: Self::Msg,
        state: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            Px4LinkMsg::Frame(f) => state.on_frame(&myself, f),
            Px4LinkMsg::Applied(change) => state.on_change(&myself, change),
            Px4LinkMsg::Command(cmd, reply) => {
                if state.link.is_lost() {
                    let _ = reply.send(Err(LinkError::NoLink));
                } else {
                    state.start(&myself, cmd, Some(reply));
                }
            }
            Px4LinkMsg::CommandNoReply(cmd) => state.start(&myself, cmd, None),
            Px4LinkMsg::Tick => state.on_tick(&myself),
            Px4LinkMsg::AckDeadline(id, generation) => {
                state.on_ack_deadline(&myself, id, generation)
            }
            Px4LinkMsg::LogList(reply) => {
                state.start_log_listing(&myself, logs::AfterListing::Reply(reply))
            }
            Px4LinkMsg::LogDownload(id, progress, reply) => {
                state.start_log_listing(&myself, logs::AfterListing::Download(id, progress, reply))
            }
            Px4LinkMsg::LogTick(generation) => state.on_log_tick(&myself, generation),
            Px4LinkMsg::MetaTick(generation) => state.on_meta_tick(&myself, generation),
            Px4LinkMsg::ReasonDeadline(id, generation) => {
                state.on_reason_deadline(&myself, id, generation)
            }
            Px4LinkMsg::ModeDeadline(generation) => {
                let id = MavCmd::MAV_CMD_DO_SET_MODE as u32;
                if let Some(p) = state.pending.get(&id)
                    && p.generation == generation
                    && let Some(wanted) = p.awaiting_mode
                {
                    let reported = state
                        .link
                        .with_telemetry(|t| t.heartbeat.map(|h| h.mode.name()))
                        .unwrap_or("nothing");
                    state.finish(
                        &myself,
                        id,
                        Err(LinkError::ModeNotConfirmed {
                            wanted: wanted.name().to_string(),
                            reported: reported.to_string(),
                        }),
                    );
                }
            }
            Px4LinkMsg::ParamGet(name, reply) => {
                if state.link.is_lost() {
                    let _ = reply.send(Err(LinkError::NoLink));
                } else {
                    state.param(&myself, &name, ParamOp::Get, Some(reply));
                }
            }
            Px4LinkMsg::ParamSet(name, value, reply) => {
                if state.link.is_lost() {
                    let _ = reply.send(Err(LinkError::NoLink));
                } else {
                    state.param(&myself, &name, ParamOp::Set(value), Some(reply));
                }
            }
            Px4LinkMsg::ParamDeadline(name, generation) => {
                let t = state.params.on_deadline(&name, generation, state.target());
                state.transmit_param(&myself, t);
            }
            Px4LinkMsg::Params(reply) => {
                let mut all: Vec<(String, ParamValue)> = state
                    .params
                    .cache()
                    .iter()
                    .map(|(k, v)| (k.clone(), *v))
                    .collect();
                all.sort_by(|a, b| a.0.cmp(&b.0));
                let _ = reply.send(all);
            }
            Px4LinkMsg::Ping(reply) => {
                let _ = reply.send(());
            }
            Px4LinkMsg::Fault(kind) => {
                let who = format!("px4link of sysid {}", state.link.sysid);
                crate::fault::inject(kind, &myself, &who).await?;
            }
            msg @ (Px4LinkMsg::MissionUpload(..)
            | Px4LinkMsg::MissionDownload(..)
            | Px4LinkMsg::MissionDeadline(..)
            | Px4LinkMsg::SyncFence { .. }
            | Px4LinkMsg::TryFence(..)) => state.on_mission_msg(&myself, msg),
        }
        Ok(())
    }
}
