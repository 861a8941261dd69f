//! Commander (PX4 `commander`): arming and its pre-arm checks, mode switching with PX4's
//! refusals, the offboard-signal check (`COM_OF_LOSS_T`), failsafes on offboard loss
//! (`COM_OBL_RC_ACT`) and GCS link loss (`COM_DL_LOSS_T`, `NAV_DLL_ACT`), and auto-disarm
//! (`COM_DISARM_PRFLT`, `COM_DISARM_LAND`). Arming starts a flight log, disarming ends it
//! (PX4's `SDLOG_MODE` 0, see `flight_log`).

#![allow(deprecated)]

use super::*;

impl Vehicle {
    pub(super) fn gcs_recent(&self, now: Instant) -> bool {
        self.heartbeats
            .gcs
            .is_some_and(|t| now.saturating_duration_since(t) <= STATUSTEXT_GCS_WINDOW)
    }

    /// True while a GCS heartbeat arrived within PX4's 1.5 s heartbeat timeout.
    pub fn gcs_connected(&self, now: Instant) -> bool {
        self.heartbeats
            .gcs
            .is_some_and(|t| now.saturating_duration_since(t) <= HEARTBEAT_TIMEOUT)
    }

    /// True while an onboard-controller heartbeat arrived within 1.5 s.
    pub fn onboard_controller_connected(&self, now: Instant) -> bool {
        self.heartbeats
            .onboard_controller
            .is_some_and(|t| now.saturating_duration_since(t) <= HEARTBEAT_TIMEOUT)
    }

    /// PX4's "offboard available": the last setpoint is younger than COM_OF_LOSS_T
    /// (PX4 v1.16 `offboardCheck.cpp`); with [`Environment::offboard_min_stream`] set,
    /// the stream must also have run that long at > 2 Hz (the rule PX4's docs state).
    pub fn offboard_available(&self, now: Instant) -> bool {
        let loss = Duration::from_secs_f64(self.params.get(Param::COM_OF_LOSS_T).max(0.0));
        let Some(last) = self.setpoint_last else {
            return false;
        };
        let age = now.saturating_duration_since(last);
        if age >= loss {
            return false;
        }
        if self.env.offboard_min_stream.is_zero() {
            return true;
        }
        age <= OFFBOARD_MAX_GAP
            && self
                .setpoint_stream_start
                .is_some_and(|s| now.saturating_duration_since(s) >= self.env.offboard_min_stream)
    }

