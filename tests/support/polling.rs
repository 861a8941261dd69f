//! Polling with deadlines: the only way e2e tests wait (never a fixed sleep).

use std::time::{Duration, Instant};

/// Polls `f` every 50 ms until it returns `Some`, or panics after `timeout` with `what`
/// and the last thing `describe` said.
pub fn eventually<T>(what: &str, timeout: Duration, mut f: impl FnMut() -> Result<T, String>) -> T {
    let deadline = Instant::now() + timeout;
    loop {
        match f() {
            Ok(v) => return v,
            Err(last) => {
                if Instant::now() > deadline {
                    panic!("timed out after {timeout:?} waiting for {what}; last: {last}");
                }
            }
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Polls `f` every 100 ms until it has returned `Ok` on every poll for `hold` in a row,
/// and returns those values, oldest first; an `Err` starts the run again. Panics after
/// `timeout` with `what` and the last `Err`.
pub fn steady_for<T>(
    what: &str,
    hold: Duration,
    timeout: Duration,
    mut f: impl FnMut() -> Result<T, String>,
) -> Vec<T> {
    let deadline = Instant::now() + timeout;
    let mut run: Option<(Instant, Vec<T>)> = None;
    let mut last = String::from("never polled");
    loop {
        let now = Instant::now();
        match f() {
            Ok(v) => {
                let (since, values) = run.get_or_insert_with(|| (now, Vec::new()));
                values.push(v);
                if now.duration_since(*since) >= hold {
                    return run.map(|(_, values)| values).unwrap_or_default();
                }
            }
            Err(e) => {
                run = None;
                last = e;
            }
        }
        if Instant::now() > deadline {
            panic!(
                "timed out after {timeout:?} waiting for {what} ({hold:?} in a row); last: {last}"
            );
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}
