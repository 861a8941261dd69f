//! The detector plugin on the camera plugin's real frames: intruders the simulated camera
//! draws at known ranges and bearings are found as bearings within 1°; an empty sky and an
//! empty landscape give nothing. Both plugins loaded with `dlopen`, the detector in-process
//! and in a `skein plugin-host` child process.

use crate::spec;
use crate::support::*;
use serde_json::{Value, json};
use skein_model::geo::Ned;
use skein_model::vehicle::Velocity;
use skein_payload::SimAircraft;
use skein_plugin_host::{Isolation, PayloadDriver, PayloadFactory, PluginManager};
use std::sync::Arc;

/// uav-2 hovering 10 m up, heading north, its gimbal at `pitch_deg`; a camera (640×480,
/// 75° wide) and a detector on it.
struct Rig {
    world: Arc<World>,
    camera: Box<dyn PayloadDriver>,
    detector: Box<dyn PayloadDriver>,
}

const EYE: Ned = Ned::new(0.0, 0.0, -10.0);

impl Rig {
    fn new(m: &PluginManager, isolation: Isolation, pitch_deg: f64) -> Rig {
        let world = World::new(true);
        world.put("uav-2", 2, (EYE.north_m, EYE.east_m, EYE.down_m), 0.0);
        world.set_state(
            "uav-2",
            "gimbal",
            json!({"pitch_deg": pitch_deg, "yaw_deg": 0.0}),
        );
        let camera = m
            .create(
                &spec(
                    "camera",
                    "camera",
                    Isolation::InProcess,
                    json!({"frame_rate_hz": 0}),
                ),
                world.host("uav-2", "camera"),
            )
            .unwrap();
        let detector = m
            .create(
                &spec("detector", "detector", isolation, json!({"rate_hz": 0})),
                world.host("uav-2", "detector"),
            )
            .unwrap();
        Rig {
            world,
            camera,
            detector,
        }
    }

    /// An intruder at `range_m` along (`azimuth_deg`, `elevation_deg`) from the camera.
    fn intruder_at(&self, id: &str, range_m: f64, azimuth_deg: f64, elevation_deg: f64) {
        let (sa, ca) = azimuth_deg.to_radians().sin_cos();
        let (se, ce) = elevation_deg.to_radians().sin_cos();
        let p = EYE + Ned::new(ce * ca, ce * sa, -se) * range_m;
        self.world.sim_aircraft.lock().unwrap().push(SimAircraft {
            id: id.into(),
            north_m: p.north_m,
            east_m: p.east_m,
            down_m: p.down_m,
            velocity: Velocity::default(),
            span_m: 0.8,
        });
    }

    /// Captures a frame and runs the detector on it: the frame's detections object, which
    /// is also the state's `last` and the newest of its `recent`. The first frame also
    /// raises the one event, `detections_changed` with the count (events only say what
    /// changed; the frames go to the state).
    fn detect(&mut self) -> Value {
        self.camera.handle(json!({"command": "capture"})).unwrap();
        let ev = self.detector.handle(json!({"command": "detect"})).unwrap();
        let state = self.world.states.lock().unwrap()[&("uav-2".into(), "detector".into())].clone();
        assert_eq!(state["last"], ev, "{state}");
        assert_eq!(
            state["recent"].as_array().and_then(|r| r.last()),
            Some(&ev),
            "{state}"
        );
        let events = self.world.events.lock().unwrap();
        let (vehicle, kind, data) = events.last().expect("a detections_changed event");
        assert_eq!(
            (vehicle.as_str(), kind.as_str()),
            ("uav-2", "detections_changed")
        );
        assert_eq!(
            data["count"],
            ev["detections"].as_array().unwrap().len(),
            "{data}"
        );
        assert_eq!(data["frame"], ev["frame"], "{data}");
        ev
    }
}

fn bearings(ev: &Value) -> Vec<(f64, f64)> {
    ev["detections"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| {
            (
                d["azimuth_deg"].as_f64().unwrap(),
                d["elevation_deg"].as_f64().unwrap(),
            )
        })
        .collect()
}

fn angle_deg(a: (f64, f64), b: (f64, f64)) -> f64 {
    let dir = |(az, el): (f64, f64)| {
        let (sa, ca) = f64::to_radians(az).sin_cos();
        let (se, ce) = f64::to_radians(el).sin_cos();
        [ce * ca, ce * sa, -se]
    };
    let (u, v) = (dir(a), dir(b));
    let dot: f64 = u.iter().zip(v).map(|(x, y)| x * y).sum();
    dot.clamp(-1.0, 1.0).acos().to_degrees()
}

