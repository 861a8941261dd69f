//! The roles' clock: tokio's, so that the unit tests run the election, the agent's
//! coordinator watch and the formation mirror on a paused clock
//! (`#[tokio::test(start_paused = true)]`). Outside a paused test it is the monotonic
//! clock of `std::time::Instant::now`.

use std::time::Instant;

/// Now, as the election and the lease observer take it.
pub(crate) fn now() -> Instant {
    tokio::time::Instant::now().into_std()
}
