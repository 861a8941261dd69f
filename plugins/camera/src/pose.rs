//! The vehicle's and gimbal's recent poses, for frames captured before the camera reads
//! them: a real camera's frame reaches skein tens of milliseconds after its capture, and
//! the pose written into it (and so every bearing the detector takes from it) is the one
//! interpolated at its capture time, not the pose when it arrived.

use skein_plugin_sdk::geometry::{Ned, wrap_deg_180, wrap_deg_360};
use std::collections::VecDeque;

/// How far back poses are kept, µs (real streams arrive well within a second).
pub const HISTORY_US: u64 = 3_000_000;

/// The camera's pose at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseSample {
    /// When the pose held, wall-clock µs since the Unix epoch.
    pub stamp_us: u64,
    /// Camera (vehicle) position, swarm-frame NED, metres.
    pub position: Ned,
    /// Vehicle heading, degrees clockwise from north.
    pub heading_deg: f64,
    /// Camera pitch, degrees above the horizontal.
    pub pitch_deg: f64,
    /// Camera yaw relative to the vehicle, degrees.
    pub yaw_deg: f64,
}

/// `a + (b - a) * k` for angles in degrees, along the shorter arc.
fn lerp_deg(a: f64, b: f64, k: f64) -> f64 {
    a + wrap_deg_180(b - a) * k
}

/// Poses, oldest first, no older than [`HISTORY_US`] behind the newest.
#[derive(Debug, Clone, Default)]
pub struct PoseHistory {
    samples: VecDeque<PoseSample>,
}

impl PoseHistory {
    /// Adds a sample; one not newer than the last is ignored (telemetry that did not
    /// advance).
    pub fn push(&mut self, s: PoseSample) {
        if self
            .samples
            .back()
            .is_some_and(|b| s.stamp_us <= b.stamp_us)
        {
            return;
        }
        self.samples.push_back(s);
        while self
            .samples
            .front()
            .is_some_and(|f| s.stamp_us - f.stamp_us > HISTORY_US)
        {
            self.samples.pop_front();
        }
    }

    /// The pose at `stamp_us`, interpolated between the samples around it (heading and
    /// yaw along the shorter arc), or the nearest end of the history outside it; and how
    /// far, µs, the answer is from a sample that bounds it (0 inside the history).
    /// `None` before the first sample.
    pub fn at(&self, stamp_us: u64) -> Option<(PoseSample, u64)> {
        let first = self.samples.front()?;
        let last = self.samples.back()?;
        if stamp_us <= first.stamp_us {
            return Some((*first, first.stamp_us - stamp_us));
        }
        if stamp_us >= last.stamp_us {
            return Some((*last, stamp_us - last.stamp_us));
        }
        let i = self.samples.partition_point(|s| s.stamp_us <= stamp_us);
        let (a, b) = (self.samples[i - 1], self.samples[i]);
        let k = (stamp_us - a.stamp_us) as f64 / (b.stamp_us - a.stamp_us) as f64;
        Some((
            PoseSample {
                stamp_us,
                position: a.position + (b.position - a.position) * k,
                heading_deg: wrap_deg_360(lerp_deg(a.heading_deg, b.heading_deg, k)),
                pitch_deg: a.pitch_deg + (b.pitch_deg - a.pitch_deg) * k,
                yaw_deg: lerp_deg(a.yaw_deg, b.yaw_deg, k),
            },
            0,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(t_ms: u64, north_m: f64, heading_deg: f64) -> PoseSample {
        PoseSample {
            stamp_us: t_ms * 1000,
            position: Ned::new(north_m, 0.0, -10.0),
            heading_deg,
            pitch_deg: -10.0,
            yaw_deg: 0.0,
        }
    }

    #[test]
    fn interpolates_between_samples_and_across_north() {
        let mut h = PoseHistory::default();
        assert!(h.at(0).is_none());
        h.push(sample(1000, 0.0, 350.0));
        h.push(sample(1040, 4.0, 10.0));
        h.push(sample(1040, 9.0, 90.0)); // not newer: ignored
        let (p, off) = h.at(1_030_000).unwrap();
        assert_eq!(off, 0);
        assert!((p.position.north_m - 3.0).abs() < 1e-9, "{p:?}");
        assert!((p.heading_deg - 5.0).abs() < 1e-9, "through north: {p:?}");
        // Outside the history: the nearest end, and how far outside.
        let (p, off) = h.at(1_100_000).unwrap();
        assert_eq!((p.position.north_m, off), (4.0, 60_000));
        let (p, off) = h.at(900_000).unwrap();
        assert_eq!((p.position.north_m, off), (0.0, 100_000));
    }

    #[test]
    fn forgets_what_is_older_than_the_history() {
        let mut h = PoseHistory::default();
        for t in 0..100 {
            h.push(sample(t * 100, t as f64, 0.0));
        }
        assert!(h.samples.len() <= 31, "{}", h.samples.len());
    }
}
