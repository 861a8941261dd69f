//! The slot correction against the faithful simulator (PX4 v1.16's cascade on
//! SIH-like physics, `skein_sim::VirtualVehicle`, virtual time): a point moving at 5 m/s
//! in a straight line and on a circle, followed with position + velocity setpoints at
//! 50 Hz, measured from the vehicle's own LOCAL_POSITION_NED as skein measures it. The
//! raw setpoints lag as PX4 does; with the correction the error while moving must stay
//! under the formation's 0.3 m budget.

use skein_mavlink::MavMessage;
use skein_model::geo::Ned;
use skein_sim::client;
use skein_sim::{SimConfig, VirtualVehicle};
use skein_swarm::vehicle::slot_correction::{SlotCorrection, SlotCorrectionGains};

fn setpoint(p: Ned, v: Ned, yaw: f64) -> MavMessage {
    client::setpoint(client::POSITION_VELOCITY_YAW, p, v, Ned::ZERO, yaw)
}

fn setpoint_acc(p: Ned, v: Ned, a: Option<Ned>, yaw: f64) -> MavMessage {
    match a {
        Some(a) => client::setpoint(client::POSITION_VELOCITY_ACCELERATION_YAW, p, v, a, yaw),
        None => setpoint(p, v, yaw),
    }
}

/// What the vehicle last said of its position: (time, position, velocity).
type Estimate = (f64, Ned, Ned);

fn read(last: &mut Option<Estimate>, msgs: Vec<(f64, MavMessage)>) {
    for (t, m) in msgs {
        if let MavMessage::LOCAL_POSITION_NED(p) = m {
            *last = Some((
                t,
                Ned::new(p.x.into(), p.y.into(), p.z.into()),
                Ned::new(p.vx.into(), p.vy.into(), p.vz.into()),
            ));
        }
    }
}

/// A target path: position and velocity at `t` seconds after the start.
type Path = dyn Fn(f64) -> (Ned, Ned);

/// Flies `path` for `seconds` after a hover at (0, 0, -10); returns the RMS and the
/// largest error between the measured position (moved on by its age, as skein does) and
/// the target, over `from_s..seconds`.
fn fly(path: &Path, seconds: f64, from_s: f64, gains: Option<SlotCorrectionGains>) -> (f64, f64) {
    fly_where(path, seconds, &|t| t >= from_s, gains, false)
}

/// [`fly`] measured while the legs cruise, past the first quarter of each cruise (as the
/// end-to-end test measures), from the second leg on (the first one teaches the
/// correction the drag; a formation keeps what it learnt).
fn fly_cruising(
    path: &Path,
    seconds: f64,
    gains: Option<SlotCorrectionGains>,
    noise: bool,
) -> (f64, f64) {
    let (a, v, d, hold) = (1.5, 5.0, 60.0, 5.0);
    let ta = v / a;
    let tc = (d - v * ta) / v;
    let leg = 2.0 * ta + tc + hold;
    fly_where(
        path,
        seconds,
        &|t| {
            // From the second leg on: the first teaches the correction the drag.
            let tl = t - (t / leg).floor() * leg;
            t >= leg && tl >= ta + tc / 4.0 && tl < ta + tc
        },
        gains,
        noise,
    )
}

fn fly_where(
    path: &Path,
    seconds: f64,
    keep: &dyn Fn(f64) -> bool,
    gains: Option<SlotCorrectionGains>,
    estimator_noise: bool,
) -> (f64, f64) {
    let cfg = SimConfig {
        estimator_noise,
        seed: 7,
        ..SimConfig::default()
    };
    let mut vv = VirtualVehicle::new(&cfg);
    let mut est: Option<Estimate> = None;
    assert!(vv.take_off_offboard(10.0, 20.0), "did not take off");
    let mut next_sp = vv.time_s();
    let mut next_hb = vv.time_s() + 1.0;
    let t0 = vv.time_s();
    let mut correction = SlotCorrection::default();
    let mut errors = Vec::new();
    while vv.time_s() - t0 < seconds {
        let t = vv.time_s() - t0;
        if vv.time_s() >= next_sp {
            next_sp += 0.02;
            let (p, v) = path(t);
            let measured = est.map(|(at, pos, vel)| pos + vel * (vv.time_s() - at).min(0.2));
            let c = match (gains, measured) {
                (Some(g), Some(m)) => Some(correction.update(&g, p, v, m, 0.02)),
                _ => None,
            };
            let yaw = if v.horizontal_norm() > 0.1 {
                v.east_m.atan2(v.north_m)
            } else {
                0.0
            };
            match c {
                Some(c) => vv.send(&setpoint_acc(p + c.offset, v, Some(c.acceleration), yaw)),
                None => vv.send(&setpoint(p, v, yaw)),
            };
            if keep(t)
                && let Some(m) = measured
            {
                errors.push((m - p).norm());
            }
        }
        if vv.time_s() >= next_hb {
            vv.send(&client::gcs_heartbeat());
            next_hb += 1.0;
        }
        read(&mut est, vv.step());
    }
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    (rms, errors.iter().copied().fold(0.0, f64::max))
}

