//! [`GroundStation`]: what a ground station does with a simulated vehicle (commands,
//! modes, arming, parameters, waiting for telemetry), written once over two primitives,
//! sending a message and reading the next frame before a deadline, so the same steps
//! run over real UDP ([`super::Client`]) and on the virtual clock
//! ([`super::VirtualClient`]).

use skein_mavlink::dialect::*;
use skein_mavlink::{CommandTarget, Frame, MavMessage, command_long};
use skein_model::px4::Px4Mode;
use skein_sim::client;
use std::time::{Duration, Instant};

/// A MAVLink ground station talking to one simulated vehicle.
// The trait is private to each test binary: no caller needs its futures to be `Send`.
#[allow(async_fn_in_trait)]
pub trait GroundStation {
    /// The vehicle's system id (`target_system` of what is sent).
    fn sysid(&self) -> u8;

    /// The station's clock: wall time over UDP, the vehicle's clock in virtual time.
    fn now(&self) -> Instant;

    /// Sends `msg` to the vehicle.
    async fn send(&mut self, msg: &MavMessage);

    /// The next frame from the vehicle, or `None` once `deadline` (on [`Self::now`]'s
    /// clock) has passed.
    async fn next(&mut self, deadline: Instant) -> Option<Frame>;

    /// Waits up to `timeout` for a frame `pred` maps to a value; other frames are
    /// dropped.
    async fn wait_for<T>(
        &mut self,
        timeout: Duration,
        mut pred: impl FnMut(&Frame) -> Option<T>,
    ) -> Option<T> {
        let deadline = self.now() + timeout;
        while let Some(f) = self.next(deadline).await {
            if let Some(t) = pred(&f) {
                return Some(t);
            }
        }
        None
    }

    /// Sends `request` and returns what `reply` picks out of the first frame it matches
    /// within 2 s; panics naming `what` otherwise.
    async fn request<T>(
        &mut self,
        request: &MavMessage,
        what: &str,
        reply: impl FnMut(&MavMessage) -> Option<T>,
    ) -> T {
        let mut reply = reply;
        self.send(request).await;
        self.wait_for(Duration::from_secs(2), |f| reply(&f.msg))
            .await
            .unwrap_or_else(|| panic!("no {what}"))
    }

    /// A HEARTBEAT of `mavtype` (GCS, onboard controller...).
    async fn heartbeat(&mut self, mavtype: MavType) {
        self.send(&client::heartbeat(mavtype)).await;
    }

    /// COMMAND_LONG `command` to the vehicle's autopilot (component 1).
    fn command_long_msg(&self, command: MavCmd, p: [f32; 7], confirmation: u8) -> MavMessage {
        command_long(
            CommandTarget::new(self.sysid(), 1),
            command,
            p,
            confirmation,
        )
    }

    /// Sends a COMMAND_LONG and returns the first COMMAND_ACK for it (within 3 s).
    async fn command(&mut self, command: MavCmd, p: [f32; 7]) -> MavResult {
        let msg = self.command_long_msg(command, p, 0);
        self.send(&msg).await;
        self.wait_ack(command, Duration::from_secs(3))
            .await
            .unwrap_or_else(|| panic!("no COMMAND_ACK for {command:?}"))
    }

    /// The result of the next COMMAND_ACK for `command`, within `timeout`.
    async fn wait_ack(&mut self, command: MavCmd, timeout: Duration) -> Option<MavResult> {
        self.wait_for(timeout, |f| match &f.msg {
            MavMessage::COMMAND_ACK(a) if a.command == command => Some(a.result),
            _ => None,
        })
        .await
    }

    /// DO_SET_MODE; returns both ACKs PX4 sends.
    async fn set_mode(&mut self, mode: Px4Mode) -> (MavResult, MavResult) {
        self.send(&set_mode_msg(self.sysid(), mode)).await;
        let first = self
            .wait_ack(MavCmd::MAV_CMD_DO_SET_MODE, Duration::from_secs(3))
            .await
            .expect("first ACK");
        let second = self
            .wait_ack(MavCmd::MAV_CMD_DO_SET_MODE, Duration::from_secs(3))
            .await
            .expect("second ACK");
        (first, second)
    }

