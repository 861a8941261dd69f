//! Benchmarks run from tests: their JSON report.

use super::Process;
use serde_json::Value;
use std::time::Duration;

/// Runs `skein bench <args>` to its end and returns its JSON report: the stdout line
/// holding `key` (a field of the report, quoted), within `timeout`; the benchmark must
/// exit 0 (its stderr is in the message otherwise).
pub fn bench_report(args: &[&str], key: &str, timeout: Duration) -> Value {
    let mut all = vec!["bench"];
    all.extend_from_slice(args);
    let mut p = Process::start(&all);
    let line = p.wait_line(&format!("\"{key}\""), timeout);
    let code = p.wait_exit(Duration::from_secs(60));
    assert_eq!(code, Some(0), "stderr:\n{}", p.stderr_text());
    serde_json::from_str(&line).expect("one JSON object")
}
