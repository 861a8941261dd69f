//! A failing test's message, repeated after the logs its processes print as they are
//! dropped: CI shows the end of a failing test's output, and five processes' last warnings
//! (30 lines each) had pushed the message itself out of it.

use std::sync::{Mutex, Once};

/// The last panic's message and place, once [`keep_panic_messages`] ran.
static LAST: Mutex<Option<String>> = Mutex::new(None);

/// Keeps every panic's message (the default hook still prints it), idempotently; called
/// by whatever prints logs on a failure ([`super::Process`], the docker followers).
pub fn keep_panic_messages() {
    static HOOK: Once = Once::new();
    HOOK.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let place = info
                .location()
                .map(|l| format!("{}:{}", l.file(), l.line()))
                .unwrap_or_default();
            let message = info
                .payload()
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| info.payload().downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            *LAST.lock().unwrap_or_else(|e| e.into_inner()) = Some(format!("{place}: {message}"));
            default(info);
        }));
    });
}

/// Prints the failure's message again (after a process's log), if one was kept.
pub fn repeat_failure() {
    if let Some(m) = LAST.lock().unwrap_or_else(|e| e.into_inner()).as_ref() {
        eprintln!("--- the test failed at {m}");
    }
}

/// `lines` with runs of the same message (the text after the first word, a log line's
/// timestamp) collapsed into their last line and a count.
pub fn collapsed<'a>(lines: impl IntoIterator<Item = &'a String>) -> Vec<String> {
    let mut out: Vec<(String, String, usize)> = Vec::new();
    for l in lines {
        let text = l.split_once(' ').map_or(l.as_str(), |(_, t)| t).to_string();
        match out.last_mut() {
            Some((last, t, n)) if *t == text => {
                *last = l.clone();
                *n += 1;
            }
            _ => out.push((l.clone(), text, 1)),
        }
    }
    out.into_iter()
        .map(|(l, _, n)| if n > 1 { format!("{l} (×{n})") } else { l })
        .collect()
}
