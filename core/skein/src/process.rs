//! The process around the swarm: signals that end it, the exit status that tells systemd
//! or Docker the coordinator failed, and the watchdog thread that exits when the root
//! actor stops answering (and tells systemd's watchdog each time it answers, see
//! [`crate::service`]).

use std::time::Duration;

/// Exit status when the coordinator failed (EX_SOFTWARE): for systemd or Docker to
/// restart the process.
pub(crate) const EXIT_COORDINATOR_FAILED: u8 = 70;

/// Pings the coordinator from a thread of its own (so a wedged runtime cannot stop it);
/// a coordinator that does not answer within `deadline` is a hung root: exit non-zero.
/// Every answer is a `WATCHDOG=1` to systemd (with `WatchdogSec=`), pinged at least twice
/// per watchdog interval.
pub(crate) fn spawn_process_watchdog(
    coordinator: ractor::ActorRef<skein_swarm::CoordinatorMsg>,
    deadline: Duration,
) {
    let period = crate::service::watchdog_interval().map_or(Duration::from_millis(500), |w| {
        (w / 2).clamp(Duration::from_millis(50), Duration::from_millis(500))
    });
    std::thread::Builder::new()
        .name("skein-watchdog".into())
        .spawn(move || {
            let Ok(rt) = tokio::runtime::Builder::new_current_thread()
                .enable_time()
                .build()
            else {
                return;
            };
            rt.block_on(async move {
                loop {
                    tokio::time::sleep(period).await;
                    match coordinator
                        .call(|r| skein_swarm::AdminMsg::Ping(r).into(), Some(deadline))
                        .await
                    {
                        Ok(ractor::rpc::CallResult::Success(())) => crate::service::watchdog(),
                        Ok(ractor::rpc::CallResult::Timeout) => {
                            tracing::error!(
                                "the coordinator did not answer for {} ms: exiting",
                                deadline.as_millis()
                            );
                            std::process::exit(i32::from(EXIT_COORDINATOR_FAILED));
                        }
                        // Stopped or failed: the main task handles it.
                        _ => return,
                    }
                }
            });
        })
        .expect("spawn the watchdog thread");
}

/// Resolves at Ctrl-C or SIGTERM: the signal to shut down cleanly.
pub(crate) async fn shutdown_signal() {
    let ctrl_c = tokio::signal::ctrl_c();
    #[cfg(unix)]
    {
        let mut term =
            match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
                Ok(t) => t,
                Err(_) => {
                    let _ = ctrl_c.await;
                    return;
                }
            };
        tokio::select! {
            _ = ctrl_c => {}
            _ = term.recv() => {}
        }
    }
    #[cfg(not(unix))]
    let _ = ctrl_c.await;
}