    pub(super) fn arming_denied_reason(&self, now: Instant) -> Option<&'static str> {
        if !self.ekf_ok(now) {
            return Some("Arming denied: no valid global position");
        }
        match self.mode {
            Px4Mode::Land | Px4Mode::Precland => {
                Some("Arming denied: Land mode does not allow arming")
            }
            Px4Mode::Rtl => Some("Arming denied: Return mode does not allow arming"),
            Px4Mode::Mission => Some("Arming denied: no valid mission"),
            Px4Mode::Offboard if !self.offboard_available(now) => {
                Some("Arming denied: no offboard signal")
            }
            Px4Mode::Unknown(_) | Px4Mode::FollowTarget | Px4Mode::Ready => {
                Some("Arming denied: mode not available")
            }
            _ => None,
        }
    }

    /// The health check that fails arming in every mode, as PX4's
    /// `HealthAndArmingChecks` logs it: with `COM_ARM_ODID` = 2 (enforce), a vehicle
    /// without an Open Drone ID transmitter (the simulator has none) may not arm
    /// (`checks/openDroneIDCheck.cpp`).
    pub(super) fn health_failure(&self) -> Option<&'static str> {
        (self.params.get(Param::COM_ARM_ODID) as i32 == 2)
            .then_some("Preflight Fail: Open Drone ID system missing")
    }

    /// True when PX4's pre-arm checks pass in the current state (SYS_STATUS PREARM_CHECK).
    pub fn prearm_ok(&self, now: Instant) -> bool {
        self.armed || (self.health_failure().is_none() && self.arming_denied_reason(now).is_none())
    }

    pub(super) fn mode_denied_reason(&self, now: Instant, mode: Px4Mode) -> Option<&'static str> {
        match mode {
            Px4Mode::Offboard if !self.offboard_available(now) => {
                Some("Switching to Offboard is currently not available")
            }
            Px4Mode::Mission => Some("Switching to Mission is currently not available"),
            Px4Mode::FollowTarget | Px4Mode::Ready | Px4Mode::Unknown(_) => {
                Some("Switching to this mode is currently not available")
            }
            Px4Mode::Hold | Px4Mode::Takeoff | Px4Mode::Rtl | Px4Mode::Posctl
                if !self.ekf_ok(now) =>
            {
                Some("No valid global position")
            }
            _ => None,
        }
    }

    pub(super) fn mode_command(
        &mut self,
        now: Instant,
        mode: Px4Mode,
        out: &mut Outbox,
    ) -> MavResult {
        match self.request_mode(now, mode) {
            Ok(()) => MavResult::MAV_RESULT_ACCEPTED,
            Err(reason) => {
                self.statustext(now, MavSeverity::MAV_SEVERITY_CRITICAL, reason, out);
                MavResult::MAV_RESULT_TEMPORARILY_REJECTED
            }
        }
    }

    pub(super) fn arm_disarm(
        &mut self,
        now: Instant,
        arm: bool,
        force: bool,
        out: &mut Outbox,
    ) -> MavResult {
        if arm {
            if self.armed {
                return MavResult::MAV_RESULT_ACCEPTED;
            }
            if !force {
                // PX4 runs its checks and reports them (events) on every attempt.
                self.force_health_report(now, out);
            }
            if !force && let Some(failure) = self.health_failure() {
                // The failed check's own text (no tab: `openDroneIDCheck.cpp`), then the
                // commander's verdict, as text and event.
                self.statustext(now, MavSeverity::MAV_SEVERITY_CRITICAL, failure, out);
                self.say(
                    now,
                    MavSeverity::MAV_SEVERITY_CRITICAL,
                    &crate::px4_events::ARM_DENIED_RESOLVE_FAILURES,
                    "Arming denied: Resolve system health failures first",
                    [0; 40],
                    out,
                );
                return MavResult::MAV_RESULT_TEMPORARILY_REJECTED;
            }
            if !force && let Some(reason) = self.arming_denied_reason(now) {
                self.statustext(now, MavSeverity::MAV_SEVERITY_CRITICAL, reason, out);
                return MavResult::MAV_RESULT_TEMPORARILY_REJECTED;
            }
            self.arm(now, out);
            MavResult::MAV_RESULT_ACCEPTED
        } else {
            if !self.armed {
                return MavResult::MAV_RESULT_ACCEPTED;
            }
            if !self.landed && !force {
                self.say(
                    now,
                    MavSeverity::MAV_SEVERITY_CRITICAL,
                    &crate::px4_events::DISARM_DENIED_NOT_LANDED,
                    "Disarming denied: not landed",
                    [0; 40],
                    out,
                );
                return MavResult::MAV_RESULT_DENIED;
            }
            self.disarm(now, "Disarmed by external command", out);
            MavResult::MAV_RESULT_ACCEPTED
        }
    }

    pub(super) fn arm(&mut self, now: Instant, out: &mut Outbox) {
        self.armed = true;
        self.armed_at = now;
        self.start_flight_log(now);
        self.took_off = false;
        self.landed_at = None;
        self.pos_ctrl.reset();
        self.traj_valid = false;
        if self.landed {
            // PX4 sets home where it arms.
            self.set_home_here(now, out);
        }
        if matches!(
            self.mode,
            Px4Mode::Hold
                | Px4Mode::Posctl
                | Px4Mode::Altctl
                | Px4Mode::Manual
                | Px4Mode::Stabilized
                | Px4Mode::Acro
        ) {
            self.hold_pos = self.nav_pos();
        }
        let reason = crate::px4_events::arm_disarm_reason::COMMAND_EXTERNAL;
        self.say(
            now,
            MavSeverity::MAV_SEVERITY_INFO,
            &crate::px4_events::ARMED_BY,
            "Armed by external command",
            events::args(&[&[reason]]),
            out,
        );
    }

    pub(super) fn disarm(&mut self, now: Instant, reason: &str, out: &mut Outbox) {
        self.armed = false;
        self.failsafe = false;
        self.finish_flight_log();
        use crate::px4_events::arm_disarm_reason as why;
        let code = match reason {
            "Disarmed by external command" => Some(why::COMMAND_EXTERNAL),
            "Disarmed by landing" => Some(why::AUTO_DISARM_LAND),
            "Disarmed by auto preflight disarming" => Some(why::AUTO_DISARM_PREFLIGHT),
            _ => None, // failsafes and termination: PX4's failsafe texts, not events here
        };
        match code {
            Some(c) => {
                let def = crate::px4_events::DISARMED_BY;
                let a = events::args(&[&[c]]);
                self.say(now, MavSeverity::MAV_SEVERITY_INFO, &def, reason, a, out);
            }
            None => self.statustext(now, MavSeverity::MAV_SEVERITY_INFO, reason, out),
        }
    }

    pub(super) fn set_home_here(&mut self, now: Instant, out: &mut Outbox) {
        let _ = out;
        self.home_local = self.nav_pos();
        self.home = self.origin.to_geo(self.home_local);
        self.home_yaw_rad = self.yaw_rad;
        self.streams
            .force(crate::vehicle::telemetry::Stream::HomePosition, now);
    }

    /// Switches mode if PX4 would allow it; `Err` carries PX4's refusal text.
    pub(super) fn request_mode(&mut self, now: Instant, mode: Px4Mode) -> Result<(), &'static str> {
        if let Some(reason) = self.mode_denied_reason(now, mode) {
            return Err(reason);
        }
        if mode != self.mode || self.failsafe {
            self.enter_mode(mode);
        }
        self.failsafe = false;
        Ok(())
    }

    pub(super) fn failsafe_to(&mut self, mode: Px4Mode) {
        self.enter_mode(mode);
        self.failsafe = true;
    }

    pub(super) fn check_offboard_loss(&mut self, now: Instant, out: &mut Outbox) {
        if self.mode != Px4Mode::Offboard || !self.armed {
            return;
        }
        let loss = Duration::from_secs_f64(self.params.get(Param::COM_OF_LOSS_T).max(0.0));
        let lost = self
            .setpoint_last
            .is_none_or(|t| now.saturating_duration_since(t) > loss);
        if !lost {
            return;
        }
        self.counters.offboard_loss_failsafes += 1;
        let (mode, text) = match self.params.get(Param::COM_OBL_RC_ACT) as i32 {
            3 => (Px4Mode::Rtl, "Failsafe: no offboard signal, returning"),
            5 => (Px4Mode::Hold, "Failsafe: no offboard signal, holding"),
            // 0 Position, 1 Altitude, 2 Manual: without RC PX4 falls back to landing.
            _ => (Px4Mode::Land, "Failsafe: no offboard signal, landing"),
        };
        self.failsafe_to(mode);
        self.statustext(now, MavSeverity::MAV_SEVERITY_CRITICAL, text, out);
    }

    pub(super) fn check_links(&mut self, now: Instant, out: &mut Outbox) {
        let Some(last) = self.heartbeats.gcs else {
            return;
        };
        if self.gcs_lost {
            return;
        }
        let timeout = Duration::from_secs_f64(self.params.get(Param::COM_DL_LOSS_T).max(0.0));
        if now.saturating_duration_since(last) <= timeout {
            return;
        }
        self.gcs_lost = true;
        if !self.armed {
            return;
        }
        let action = match self.params.get(Param::NAV_DLL_ACT) as i32 {
            1 => Some((Px4Mode::Hold, "Failsafe: GCS connection lost, holding")),
            2 => Some((Px4Mode::Rtl, "Failsafe: GCS connection lost, returning")),
            3 => Some((Px4Mode::Land, "Failsafe: GCS connection lost, landing")),
            5 | 6 => {
                self.counters.gcs_loss_failsafes += 1;
                self.disarm(now, "Failsafe: GCS connection lost, terminating", out);
                None
            }
            _ => None,
        };
        if let Some((mode, text)) = action {
            self.counters.gcs_loss_failsafes += 1;
            self.failsafe_to(mode);
            self.statustext(now, MavSeverity::MAV_SEVERITY_CRITICAL, text, out);
        }
    }

    pub(super) fn auto_disarm(&mut self, now: Instant, out: &mut Outbox) {
        if !self.armed || !self.landed {
            return;
        }
        let prflt = self.params.get(Param::COM_DISARM_PRFLT);
        let land = self.params.get(Param::COM_DISARM_LAND);
        if !self.took_off {
            if prflt > 0.0 && now.saturating_duration_since(self.armed_at).as_secs_f64() >= prflt {
                self.disarm(now, "Disarmed by auto preflight disarming", out);
            }
        } else if let Some(at) = self.landed_at
            && land > 0.0
            && now.saturating_duration_since(at).as_secs_f64() >= land
        {
            self.disarm(now, "Disarmed by landing", out);
        }
    }
}
