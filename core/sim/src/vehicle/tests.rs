//! Unit tests of the vehicle: flight logic against the wall-clock protocol timers.

use super::test_harness::{Harness, env};
use super::*;
use crate::client;

#[test]
fn holds_position_against_wind_and_gusts() {
    // 5 m/s with 1 m/s gusts: with SIH's drag (1 N/(m/s) on 1 kg) and the 45° tilt
    // limit, winds much above 9 m/s cannot be held at all, as on PX4 SIH.
    let wind = WindConfig::from_direction(5.0, 270.0, 1.0);
    let mut h = Harness::new(env(wind, 0.0, 7));
    h.takeoff();
    h.run(10.0);
    let mut worst: f64 = 0.0;
    let mut tilt: f64 = 0.0;
    for _ in 0..200 {
        h.run(0.1);
        worst = worst.max(h.v.pos.horizontal_norm());
        tilt = tilt.max(h.v.roll_rad.abs().max(h.v.pitch_rad.abs()));
    }
    // SIH drag turns the wind into 5 m/s² that only PX4's slow velocity integrator
    // cancels: gusts push the vehicle about as they push PX4.
    assert!(worst < 1.5, "drifted {worst} m in 5 m/s wind");
    assert!(tilt > 0.03, "not leaning into the wind: {tilt} rad");
    assert!(
        (h.v.pos.down_m + 2.5).abs() < 0.3,
        "altitude {}",
        h.v.pos.down_m
    );
}

#[test]
fn same_seed_same_trajectory_different_seed_different() {
    let wind = WindConfig::from_direction(5.0, 200.0, 1.5);
    let fly = |seed: u64| {
        let mut h = Harness::new(env(wind, 1.0, seed));
        h.takeoff();
        h.run(5.0);
        (h.v.pos, h.v.est_noise)
    };
    assert_eq!(fly(42), fly(42));
    assert_ne!(fly(42), fly(43));
}

#[test]
fn offboard_speed_limits_and_yaw_keep() {
    let mut h = Harness::new(env(WindConfig::default(), 0.0, 0));
    h.run(0.1);
    h.setpoint(type_mask::POSITION_YAW, [0.0, 0.0, -10.0], [0.0; 3]);
    let (main, sub) = Px4Mode::Offboard.main_sub();
    let acks = h.command(
        MavCmd::MAV_CMD_DO_SET_MODE,
        [1.0, f32::from(main), f32::from(sub), 0.0, 0.0, 0.0, 0.0],
    );
    assert_eq!(
        acks,
        vec![
            MavResult::MAV_RESULT_ACCEPTED,
            MavResult::MAV_RESULT_ACCEPTED
        ]
    );
    assert_eq!(
        h.command(
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        ),
        vec![MavResult::MAV_RESULT_ACCEPTED]
    );
    // Climb: limited to MPC_Z_VEL_MAX_UP (3 m/s).
    let mut max_up: f64 = 0.0;
    for _ in 0..40 {
        h.stream(0.1, type_mask::POSITION_YAW, [0.0, 0.0, -10.0], [0.0; 3]);
        max_up = max_up.max(-h.v.vel.down_m);
    }
    assert!(max_up > 2.8 && max_up <= 3.05, "climb rate {max_up}");
    // 20 m/s asked: MPC_XY_VEL_MAX (12 m/s) limits the setpoint, and SIH's drag at the
    // tilt limit (MPC_TILTMAX_AIR 45°: g tan 45° = 9.8 m/s² against 1 /s of drag) the
    // speed flown; yaw ignored → heading kept.
    let yaw0 = h.v.yaw_rad;
    h.stream(
        8.0,
        type_mask::VELOCITY_YAW_RATE | type_mask::IGNORE_YAW_RATE,
        [0.0; 3],
        [20.0, 0.0, 0.0],
    );
    let v = h.v.vel.horizontal_norm();
    assert!(v > 9.0 && v < 12.0, "speed {v}");
    assert!((h.v.ctrl_vel_sp.horizontal_norm() - 12.0).abs() < 1e-6);
    assert!((h.v.yaw_rad - yaw0).abs() < 1e-9);
    // Tilt stays within MPC_TILTMAX_AIR.
    assert!(h.v.roll_rad.abs().max(h.v.pitch_rad.abs()) <= 45f64.to_radians() + 1e-3);
}

#[test]
fn forced_disarm_in_air_falls_and_lands() {
    let mut h = Harness::new(env(WindConfig::default(), 0.0, 0));
    h.takeoff();
    let r = h.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [0.0; 7]);
    assert_eq!(
        r,
        vec![MavResult::MAV_RESULT_DENIED],
        "disarm in air must need force"
    );
    let r = h.command(
        MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        [0.0, FORCE_ARM_DISARM_MAGIC, 0.0, 0.0, 0.0, 0.0, 0.0],
    );
    assert_eq!(r, vec![MavResult::MAV_RESULT_ACCEPTED]);
    h.run(2.0);
    assert!(!h.v.armed && h.v.landed && h.v.pos.down_m == 0.0);
    assert_eq!(h.v.landed_state(), LandedState::OnGround);
}

#[test]
fn battery_drains_faster_in_flight() {
    let mut idle = Harness::new(env(WindConfig::default(), 0.0, 0));
    idle.run(60.0);
    let mut flying = Harness::new(env(WindConfig::default(), 0.0, 0));
    flying.takeoff();
    flying.run(54.0);
    assert!(idle.v.battery.remaining > flying.v.battery.remaining);
    assert!(
        flying.v.battery.consumed_mah > 150.0,
        "{}",
        flying.v.battery.consumed_mah
    );
    assert!(flying.v.battery.voltage_v < idle.v.battery.voltage_v);
}

#[test]
fn land_mode_descends_at_mpc_land_speed_near_the_ground() {
    let mut h = Harness::new(env(WindConfig::default(), 0.0, 0));
    h.takeoff();
    h.command(MavCmd::MAV_CMD_NAV_LAND, [0.0; 7]);
    h.run(1.5);
    assert!(
        (h.v.vel.down_m - 0.7).abs() < 0.1,
        "descent {}",
        h.v.vel.down_m
    );
    // Crawl below MPC_LAND_ALT3 (0.3 m/s), PX4's land-detector stages, COM_DISARM_LAND.
    h.run(15.0);
    assert!(h.v.landed && !h.v.armed, "not landed and disarmed");
}

#[test]
fn gcs_link_loss_takes_nav_dll_act() {
    let mut e = env(WindConfig::default(), 0.0, 0);
    e.params = vec![("NAV_DLL_ACT".into(), 2.0), ("COM_DL_LOSS_T".into(), 2.0)];
    let mut h = Harness::new(e);
    let gcs = client::gcs_heartbeat;
    h.input(gcs());
    h.run(0.1);
    let nan = f32::NAN;
    h.command(
        MavCmd::MAV_CMD_NAV_TAKEOFF,
        [0.0, 0.0, 0.0, nan, nan, nan, nan],
    );
    h.command(
        MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    );
    for _ in 0..10 {
        h.input(gcs());
        h.run(1.0);
    }
    assert_eq!(h.v.mode, Px4Mode::Hold);
    h.run(2.5);
    assert_eq!(h.v.mode, Px4Mode::Rtl, "no failsafe after COM_DL_LOSS_T");
    assert!(h.v.failsafe);
    assert_eq!(h.v.counters.gcs_loss_failsafes, 1);
}