/// A point accelerating at 1.5 m/s² (the formation reference's limit) to 5 m/s north.
fn cruise(t: f64) -> (Ned, Ned) {
    let (a, v) = (1.5, 5.0);
    let ta = v / a;
    let (s, speed) = if t < ta {
        (0.5 * a * t * t, a * t)
    } else {
        (0.5 * a * ta * ta + v * (t - ta), v)
    };
    (Ned::new(s, 0.0, -10.0), Ned::new(speed, 0.0, 0.0))
}

/// A circle of radius 25 m at 5 m/s around (0, 25), starting at the origin heading north.
fn orbit(t: f64) -> (Ned, Ned) {
    let (r, v) = (25.0, 5.0);
    let w = v / r;
    // Ramp the angular speed up over 3 s so that the start is not a step.
    let (angle, rate) = if t < 3.0 {
        (0.5 * w / 3.0 * t * t, w * t / 3.0)
    } else {
        (0.5 * w * 3.0 + w * (t - 3.0), w)
    };
    (
        Ned::new(r * angle.sin(), r * (1.0 - angle.cos()), -10.0),
        Ned::new(r * rate * angle.cos(), r * rate * angle.sin(), 0.0),
    )
}

/// Legs of 60 m north and back at 5 m/s (accelerating and braking at 1.5 m/s², 5 s of
/// hold between legs), as the end-to-end formation test flies them.
fn legs(t: f64) -> (Ned, Ned) {
    let (a, v, d, hold) = (1.5, 5.0, 60.0, 5.0);
    let ta = v / a;
    let tc = (d - v * ta) / v;
    let leg = 2.0 * ta + tc;
    let k = (t / (leg + hold)).floor();
    let tl = t - k * (leg + hold);
    let (s, speed) = if tl < ta {
        (0.5 * a * tl * tl, a * tl)
    } else if tl < ta + tc {
        (0.5 * a * ta * ta + v * (tl - ta), v)
    } else if tl < leg {
        let tb = leg - tl;
        (d - 0.5 * a * tb * tb, a * tb)
    } else {
        (d, 0.0)
    };
    if (k as i64) % 2 == 0 {
        (Ned::new(s, 0.0, -10.0), Ned::new(speed, 0.0, 0.0))
    } else {
        (Ned::new(d - s, 0.0, -10.0), Ned::new(-speed, 0.0, 0.0))
    }
}

#[test]
fn the_correction_cancels_px4s_lag_in_cruise_and_on_a_circle() {
    let g = SlotCorrectionGains::default();
    let (raw_legs, _) = fly_cruising(&legs, 120.0, None, false);
    let (legs_rms, legs_max) = fly_cruising(&legs, 120.0, Some(g), false);
    let (noisy_legs, noisy_max) = fly_cruising(&legs, 120.0, Some(g), true);
    let (raw_orbit, _) = fly(&orbit, 50.0, 20.0, None);
    let (orbit_rms, orbit_max) = fly(&orbit, 50.0, 20.0, Some(g));
    let (cruise_rms, _) = fly(&cruise, 40.0, 10.0, Some(g));
    println!(
        "{}",
        serde_json::json!({
            "legs_60m_5_m_s": {"raw_rms_m": raw_legs, "corrected_rms_m": legs_rms, "corrected_max_m": legs_max,
                               "corrected_with_estimator_noise_rms_m": noisy_legs, "with_noise_max_m": noisy_max},
            "orbit_r25_5_m_s": {"raw_rms_m": raw_orbit, "corrected_rms_m": orbit_rms, "corrected_max_m": orbit_max},
            "long_cruise_5_m_s": {"corrected_rms_m": cruise_rms},
        })
    );
    // PX4's own lag shows without the correction…
    assert!(raw_legs > 0.5, "raw legs {raw_legs}");
    assert!(raw_orbit > 1.0, "raw orbit {raw_orbit}");
    // … and the correction keeps the error well inside the formation's 0.3 m budget.
    assert!(legs_rms < 0.2, "legs {legs_rms}");
    assert!(noisy_legs < 0.3, "legs with estimator noise {noisy_legs}");
    assert!(orbit_rms < 0.15, "orbit {orbit_rms}");
    assert!(cruise_rms < 0.1, "cruise {cruise_rms}");
}
