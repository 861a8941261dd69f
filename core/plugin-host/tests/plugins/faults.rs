//! Fault fixtures: a panic is an error and the host lives on; an abort, a stack overflow
//! or a hang under process isolation kills only the child, and a new driver works.

use crate::spec;
use crate::support::*;
use serde_json::json;
use skein_plugin_host::{
    ChildCommand, HostConfig, Isolation, PayloadDriver, PayloadFactory, PluginManager,
};
use std::sync::Arc;
use std::time::{Duration, Instant};

fn fault_driver(
    m: &PluginManager,
    world: &Arc<World>,
    isolation: Isolation,
    config: serde_json::Value,
) -> Box<dyn PayloadDriver> {
    m.create(
        &spec("fault", "fault", isolation, config),
        world.host("uav-1", "fault"),
    )
    .unwrap()
}

fn world() -> Arc<World> {
    let w = World::new(true);
    w.put("uav-1", 1, (0.0, 0.0, -10.0), 0.0);
    w
}

fn pid_of(m: &PluginManager) -> Option<u32> {
    m.library("fault")
        .unwrap()
        .instances
        .first()
        .and_then(|r| r.pid)
}

#[test]
fn a_panicking_plugin_returns_an_error_and_the_host_lives_on() {
    let m = manager_with(&["skein-plugin-fault", "skein-plugin-example"]);
    let w = world();
    for isolation in [Isolation::InProcess, Isolation::Process] {
        let mut d = fault_driver(&m, &w, isolation, json!(null));
        assert_eq!(d.handle(json!({"command": "ping"})).unwrap()["pong"], true);
        let e = d.handle(json!({"command": "panic"})).unwrap_err();
        assert!(
            e.starts_with(
                "plugin `fault` panicked in `handle`: fault fixture: deliberate panic in handle"
            ),
            "{e}"
        );
        assert!(
            e.contains("plugins/fixtures/fault/src/lib.rs:"),
            "the location is reported: {e}"
        );
        // The instance is poisoned: its state after a panic is not trusted.
        let e = d.handle(json!({"command": "ping"})).unwrap_err();
        assert!(e.contains("instance is poisoned"), "{e}");
        // A plain error is just an error.
        let mut d2 = fault_driver(&m, &w, isolation, json!(null));
        let e = d2.handle(json!({"command": "error"})).unwrap_err();
        assert_eq!(e, "fault fixture: deliberate error in handle");
        assert_eq!(d2.handle(json!({"command": "ping"})).unwrap()["pong"], true);
        drop(d);
        // Re-created, it works; other plugins were never affected.
        let mut d = fault_driver(&m, &w, isolation, json!(null));
        assert_eq!(d.handle(json!({"command": "ping"})).unwrap()["pong"], true);
    }
    // A panic in the tick, after two good ticks, and one during creation.
    let mut d = fault_driver(
        &m,
        &w,
        Isolation::InProcess,
        json!({"on_tick": "panic", "after_ticks": 2}),
    );
    d.tick(0.1).unwrap();
    d.tick(0.1).unwrap();
    let e = d.tick(0.1).unwrap_err();
    assert!(e.contains("panicked in `tick`"), "{e}");
    let e = m
        .create(
            &spec(
                "fault",
                "fault",
                Isolation::InProcess,
                json!({"on_create": "panic"}),
            ),
            w.host("uav-1", "fault"),
        )
        .err()
        .unwrap();
    assert!(e.contains("panicked in `create`"), "{e}");
    let mut ex = m
        .create(
            &spec("example", "example", Isolation::InProcess, json!(null)),
            w.host("uav-1", "example"),
        )
        .unwrap();
    assert_eq!(ex.handle(json!({"command": "ping"})).unwrap()["pong"], true);
}

