//! Corrections relayed between the processes of a distributed swarm (the DDS side is
//! `skein_dds::rtcm`, the topic `/skein/rtcm`): the active coordinator publishes every
//! good frame of its own source ([`crate::RtkService::tap`]), and an agent without a
//! source of its own takes the frames as its source ([`crate::RtkService::relayed`]):
//! each sample is framed and checked by the same [`RtcmFramer`] as a source's bytes, and
//! its frames go to the vehicles through the same hub (cap, pacing, counters). What the
//! process does with the topic, and what it counted, is the status's [`RelayStatus`].

use crate::framer::{Frame, FramerCounts, RtcmFramer};
use serde::Serialize;
use std::sync::{Mutex, MutexGuard, PoisonError};

/// The source an agent's status shows for relayed corrections: `dds:` and the topic
/// (`dds:/skein/rtcm`).
pub fn source_name(topic: &str) -> String {
    format!("dds:{topic}")
}

/// What this process does with the relay topic.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum RelayRole {
    /// The active coordinator (or `skein up --dds`): every good frame of its source is
    /// published on the topic.
    Publishing,
    /// A standby coordinator: its source stays connected, its frames are published once
    /// it is active.
    Standby,
    /// An agent without a source of its own: the topic is its source.
    Receiving,
    /// An agent with a source of its own (`[rtk]`, `PUT /api/v1/rtk`): the topic is
    /// ignored while it has one.
    Ignoring,
}

/// The relay in `GET /api/v1/rtk` (`relay`; `null` in a process without DDS).
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct RelayStatus {
    /// The ROS 2 topic (`/skein/rtcm`, `rtcm_msgs/Message`).
    pub topic: String,
    /// What this process does with it.
    pub role: RelayRole,
    /// Frames of this process's source published on the topic.
    pub published: u64,
    /// Frames of this process's source that should have been published and were not (a
    /// failed write, or the publisher fell behind the source).
    pub publish_failures: u64,
    /// Samples received from the topic.
    pub received: u64,
    /// Samples received with no good RTCM3 frame (dropped; their bytes count as
    /// `garbage_bytes`, bad CRCs as `crc_failures`).
    pub malformed: u64,
    /// Samples received while this process had a source of its own (not used).
    pub ignored: u64,
}

/// What became of one relayed sample ([`crate::RtkService::relayed`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Relayed {
    /// Its good frames (how many) went to the vehicles.
    Delivered(usize),
    /// Not used: this process has a source of its own, or takes no relayed frames.
    Ignored,
    /// No good RTCM3 frame in it: counted and dropped.
    Malformed,
}

/// The relay's state in a corrections service: its status, and the framer of the
/// relayed samples.
#[derive(Debug, Default)]
pub(crate) struct Relay {
    state: Mutex<RelayState>,
}

#[derive(Debug, Default)]
struct RelayState {
    status: Option<RelayStatus>,
    framer: RtcmFramer,
}

impl Relay {
    fn lock(&self) -> MutexGuard<'_, RelayState> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The status now (`None` before the process said what it does with a topic).
    pub(crate) fn status(&self) -> Option<RelayStatus> {
        self.lock().status.clone()
    }

    /// This process plays `role` on `topic` from now on (the counts go on).
    pub(crate) fn set_role(&self, topic: &str, role: RelayRole) {
        let mut s = self.lock();
        match &mut s.status {
            Some(st) => {
                st.topic = topic.to_string();
                st.role = role;
            }
            None => {
                s.status = Some(RelayStatus {
                    topic: topic.to_string(),
                    role,
                    published: 0,
                    publish_failures: 0,
                    received: 0,
                    malformed: 0,
                    ignored: 0,
                });
            }
        }
    }

    /// The topic this process receives from, whether or not it uses it now.
    pub(crate) fn receiving_topic(&self) -> Option<String> {
        self.lock()
            .status
            .as_ref()
            .filter(|s| matches!(s.role, RelayRole::Receiving | RelayRole::Ignoring))
            .map(|s| s.topic.clone())
    }

    /// Forgets a partial frame and the counts of relayed samples' bytes: the relay
    /// becomes the source afresh.
    pub(crate) fn restart_framing(&self) {
        self.lock().framer = RtcmFramer::default();
    }

    /// Counts `frames` published and `failures` not.
    pub(crate) fn count_published(&self, frames: u64, failures: u64) {
        if let Some(s) = &mut self.lock().status {
            s.published += frames;
            s.publish_failures += failures;
        }
    }

    /// A sample received while the topic is not this process's source.
    pub(crate) fn count_ignored(&self) {
        if let Some(s) = &mut self.lock().status {
            s.received += 1;
            s.ignored += 1;
        }
    }

    /// Frames a received sample's `bytes` (a sample is whole: a partial frame at its end
    /// is garbage, not the start of the next sample's); the good frames and the framer's
    /// counts since the relay became the source. A sample without a good frame is counted
    /// as malformed.
    pub(crate) fn frame(&self, bytes: &[u8]) -> (Vec<Frame>, FramerCounts) {
        let mut s = self.lock();
        let frames = s.framer.push(bytes);
        s.framer.reset();
        let counts = s.framer.counts().clone();
        if let Some(st) = &mut s.status {
            st.received += 1;
            if frames.is_empty() {
                st.malformed += 1;
            }
        }
        (frames, counts)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::frame_of;

    #[test]
    fn a_sample_is_framed_whole_and_one_without_a_good_frame_is_malformed() {
        let relay = Relay::default();
        relay.set_role("/skein/rtcm", RelayRole::Receiving);
        let good = frame_of(1074, 200);
        let (frames, _) = relay.frame(&good);
        assert_eq!(frames.len(), 1);
        assert_eq!(frames[0].bytes, good);
        // A sample cut short: its start does not wait for the next sample.
        let (frames, counts) = relay.frame(&good[..100]);
        assert!(frames.is_empty());
        assert_eq!(counts.garbage_bytes, 100);
        let mut corrupt = good.clone();
        corrupt[60] ^= 0x10;
        let (frames, counts) = relay.frame(&corrupt);
        assert!(frames.is_empty());
        assert_eq!(counts.crc_failures, 1);
        let (frames, _) = relay.frame(&good);
        assert_eq!(frames.len(), 1, "the next good sample is taken");
        let s = relay.status().unwrap();
        assert_eq!((s.received, s.malformed), (4, 2), "{s:?}");
        assert_eq!(relay.receiving_topic().as_deref(), Some("/skein/rtcm"));
        relay.set_role("/skein/rtcm", RelayRole::Publishing);
        assert_eq!(relay.receiving_topic(), None);
    }
}
