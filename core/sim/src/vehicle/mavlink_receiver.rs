//! MAVLink message handling (PX4 `mavlink_receiver`): heartbeats per MAV_TYPE, the command
//! protocol (COMMAND_LONG / COMMAND_INT, two ACKs for DO_SET_MODE, retransmission dedup),
//! parameters (PARAM_* with PX4's bytewise integer encoding), the mission protocol's
//! messages (handled in `mission`), the log protocol's (handled in `log_handler`) and
//! offboard setpoints (SET_POSITION_TARGET_LOCAL_NED / _GLOBAL_INT with PX4's `type_mask`
//! semantics) and RTK corrections (GPS_RTCM_DATA, handed to the GNSS receiver as PX4's
//! `handle_message_gps_rtcm_data` publishes them).

#![allow(deprecated)]

use super::*;
use skein_mavlink::statustext;

#[derive(Debug, Clone, Copy)]
pub(super) struct Command {
    pub(super) command: MavCmd,
    pub(super) params: [f32; 7],
    /// COMMAND_INT's frame and integer x/y (degE7 for global frames).
    pub(super) int_xy: Option<(MavFrame, i32, i32)>,
    pub(super) confirmation: u8,
    pub(super) src_sysid: u8,
    pub(super) src_compid: u8,
}

#[derive(Debug, Clone, Copy)]
pub(super) struct LastCommand {
    command: MavCmd,
    src: (u8, u8),
    at: Instant,
    acks: [Option<MavResult>; 2],
}

/// What a command asks for after its ACK(s).
#[derive(Debug, Clone, Copy)]
pub(super) enum Followup {
    Message(u32),
    MessageInterval(u32),
}

impl Vehicle {
    pub(super) fn statustext(
        &mut self,
        now: Instant,
        severity: MavSeverity,
        text: &str,
        out: &mut Outbox,
    ) {
        if !self.gcs_recent(now) {
            self.counters.statustexts_suppressed += 1;
            return;
        }
        // PX4 gives every text an id of its own and sends a long one in chunks.
        let id = self.counters.statustexts_sent as u16;
        self.counters.statustexts_sent += 1;
        for chunk in statustext::chunks(severity, text, id) {
            out.push(&MavMessage::STATUSTEXT(chunk));
        }
    }

