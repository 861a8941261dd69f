//! Scanning, validation, listing, load / unload rules, and the vehicle-snapshot contract.

use crate::spec;
use crate::support::*;
use serde_json::json;
use skein_plugin_host::{
    HostConfig, HostError, Isolation, LibraryStatus, PayloadFactory, PluginEvent, PluginManager,
};
use std::sync::{Arc, Mutex};

#[test]
fn every_plugin_loads_and_mismatched_builds_are_refused_by_name() {
    let dir = plugin_dir_with(&PLUGIN_PACKAGES);
    // The ABI-mismatch fixture in the directory reports ABI 999; add its stamp variant and
    // a file that is not a library at all.
    let stamp_variant = built_variant(
        "skein-plugin-abi-mismatch",
        &[("SKEIN_FIXTURE_MISMATCH", "stamp")],
    );
    std::fs::copy(&stamp_variant, dir.join("libstamp_mismatch.so")).unwrap();
    std::fs::write(dir.join("libnot_a_plugin.so"), b"just text").unwrap();
    std::fs::write(dir.join("README.txt"), b"ignored: not lib*.so").unwrap();

    let mut cfg = HostConfig::new(&dir);
    cfg.work_dir = Some(scratch("work"));
    let m = PluginManager::new(cfg).unwrap();
    let events = Arc::new(Mutex::new(Vec::new()));
    let ev = Arc::clone(&events);
    m.subscribe(move |e| ev.lock().unwrap().push(e.clone()));

    let scan = m.scan().unwrap();
    assert_eq!(scan.len(), 9, "{scan:#?}");
    let outcome = |file: &str| {
        scan.iter()
            .find(|e| e.file.file_name().unwrap() == file)
            .unwrap_or_else(|| panic!("{file} not scanned"))
            .result
            .clone()
    };

    let abi = outcome("libskein_plugin_abi_mismatch.so").unwrap_err();
    assert!(matches!(abi, HostError::Incompatible { .. }), "{abi:?}");
    let text = abi.to_string();
    assert!(text.contains("libskein_plugin_abi_mismatch.so"), "{text}");
    assert!(
        text.contains(
            "ABI version mismatch: the plugin was built for ABI 999, this skein speaks ABI 2"
        ),
        "{text}"
    );
    let stamp = outcome("libstamp_mismatch.so").unwrap_err().to_string();
    assert!(stamp.contains("libstamp_mismatch.so"), "{stamp}");
    assert!(
        stamp.contains("build stamp mismatch: messages: plugin 999, host 1"),
        "{stamp}"
    );
    let junk = outcome("libnot_a_plugin.so").unwrap_err();
    assert!(matches!(junk, HostError::Load { .. }), "{junk:?}");
    assert!(junk.to_string().contains("libnot_a_plugin.so"));

    // The good ones loaded, with their kinds and versions.
    let libs = m.libraries();
    let names: Vec<&str> = libs.iter().map(|l| l.name.as_str()).collect();
    assert_eq!(
        names,
        ["camera", "detector", "example", "fault", "gimbal", "radio"]
    );
    for l in &libs {
        assert_eq!(l.version, "0.1.0");
        assert_eq!(l.generation, 1);
        assert_eq!(l.status, LibraryStatus::Loaded);
        assert_eq!(l.instance_count, 0);
        assert_eq!(l.kinds, [l.name.as_str()]);
        assert_eq!(l.build_stamp, skein_plugin_sdk::abi::build_stamp());
        assert!(l.file.is_absolute());
    }
    let providers = m.providers();
    assert_eq!(providers.len(), 6);

    // Refusals were announced; the host carries on and instances work.
    let refused = events
        .lock()
        .unwrap()
        .iter()
        .filter(|e| matches!(e, PluginEvent::Refused { .. }))
        .count();
    assert_eq!(refused, 3);
    let world = World::new(true);
    world.put("uav-1", 1, (0.0, 0.0, -10.0), 0.0);
    let mut d = m
        .create(
            &spec("example", "example", Isolation::InProcess, json!(null)),
            world.host("uav-1", "example"),
        )
        .unwrap();
    let pong = d.handle(json!({"command": "ping"})).unwrap();
    assert_eq!(pong["vehicle"], "uav-1");
    assert_eq!(pong["version"], "0.1.0");
    // A rescan loads nothing new and refuses the same files again.
    assert!(m.scan().unwrap().iter().all(|e| e.result.is_err()));
}

