//! RTK corrections for the fleet, end to end: RTKLIB's `str2str` serves an NTRIP caster
//! fed by a base station streaming pyrtcm-checked RTCM3 (every fifth observation frame
//! with a bad CRC); `skein up` with three simulated vehicles whose GNSS wanders is given
//! the caster through `PUT /api/v1/rtk`. Every vehicle reaches RTK fixed and its error
//! drops from metres to centimetres (the simulator's truth), and a 5 m formation, refused
//! with plain GNSS, is accepted; the base stops sending: the source is stalled within its
//! timeout, the fixes fall back to float and the 5 m formation is refused again; the
//! caster stops and comes back: skein reconnects and streams again.

mod support;

use serde_json::{Value, json};
use std::time::{Duration, Instant};
use support::rtk::Caster;
use support::{Skein, eventually};

/// A base station 600 m north-east of the simulator's home (PX4 SITL's, Zurich).
const BASE: (f64, f64, f64) = (47.4021, 8.5512, 535.0);
/// The stall timeout given to skein.
const STALL_S: f64 = 3.0;

/// Each vehicle's receiver error (horizontal, metres) from the simulator's truth.
fn receiver_errors_m(skein: &Skein) -> Vec<f64> {
    let (_, truth) = skein.get("/api/v1/sim/truth");
    truth["vehicles"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| {
            let e = &v["gnss"]["error_ned_m"];
            e[0].as_f64().unwrap().hypot(e[1].as_f64().unwrap())
        })
        .collect()
}

fn rtk(skein: &Skein) -> Value {
    let (status, r) = skein.get("/api/v1/rtk");
    assert_eq!(status, 200, "{r}");
    r
}

/// Sets a 5 m line on the (landed) vehicles; returns the answer.
fn five_metre_line(skein: &Skein) -> (u16, Value) {
    skein.put(
        "/api/v1/formation",
        json!({"shape": "line", "spacing_m": 5.0, "leader": "virtual", "altitude_m": 10.0}),
    )
}

fn fixes(skein: &Skein) -> Vec<u64> {
    skein
        .vehicles()
        .iter()
        .map(|v| v["gps"]["fix_type"].as_u64().unwrap_or(0))
        .collect()
}

#[test]
fn three_vehicles_reach_rtk_fixed_from_an_ntrip_caster_and_fall_back_when_it_stops() {
    let skein = Skein::up_sim(3, &["--sim-gnss-wander"]);
    skein.wait_all(
        "a 3D fix on every vehicle",
        3,
        Duration::from_secs(30),
        |v| v["gps"]["fix_type"].as_u64() == Some(3),
    );
    let plain = receiver_errors_m(&skein);
    assert!(
        plain.iter().any(|e| *e > 0.3),
        "plain GNSS wanders metres: {plain:?}"
    );
    let (status, refused) = five_metre_line(&skein);
    assert_eq!(
        (status, refused["field"].as_str()),
        (400, Some("spacing_m")),
        "{refused}"
    );
    assert!(
        refused["error"].as_str().unwrap().contains("RTK"),
        "{refused}"
    );

    let mut caster = Caster::start(BASE, 5);
    let (status, r) = skein.put(
        "/api/v1/rtk",
        json!({"source": caster.source(), "stall_timeout_s": STALL_S}),
    );
    assert_eq!(status, 200, "{r}");
    assert!(
        !r["source"]
            .as_str()
            .unwrap()
            .contains(support::rtk::PASSWORD),
        "{r}"
    );
    fixed_everywhere(&skein);
    let (status, accepted) = five_metre_line(&skein);
    assert_eq!(status, 200, "RTK fixed lets a 5 m line fly: {accepted}");
    assert_eq!(skein.delete("/api/v1/formation").0, 200);

    caster.stop_feed();
    stalled_then_float(&skein);
    caster.stop_caster();
    eventually("the source failed", Duration::from_secs(15), || {
        let r = rtk(&skein);
        (r["state"] == "failed").then_some(()).ok_or(r.to_string())
    });
    caster.start_caster();
    caster.start_feed();
    eventually("streaming again", Duration::from_secs(40), || {
        let r = rtk(&skein);
        let fresh = r["vehicles"]
            .as_array()
            .unwrap()
            .iter()
            .all(|v| v["correction_age_s"].as_f64().is_some_and(|a| a < 2.0));
        (r["state"] == "streaming" && fresh)
            .then_some(())
            .ok_or(r.to_string())
    });
}

/// Waits for RTK fixed on every vehicle with its error in centimetres, and checks what
/// `GET /api/v1/rtk` says of the stream.
fn fixed_everywhere(skein: &Skein) {
    let started = Instant::now();
    eventually(
        "RTK fixed on every vehicle",
        Duration::from_secs(60),
        || {
            let f = fixes(skein);
            (f == [6, 6, 6])
                .then_some(())
                .ok_or(format!("{f:?} {}", rtk(skein)))
        },
    );
    let fixed_after_s = started.elapsed().as_secs_f64();
    let errors = eventually("centimetres of wander", Duration::from_secs(15), || {
        let e = receiver_errors_m(skein);
        e.iter()
            .all(|e| *e < 0.05)
            .then_some(e.clone())
            .ok_or(format!("{e:?}"))
    });
    let r = rtk(skein);
    assert_eq!(r["state"], "streaming", "{r}");
    assert_eq!(r["base"]["station_id"], 42, "{r}");
    let base_lat = r["base"]["position"]["lat_deg"].as_f64().unwrap();
    assert!((base_lat - BASE.0).abs() < 1e-6, "{r}");
    assert!(r["message_types"]["1005"].as_u64() >= Some(5), "{r}");
    assert!(r["message_types"]["1074"].as_u64() >= Some(5), "{r}");
    assert!(
        r["crc_failures"].as_u64() >= Some(1),
        "every fifth frame is bad: {r}"
    );
    for v in r["vehicles"].as_array().unwrap() {
        assert!(v["messages"].as_u64() >= Some(10), "{v}");
        assert_eq!(v["fix_type"], 6, "{v}");
    }
    eprintln!(
        "RTK fixed everywhere {fixed_after_s:.1} s after the source was set; errors {errors:?} m"
    );
}

/// The base stops: stalled within the stall timeout, the fixes back to float, the 5 m
/// line refused naming the uncertainty.
fn stalled_then_float(skein: &Skein) {
    let stopped = Instant::now();
    let r = eventually("stalled", Duration::from_secs(15), || {
        let r = rtk(skein);
        (r["state"] == "stalled")
            .then_some(r.clone())
            .ok_or(r.to_string())
    });
    let stalled_after_s = stopped.elapsed().as_secs_f64();
    assert!(
        stalled_after_s < STALL_S + 2.0,
        "stalled after {stalled_after_s:.1} s: {r}"
    );
    assert!(
        r["error"].as_str().unwrap().contains("no RTCM frame"),
        "{r}"
    );
    eventually(
        "RTK float on every vehicle",
        Duration::from_secs(20),
        || {
            let f = fixes(skein);
            (f == [5, 5, 5]).then_some(()).ok_or(format!("{f:?}"))
        },
    );
    let (status, refused) = five_metre_line(skein);
    assert_eq!(
        (status, refused["field"].as_str()),
        (400, Some("spacing_m")),
        "{refused}"
    );
    assert!(
        refused["error"].as_str().unwrap().contains("eph 0.35 m"),
        "{refused}"
    );
}