#[test]
fn an_aborting_plugin_kills_only_its_child_and_a_new_driver_works() {
    let m = manager_with(&["skein-plugin-fault"]);
    let w = world();
    for crash in ["abort", "stack_overflow"] {
        let mut d = fault_driver(&m, &w, Isolation::Process, json!(null));
        let pid = pid_of(&m).expect("the child's pid is recorded");
        assert_eq!(d.handle(json!({"command": "ping"})).unwrap()["pong"], true);
        let e = d.handle(json!({"command": crash})).unwrap_err();
        assert!(
            e.starts_with("plugin `fault` (process-isolated): process "),
            "{e}"
        );
        assert!(e.contains("killed by signal"), "{crash}: {e}");
        assert!(e.contains("during `handle`"), "{e}");
        if crash == "abort" {
            assert!(e.contains("SIGABRT"), "{e}");
        }
        // The driver stays failed, so the supervisor re-creates it.
        let e = d.handle(json!({"command": "ping"})).unwrap_err();
        assert!(
            e.contains("is not running") && e.contains("re-create the payload"),
            "{e}"
        );
        assert!(d.tick(0.1).is_err());
        drop(d);
        // The dead child is reaped (no zombie): its /proc entry is gone.
        wait_for(
            Duration::from_secs(5),
            "the dead child to be reaped",
            || (!std::path::Path::new(&format!("/proc/{pid}")).exists()).then_some(()),
        );
        let mut d = fault_driver(&m, &w, Isolation::Process, json!(null));
        assert_ne!(pid_of(&m), Some(pid), "a new child");
        assert_eq!(d.handle(json!({"command": "ping"})).unwrap()["pong"], true);
    }
    // An abort in a tick, likewise.
    let mut d = fault_driver(
        &m,
        &w,
        Isolation::Process,
        json!({"on_tick": "abort", "after_ticks": 1}),
    );
    d.tick(0.1).unwrap();
    assert!(d.tick(0.1).unwrap_err().contains("SIGABRT"));
}

#[test]
fn a_hung_plugin_call_times_out_under_process_isolation() {
    let dir = plugin_dir_with(&["skein-plugin-fault"]);
    let mut cfg = HostConfig::new(&dir);
    cfg.child = Some(child_command());
    cfg.work_dir = Some(scratch("work"));
    cfg.call_timeout = Duration::from_millis(300);
    let m = PluginManager::new(cfg).unwrap();
    m.scan().unwrap();
    let w = world();
    let mut d = fault_driver(&m, &w, Isolation::Process, json!(null));
    let pid = pid_of(&m).unwrap();
    let t = Instant::now();
    let e = d.handle(json!({"command": "hang"})).unwrap_err();
    let took = t.elapsed();
    assert!(took >= Duration::from_millis(300), "{took:?}");
    assert!(
        took < Duration::from_secs(5),
        "the deadline was not enforced: {took:?}"
    );
    assert!(
        e.contains(&format!(
            "process {pid} did not answer `handle` within 300 ms and was killed"
        )),
        "{e}"
    );
    assert!(
        !std::path::Path::new(&format!("/proc/{pid}")).exists(),
        "the hung child was killed and reaped"
    );
    assert!(d.handle(json!({"command": "ping"})).is_err());
    drop(d);
    let mut d = fault_driver(&m, &w, Isolation::Process, json!(null));
    assert_eq!(d.handle(json!({"command": "ping"})).unwrap()["pong"], true);
    // A tick that hangs is cut off the same way.
    let mut d = fault_driver(&m, &w, Isolation::Process, json!({"on_tick": "hang"}));
    assert!(
        d.tick(0.1)
            .unwrap_err()
            .contains("did not answer `tick` within 300 ms")
    );
}

#[test]
fn a_missing_plugin_host_executable_is_a_clear_error() {
    let dir = plugin_dir_with(&["skein-plugin-fault"]);
    let mut cfg = HostConfig::new(&dir);
    cfg.work_dir = Some(scratch("work"));
    cfg.child = Some(ChildCommand::standalone("/nonexistent/skein"));
    let m = PluginManager::new(cfg).unwrap();
    m.scan().unwrap();
    let e = m
        .create(
            &spec("fault", "fault", Isolation::Process, json!(null)),
            world().host("uav-1", "fault"),
        )
        .err()
        .unwrap();
    assert!(
        e.contains("cannot start the plugin host `/nonexistent/skein`"),
        "{e}"
    );
    assert_eq!(m.library("fault").unwrap().instance_count, 0);
    // An executable that is not a plugin host exits before connecting.
    let mut cfg = HostConfig::new(&dir);
    cfg.work_dir = Some(scratch("work"));
    cfg.child = Some(ChildCommand::standalone("/bin/true"));
    let m = PluginManager::new(cfg).unwrap();
    m.scan().unwrap();
    let e = m
        .create(
            &spec("fault", "fault", Isolation::Process, json!(null)),
            world().host("uav-1", "fault"),
        )
        .err()
        .unwrap();
    assert!(e.contains("exited with code 0 before connecting"), "{e}");
}