#[test]
fn vehicle_snapshot_reaches_the_plugin_typed() {
    // The SDK's typed view parses what the host serialises from `VehicleSnapshot`.
    let m = manager_with(&["skein-plugin-example"]);
    let world = World::new(true);
    world.put("uav-3", 3, (5.0, 6.0, -12.5), 45.0);
    for isolation in [Isolation::InProcess, Isolation::Process] {
        let mut d = m
            .create(
                &spec("example", "example", isolation, json!({"greeting": "hi"})),
                world.host("uav-3", "example"),
            )
            .unwrap();
        let s = d.handle(json!({"command": "status"})).unwrap();
        assert_eq!(s["vehicle_state"], "Hovering", "{isolation:?}: {s}");
        assert!(
            (s["relative_alt_m"].as_f64().unwrap() - 12.5).abs() < 1e-6,
            "{s}"
        );
        assert_eq!(
            d.handle(json!({"command": "ping"})).unwrap()["greeting"],
            "hi"
        );
        // Events and state cross the boundary too.
        assert_eq!(
            d.handle(json!({"command": "emit", "message": "m1"}))
                .unwrap()["emitted"],
            true
        );
        d.tick(0.1).unwrap();
        let published = wait_for(std::time::Duration::from_secs(5), "published state", || {
            world.state("uav-3", "example")
        });
        assert_eq!(published["ticks"], 1, "{published}");
        drop(d);
        world.states.lock().unwrap().clear();
    }
    let events = world.events.lock().unwrap();
    assert_eq!(events.len(), 2);
    assert!(
        events
            .iter()
            .all(|(v, k, d)| v == "uav-3" && k == "example" && d["message"] == "m1")
    );
}

#[test]
fn bad_commands_and_configs_are_refused_naming_the_field() {
    let m = manager_with(&["skein-plugin-gimbal", "skein-plugin-example"]);
    let world = World::new(true);
    world.put("uav-1", 1, (0.0, 0.0, -10.0), 0.0);
    let err = m
        .create(
            &spec(
                "gimbal",
                "gimbal",
                Isolation::InProcess,
                json!({"max_rate": 30}),
            ),
            world.host("uav-1", "gimbal"),
        )
        .err()
        .unwrap();
    assert!(
        err.contains("plugin `gimbal` could not create slot `gimbal` on uav-1"),
        "{err}"
    );
    assert!(err.contains("unknown field `max_rate`"), "{err}");
    let mut g = m
        .create(
            &spec("gimbal", "gimbal", Isolation::InProcess, json!(null)),
            world.host("uav-1", "gimbal"),
        )
        .unwrap();
    let e = g
        .handle(json!({"command": "set_angles", "pich_deg": -45}))
        .unwrap_err();
    assert!(e.contains("unknown field `pich_deg`"), "{e}");
    let e = g
        .handle(json!({"command": "set_angles", "pitch_deg": "down"}))
        .unwrap_err();
    // `field: message`: the API answers it with `"field": "pitch_deg"`.
    assert!(
        e.starts_with("pitch_deg: ") && e.contains("expected f64"),
        "{e}"
    );
    let e = g
        .handle(json!({"command": "set_angles", "pitch_deg": -120}))
        .unwrap_err();
    assert!(
        e.starts_with("pitch_deg: -120 is outside the gimbal's pitch range"),
        "{e}"
    );
    let e = g.handle(json!({"command": "fly"})).unwrap_err();
    assert!(e.contains("unknown command `fly`"), "{e}");
    // Still usable after refusals.
    g.handle(json!({"command": "set_angles", "pitch_deg": -10}))
        .unwrap();

    // Payload kinds and plugin names that nobody provides.
    let e = m
        .create(
            &spec("lidar", "lidar", Isolation::InProcess, json!(null)),
            world.host("uav-1", "lidar"),
        )
        .err()
        .unwrap();
    assert!(
        e.contains("no loaded plugin provides payload kind `lidar`"),
        "{e}"
    );
    let mut s = spec("x", "gimbal", Isolation::InProcess, json!(null));
    s.plugin = Some("example".into());
    let e = m.create(&s, world.host("uav-1", "x")).err().unwrap();
    assert!(
        e.contains("plugin `example` does not provide payload kind `gimbal`"),
        "{e}"
    );
}

