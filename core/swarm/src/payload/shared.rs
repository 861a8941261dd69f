//! What a payload published, kept across restarts of its actor and shown by the API: its
//! spec, its state, its last video frame, which library serves it, and whether it waits
//! for a plugin.

use skein_payload::{PayloadSpec, PayloadState, ServedBy};
use std::sync::{Arc, PoisonError, RwLock};
use tokio::sync::watch;

/// What a payload published, kept across restarts of its actor.
pub struct PayloadShared {
    /// The payload's spec (slot, kind, plugin, config).
    pub spec: PayloadSpec,
    pub(super) state: RwLock<Option<PayloadState>>,
    pub(super) frame: watch::Sender<Option<Arc<Vec<u8>>>>,
    pub(super) frames: std::sync::atomic::AtomicU64,
    served_by: RwLock<Option<ServedBy>>,
    waiting: RwLock<Option<String>>,
}

impl std::fmt::Debug for PayloadShared {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PayloadShared")
            .field("slot", &self.spec.slot)
            .finish_non_exhaustive()
    }
}

impl PayloadShared {
    /// Nothing published yet.
    pub fn new(spec: PayloadSpec) -> Arc<Self> {
        Arc::new(PayloadShared {
            spec,
            state: RwLock::new(None),
            frame: watch::channel(None).0,
            frames: std::sync::atomic::AtomicU64::new(0),
            served_by: RwLock::new(None),
            waiting: RwLock::new(None),
        })
    }

    /// The library (and generation) running the current driver; `None` while no driver
    /// exists.
    pub fn served_by(&self) -> Option<ServedBy> {
        self.served_by
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// Records which library runs the driver (`None` once it is dropped).
    pub(crate) fn set_served_by(&self, by: Option<ServedBy>) {
        *self
            .served_by
            .write()
            .unwrap_or_else(PoisonError::into_inner) = by;
    }

    /// Why the slot waits for a plugin (naming the kind), if it does.
    pub fn waiting(&self) -> Option<String> {
        self.waiting
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// Marks the slot waiting for a plugin (`Some(why)`) or not.
    pub(crate) fn set_waiting(&self, why: Option<String>) {
        *self.waiting.write().unwrap_or_else(PoisonError::into_inner) = why;
    }

    /// The last published state.
    pub fn state(&self) -> Option<PayloadState> {
        self.state
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// Keeps the driver's latest state (`PayloadHost::publish_state`).
    pub(crate) fn publish_state(&self, state: PayloadState) {
        *self.state.write().unwrap_or_else(PoisonError::into_inner) = Some(state);
    }

    /// Keeps the driver's latest video frame, JPEG, and wakes the frame streams
    /// (`PayloadHost::publish_frame`).
    pub(crate) fn publish_frame(&self, jpeg: Vec<u8>) {
        self.frames
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.frame.send_replace(Some(Arc::new(jpeg)));
    }

    /// The last published video frame (JPEG).
    pub fn frame(&self) -> Option<Arc<Vec<u8>>> {
        self.frame.borrow().clone()
    }

    /// A receiver that wakes at every new frame (MJPEG streaming).
    pub fn subscribe_frames(&self) -> watch::Receiver<Option<Arc<Vec<u8>>>> {
        self.frame.subscribe()
    }

    /// Frames published so far.
    pub fn frames_published(&self) -> u64 {
        self.frames.load(std::sync::atomic::Ordering::Relaxed)
    }
}
