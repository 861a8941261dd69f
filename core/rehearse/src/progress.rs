//! How far a rehearsal has got, readable from another thread while it runs.

use std::sync::atomic::{AtomicU64, Ordering};

/// The mission time a running rehearsal has flown, seconds (0 before the mission starts).
/// Written by the rehearsal's thread at every control period, read by anyone.
#[derive(Debug, Default)]
pub struct Progress {
    /// `f64` bits of the mission seconds flown.
    mission_s_bits: AtomicU64,
}

impl Progress {
    /// Mission seconds flown so far.
    pub fn mission_s(&self) -> f64 {
        f64::from_bits(self.mission_s_bits.load(Ordering::Relaxed))
    }

    /// Records `s` mission seconds flown.
    pub(crate) fn set_mission_s(&self, s: f64) {
        self.mission_s_bits.store(s.to_bits(), Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mission_seconds_read_back_as_written() {
        let p = Progress::default();
        assert_eq!(p.mission_s(), 0.0);
        p.set_mission_s(12.5);
        assert_eq!(p.mission_s(), 12.5);
    }
}
