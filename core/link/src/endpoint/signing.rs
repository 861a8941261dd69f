//! Per-vehicle MAVLink 2 signing of an endpoint: the configured key and link id
//! ([`SigningSpec`]), which sysids sign, and the counters summed over them.

use super::Endpoint;
use skein_mavlink::signing::{LinkSigning, SigningCounts};
use std::collections::HashMap;
use std::sync::Arc;

/// MAVLink 2 signing of one vehicle's link, as configured (`signing_key_file`,
/// `signing_link_id`); installed with [`Endpoint::set_signing`].
#[derive(Debug, Clone, PartialEq)]
pub struct SigningSpec {
    /// The secret key shared with the vehicle.
    pub key: skein_mavlink::signing::SigningKey,
    /// The link id our signed frames carry (MAVLink's channel number; default 0).
    pub link_id: u8,
}

impl SigningSpec {
    /// The signing state to install on an endpoint.
    pub fn signing(&self) -> Arc<LinkSigning> {
        Arc::new(LinkSigning::new(self.key.clone(), self.link_id))
    }
}

/// Which vehicles of an endpoint sign, and with what.
#[derive(Default)]
pub(super) struct SigningTable {
    /// For every sysid without its own entry.
    default: Option<Arc<LinkSigning>>,
    by_sysid: HashMap<u8, Arc<LinkSigning>>,
}

impl SigningTable {
    pub(super) fn get(&self, sysid: u8) -> Option<&Arc<LinkSigning>> {
        self.by_sysid.get(&sysid).or(self.default.as_ref())
    }
}

impl Endpoint {
    /// Requires MAVLink 2 signing of vehicle `sysid` (`None`: of every vehicle of this
    /// endpoint without its own entry): frames to it are signed with `signing`, and its
    /// frames are accepted only with a valid, fresh signature (PX4's unsigned exceptions
    /// RADIO_STATUS, ADSB_VEHICLE and COLLISION aside); the others are counted and dropped.
    pub fn set_signing(&self, sysid: Option<u8>, signing: Arc<LinkSigning>) {
        let mut t = self.signing.write().expect("signing lock");
        match sysid {
            Some(s) => {
                t.by_sysid.insert(s, signing);
            }
            None => t.default = Some(signing),
        }
    }

    /// The signing of vehicle `sysid`, if it signs.
    pub fn signing_of(&self, sysid: u8) -> Option<Arc<LinkSigning>> {
        self.signing
            .read()
            .expect("signing lock")
            .get(sysid)
            .cloned()
    }

    /// Signing counters summed over this endpoint's signing vehicles; `None` when none
    /// signs.
    pub fn signing_counts(&self) -> Option<SigningCounts> {
        let t = self.signing.read().expect("signing lock");
        let mut all: Vec<&Arc<LinkSigning>> = Vec::new();
        for s in t.default.iter().chain(t.by_sysid.values()) {
            if !all.iter().any(|a| Arc::ptr_eq(a, s)) {
                all.push(s);
            }
        }
        if all.is_empty() {
            return None;
        }
        let mut total = SigningCounts::default();
        for s in all {
            total.add(&s.counts());
        }
        Some(total)
    }
}
