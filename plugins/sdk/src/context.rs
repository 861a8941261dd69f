//! [`Context`]: the host services a plugin instance may use during a call.

use crate::abi::{HostApi, RawBytes, RawSink, log_level, status};
use crate::vehicle::Vehicle;
use serde_json::Value;
use skein_mavlink::{Encoder, MavMessage};

/// The host services of one plugin instance: its vehicle and the swarm, MAVLink to its
/// vehicle, events, its published state, the state of its vehicle's other payloads, video
/// frames, and the simulated link.
///
/// A context is lent to each call of [`crate::Plugin`] and cannot be kept or sent to another
/// thread: host services are available only while the host is calling the instance (that
/// is what lets the same plugin run in-process or in a `skein plugin-host` child process,
/// where each service is a message to the parent).
pub struct Context<'a> {
    api: &'a HostApi,
}

fn status_error(status: u32, out: Vec<u8>, service: &str) -> String {
    let text = String::from_utf8_lossy(&out).into_owned();
    if status == status::PANIC {
        format!("host service `{service}` panicked: {text}")
    } else {
        text
    }
}

impl<'a> Context<'a> {
    /// Wraps the host's services.
    ///
    /// # Safety
    /// `api` must be the [`HostApi`] the host passed to `create` for this instance, valid
    /// for `'a` (the duration of the current call).
    #[doc(hidden)]
    pub unsafe fn from_raw(api: *const HostApi) -> Option<Context<'a>> {
        // SAFETY: guaranteed by the caller.
        unsafe { api.as_ref() }.map(|api| Context { api })
    }

    /// Calls a host service that writes its output to a sink.
    fn with_out(
        &self,
        service: &str,
        call: impl FnOnce(RawSink) -> u32,
    ) -> Result<Vec<u8>, String> {
        let mut out = Vec::new();
        let st = call(RawSink::for_vec(&mut out));
        if st == status::OK {
            Ok(out)
        } else {
            Err(status_error(st, out, service))
        }
    }

    /// The vehicle's id (`"uav-1"`).
    pub fn vehicle_id(&self) -> String {
        let api = self.api;
        // SAFETY: `api` is valid for this call (see `from_raw`); the sink lives until the
        // callback returns.
        self.with_out("vehicle_id", |out| unsafe {
            (api.vehicle_id)(api.ctx, out)
        })
        .map(|b| String::from_utf8_lossy(&b).into_owned())
        .unwrap_or_default()
    }

    /// The vehicle's snapshot as the host sent it (the JSON of `GET /api/v1/vehicles/{id}`).
    ///
    /// # Errors
    /// When the host failed to produce it or sent invalid JSON.
    pub fn vehicle_json(&self) -> Result<Value, String> {
        let api = self.api;
        // SAFETY: as in `vehicle_id`.
        let bytes = self.with_out("vehicle", |out| unsafe { (api.vehicle)(api.ctx, out) })?;
        serde_json::from_slice(&bytes).map_err(|e| format!("host sent an invalid vehicle: {e}"))
    }

    /// The vehicle's snapshot, typed.
    ///
    /// # Errors
    /// As [`Context::vehicle_json`], or when the snapshot does not have the documented
    /// shape.
    pub fn vehicle(&self) -> Result<Vehicle, String> {
        serde_json::from_value(self.vehicle_json()?)
            .map_err(|e| format!("host sent a vehicle of an unexpected shape: {e}"))
    }

    /// Every vehicle of the swarm (including this one), typed.
    ///
    /// # Errors
    /// When the host failed to produce the list or sent an unexpected shape.
    pub fn swarm(&self) -> Result<Vec<Vehicle>, String> {
        let api = self.api;
        // SAFETY: as in `vehicle_id`.
        let bytes = self.with_out("swarm", |out| unsafe { (api.swarm)(api.ctx, out) })?;
        serde_json::from_slice(&bytes).map_err(|e| format!("host sent an invalid swarm: {e}"))
    }

    /// True when the vehicle is simulated (the payload should then simulate its device).
    pub fn simulated(&self) -> bool {
        // SAFETY: `api` is valid for this call.
        unsafe { (self.api.simulated)(self.api.ctx) == 1 }
    }

    /// Sends a MAVLink message (common dialect) to the vehicle's system, from skein's
    /// identity on the vehicle's link. Target fields are the caller's business (use
    /// [`Vehicle::sysid`]).
    ///
    /// # Errors
    /// When the link cannot send (no address yet, socket full) or the host is gone.
    pub fn send_mavlink(&self, msg: &MavMessage) -> Result<(), String> {
        let frame = Encoder::new(0, 0).encode(msg);
        let api = self.api;
        // SAFETY: `api` valid for this call; `frame` outlives the callback.
        self.with_out("send_mavlink", |err| unsafe {
            (api.send_mavlink)(api.ctx, RawBytes::from_slice(frame.as_bytes()), err)
        })
        .map(|_| ())
    }

    /// Raises an event on skein's stream (`{"type": "payload_event", "kind": kind, "data":
    /// data}`).
    ///
    /// # Errors
    /// When the host refused it.
    pub fn emit_event(&self, kind: &str, data: &Value) -> Result<(), String> {
        let json = serde_json::to_vec(data).map_err(|e| e.to_string())?;
        let api = self.api;
        // SAFETY: `api` valid for this call; `kind` and `json` outlive the callback.
        self.with_out("emit_event", |err| unsafe {
            (api.emit_event)(
                api.ctx,
                RawBytes::from_slice(kind.as_bytes()),
                RawBytes::from_slice(&json),
                err,
            )
        })
        .map(|_| ())
    }

    /// Publishes the instance's state (a JSON object; replaces the previous one). Shown by
    /// `GET /api/v1/vehicles/{id}/payloads` and readable by the vehicle's other payloads.
    ///
    /// # Errors
    /// When the host refused it.
    pub fn publish_state(&self, state: &Value) -> Result<(), String> {
        let json = serde_json::to_vec(state).map_err(|e| e.to_string())?;
        let api = self.api;
        // SAFETY: `api` valid for this call; `json` outlives the callback.
        self.with_out("publish_state", |err| unsafe {
            (api.publish_state)(api.ctx, RawBytes::from_slice(&json), err)
        })
        .map(|_| ())
    }

    /// The state the payload in `slot` of the same vehicle last published (a camera reads
    /// the gimbal's angles), `None` when it has published nothing.
    ///
    /// # Errors
    /// When the host failed or sent invalid JSON.
    pub fn payload_state(&self, slot: &str) -> Result<Option<Value>, String> {
        let api = self.api;
        // SAFETY: `api` valid for this call; `slot` outlives the callback.
        let bytes = self.with_out("payload_state", |out| unsafe {
            (api.payload_state)(api.ctx, RawBytes::from_slice(slot.as_bytes()), out)
        })?;
        if bytes.is_empty() {
            return Ok(None);
        }
        let v: Value = serde_json::from_slice(&bytes)
            .map_err(|e| format!("host sent an invalid state for slot `{slot}`: {e}"))?;
        Ok((!v.is_null()).then_some(v))
    }

    /// Publishes one video frame (a baseline JPEG image) on the vehicle's camera stream.
    ///
    /// # Errors
    /// When the host refused it.
    pub fn publish_frame(&self, jpeg: &[u8]) -> Result<(), String> {
        let api = self.api;
        // SAFETY: `api` valid for this call; `jpeg` outlives the callback.
        self.with_out("publish_frame", |err| unsafe {
            (api.publish_frame)(api.ctx, RawBytes::from_slice(jpeg), err)
        })
        .map(|_| ())
    }

    /// Degrades (or, with `(0.0, 0.0)`, restores) the simulated radio link of the vehicle:
    /// `loss_fraction` of datagrams dropped (0..1), `latency_ms` of one-way delay added.
    /// Returns true when a simulator applied it (false for a real vehicle).
    pub fn set_simulated_link(&self, loss_fraction: f64, latency_ms: f64) -> bool {
        // SAFETY: `api` valid for this call.
        unsafe { (self.api.set_simulated_link)(self.api.ctx, loss_fraction, latency_ms) == 1 }
    }

    /// The simulated non-cooperative aircraft (intruders) of the simulator this vehicle
    /// flies in, swarm-frame NED: what a simulated camera draws besides the swarm. Empty
    /// for a real vehicle or a simulation without intruders. Never use it for detection:
    /// it is the simulator's truth.
    ///
    /// # Errors
    /// When the host failed or sent an unexpected shape.
    pub fn sim_aircraft(&self) -> Result<Vec<crate::vehicle::SimAircraft>, String> {
        let api = self.api;
        // SAFETY: as in `vehicle_id`.
        let bytes = self.with_out("sim_aircraft", |out| unsafe {
            (api.sim_aircraft)(api.ctx, out)
        })?;
        serde_json::from_slice(&bytes)
            .map_err(|e| format!("host sent invalid simulated aircraft: {e}"))
    }

    /// The latest video frame (a JPEG image) the payload in `slot` of the same vehicle
    /// published (a detector reads the camera's), `None` when it has published none.
    ///
    /// # Errors
    /// When the host failed.
    pub fn payload_frame(&self, slot: &str) -> Result<Option<Vec<u8>>, String> {
        let api = self.api;
        // SAFETY: `api` valid for this call; `slot` outlives the callback.
        let bytes = self.with_out("payload_frame", |out| unsafe {
            (api.payload_frame)(api.ctx, RawBytes::from_slice(slot.as_bytes()), out)
        })?;
        Ok((!bytes.is_empty()).then_some(bytes))
    }

    fn log(&self, level: u32, message: &str) {
        // SAFETY: `api` valid for this call; `message` outlives the callback.
        unsafe {
            (self.api.log)(
                self.api.ctx,
                level,
                RawBytes::from_slice(message.as_bytes()),
            )
        }
    }

    /// Logs an error line into skein's log, attributed to this instance.
    pub fn log_error(&self, message: &str) {
        self.log(log_level::ERROR, message)
    }

    /// Logs a warning.
    pub fn log_warn(&self, message: &str) {
        self.log(log_level::WARN, message)
    }

    /// Logs an information line.
    pub fn log_info(&self, message: &str) {
        self.log(log_level::INFO, message)
    }

    /// Logs a debugging line.
    pub fn log_debug(&self, message: &str) {
        self.log(log_level::DEBUG, message)
    }
}
