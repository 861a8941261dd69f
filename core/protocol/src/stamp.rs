//! Time on the wire: wall-clock microseconds since the Unix epoch ([`wall_us`]), the age
//! of a stamp ([`age_of`]), and how long a stamped target or report may be moved on by
//! its age ([`TARGET_EXTRAPOLATION`], [`extrapolate_target`], [`REPORT_EXTRAPOLATION`]).

use skein_model::geo::Ned;
use std::sync::atomic::{AtomicI64, Ordering};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// A skew added to this process's wall clock, µs ([`skew_wall_clock`]).
static WALL_SKEW_US: AtomicI64 = AtomicI64::new(0);

/// Wall-clock time now, microseconds since the Unix epoch (0 if the clock is before it),
/// plus the skew a test gave this process ([`skew_wall_clock`]).
pub fn wall_us() -> u64 {
    let now = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as i64);
    (now + WALL_SKEW_US.load(Ordering::Relaxed)).max(0) as u64
}

/// Skews this process's wall clock ([`wall_us`]) by `skew_ms`, as a host whose clock is
/// off would be: for tests of the clock exchange (`--test-clock-skew-ms`, hidden), never
/// for flight.
pub fn skew_wall_clock(skew_ms: i64) {
    WALL_SKEW_US.store(skew_ms.saturating_mul(1000), Ordering::Relaxed);
}

/// Longest a slot target is moved on along its velocity by its age (the formation loop
/// sends one ten times a second); past this the vehicle holds where the target would be.
pub const TARGET_EXTRAPOLATION: Duration = Duration::from_millis(500);

/// A slot target (swarm-frame NED position, m, and velocity, m/s) `age` after its stamp:
/// moved on along its velocity for at most [`TARGET_EXTRAPOLATION`], then held there
/// (velocity zero). Returns the position and the velocity feed-forward.
pub fn extrapolate_target(position: Ned, velocity: Ned, age: Duration) -> (Ned, Ned) {
    if age > TARGET_EXTRAPOLATION {
        (
            position + velocity * TARGET_EXTRAPOLATION.as_secs_f64(),
            Ned::ZERO,
        )
    } else {
        (position + velocity * age.as_secs_f64(), velocity)
    }
}

/// Longest a report's position is moved on by its age (reports come at the control rate;
/// a vehicle at 5 m/s covers 1 m in this time).
pub const REPORT_EXTRAPOLATION: Duration = Duration::from_millis(200);

/// Age of a wall-clock stamp ([`wall_us`]) now; zero for a stamp from the future.
pub fn age_of(stamp_us: u64) -> Duration {
    Duration::from_micros(wall_us().saturating_sub(stamp_us))
}
