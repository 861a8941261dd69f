//! A lost vehicle is still in the air: formations plan around it. From the outside, with
//! simulated PX4s over real UDP; a vehicle is "lost" by cutting its link in the
//! simulator (every datagram both ways dropped), so it flies on exactly as PX4 would
//! without a link: it takes its offboard-loss action (`COM_OBL_RC_ACT`) after
//! `COM_OF_LOSS_T`. Separation is checked on the simulator's ground truth, the lost
//! vehicle included.

mod support;

use serde_json::{Value, json};
use std::time::{Duration, Instant};
use support::{
    EventLog, Skein, eventually, one_at_a_time, sim_stats, summary, truth_min_separation,
};

/// Separation plus tracking margin the formation keeps from a hazard, metres.
const CLEARANCE_M: f64 = 3.5;

fn ned(v: &Value) -> (f64, f64, f64) {
    (
        v["north_m"].as_f64().unwrap(),
        v["east_m"].as_f64().unwrap(),
        v["down_m"].as_f64().unwrap(),
    )
}

fn dist(a: (f64, f64, f64), b: (f64, f64, f64)) -> f64 {
    ((a.0 - b.0).powi(2) + (a.1 - b.1).powi(2) + (a.2 - b.2).powi(2)).sqrt()
}

/// Settled clear of the hazard of `lost`: `n` members within `tol` of their slots, no
/// change in flight, and every slot the clearance plus the hazard's radius from it.
fn settled_clear(f: &Value, n: usize, tol: f64, lost: &str) -> Result<(), String> {
    let members = f["members"].as_array().cloned().unwrap_or_default();
    let hazard = f["hazards"]
        .as_array()
        .and_then(|h| h.iter().find(|h| h["id"] == lost).cloned())
        .ok_or_else(|| format!("{lost} is no hazard: {f}"))?;
    let (hp, r) = (
        ned(&hazard["position"]),
        hazard["radius_m"].as_f64().unwrap(),
    );
    let clear = members
        .iter()
        .all(|m| dist(ned(&m["target"]), hp) >= CLEARANCE_M + r - 0.05);
    let close = members
        .iter()
        .all(|m| m["error_m"].as_f64().unwrap_or(99.0) < tol);
    if members.len() == n && clear && close && f["transition_progress"].is_null() {
        Ok(())
    } else {
        Err(format!("{f}"))
    }
}

/// Flies a line of four behind uav-1 at 7 m spacing; returns the running skein.
fn line_of_four() -> Skein {
    let skein = Skein::up_sim(4, &[]);
    skein.take_off(4, 10.0);
    let (status, body) = skein.put(
        "/api/v1/formation",
        json!({"shape": "line", "spacing_m": 7.0, "leader": "uav-1"}),
    );
    assert_eq!(status, 200, "{body}");
    skein.settled(4, 0.5, Duration::from_secs(60));
    skein
}

/// Polls `check` until it holds (deadline `within`), keeping the smallest ground-truth
/// distance between any two airborne vehicles in `min_sep`.
fn watch(
    skein: &Skein,
    what: &str,
    within: Duration,
    min_sep: &mut f64,
    mut check: impl FnMut(&Value) -> Result<(), String>,
) {
    let stats = skein.sim_stats_addr();
    eventually(what, within, || {
        *min_sep = min_sep.min(truth_min_separation(&stats));
        check(&skein.formation())
    });
}