    /// COMPONENT_ARM_DISARM (not forced).
    async fn arm(&mut self, arm: bool) -> MavResult {
        self.command(
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            [if arm { 1.0 } else { 0.0 }, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        )
        .await
    }

    /// PARAM_SET; returns the PARAM_VALUEs for `name` that answer it within 2 s (PX4
    /// sends two).
    async fn param_set(
        &mut self,
        name: &str,
        value: f32,
        param_type: MavParamType,
    ) -> Vec<PARAM_VALUE_DATA> {
        let sysid = self.sysid();
        self.send(&MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: value,
            target_system: sysid,
            target_component: 1,
            param_id: name.into(),
            param_type,
        }))
        .await;
        let mut got = Vec::new();
        let deadline = self.now() + Duration::from_secs(2);
        while got.len() < 2 {
            let Some(f) = self.next(deadline).await else {
                break;
            };
            if let MavMessage::PARAM_VALUE(v) = f.msg
                && v.param_id.to_str().ok() == Some(name)
            {
                got.push(v);
            }
        }
        got
    }

    /// Sets a REAL32 parameter and checks the answer.
    async fn param_set_f32(&mut self, name: &str, value: f32) {
        let got = self
            .param_set(name, value, MavParamType::MAV_PARAM_TYPE_REAL32)
            .await;
        assert!(!got.is_empty(), "no PARAM_VALUE for {name}");
        assert_eq!(got[0].param_value, value, "{name}");
    }

    /// Sets an INT32 parameter (bytewise in the float) and checks the answer.
    async fn param_set_i32(&mut self, name: &str, value: i32) {
        let got = self
            .param_set(
                name,
                f32::from_bits(value as u32),
                MavParamType::MAV_PARAM_TYPE_INT32,
            )
            .await;
        assert!(!got.is_empty(), "no PARAM_VALUE for {name}");
        assert_eq!(got[0].param_value.to_bits() as i32, value, "{name}");
    }

    /// Waits for an autopilot HEARTBEAT satisfying `pred`.
    async fn wait_heartbeat(
        &mut self,
        timeout: Duration,
        mut pred: impl FnMut(&HEARTBEAT_DATA) -> bool,
    ) -> Option<HEARTBEAT_DATA> {
        self.wait_for(timeout, |f| {
            autopilot_heartbeat(f).filter(|h| pred(h)).cloned()
        })
        .await
    }

    /// True once a HEARTBEAT reports `mode` within `timeout`.
    async fn wait_mode(&mut self, mode: Px4Mode, timeout: Duration) -> bool {
        self.wait_heartbeat(timeout, |h| h.custom_mode == mode.custom_mode())
            .await
            .is_some()
    }

    /// True once a HEARTBEAT reports the armed flag `armed` within `timeout`.
    async fn wait_armed(&mut self, armed: bool, timeout: Duration) -> bool {
        self.wait_heartbeat(timeout, |h| {
            h.base_mode
                .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED)
                == armed
        })
        .await
        .is_some()
    }

    /// Waits for LOCAL_POSITION_NED satisfying `pred`; returns it.
    async fn wait_local(
        &mut self,
        timeout: Duration,
        mut pred: impl FnMut(&LOCAL_POSITION_NED_DATA) -> bool,
    ) -> Option<LOCAL_POSITION_NED_DATA> {
        self.wait_for(timeout, |f| match &f.msg {
            MavMessage::LOCAL_POSITION_NED(p) if pred(p) => Some(p.clone()),
            _ => None,
        })
        .await
    }

    /// Waits until the vehicle reports a home position (EKF has a fix), within 5 s.
    async fn wait_home(&mut self) -> HOME_POSITION_DATA {
        self.wait_for(Duration::from_secs(5), |f| match &f.msg {
            MavMessage::HOME_POSITION(h) => Some(h.clone()),
            _ => None,
        })
        .await
        .expect("HOME_POSITION")
    }
}

/// The HEARTBEAT in `f` when it is the autopilot's (component 1).
fn autopilot_heartbeat(f: &Frame) -> Option<&HEARTBEAT_DATA> {
    match &f.msg {
        MavMessage::HEARTBEAT(h) if f.compid == 1 => Some(h),
        _ => None,
    }
}

/// DO_SET_MODE to PX4 `mode` for `sysid` (PX4's custom main / sub mode in params 2, 3).
pub fn set_mode_msg(sysid: u8, mode: Px4Mode) -> MavMessage {
    let (main, sub) = mode.main_sub();
    command_long(
        CommandTarget::new(sysid, 1),
        MavCmd::MAV_CMD_DO_SET_MODE,
        [1.0, f32::from(main), f32::from(sub), 0.0, 0.0, 0.0, 0.0],
        0,
    )
}
