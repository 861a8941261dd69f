//! `bench_plugins` on the built plugins, with small counts: the figures exist, are sane,
//! and are printed (run with `--nocapture` to see them).

use crate::support::*;
use skein_plugin_host::{BenchConfig, bench_plugins};

#[test]
fn bench_plugins_measures_round_trips_loads_and_restarts() {
    let dir = plugin_dir_with(&["skein-plugin-example", "skein-plugin-fault"]);
    let mut cfg = BenchConfig::new(&dir, child_command());
    cfg.round_trips = 2_000;
    cfg.isolated_round_trips = 300;
    cfg.loads = 5;
    cfg.restarts = 10;
    let report = bench_plugins(&cfg).unwrap();
    println!("{}", serde_json::to_string_pretty(&report).unwrap());
    let p50 = |path: &[&str]| {
        let mut v = &report;
        for k in path {
            v = &v[*k];
        }
        v["p50"]
            .as_f64()
            .unwrap_or_else(|| panic!("{path:?} missing in {report}"))
    };
    let local = p50(&["round_trip_us", "in_process"]);
    let remote = p50(&["round_trip_us", "process"]);
    assert!(local > 0.0 && remote > 0.0);
    // A socket round trip between processes costs more than a function call.
    assert!(
        remote > local,
        "in-process {local} µs vs process {remote} µs"
    );
    assert!(p50(&["load_us"]) > 0.0 && p50(&["reload_us"]) > 0.0);
    assert!(p50(&["restart_after_panic_us"]) > 0.0);
    assert!(p50(&["restart_after_abort_us"]) > p50(&["restart_after_panic_us"]));
    assert_eq!(report["round_trip_us"]["in_process"]["n"], 2_000);
    assert_eq!(report["plugin"]["name"], "example");
    // Without the example plugin there is nothing to measure.
    let empty = scratch("empty");
    let e = bench_plugins(&BenchConfig::new(&empty, child_command())).unwrap_err();
    assert!(e.contains("libskein_plugin_example.so not found"), "{e}");
}