fn check_finds_every_intruder(isolation: Isolation) {
    let m = manager_with(&["skein-plugin-camera", "skein-plugin-detector"]);
    let mut rig = Rig::new(&m, isolation, 0.0);
    // The near one is drawn as a quadcopter (rotors around a body), the others as blurs.
    let truth = [
        (12.0, 15.0, 10.0),
        (40.0, -20.0, 6.0),
        (75.0, 5.0, 3.0),
        (120.0, 25.0, 9.0),
    ];
    for (i, (range, az, el)) in truth.iter().enumerate() {
        rig.intruder_at(&format!("intruder-{}", i + 1), *range, *az, *el);
    }
    let ev = rig.detect();
    let found = bearings(&ev);
    assert_eq!(found.len(), truth.len(), "one detection per intruder: {ev}");
    for (range, az, el) in truth {
        let best = found
            .iter()
            .map(|b| angle_deg(*b, (az, el)))
            .fold(f64::INFINITY, f64::min);
        assert!(
            best < 1.0,
            "intruder at {range} m, ({az}°, {el}°): nearest detection {best}° off: {ev}"
        );
    }
    // The frame's own pose went along: the observer is the camera.
    assert!(
        (ev["observer"]["down_m"].as_f64().unwrap() + 10.0).abs() < 1e-6,
        "{ev}"
    );
    assert!(ev["frame"].as_u64().unwrap() >= 1);
    // Size: the ones at 12 and 40 m are wide enough to measure (the range it gives is
    // within 25 %);
    // the one at 120 m is a blur of a few pixels, reported without a size.
    let size_at = |az: f64, el: f64| {
        ev["detections"]
            .as_array()
            .unwrap()
            .iter()
            .min_by(|a, b| {
                let d = |x: &Value| {
                    angle_deg(
                        (
                            x["azimuth_deg"].as_f64().unwrap(),
                            x["elevation_deg"].as_f64().unwrap(),
                        ),
                        (az, el),
                    )
                };
                d(a).total_cmp(&d(b))
            })
            .unwrap()["angular_size_deg"]
            .as_f64()
    };
    for (range, az, el) in [(40.0, -20.0, 6.0), (12.0, 15.0, 10.0)] {
        let size = size_at(az, el).expect("a size for the near ones");
        let size_range = 0.8 / size.to_radians();
        assert!(
            (size_range - range).abs() < 0.25 * range,
            "size range {size_range:.1} m of the one at {range} m: {ev}"
        );
    }
    assert_eq!(size_at(25.0, 9.0), None, "{ev}");
}

#[test]
fn finds_rendered_intruders_within_a_degree() {
    check_finds_every_intruder(Isolation::InProcess);
}

#[test]
fn finds_rendered_intruders_within_a_degree_process_isolated() {
    check_finds_every_intruder(Isolation::Process);
}

#[test]
fn an_empty_sky_and_an_empty_landscape_give_no_detection() {
    let m = manager_with(&["skein-plugin-camera", "skein-plugin-detector"]);
    // Looking up: sky only.
    let mut up = Rig::new(&m, Isolation::InProcess, 20.0);
    let ev = up.detect();
    assert_eq!(bearings(&ev), vec![], "{ev}");
    // Level and looking down: horizon, fields and their grid.
    for pitch in [0.0, -20.0] {
        let mut rig = Rig::new(&m, Isolation::InProcess, pitch);
        let ev = rig.detect();
        assert_eq!(bearings(&ev), vec![], "pitch {pitch}: {ev}");
    }
}

#[test]
fn a_real_vehicle_sees_no_simulated_intruders() {
    let m = manager_with(&["skein-plugin-camera", "skein-plugin-detector"]);
    let mut rig = Rig::new(&m, Isolation::InProcess, 0.0);
    rig.intruder_at("intruder-1", 50.0, 0.0, 5.0);
    assert_eq!(bearings(&rig.detect()).len(), 1);
    // The same world, but the vehicle is real: the camera draws no simulator truth.
    let world = World::new(false);
    world.put("uav-2", 2, (0.0, 0.0, -10.0), 0.0);
    *world.sim_aircraft.lock().unwrap() = rig.world.sim_aircraft.lock().unwrap().clone();
    let mut camera = m
        .create(
            &spec(
                "camera",
                "camera",
                Isolation::InProcess,
                json!({"frame_rate_hz": 0, "gimbal_slot": ""}),
            ),
            world.host("uav-2", "camera"),
        )
        .unwrap();
    let reply = camera.handle(json!({"command": "capture"})).unwrap();
    assert_eq!(reply["visible"], json!([]), "{reply}");
}
