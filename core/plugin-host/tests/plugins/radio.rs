//! The radio plugin: a log-distance link whose loss and latency grow with the distance to
//! the ground station, applied to the simulator through `set_simulated_link`.

use crate::spec;
use crate::support::*;
use serde_json::{Value, json};
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::RADIO_STATUS_DATA;
use skein_plugin_host::{Isolation, PayloadFactory};

fn num(v: &Value, k: &str) -> f64 {
    v[k].as_f64()
        .unwrap_or_else(|| panic!("`{k}` missing in {v}"))
}

/// The documented default model, computed here independently.
fn expected_loss(distance_m: f64) -> f64 {
    let pl1 = 20.0 * 2400f64.log10() - 27.55;
    let rssi = 20.0 - (pl1 + 27.0 * distance_m.log10());
    1.0 / (1.0 + ((rssi + 92.0) / 2.0).exp())
}

#[test]
fn loss_and_latency_grow_with_distance_and_reach_the_simulator() {
    let m = manager_with(&["skein-plugin-radio"]);
    for isolation in [Isolation::InProcess, Isolation::Process] {
        let world = World::new(true);
        world.put("uav-1", 1, (0.0, 50.0, -20.0), 0.0);
        let mut radio = m
            .create(
                &spec("radio", "radio", isolation, json!({"rate_hz": 2})),
                world.host("uav-1", "radio"),
            )
            .unwrap();
        let mut last: Option<Value> = None;
        for east in [50.0, 150.0, 250.0, 300.0, 350.0, 450.0, 600.0] {
            world.put("uav-1", 1, (0.0, east, -20.0), 0.0);
            radio.tick(0.5).unwrap();
            let s = world.state("uav-1", "radio").unwrap();
            let d = f64::hypot(east, 20.0);
            assert!((num(&s, "distance_m") - d).abs() < 1e-6);
            assert!(
                (num(&s, "loss_percent") / 100.0 - expected_loss(d)).abs() < 1e-9,
                "{s}"
            );
            if let Some(prev) = &last {
                assert!(
                    num(&s, "loss_percent") > num(prev, "loss_percent"),
                    "{isolation:?} at {east} m"
                );
                assert!(num(&s, "latency_ms") > num(prev, "latency_ms"));
                assert!(num(&s, "rssi_dbm") < num(prev, "rssi_dbm"));
            }
            // What the simulator was told is what the state says.
            let (loss, latency) = *world
                .links("uav-1")
                .last()
                .expect("set_simulated_link called");
            let state_loss = num(&s, "loss_percent") / 100.0;
            assert!(
                loss == 0.0 && state_loss < 1e-4 || (loss - state_loss).abs() < 1e-12,
                "{loss} vs {state_loss}"
            );
            assert!((latency - num(&s, "latency_ms")).abs() < 1e-9);
            assert_eq!(s["applied_to_simulator"], true);
            last = Some(s);
        }
        // Far out the link is poor: more than half the datagrams lost.
        assert!(num(last.as_ref().unwrap(), "loss_percent") > 50.0);
        let calls = world.links("uav-1").len();
        // Unchanged link: the simulator is not told again.
        radio.tick(0.5).unwrap();
        assert_eq!(world.links("uav-1").len(), calls);

        // An imposed link condition, then back to the model.
        let s = radio
            .handle(json!({"command": "override", "loss_fraction": 0.3, "latency_ms": 150}))
            .unwrap();
        assert_eq!(s["override"]["loss_fraction"], 0.3);
        assert_eq!(*world.links("uav-1").last().unwrap(), (0.3, 150.0));
        radio.handle(json!({"command": "clear_override"})).unwrap();
        let (loss, _) = *world.links("uav-1").last().unwrap();
        assert!((loss - expected_loss(f64::hypot(600.0, 20.0))).abs() < 1e-12);
        let e = radio
            .handle(json!({"command": "override", "loss_fraction": 2}))
            .unwrap_err();
        assert_eq!(e, "loss_fraction: 2 is outside [0, 1]");

        // A better radio (set_model) shrinks the loss at the same distance.
        let s = radio
            .handle(json!({"command": "set_model", "tx_power_dbm": 30}))
            .unwrap();
        assert!(num(&s, "loss_percent") < 5.0, "{s}");

        // Removing the radio restores a perfect simulated link.
        drop(radio);
        assert_eq!(
            *world.links("uav-1").last().unwrap(),
            (0.0, 0.0),
            "{isolation:?}"
        );
    }
}

#[test]
fn real_radio_reports_radio_status() {
    let m = manager_with(&["skein-plugin-radio"]);
    let world = World::new(false);
    world.put("uav-1", 1, (0.0, 900.0, -20.0), 0.0);
    let mut radio = m
        .create(
            &spec("radio", "radio", Isolation::InProcess, json!(null)),
            world.host("uav-1", "radio"),
        )
        .unwrap();
    radio.tick(0.5).unwrap();
    let s = world.state("uav-1", "radio").unwrap();
    assert_eq!(s["backend"], "mavlink");
    assert!(s["rssi_dbm"].is_null() && s["loss_percent"].is_null());
    assert!(
        world.links("uav-1").is_empty(),
        "a real vehicle's link is not simulated"
    );
    radio
        .on_mavlink(
            68,
            &MavMessage::RADIO_STATUS(RADIO_STATUS_DATA {
                rxerrors: 3,
                fixed: 1,
                rssi: 100,
                remrssi: 95,
                txbuf: 90,
                noise: 20,
                remnoise: 22,
            }),
        )
        .unwrap();
    radio.tick(0.5).unwrap();
    let s = world.state("uav-1", "radio").unwrap();
    assert!((num(&s, "rssi_dbm") - (100.0 / 1.9 - 127.0)).abs() < 1e-9);
    assert!(
        s["loss_percent"].is_null(),
        "loss is not measured on a real radio: {s}"
    );
    assert_eq!(s["radio_status"]["rxerrors"], 3);
    let e = radio
        .handle(json!({"command": "override", "loss_fraction": 0.5}))
        .unwrap_err();
    assert!(e.contains("only a simulated radio link"), "{e}");
}