    pub(super) fn ack(&self, cmd: &Command, result: MavResult, out: &mut Outbox) {
        out.push(&MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: cmd.command,
            result,
            progress: 0,
            result_param2: 0,
            target_system: cmd.src_sysid,
            target_component: cmd.src_compid,
        }));
    }

    pub(super) fn param_value(&self, index: usize, out: &mut Outbox) {
        let (Some(name), Some(value)) = (Params::name_at(index), self.params.value_at(index))
        else {
            return;
        };
        let (param_value, param_type) = value.to_wire();
        out.push(&MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
            param_value,
            param_count: PARAM_COUNT as u16,
            param_index: index as u16,
            param_id: name.into(),
            param_type,
        }));
    }

    pub(super) fn targets_me(&self, target_system: u8, target_component: u8) -> bool {
        (target_system == 0 || target_system == self.sysid)
            && (target_component == 0 || target_component == 1)
    }

    /// Handles one received frame.
    pub fn handle_frame(&mut self, now: Instant, frame: &Frame, out: &mut Outbox) {
        self.counters.frames_received += 1;
        self.link.rx_frames += 1;
        if frame.sysid == self.sysid && frame.compid == 1 {
            return; // our own frames echoed back
        }
        if let Some(cmd) = self.command_of(frame) {
            self.on_command(now, cmd, out);
            return;
        }
        if self.on_param_frame(now, frame, out)
            || self.on_mission_frame(now, frame, out)
            || self.on_log_frame(frame)
        {
            return;
        }
        let from = (frame.sysid, frame.compid);
        match &frame.msg {
            MavMessage::HEARTBEAT(hb) => {
                let gcs_was_connected = self.gcs_connected(now);
                self.on_heartbeat(now, hb);
                if hb.mavtype == MavType::MAV_TYPE_GCS && !gcs_was_connected {
                    // PX4: a ground station connected gets the sequence and the report.
                    self.send_current_sequence(now, out);
                    self.force_health_report(now, out);
                }
            }
            MavMessage::FILE_TRANSFER_PROTOCOL(m) => self.on_ftp(now, m, from, out),
            MavMessage::REQUEST_EVENT(r)
                if self.targets_me(r.target_system, r.target_component) =>
            {
                self.on_request_event(r, from, out)
            }
            MavMessage::SET_POSITION_TARGET_LOCAL_NED(sp) => self.on_setpoint_local(now, sp),
            MavMessage::SET_POSITION_TARGET_GLOBAL_INT(sp) => self.on_setpoint_global(now, sp),
            MavMessage::GPS_RTCM_DATA(d) => self.gnss.on_rtcm_data(d, &mut self.counters.rtcm),
            MavMessage::PING(p) if p.target_system == 0 && p.target_component == 0 => {
                // A ping request: answer it, addressed to the requester.
                out.push(&MavMessage::PING(PING_DATA {
                    time_usec: p.time_usec,
                    seq: p.seq,
                    target_system: frame.sysid,
                    target_component: frame.compid,
                }));
            }
            MavMessage::TIMESYNC(t) if t.tc1 == 0 => {
                // A timesync request: tc1 = our time (ns), ts1 echoed.
                out.push(&MavMessage::TIMESYNC(TIMESYNC_DATA {
                    tc1: self.time_boot_us(now) as i64 * 1000,
                    ts1: t.ts1,
                    target_system: frame.sysid,
                    target_component: frame.compid,
                }));
            }
            MavMessage::SET_MODE(m)
                if m.target_system == self.sysid
                    && m.base_mode
                        .contains(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED) =>
            {
                let mode = Px4Mode::from_custom_mode(m.custom_mode);
                if let Err(reason) = self.request_mode(now, mode) {
                    self.statustext(now, MavSeverity::MAV_SEVERITY_CRITICAL, reason, out);
                }
            }
            _ => {}
        }
    }

    /// The command in `frame` (COMMAND_LONG or COMMAND_INT) when it is addressed to us.
    fn command_of(&self, frame: &Frame) -> Option<Command> {
        let (src_sysid, src_compid) = (frame.sysid, frame.compid);
        match &frame.msg {
            MavMessage::COMMAND_LONG(c) if self.targets_me(c.target_system, c.target_component) => {
                Some(Command {
                    command: c.command,
                    params: [
                        c.param1, c.param2, c.param3, c.param4, c.param5, c.param6, c.param7,
                    ],
                    int_xy: None,
                    confirmation: c.confirmation,
                    src_sysid,
                    src_compid,
                })
            }
            MavMessage::COMMAND_INT(c) if self.targets_me(c.target_system, c.target_component) => {
                Some(Command {
                    command: c.command,
                    params: [
                        c.param1, c.param2, c.param3, c.param4, c.x as f32, c.y as f32, c.z,
                    ],
                    int_xy: Some((c.frame, c.x, c.y)),
                    confirmation: 0,
                    src_sysid,
                    src_compid,
                })
            }
            _ => None,
        }
    }

    /// The parameter protocol's requests addressed to us; false for any other frame.
    fn on_param_frame(&mut self, now: Instant, frame: &Frame, out: &mut Outbox) -> bool {
        match &frame.msg {
            MavMessage::PARAM_REQUEST_READ(r)
                if self.targets_me(r.target_system, r.target_component) =>
            {
                let index = if r.param_index >= 0 {
                    Some(r.param_index as usize).filter(|&i| i < PARAM_COUNT)
                } else {
                    r.param_id.to_str().ok().and_then(Params::index_of)
                };
                if let Some(i) = index {
                    self.param_value(i, out);
                }
            }
            MavMessage::PARAM_REQUEST_LIST(r)
                if self.targets_me(r.target_system, r.target_component) =>
            {
                for i in 0..PARAM_COUNT {
                    self.param_value(i, out);
                }
            }
            MavMessage::PARAM_SET(s) if self.targets_me(s.target_system, s.target_component) => {
                self.on_param_set(now, s, out);
            }
            _ => return false,
        }
        true
    }

    /// The mission protocol's messages addressed to us (see `mission`: fence and rally
    /// plans; flight plans are an empty list); false for any other frame.
    fn on_mission_frame(&mut self, now: Instant, frame: &Frame, out: &mut Outbox) -> bool {
        let from = (frame.sysid, frame.compid);
        match &frame.msg {
            MavMessage::MISSION_REQUEST_LIST(m)
                if self.targets_me(m.target_system, m.target_component) =>
            {
                self.on_mission_request_list(from, m.mission_type, out);
            }
            MavMessage::MISSION_COUNT(c)
                if self.targets_me(c.target_system, c.target_component) =>
            {
                self.on_mission_count(now, from, c, out);
            }
            MavMessage::MISSION_ITEM_INT(i)
                if self.targets_me(i.target_system, i.target_component) =>
            {
                self.on_mission_item(now, from, i, out);
            }
            MavMessage::MISSION_REQUEST_INT(r)
                if self.targets_me(r.target_system, r.target_component) =>
            {
                self.on_mission_request(from, r.mission_type, r.seq, out);
            }
            MavMessage::MISSION_REQUEST(r)
                if self.targets_me(r.target_system, r.target_component) =>
            {
                self.on_mission_request(from, r.mission_type, r.seq, out);
            }
            MavMessage::MISSION_CLEAR_ALL(c)
                if self.targets_me(c.target_system, c.target_component) =>
            {
                self.on_mission_clear(from, c.mission_type, out);
            }
            _ => return false,
        }
        true
    }

    /// The log protocol's requests addressed to us (see `log_handler`: what is sent
    /// goes out on the next steps); false for any other frame.
    fn on_log_frame(&mut self, frame: &Frame) -> bool {
        match &frame.msg {
            MavMessage::LOG_REQUEST_LIST(r)
                if self.targets_me(r.target_system, r.target_component) =>
            {
                self.on_log_request_list(r);
            }
            MavMessage::LOG_REQUEST_DATA(r)
                if self.targets_me(r.target_system, r.target_component) =>
            {
                self.on_log_request_data(r);
            }
            MavMessage::LOG_REQUEST_END(r)
                if self.targets_me(r.target_system, r.target_component) =>
            {
                self.on_log_request_end();
            }
            MavMessage::LOG_ERASE(r) if self.targets_me(r.target_system, r.target_component) => {
                self.on_log_erase();
            }
            _ => return false,
        }
        true
    }

    pub(super) fn on_heartbeat(&mut self, now: Instant, hb: &HEARTBEAT_DATA) {
        match hb.mavtype {
            MavType::MAV_TYPE_GCS => {
                self.heartbeats.gcs = Some(now);
                self.gcs_lost = false;
            }
            MavType::MAV_TYPE_ONBOARD_CONTROLLER => {
                self.heartbeats.onboard_controller = Some(now);
            }
            MavType::MAV_TYPE_GIMBAL => self.heartbeats.gimbal = Some(now),
            MavType::MAV_TYPE_CAMERA => self.heartbeats.camera = Some(now),
            _ => {}
        }
    }

    pub(super) fn on_param_set(&mut self, now: Instant, s: &PARAM_SET_DATA, out: &mut Outbox) {
        let Some(index) = s.param_id.to_str().ok().and_then(Params::index_of) else {
            return; // PX4 ignores unknown parameters
        };
        let Some(current) = self.params.value_at(index) else {
            return;
        };
        let new = current.with_wire_value(s.param_value);
        let valid = match new {
            ParamValue::Real32(f) => f.is_finite(),
            ParamValue::Int32(_) => true,
        };
        if valid {
            self.params.set_at(index, new);
            // PX4 answers a PARAM_SET right away and again when the change notification
            // goes round: two PARAM_VALUEs.
            self.param_value(index, out);
            self.param_value(index, out);
        } else {
            self.statustext(
                now,
                MavSeverity::MAV_SEVERITY_WARNING,
                "Parameter value rejected",
                out,
            );
            self.param_value(index, out);
        }
    }

    pub(super) fn record_setpoint(&mut self, now: Instant, sp: Setpoint) {
        self.counters.setpoints_received += 1;
        match self.setpoint_last {
            Some(last) => {
                let gap = now.saturating_duration_since(last);
                self.setpoint_intervals.record(gap);
                self.counters.setpoint_max_gap = self.counters.setpoint_max_gap.max(gap);
                if self.mode == Px4Mode::Offboard {
                    self.counters.setpoint_max_gap_offboard =
                        self.counters.setpoint_max_gap_offboard.max(gap);
                }
                if gap > OFFBOARD_MAX_GAP {
                    self.setpoint_stream_start = Some(now);
                }
            }
            None => self.setpoint_stream_start = Some(now),
        }
        self.setpoint_last = Some(now);
        self.setpoint = Some(sp);
    }

    pub(super) fn on_setpoint_local(
        &mut self,
        now: Instant,
        sp: &SET_POSITION_TARGET_LOCAL_NED_DATA,
    ) {
        if !self.targets_me(sp.target_system, sp.target_component) {
            return;
        }
        let mask = sp.type_mask.bits();
        let field = |bit: u16, v: f32| (mask & bit == 0 && v.is_finite()).then_some(f64::from(v));
        let mut pos = [
            field(type_mask::IGNORE_PX, sp.x),
            field(type_mask::IGNORE_PY, sp.y),
            field(type_mask::IGNORE_PZ, sp.z),
        ];
        let mut vel = [
            field(type_mask::IGNORE_VX, sp.vx),
            field(type_mask::IGNORE_VY, sp.vy),
            field(type_mask::IGNORE_VZ, sp.vz),
        ];
        let here = self.nav_pos();
        match sp.coordinate_frame {
            MavFrame::MAV_FRAME_LOCAL_NED => {}
            MavFrame::MAV_FRAME_LOCAL_OFFSET_NED => {
                for (i, p) in pos.iter_mut().enumerate() {
                    *p = p.map(|d| d + axis(&here, i));
                }
            }
            MavFrame::MAV_FRAME_BODY_NED | MavFrame::MAV_FRAME_BODY_OFFSET_NED => {
                let rot = |v: [Option<f64>; 3]| -> [Option<f64>; 3] {
                    let r = Ned::new(v[0].unwrap_or(0.0), v[1].unwrap_or(0.0), 0.0)
                        .rotated_yaw(self.yaw_rad);
                    let both = v[0].is_some() || v[1].is_some();
                    [both.then_some(r.north_m), both.then_some(r.east_m), v[2]]
                };
                vel = rot(vel);
                pos = rot(pos);
                for (i, p) in pos.iter_mut().enumerate() {
                    *p = p.map(|d| d + axis(&here, i));
                }
            }
            _ => return, // PX4 ignores other frames for multicopters
        }
        let acc = if mask & type_mask::FORCE == 0 {
            [
                field(type_mask::IGNORE_AX, sp.afx),
                field(type_mask::IGNORE_AY, sp.afy),
                field(type_mask::IGNORE_AZ, sp.afz),
            ]
        } else {
            [None; 3]
        };
        let setpoint = Setpoint {
            pos,
            vel,
            acc,
            yaw_rad: field(type_mask::IGNORE_YAW, sp.yaw),
            yaw_rate_rad_s: field(type_mask::IGNORE_YAW_RATE, sp.yaw_rate),
        };
        self.record_setpoint(now, setpoint);
    }

    pub(super) fn on_setpoint_global(
        &mut self,
        now: Instant,
        sp: &SET_POSITION_TARGET_GLOBAL_INT_DATA,
    ) {
        if !self.targets_me(sp.target_system, sp.target_component) {
            return;
        }
        let mask = sp.type_mask.bits();
        let ignore_pos = mask & type_mask::IGNORE_POSITION == type_mask::IGNORE_POSITION;
        let alt_amsl = match sp.coordinate_frame {
            MavFrame::MAV_FRAME_GLOBAL_INT | MavFrame::MAV_FRAME_GLOBAL => f64::from(sp.alt),
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
            | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT
            | MavFrame::MAV_FRAME_GLOBAL_TERRAIN_ALT_INT
            | MavFrame::MAV_FRAME_GLOBAL_TERRAIN_ALT => self.home.alt_amsl_m + f64::from(sp.alt),
            _ => return,
        };
        let local = if ignore_pos {
            Ned::ZERO
        } else {
            self.origin.to_ned(&GeoPoint::new(
                f64::from(sp.lat_int) * 1e-7,
                f64::from(sp.lon_int) * 1e-7,
                alt_amsl,
            ))
        };
        let field = |bit: u16, v: f64| (mask & bit == 0 && v.is_finite()).then_some(v);
        let setpoint = Setpoint {
            pos: [
                field(type_mask::IGNORE_PX, local.north_m),
                field(type_mask::IGNORE_PY, local.east_m),
                field(type_mask::IGNORE_PZ, local.down_m),
            ],
            vel: [
                field(type_mask::IGNORE_VX, f64::from(sp.vx)),
                field(type_mask::IGNORE_VY, f64::from(sp.vy)),
                field(type_mask::IGNORE_VZ, f64::from(sp.vz)),
            ],
            acc: if mask & type_mask::FORCE == 0 {
                [
                    field(type_mask::IGNORE_AX, f64::from(sp.afx)),
                    field(type_mask::IGNORE_AY, f64::from(sp.afy)),
                    field(type_mask::IGNORE_AZ, f64::from(sp.afz)),
                ]
            } else {
                [None; 3]
            },
            yaw_rad: field(type_mask::IGNORE_YAW, f64::from(sp.yaw)),
            yaw_rate_rad_s: field(type_mask::IGNORE_YAW_RATE, f64::from(sp.yaw_rate)),
        };
        self.record_setpoint(now, setpoint);
    }

    pub(super) fn on_command(&mut self, now: Instant, cmd: Command, out: &mut Outbox) {
        self.counters.commands_received += 1;
        if cmd.confirmation > 0
            && let Some(last) = self.last_command
            && last.command == cmd.command
            && last.src == (cmd.src_sysid, cmd.src_compid)
            && now.saturating_duration_since(last.at) <= COMMAND_DEDUP_WINDOW
        {
            // A retransmission of a command already executed: answer again, do not
            // execute twice.
            for result in last.acks.into_iter().flatten() {
                self.ack(&cmd, result, out);
            }
            return;
        }
        let (first, second, followup) = self.execute(now, &cmd, out);
        self.ack(&cmd, first, out);
        if let Some(second) = second {
            self.ack(&cmd, second, out);
        }
        self.last_command = Some(LastCommand {
            command: cmd.command,
            src: (cmd.src_sysid, cmd.src_compid),
            at: now,
            acks: [Some(first), second],
        });
        match followup {
            Some(Followup::Message(id)) => {
                self.send_message_now(now, id, out);
            }
            Some(Followup::MessageInterval(id)) => {
                let interval_us = self.streams.interval_report_us(id);
                out.push(&MavMessage::MESSAGE_INTERVAL(MESSAGE_INTERVAL_DATA {
                    interval_us,
                    message_id: id as u16,
                }));
            }
            None => {}
        }
    }

    /// Executes `cmd`: its ACK result, PX4's second ACK where it sends one, and what is
    /// sent after the ACK.
    pub(super) fn execute(
        &mut self,
        now: Instant,
        cmd: &Command,
        out: &mut Outbox,
    ) -> (MavResult, Option<MavResult>, Option<Followup>) {
        use MavResult::*;
        let p = cmd.params;
        let result = match cmd.command {
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM => {
                let force = (p[1] - FORCE_ARM_DISARM_MAGIC).abs() < 0.5;
                self.arm_disarm(now, p[0] > 0.5, force, out)
            }
            MavCmd::MAV_CMD_DO_SET_MODE => {
                // PX4 acknowledges twice: ACCEPTED first, then the real result.
                let second = self.set_mode_command(now, p, out);
                return (MAV_RESULT_ACCEPTED, Some(second), None);
            }
            MavCmd::MAV_CMD_NAV_TAKEOFF => self.takeoff(now, p[6], out),
            MavCmd::MAV_CMD_NAV_LAND => {
                let r = self.mode_command(now, Px4Mode::Land, out);
                if r == MAV_RESULT_ACCEPTED {
                    let text = "Landing at current position";
                    let def = crate::px4_events::LANDING_CURRENT_POS;
                    self.say(
                        now,
                        MavSeverity::MAV_SEVERITY_INFO,
                        &def,
                        text,
                        [0; 40],
                        out,
                    );
                }
                r
            }
            MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH => {
                let r = self.mode_command(now, Px4Mode::Rtl, out);
                if r == MAV_RESULT_ACCEPTED {
                    let def = crate::px4_events::RTL;
                    self.say(
                        now,
                        MavSeverity::MAV_SEVERITY_INFO,
                        &def,
                        "Returning to launch",
                        [0; 40],
                        out,
                    );
                }
                r
            }
            MavCmd::MAV_CMD_NAV_LOITER_UNLIM => self.mode_command(now, Px4Mode::Hold, out),
            MavCmd::MAV_CMD_DO_REPOSITION => self.reposition(now, cmd, out),
            MavCmd::MAV_CMD_DO_CHANGE_SPEED => {
                if p[1] > 0.0 && p[1].is_finite() {
                    self.auto_speed_m_s = Some(f64::from(p[1]));
                }
                MAV_RESULT_ACCEPTED
            }
            MavCmd::MAV_CMD_DO_SET_HOME => self.set_home_command(now, cmd, out),
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL
            | MavCmd::MAV_CMD_GET_MESSAGE_INTERVAL
            | MavCmd::MAV_CMD_REQUEST_MESSAGE
            | MavCmd::MAV_CMD_GET_HOME_POSITION
            | MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES
            | MavCmd::MAV_CMD_REQUEST_PROTOCOL_VERSION => {
                let (result, followup) = self.message_command(now, cmd);
                return (result, None, followup);
            }
            MavCmd::MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN => self.reboot_command(p),
            MavCmd::MAV_CMD_DO_FLIGHTTERMINATION => {
                if p[0] > 0.5 {
                    self.disarm(now, "Flight termination", out);
                }
                MAV_RESULT_ACCEPTED
            }
            MavCmd::MAV_CMD_MISSION_START => {
                self.statustext(
                    now,
                    MavSeverity::MAV_SEVERITY_CRITICAL,
                    "Mission start denied: no valid mission",
                    out,
                );
                MAV_RESULT_DENIED
            }
            _ => MAV_RESULT_UNSUPPORTED,
        };
        (result, None, None)
    }

    /// `MAV_CMD_DO_SET_MODE`'s real result (its second ACK): denied without the custom
    /// mode flag or for an unknown mode, temporarily rejected (with a STATUSTEXT) when
    /// the mode cannot be entered now.
    fn set_mode_command(&mut self, now: Instant, p: [f32; 7], out: &mut Outbox) -> MavResult {
        use MavResult::*;
        if (p[0] as u32) & 1 == 0 {
            return MAV_RESULT_DENIED;
        }
        match Px4Mode::from_main_sub(p[1] as u8, p[2] as u8) {
            None => MAV_RESULT_DENIED,
            Some(mode) => match self.request_mode(now, mode) {
                Ok(()) => MAV_RESULT_ACCEPTED,
                Err(reason) => {
                    self.statustext(now, MavSeverity::MAV_SEVERITY_CRITICAL, reason, out);
                    MAV_RESULT_TEMPORARILY_REJECTED
                }
            },
        }
    }

    /// `MAV_CMD_DO_SET_HOME`: here (param 1), or at the given point (degrees, or degE7
    /// in a COMMAND_INT).
    fn set_home_command(&mut self, now: Instant, cmd: &Command, out: &mut Outbox) -> MavResult {
        let p = cmd.params;
        if p[0] > 0.5 {
            self.set_home_here(now, out);
        } else if p[4].is_finite() && p[5].is_finite() && p[6].is_finite() {
            let (lat, lon) = match cmd.int_xy {
                Some((_, x, y)) => (f64::from(x) * 1e-7, f64::from(y) * 1e-7),
                None => (f64::from(p[4]), f64::from(p[5])),
            };
            self.home = GeoPoint::new(lat, lon, f64::from(p[6]));
            self.home_local = self.origin.to_ned(&self.home);
            self.streams
                .force(crate::vehicle::telemetry::Stream::HomePosition, now);
        } else {
            return MavResult::MAV_RESULT_DENIED;
        }
        MavResult::MAV_RESULT_ACCEPTED
    }

    /// The commands about messages: set or get a stream's interval, request one message
    /// (the home position, the autopilot version and the protocol version by their own
    /// commands too). Returns the result and the message to send after the ACK.
    fn message_command(&mut self, now: Instant, cmd: &Command) -> (MavResult, Option<Followup>) {
        use MavResult::*;
        let p = cmd.params;
        let message = |id: u32| (MAV_RESULT_ACCEPTED, Some(Followup::Message(id)));
        match cmd.command {
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => {
                if self.streams.set_interval(p[0] as u32, p[1], now) {
                    (MAV_RESULT_ACCEPTED, None)
                } else {
                    (MAV_RESULT_DENIED, None)
                }
            }
            MavCmd::MAV_CMD_GET_MESSAGE_INTERVAL => (
                MAV_RESULT_ACCEPTED,
                Some(Followup::MessageInterval(p[0] as u32)),
            ),
            MavCmd::MAV_CMD_REQUEST_MESSAGE => {
                let id = p[0] as u32;
                if self.can_send_message(now, id) {
                    message(id)
                } else if crate::vehicle::telemetry::is_known_message(id) {
                    (MAV_RESULT_TEMPORARILY_REJECTED, None)
                } else {
                    (MAV_RESULT_UNSUPPORTED, None)
                }
            }
            MavCmd::MAV_CMD_GET_HOME_POSITION if self.has_fix => {
                message(crate::vehicle::telemetry::HOME_POSITION_ID)
            }
            MavCmd::MAV_CMD_GET_HOME_POSITION => (MAV_RESULT_TEMPORARILY_REJECTED, None),
            MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES => {
                message(crate::vehicle::telemetry::AUTOPILOT_VERSION_ID)
            }
            MavCmd::MAV_CMD_REQUEST_PROTOCOL_VERSION => {
                message(crate::vehicle::telemetry::PROTOCOL_VERSION_ID)
            }
            _ => (MAV_RESULT_UNSUPPORTED, None),
        }
    }

    /// `MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN`: a reboot of the autopilot (param 1 = 1), not
    /// while armed; nothing else is supported.
    fn reboot_command(&mut self, p: [f32; 7]) -> MavResult {
        if p[0].round() as i32 != 1 {
            return MavResult::MAV_RESULT_UNSUPPORTED;
        }
        if self.armed {
            return MavResult::MAV_RESULT_DENIED;
        }
        self.reboot_requested = true;
        MavResult::MAV_RESULT_ACCEPTED
    }
}
