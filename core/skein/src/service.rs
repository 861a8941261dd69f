//! Talking to the service manager (systemd, `Type=notify`) through sd_notify(3) with the
//! `sd-notify` crate: `READY=1` once the API and DDS are up, `WATCHDOG=1` from the process
//! watchdog each time the coordinator answers its ping (so with `WatchdogSec=` systemd
//! restarts a hung skein), `STOPPING=1` and `STATUS=` lines while shutting down.
//!
//! Without `NOTIFY_SOCKET` in the environment (not started by systemd) every call does
//! nothing; a failed send is logged at debug level and otherwise ignored: the service
//! manager is told, never waited for.

use sd_notify::NotifyState;
use std::time::Duration;

fn send(states: &[NotifyState]) {
    if let Err(e) = sd_notify::notify(states) {
        tracing::debug!("sd_notify: {e}");
    }
}

/// Startup is done (the API listens, DDS has started): `READY=1` with a status line.
pub(crate) fn ready(status: &str) {
    send(&[NotifyState::Ready, NotifyState::Status(status)]);
}

/// The process is shutting down: `STOPPING=1` with a status line.
pub(crate) fn stopping(status: &str) {
    send(&[NotifyState::Stopping, NotifyState::Status(status)]);
}

/// A status line (`systemctl status` shows the last one).
pub(crate) fn status(status: &str) {
    send(&[NotifyState::Status(status)]);
}

/// The process is alive: `WATCHDOG=1`.
pub(crate) fn watchdog() {
    send(&[NotifyState::Watchdog]);
}

/// The watchdog interval systemd asked for (`WATCHDOG_USEC`, for this process), if any.
pub(crate) fn watchdog_interval() -> Option<Duration> {
    sd_notify::watchdog_enabled()
}
