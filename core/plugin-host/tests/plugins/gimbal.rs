//! The gimbal plugin: rate-limited pitch, ROI tracking of a moving vehicle, and the
//! Gimbal Protocol v2 messages of the real-gimbal backend.

use crate::spec;
use crate::support::*;
use serde_json::{Value, json};
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::{
    GIMBAL_DEVICE_ATTITUDE_STATUS_DATA, GimbalDeviceErrorFlags, GimbalDeviceFlags,
    GimbalManagerFlags, MavCmd,
};
use skein_plugin_host::{Isolation, PayloadFactory};

fn num(v: &Value, k: &str) -> f64 {
    v[k].as_f64()
        .unwrap_or_else(|| panic!("`{k}` missing in {v}"))
}

fn wrap180(d: f64) -> f64 {
    (d + 180.0).rem_euclid(360.0) - 180.0
}

#[test]
fn pitch_command_is_reached_at_the_rate_limit() {
    let m = manager_with(&["skein-plugin-gimbal"]);
    for isolation in [Isolation::InProcess, Isolation::Process] {
        let world = World::new(true);
        world.put("uav-1", 1, (0.0, 0.0, -20.0), 90.0);
        let mut g = m
            .create(
                &spec(
                    "gimbal",
                    "gimbal",
                    isolation,
                    json!({"max_rate_deg_s": 30.0, "rate_hz": 20}),
                ),
                world.host("uav-1", "gimbal"),
            )
            .unwrap();
        assert_eq!(g.tick_rate_hz(), 20.0);
        let reply = g
            .handle(json!({"command": "set_angles", "pitch_deg": -45.0}))
            .unwrap();
        assert_eq!(reply["mode"], "angles");
        assert_eq!(reply["target"]["pitch_deg"], -45.0);
        // Simulated time: 20 Hz ticks. 45° at 30°/s takes 1.5 s.
        let dt = 0.05;
        let (mut t, mut reached_at, mut last_pitch) = (0.0, None, 0.0);
        while t < 3.0 {
            g.tick(dt).unwrap();
            t += dt;
            let s = world.state("uav-1", "gimbal").unwrap();
            let pitch = num(&s, "pitch_deg");
            assert!(pitch <= last_pitch + 1e-9, "pitch went back up at {t:.2} s");
            assert!(
                (last_pitch - pitch) <= 30.0 * dt + 1e-6,
                "{isolation:?}: moved {} in one tick",
                last_pitch - pitch
            );
            assert!(num(&s, "pitch_rate_deg_s").abs() <= 30.0 + 1e-6);
            if reached_at.is_none() && (pitch + 45.0).abs() < 1e-6 {
                reached_at = Some(t);
            }
            last_pitch = pitch;
        }
        let reached = reached_at.expect("pitch -45 never reached");
        assert!(
            (reached - 1.5).abs() < dt + 1e-9,
            "{isolation:?}: reached at {reached} s"
        );
        let s = world.state("uav-1", "gimbal").unwrap();
        assert_eq!(s["attitude_source"], "simulated");
        assert_eq!(num(&s, "pitch_rate_deg_s"), 0.0);
        // Yaw relative to the vehicle stayed 0: absolute yaw is the vehicle's heading.
        assert!((num(&s, "yaw_absolute_deg") - 90.0).abs() < 1e-9);
        // The quaternion of pitch -45° about the pitch axis: (cos 22.5°, 0, -sin 22.5°, 0).
        let q: Vec<f64> = s["q"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        let half = 22.5f64.to_radians();
        assert!(
            (q[0] - half.cos()).abs() < 1e-6 && (q[2] + half.sin()).abs() < 1e-6,
            "{q:?}"
        );
    }
}

/// Moves two vehicles and checks the gimbal's absolute pointing follows the line of sight.
#[test]
fn roi_on_another_vehicle_tracks_it_while_both_move() {
    let m = manager_with(&["skein-plugin-gimbal"]);
    for isolation in [Isolation::InProcess, Isolation::Process] {
        let world = World::new(true);
        let observer = |t: f64| ((2.0 * t, 0.0, -20.0), (10.0 + 5.0 * t) % 360.0);
        let target = |t: f64| (40.0 - 1.0 * t, -15.0 + 3.0 * t, -30.0 + 0.5 * t);
        let (p, h) = observer(0.0);
        world.put("uav-1", 1, p, h);
        world.put("uav-2", 2, target(0.0), 200.0);
        let mut g = m
            .create(
                &spec(
                    "gimbal",
                    "gimbal",
                    isolation,
                    json!({"max_rate_deg_s": 60.0}),
                ),
                world.host("uav-1", "gimbal"),
            )
            .unwrap();
        let reply = g
            .handle(json!({"command": "roi_vehicle", "vehicle": "uav-2"}))
            .unwrap();
        assert_eq!(reply["mode"], "roi_vehicle");
        assert_eq!(reply["roi"]["vehicle"], "uav-2");
        let dt = 0.05;
        let mut first_yaw = None;
        let mut last_yaw = 0.0;
        for i in 1..=200 {
            let t = f64::from(i) * dt;
            let (p, h) = observer(t);
            world.put("uav-1", 1, p, h);
            world.put("uav-2", 2, target(t), 200.0);
            g.tick(dt).unwrap();
            let s = world.state("uav-1", "gimbal").unwrap();
            if t < 2.0 {
                continue; // slewing onto the target
            }
            // The true line of sight, computed here independently.
            let (o, tg) = (observer(t).0, target(t));
            let (dn, de, dd) = (tg.0 - o.0, tg.1 - o.1, tg.2 - o.2);
            let azimuth = de.atan2(dn).to_degrees();
            let elevation = (-dd).atan2(dn.hypot(de)).to_degrees();
            let yaw_abs = num(&s, "yaw_absolute_deg");
            assert!(
                wrap180(yaw_abs - azimuth).abs() < 0.5,
                "{isolation:?} t={t:.2}: yaw {yaw_abs} vs {azimuth}"
            );
            assert!(
                (num(&s, "pitch_deg") - elevation).abs() < 0.5,
                "t={t:.2}: pitch vs {elevation}"
            );
            // Relative yaw = absolute yaw − heading.
            assert!(wrap180(num(&s, "yaw_deg") + observer(t).1 - yaw_abs).abs() < 1e-6);
            assert!(s["roi"]["range_m"].as_f64().unwrap() > 10.0);
            first_yaw.get_or_insert(yaw_abs);
            last_yaw = yaw_abs;
        }
        // It really had to move to keep up.
        assert!(
            wrap180(last_yaw - first_yaw.unwrap()).abs() > 20.0,
            "{first_yaw:?} → {last_yaw}"
        );

        // A vehicle that leaves the swarm: the gimbal holds and says why.
        world.vehicles.lock().unwrap().retain(|v| v.id != "uav-2");
        g.tick(dt).unwrap();
        let s = world.state("uav-1", "gimbal").unwrap();
        assert_eq!(s["roi_error"], "vehicle `uav-2` is not in the swarm");
        assert!(
            g.handle(json!({"command": "roi_vehicle", "vehicle": "uav-2", "extra": 1}))
                .is_err()
        );
    }
}

#[test]
fn real_gimbal_gets_gimbal_manager_messages_and_reports_device_attitude() {
    let m = manager_with(&["skein-plugin-gimbal"]);
    let world = World::new(false);
    world.put("uav-7", 7, (0.0, 0.0, -20.0), 30.0);
    world.put("uav-8", 8, (0.0, 50.0, -20.0), 0.0);
    let mut g = m
        .create(
            &spec(
                "gimbal",
                "gimbal",
                Isolation::InProcess,
                json!({"manager_compid": 1}),
            ),
            world.host("uav-7", "gimbal"),
        )
        .unwrap();
    let sent = |world: &World| -> Vec<MavMessage> {
        world
            .mavlink
            .lock()
            .unwrap()
            .drain(..)
            .map(|(_, m)| m)
            .collect()
    };
    // Taking control of the gimbal manager at creation.
    let first = sent(&world);
    assert!(
        matches!(&first[..], [MavMessage::COMMAND_LONG(c)]
            if c.command == MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE && c.param1 == -2.0 && c.target_system == 7),
        "{first:?}"
    );
    // Angles → GIMBAL_MANAGER_SET_PITCHYAW in the vehicle frame, radians.
    g.handle(json!({"command": "set_angles", "pitch_deg": -45.0, "yaw_deg": 10.0}))
        .unwrap();
    match &sent(&world)[..] {
        [MavMessage::GIMBAL_MANAGER_SET_PITCHYAW(p)] => {
            assert!((p.pitch - (-45f32).to_radians()).abs() < 1e-6);
            assert!((p.yaw - 10f32.to_radians()).abs() < 1e-6);
            assert!(p.pitch_rate.is_nan() && p.yaw_rate.is_nan());
            assert!(
                p.flags
                    .contains(GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_YAW_IN_VEHICLE_FRAME)
            );
            assert_eq!((p.target_system, p.target_component), (7, 1));
        }
        other => panic!("{other:?}"),
    }
    // ROI at a location → DO_SET_ROI_LOCATION as COMMAND_INT with lat/lon in degE7.
    g.handle(
        json!({"command": "roi_location", "lat_deg": 47.4, "lon_deg": 8.55, "alt_amsl_m": 500.0}),
    )
    .unwrap();
    match &sent(&world)[..] {
        [MavMessage::COMMAND_INT(c)] => {
            assert_eq!(c.command, MavCmd::MAV_CMD_DO_SET_ROI_LOCATION);
            assert_eq!((c.x, c.y), (474_000_000, 85_500_000));
            assert_eq!(c.z, 500.0);
        }
        other => panic!("{other:?}"),
    }
    // Tracking a vehicle: earth-frame setpoints from the tick, at track_send_hz (10 Hz).
    g.handle(json!({"command": "roi_vehicle", "sysid": 8}))
        .unwrap();
    assert!(
        matches!(&sent(&world)[..], [MavMessage::COMMAND_LONG(c)] if c.command == MavCmd::MAV_CMD_DO_SET_ROI_NONE)
    );
    for _ in 0..20 {
        g.tick(0.05).unwrap();
    }
    let setpoints = sent(&world);
    assert_eq!(setpoints.len(), 10, "{setpoints:?}");
    for s in &setpoints {
        let MavMessage::GIMBAL_MANAGER_SET_PITCHYAW(p) = s else {
            panic!("{s:?}")
        };
        assert!(
            p.flags
                .contains(GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_YAW_IN_EARTH_FRAME)
        );
        // uav-8 is due east, level: yaw 90° absolute, pitch 0.
        assert!(
            (p.yaw.to_degrees() - 90.0).abs() < 1e-3 && p.pitch.abs() < 1e-4,
            "{p:?}"
        );
    }
    // The device's attitude comes from GIMBAL_DEVICE_ATTITUDE_STATUS.
    assert_eq!(
        world.state("uav-7", "gimbal").unwrap()["attitude_source"],
        "none"
    );
    let half = (-30f32).to_radians() / 2.0;
    g.on_mavlink(
        154,
        &MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(GIMBAL_DEVICE_ATTITUDE_STATUS_DATA {
            time_boot_ms: 1,
            q: [half.cos(), 0.0, half.sin(), 0.0],
            angular_velocity_x: 0.0,
            angular_velocity_y: 0.1,
            angular_velocity_z: 0.0,
            failure_flags: GimbalDeviceErrorFlags::empty(),
            flags: GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME,
            target_system: 0,
            target_component: 0,
            delta_yaw: f32::NAN,
            delta_yaw_velocity: f32::NAN,
            gimbal_device_id: 0,
        }),
    )
    .unwrap();
    g.tick(0.05).unwrap();
    let s = world.state("uav-7", "gimbal").unwrap();
    assert_eq!(s["attitude_source"], "GIMBAL_DEVICE_ATTITUDE_STATUS");
    assert!((num(&s, "pitch_deg") + 30.0).abs() < 1e-3, "{s}");
    assert!((num(&s, "pitch_rate_deg_s") - 0.1f64.to_degrees()).abs() < 1e-3);
    // Messages it did not ask for are filtered before they reach it.
    g.on_mavlink(1, &MavMessage::HEARTBEAT(Default::default()))
        .unwrap();
    sent(&world);
    drop(g);
    // Shutdown hands the gimbal manager back.
    assert!(matches!(&sent(&world)[..], [MavMessage::COMMAND_LONG(c)] if c.param1 == -3.0));
}
