//! MAVLink 2 signing of one simulated vehicle, as PX4 v1.16 does it
//! (`src/modules/mavlink/mavlink_sign_control.cpp`):
//!
//! - `MAV_SIGN_CFG` says when signing is required: 0 never (unsigned frames accepted;
//!   signed ones still checked once a key is installed), 1 on every link but USB, 2 on
//!   every link. The simulator's links are UDP, never USB, so 1 and 2 behave alike.
//!   `skein sim --signing-key-file FILE` installs the key and sets `MAV_SIGN_CFG` 2.
//! - Where signing is required, unsigned, badly signed and replayed frames are dropped
//!   before the vehicle sees them (and counted in `SimVehicleStats::signing`), except
//!   RADIO_STATUS, ADSB_VEHICLE and COLLISION, which PX4 accepts unsigned. Without a key
//!   every unsigned frame is dropped: PX4 then only listens on USB, so over UDP a vehicle
//!   that requires signing and has no key cannot be provisioned at all.
//! - `SETUP_SIGNING` installs or replaces the key (and starts the signing clock at its
//!   `initial_timestamp`); a blank key with timestamp 0 clears it. Like any other frame it
//!   only gets through the check above: on a link that requires signing it must be
//!   signed with the current key. PX4 handles it whatever its `target_system`.
//! - Once a key is installed every frame the vehicle sends is signed (link id 0: the
//!   vehicle's only MAVLink instance). The key survives a reboot, as PX4's key file does.

use skein_mavlink::MavMessage;
use skein_mavlink::signing::{
    LinkSigning, PX4_UNSIGNED_OK, SigningCounts, SigningKey, frame_msgid, is_signed,
};
use std::sync::Arc;

/// The link id a simulated vehicle signs with (PX4: its MAVLink instance number).
pub const SIM_LINK_ID: u8 = 0;

/// Signing state of one vehicle.
#[derive(Debug, Default)]
pub(crate) struct SimSigning {
    /// The installed key, if any.
    pub current: Option<Arc<LinkSigning>>,
    /// Counts of keys replaced since, and unsigned frames dropped while no key was set.
    base: SigningCounts,
    /// The live key's counts at the last reset.
    baseline: SigningCounts,
}

impl SimSigning {
    /// Signing with `key` from the start.
    pub fn with_key(key: Option<SigningKey>) -> Self {
        SimSigning {
            current: key.map(|k| Arc::new(LinkSigning::new(k, SIM_LINK_ID))),
            ..SimSigning::default()
        }
    }

    /// Whether to hand `raw` (one decoded frame's bytes) to the vehicle, given
    /// `MAV_SIGN_CFG` (`required` when non-zero). Counts what it drops.
    pub fn accept(&mut self, raw: &[u8], required: bool) -> bool {
        match (&self.current, required) {
            (Some(s), true) => s.accept(raw, PX4_UNSIGNED_OK),
            // Not required: unsigned frames pass; signed ones must still verify (the MAVLink
            // C library checks every signed frame once signing is set up).
            (Some(s), false) => !is_signed(raw) || s.accept(raw, &[]),
            (None, true) => {
                let unsigned_ok = PX4_UNSIGNED_OK.contains(&frame_msgid(raw));
                if !unsigned_ok {
                    self.base.unsigned += 1;
                }
                unsigned_ok
            }
            (None, false) => true,
        }
    }

    /// Handles `SETUP_SIGNING` (any other message: `false`). Returns true when the key
    /// changed, so the caller re-arms its encoder with [`SimSigning::current`].
    pub fn on_message(&mut self, msg: &MavMessage) -> bool {
        let MavMessage::SETUP_SIGNING(s) = msg else {
            return false;
        };
        self.base.add(&self.live());
        self.baseline = SigningCounts::default();
        self.current = None;
        let key = SigningKey::from_bytes(s.secret_key);
        if !(key.is_blank() && s.initial_timestamp == 0) {
            let signing = LinkSigning::new(key, SIM_LINK_ID);
            signing.advance_clock(s.initial_timestamp);
            self.current = Some(Arc::new(signing));
        }
        true
    }

    /// Counters since start or the last [`SimSigning::reset_counts`].
    pub fn counts(&self) -> SigningCounts {
        let mut c = self.base;
        c.add(&self.live());
        c
    }

    /// Clears the counters (the key and its replay state stay).
    pub fn reset_counts(&mut self) {
        self.base = SigningCounts::default();
        self.baseline = self
            .current
            .as_ref()
            .map(|s| s.counts())
            .unwrap_or_default();
    }

    /// The live key's counts since the baseline.
    fn live(&self) -> SigningCounts {
        let Some(s) = &self.current else {
            return SigningCounts::default();
        };
        let (c, b) = (s.counts(), self.baseline);
        SigningCounts {
            signed_ok: c.signed_ok.saturating_sub(b.signed_ok),
            unsigned: c.unsigned.saturating_sub(b.unsigned),
            bad_signature: c.bad_signature.saturating_sub(b.bad_signature),
            replayed: c.replayed.saturating_sub(b.replayed),
            too_old: c.too_old.saturating_sub(b.too_old),
            frames_signed: c.frames_signed.saturating_sub(b.frames_signed),
        }
    }
}