#[test]
fn a_lost_leader_is_planned_around_and_the_others_settle_clear_of_it() {
    let _serial = one_at_a_time();
    let skein = line_of_four();
    let stats = skein.sim_stats_addr();
    // This PX4 holds where it is when the offboard stream stops (COM_OBL_RC_ACT 5).
    let (status, body) = skein.put(
        "/api/v1/vehicles/uav-1/params/COM_OBL_RC_ACT",
        json!({"value": 5}),
    );
    assert_eq!(status, 200, "{body}");
    let events = EventLog::connect(&skein.base);
    let mut min_sep = f64::INFINITY;
    let t0 = Instant::now();
    assert_eq!(sim_stats(&stats, "link 1 1 0")["ok"], true);
    let change = eventually("a new leader", Duration::from_secs(3), || {
        let c = events.of_type("leader_changed");
        c.iter()
            .find(|e| e["from"] == "uav-1")
            .cloned()
            .ok_or_else(|| format!("{c:?}"))
    });
    let promoted_ms = t0.elapsed().as_millis() as u64;
    watch(
        &skein,
        "uav-1 a hazard",
        Duration::from_secs(10),
        &mut min_sep,
        |_| {
            let h = events.of_type("hazard_added");
            if h.iter().any(|e| e["id"] == "uav-1") {
                Ok(())
            } else {
                Err(format!("{h:?}"))
            }
        },
    );
    watch(
        &skein,
        "three members settled clear of uav-1",
        Duration::from_secs(30),
        &mut min_sep,
        |f| settled_clear(f, 3, 0.5, "uav-1"),
    );
    let settled_s = t0.elapsed().as_secs_f64();
    // A few more seconds: the hazard keeps growing to its cap, the slots stay clear.
    let until = Instant::now() + Duration::from_secs(8);
    while Instant::now() < until {
        min_sep = min_sep.min(truth_min_separation(&stats));
        let f = skein.formation();
        assert!(f["blocked"].is_null(), "{f}");
    }
    assert!(min_sep >= 3.0, "two vehicles came within {min_sep} m");
    // Out of the formation, not out of its figures: the lost leader is listed as absent,
    // with its distance to where its slot is now, and rms_error_m counts it.
    let f = skein.formation();
    let (_, rms, members_rms) = support::formation::assert_absent_and_counted(&f, "uav-1", "lost");
    assert!(rms > members_rms, "{f}");
    // The operator clears it: the formation no longer plans around it, nor lists it.
    let (status, body) = skein.post(
        "/api/v1/vehicles/uav-1/commands",
        json!({"command": "clear_hazard"}),
    );
    assert_eq!(status, 200, "{body}");
    let f = skein.formation();
    assert!(
        f["hazards"].as_array().unwrap().is_empty(),
        "{f} | {}",
        summary(&skein.vehicles())
    );
    assert_eq!(f["absent"], json!([]), "{f}");
    assert_eq!(f["rms_error_m"], f["members_rms_error_m"], "{f}");
    let (status, body) = skein.post(
        "/api/v1/vehicles/uav-1/commands",
        json!({"command": "clear_hazard"}),
    );
    assert_eq!(status, 409, "{body}");
    eprintln!(
        "{}",
        json!({"new_leader": change["to"], "promoted_after_ms": promoted_ms,
               "settled_clear_after_s": settled_s, "min_separation_m": min_sep})
    );
}

#[test]
fn a_lost_follower_landing_by_its_failsafe_is_a_hazard_until_seen_on_the_ground() {
    let _serial = one_at_a_time();
    let skein = line_of_four();
    let stats = skein.sim_stats_addr();
    // The member in the middle of the line: the one with a member on either side.
    let f = skein.formation();
    let members = f["members"].as_array().unwrap().clone();
    let east = |m: &Value| m["target"]["east_m"].as_f64().unwrap();
    let mut by_east = members.clone();
    by_east.sort_by(|a, b| east(a).total_cmp(&east(b)));
    let middle = by_east[1..by_east.len() - 1]
        .iter()
        .find(|m| m["id"] != "uav-1")
        .expect("a follower in the middle")["id"]
        .as_str()
        .unwrap()
        .to_string();
    let sysid: u8 = middle.trim_start_matches("uav-").parse().unwrap();
    let events = EventLog::connect(&skein.base);
    let mut min_sep = f64::INFINITY;
    let t0 = Instant::now();
    // PX4's default offboard-loss action here: land (COM_OBL_RC_ACT 0, no RC).
    assert_eq!(sim_stats(&stats, &format!("link {sysid} 1 0"))["ok"], true);
    watch(
        &skein,
        "three members settled clear of the lost follower",
        Duration::from_secs(30),
        &mut min_sep,
        |f| settled_clear(f, 3, 0.5, &middle),
    );
    let settled_s = t0.elapsed().as_secs_f64();
    // Unseen, it lands and PX4's land detector disarms it; the hazard stays while nobody
    // can see it.
    eventually(
        "the lost follower landed and disarmed",
        Duration::from_secs(60),
        || {
            let s = sim_stats(&stats, "stats");
            let v = s["vehicles"]
                .as_array()
                .unwrap()
                .iter()
                .find(|v| v["sysid"] == sysid)
                .cloned()
                .unwrap();
            if v["truth"]["landed_state"] == "OnGround" && v["truth"]["armed"] == false {
                Ok(())
            } else {
                Err(format!("{}", v["truth"]))
            }
        },
    );
    let f = skein.formation();
    assert!(
        f["hazards"]
            .as_array()
            .unwrap()
            .iter()
            .any(|h| h["id"] == middle.as_str()),
        "unseen, it is still a hazard: {f}"
    );
    // The link comes back: seen on the ground, it is no longer a hazard.
    assert_eq!(sim_stats(&stats, &format!("link {sysid} 0 0"))["ok"], true);
    let cleared = eventually("hazard cleared", Duration::from_secs(15), || {
        let c = events.of_type("hazard_cleared");
        c.iter()
            .find(|e| e["id"] == middle.as_str())
            .cloned()
            .ok_or_else(|| format!("{c:?} | {}", skein.formation()))
    });
    let states: Vec<Value> = events
        .of_type("state_changed")
        .into_iter()
        .filter(|e| e["id"] == middle.as_str())
        .collect();
    assert_eq!(
        cleared["reason"], "seen on the ground",
        "{cleared} after {states:?}"
    );
    assert!(min_sep >= 3.0, "two vehicles came within {min_sep} m");
    eprintln!(
        "{}",
        json!({"lost": middle, "settled_clear_after_s": settled_s, "min_separation_m": min_sep})
    );
}
