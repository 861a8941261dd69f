//! Reload of a rebuilt library: the example plugin built twice with different versions
//! (`SKEIN_EXAMPLE_VERSION`, read at compile time).

use crate::spec;
use crate::support::*;
use serde_json::json;
use skein_plugin_host::{
    HostConfig, Isolation, LibraryStatus, PayloadFactory, PluginEvent, PluginManager, StalePolicy,
    is_stale_instance_error,
};
use std::sync::{Arc, Mutex};

fn versions() -> (std::path::PathBuf, std::path::PathBuf) {
    (
        built_variant(
            "skein-plugin-example",
            &[("SKEIN_EXAMPLE_VERSION", "1.0.0-old")],
        ),
        built_variant(
            "skein-plugin-example",
            &[("SKEIN_EXAMPLE_VERSION", "2.0.0-new")],
        ),
    )
}

fn manager(policy: StalePolicy) -> (PluginManager, std::path::PathBuf) {
    let (old, _) = versions();
    let dir = scratch("reload");
    let file = dir.join("libskein_plugin_example.so");
    std::fs::copy(&old, &file).unwrap();
    let mut cfg = HostConfig::new(&dir);
    cfg.child = Some(child_command());
    cfg.work_dir = Some(scratch("work"));
    cfg.stale_instances = policy;
    let m = PluginManager::new(cfg).unwrap();
    m.scan().unwrap();
    (m, file)
}

#[test]
fn reload_reports_the_new_version_and_new_instances_run_new_code() {
    let (_, new) = versions();
    let (m, file) = manager(StalePolicy::FailNextCall);
    let events = Arc::new(Mutex::new(Vec::new()));
    let ev = Arc::clone(&events);
    m.subscribe(move |e| ev.lock().unwrap().push(e.clone()));
    let world = World::new(true);
    world.put("uav-1", 1, (0.0, 0.0, -10.0), 0.0);
    let mut old_local = m
        .create(
            &spec("ex", "example", Isolation::InProcess, json!(null)),
            world.host("uav-1", "ex"),
        )
        .unwrap();
    let mut old_child = m
        .create(
            &spec("ex2", "example", Isolation::Process, json!(null)),
            world.host("uav-1", "ex2"),
        )
        .unwrap();
    assert_eq!(
        old_local.handle(json!({"command": "ping"})).unwrap()["version"],
        "1.0.0-old"
    );
    assert_eq!(
        old_child.handle(json!({"command": "ping"})).unwrap()["version"],
        "1.0.0-old"
    );
    assert_eq!(m.generation("example"), Some(1));

    // A new build replaces the file in place (as `cp` does): the running code is a private
    // copy, untouched.
    std::fs::copy(&new, &file).unwrap();
    assert_eq!(
        old_local.handle(json!({"command": "ping"})).unwrap()["version"],
        "1.0.0-old"
    );
    let report = m.reload("example").unwrap();
    assert_eq!(report.library.version, "2.0.0-new");
    assert_eq!(report.previous_version, "1.0.0-old");
    assert_eq!(
        (report.previous_generation, report.library.generation),
        (1, 2)
    );
    assert_eq!(m.generation("example"), Some(2));
    let mut stale: Vec<&str> = report
        .stale_instances
        .iter()
        .map(|r| r.slot.as_str())
        .collect();
    stale.sort();
    assert_eq!(stale, ["ex", "ex2"]);
    assert!(report.stale_instances.iter().all(|r| r.generation == 1));

    // Subscribers were told which instances to re-create.
    let reloaded: Vec<PluginEvent> = events
        .lock()
        .unwrap()
        .iter()
        .filter(|e| matches!(e, PluginEvent::Reloaded { .. }))
        .cloned()
        .collect();
    match &reloaded[..] {
        [
            PluginEvent::Reloaded {
                name,
                version,
                generation,
                stale_instances,
                ..
            },
        ] => {
            assert_eq!(
                (name.as_str(), version.as_str(), *generation),
                ("example", "2.0.0-new", 2)
            );
            assert_eq!(stale_instances.len(), 2);
        }
        other => panic!("{other:?}"),
    }

    // The listing shows both libraries while the old instances live.
    let libs = m.libraries();
    assert_eq!(libs.len(), 2);
    assert_eq!(
        (
            libs[0].status,
            libs[0].version.as_str(),
            libs[0].instance_count
        ),
        (LibraryStatus::Loaded, "2.0.0-new", 0)
    );
    assert_eq!(
        (
            libs[1].status,
            libs[1].version.as_str(),
            libs[1].instance_count
        ),
        (LibraryStatus::Superseded, "1.0.0-old", 2)
    );

    // Old instances fail their next call with the stale error, so supervisors re-create them.
    for d in [&mut old_local, &mut old_child] {
        let e = d.handle(json!({"command": "ping"})).unwrap_err();
        assert!(is_stale_instance_error(&e), "{e}");
        assert!(e.contains("generation 1 (version 1.0.0-old)"), "{e}");
        assert!(d.tick(0.1).is_err());
    }
    drop(old_local);
    drop(old_child);
    assert_eq!(
        m.libraries().len(),
        1,
        "the old library leaves the listing with its last instance"
    );

    // New instances, in-process and isolated, run the new code.
    for (slot, isolation) in [("ex", Isolation::InProcess), ("ex2", Isolation::Process)] {
        let mut d = m
            .create(
                &spec(slot, "example", isolation, json!(null)),
                world.host("uav-1", slot),
            )
            .unwrap();
        assert_eq!(
            d.handle(json!({"command": "ping"})).unwrap()["version"],
            "2.0.0-new"
        );
        assert_eq!(m.library("example").unwrap().instances[0].generation, 2);
    }
}

#[test]
fn a_refused_rebuild_leaves_the_running_library_in_place() {
    let (m, file) = manager(StalePolicy::FailNextCall);
    std::fs::write(&file, b"a broken build").unwrap();
    let e = m.reload("example").unwrap_err();
    assert!(e.to_string().contains("libskein_plugin_example.so"), "{e}");
    assert_eq!(m.generation("example"), Some(1));
    assert_eq!(m.library("example").unwrap().version, "1.0.0-old");
    // A rebuild that is another plugin is refused too.
    std::fs::copy(built_plugins().join(lib_file("skein-plugin-radio")), &file).unwrap();
    let e = m.reload("example").unwrap_err().to_string();
    assert!(
        e.contains("the new build is plugin `radio`, not `example`"),
        "{e}"
    );
    assert!(m.reload("nothing").is_err());
}

#[test]
fn with_keep_running_old_instances_run_the_old_code_until_re_created() {
    let (_, new) = versions();
    let (m, file) = manager(StalePolicy::KeepRunning);
    let world = World::new(true);
    world.put("uav-1", 1, (0.0, 0.0, -10.0), 0.0);
    let mut old = m
        .create(
            &spec("ex", "example", Isolation::InProcess, json!(null)),
            world.host("uav-1", "ex"),
        )
        .unwrap();
    std::fs::copy(&new, &file).unwrap();
    m.reload("example").unwrap();
    let mut fresh = m
        .create(
            &spec("ex2", "example", Isolation::InProcess, json!(null)),
            world.host("uav-1", "ex2"),
        )
        .unwrap();
    // Two versions of the same plugin, mapped side by side, each running its own code.
    assert_eq!(
        old.handle(json!({"command": "ping"})).unwrap()["version"],
        "1.0.0-old"
    );
    assert_eq!(
        fresh.handle(json!({"command": "ping"})).unwrap()["version"],
        "2.0.0-new"
    );
    old.tick(0.1).unwrap();
}