#[test]
fn load_unload_rules() {
    let m = manager_with(&["skein-plugin-example"]);
    let dir = m.config().plugin_dir.clone();
    // Loading the same plugin twice is a conflict.
    let e = m
        .load(&dir.join(lib_file("skein-plugin-example")))
        .unwrap_err();
    assert!(matches!(e, HostError::AlreadyLoaded { .. }), "{e:?}");
    assert_eq!(e.http_status(), 409);
    // Outside the plugin directory: forbidden.
    let outside = scratch("outside").join("libx.so");
    std::fs::copy(
        built_plugins().join(lib_file("skein-plugin-radio")),
        &outside,
    )
    .unwrap();
    let e = m.load(&outside).unwrap_err();
    assert!(matches!(e, HostError::Forbidden { .. }), "{e:?}");
    assert!(
        e.to_string().contains("outside the plugin directory"),
        "{e}"
    );
    // A relative name is taken inside the plugin directory.
    std::fs::copy(
        built_plugins().join(lib_file("skein-plugin-radio")),
        dir.join("libradio2.so"),
    )
    .unwrap();
    assert_eq!(
        m.load(std::path::Path::new("libradio2.so")).unwrap().name,
        "radio"
    );

    // Unload is refused while an instance lives, then works.
    let world = World::new(true);
    world.put("uav-1", 1, (0.0, 0.0, -10.0), 0.0);
    let d = m
        .create(
            &spec("ex", "example", Isolation::InProcess, json!(null)),
            world.host("uav-1", "ex"),
        )
        .unwrap();
    let info = m.library("example").unwrap();
    assert_eq!(info.instance_count, 1);
    assert_eq!(info.instances[0].vehicle_id, "uav-1");
    assert_eq!(info.instances[0].slot, "ex");
    let e = m.unload("example").unwrap_err();
    assert_eq!(
        e.to_string(),
        "plugin `example` still has 1 live instance(s) (uav-1/ex); stop those payloads first"
    );
    drop(d);
    assert_eq!(m.library("example").unwrap().instance_count, 0);
    m.unload("example").unwrap();
    assert!(m.library("example").is_none());
    assert!(matches!(
        m.unload("example"),
        Err(HostError::NotFound { .. })
    ));
    // Loading again after an unload starts a new generation.
    let again = m
        .load(std::path::Path::new(&lib_file("skein-plugin-example")))
        .unwrap();
    assert_eq!(again.generation, 2);
}

#[test]
fn a_forced_unload_announces_the_live_instances_and_creates_nothing_more() {
    let m = manager_with(&["skein-plugin-example"]);
    let events = Arc::new(Mutex::new(Vec::new()));
    let ev = Arc::clone(&events);
    m.subscribe(move |e| ev.lock().unwrap().push(e.clone()));
    let world = World::new(true);
    world.put("uav-1", 1, (0.0, 0.0, -10.0), 0.0);
    let ex = spec("ex", "example", Isolation::InProcess, json!(null));
    let d = m.create(&ex, world.host("uav-1", "ex")).unwrap();
    assert_eq!(
        d.served_by().map(|s| (s.plugin, s.generation)),
        Some(("example".to_string(), 1))
    );

    let forced = m.unload_force("example").unwrap();
    assert_eq!(forced.library.instance_count, 1);
    assert_eq!(forced.live_instances().len(), 1);
    // Out of the loaded set at once: nothing new comes from it, it is no provider.
    assert!(m.library("example").is_none());
    assert!(m.providers().iter().all(|p| p.name != "example"));
    assert!(m.create(&ex, world.host("uav-1", "ex2")).is_err());
    let listed = m.libraries();
    let unloading = listed.iter().find(|l| l.name == "example").unwrap();
    assert_eq!(unloading.status, LibraryStatus::Unloading);
    match events.lock().unwrap().last() {
        Some(PluginEvent::Unloaded { live_instances, .. }) => {
            assert_eq!(live_instances.len(), 1);
            assert_eq!(live_instances[0].slot, "ex");
        }
        other => panic!("{other:?}"),
    }
    // The instance keeps working until its owner drops it; then the library is gone.
    drop(d);
    assert!(forced.live_instances().is_empty());
    assert!(m.libraries().iter().all(|l| l.name != "example"));
    assert!(matches!(
        m.unload_force("example"),
        Err(HostError::NotFound { .. })
    ));
}
