//! The geofence as the simulator's PX4 holds it: fence and rally plans uploaded and read
//! back with the mission protocol (PX4's storage limits, refusals, the test fault), and
//! the fence enforced in flight with `GF_ACTION` (hold, return, land), on the virtual
//! clock.
#![allow(deprecated)]

mod common;

use common::*;
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::*;
use skein_model::px4::Px4Mode;
use std::time::Duration;

const SECS: fn(u64) -> Duration = Duration::from_secs;
const FENCE: MavMissionType = MavMissionType::MAV_MISSION_TYPE_FENCE;
const RALLY: MavMissionType = MavMissionType::MAV_MISSION_TYPE_RALLY;

/// A fence item at `(north, east)` metres from the vehicle's spawn point (the default
/// home 47.397742, 8.545594), degE7 with a flat-earth conversion.
fn item(command: MavCmd, param1: f32, north_m: f64, east_m: f64) -> MISSION_ITEM_INT_DATA {
    let lat = 47.397_742 + north_m / 111_195.0;
    let lon = 8.545_594 + east_m / (111_195.0 * 47.397_742f64.to_radians().cos());
    MISSION_ITEM_INT_DATA {
        param1,
        param2: 0.0,
        param3: 0.0,
        param4: 0.0,
        x: (lat * 1e7).round() as i32,
        y: (lon * 1e7).round() as i32,
        z: 0.0,
        seq: 0,
        command,
        target_system: 1,
        target_component: 1,
        frame: MavFrame::MAV_FRAME_GLOBAL,
        current: 0,
        autocontinue: 1,
        mission_type: FENCE,
    }
}

/// A 40 m square inclusion polygon centred on the spawn point.
fn square() -> Vec<MISSION_ITEM_INT_DATA> {
    [(-20.0, -20.0), (20.0, -20.0), (20.0, 20.0), (-20.0, 20.0)]
        .iter()
        .map(|&(n, e)| {
            item(
                MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                4.0,
                n,
                e,
            )
        })
        .collect()
}

/// Uploads `items` as a plan of `mission_type`; the vehicle's final MISSION_ACK result.
async fn upload(
    c: &mut VirtualClient,
    mission_type: MavMissionType,
    items: &[MISSION_ITEM_INT_DATA],
) -> MavMissionResult {
    c.send(&MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count: items.len() as u16,
        target_system: 1,
        target_component: 1,
        mission_type,
        opaque_id: 0,
    }))
    .await;
    loop {
        let answer = c
            .wait_for(SECS(2), |f| match &f.msg {
                MavMessage::MISSION_REQUEST_INT(r) if r.mission_type == mission_type => {
                    Some(Ok(r.seq))
                }
                MavMessage::MISSION_ACK(a) if a.mission_type == mission_type => {
                    Some(Err(a.mavtype))
                }
                _ => None,
            })
            .await
            .expect("a request or an ack");
        match answer {
            Ok(seq) => {
                let mut it = items[usize::from(seq)].clone();
                it.seq = seq;
                it.mission_type = mission_type;
                c.send(&MavMessage::MISSION_ITEM_INT(it)).await;
            }
            Err(result) => return result,
        }
    }
}

/// Downloads the vehicle's plan of `mission_type`.
async fn download(
    c: &mut VirtualClient,
    mission_type: MavMissionType,
) -> Vec<MISSION_ITEM_INT_DATA> {
    c.send(&MavMessage::MISSION_REQUEST_LIST(
        MISSION_REQUEST_LIST_DATA {
            target_system: 1,
            target_component: 1,
            mission_type,
        },
    ))
    .await;
    let count = c
        .wait_for(SECS(2), |f| match &f.msg {
            MavMessage::MISSION_COUNT(n) if n.mission_type == mission_type => Some(n.count),
            _ => None,
        })
        .await
        .expect("MISSION_COUNT");
    let mut items = Vec::new();
    for seq in 0..count {
        c.send(&MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq,
            target_system: 1,
            target_component: 1,
            mission_type,
        }))
        .await;
        let it = c
            .wait_for(SECS(2), |f| match &f.msg {
                MavMessage::MISSION_ITEM_INT(i) if i.seq == seq => Some(i.clone()),
                _ => None,
            })
            .await
            .expect("MISSION_ITEM_INT");
        items.push(it);
    }
    items
}

#[tokio::test]
async fn fence_and_rally_plans_upload_read_back_and_are_refused_as_px4_refuses_them() {
    let mut c = start_virtual(|_| {});
    c.wait_home().await;
    assert_eq!(
        upload(&mut c, FENCE, &square()).await,
        MavMissionResult::MAV_MISSION_ACCEPTED
    );
    let held = download(&mut c, FENCE).await;
    assert_eq!(held.len(), 4);
    for (h, s) in held.iter().zip(square()) {
        assert_eq!(
            (h.command, h.x, h.y, h.param1),
            (s.command, s.x, s.y, s.param1)
        );
    }
    let rally = [MISSION_ITEM_INT_DATA {
        command: MavCmd::MAV_CMD_NAV_RALLY_POINT,
        z: 498.0,
        mission_type: RALLY,
        ..item(MavCmd::MAV_CMD_NAV_RALLY_POINT, 0.0, 5.0, 5.0)
    }];
    assert_eq!(
        upload(&mut c, RALLY, &rally).await,
        MavMissionResult::MAV_MISSION_ACCEPTED
    );
    assert_eq!(download(&mut c, RALLY).await.len(), 1);

    // More than PX4 stores: refused, the plan held unchanged.
    let many: Vec<_> = (0..65)
        .map(|i| {
            let a = f64::from(i) * std::f64::consts::TAU / 65.0;
            item(
                MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                65.0,
                30.0 * a.cos(),
                30.0 * a.sin(),
            )
        })
        .collect();
    assert_eq!(
        upload(&mut c, FENCE, &many).await,
        MavMissionResult::MAV_MISSION_NO_SPACE
    );
    // A vertex count that does not add up, an item of another kind.
    let mut short = square();
    short[3].param1 = 3.0;
    assert_eq!(
        upload(&mut c, FENCE, &short).await,
        MavMissionResult::MAV_MISSION_INVALID_PARAM1
    );
    let waypoint = [item(MavCmd::MAV_CMD_NAV_WAYPOINT, 0.0, 0.0, 0.0)];
    assert_eq!(
        upload(&mut c, FENCE, &waypoint).await,
        MavMissionResult::MAV_MISSION_UNSUPPORTED
    );
    // The test fault: a vehicle that cannot store it.
    c.vehicle
        .set_mission_fault(Some(MavMissionResult::MAV_MISSION_ERROR));
    assert_eq!(
        upload(&mut c, FENCE, &square()[..3]).await,
        MavMissionResult::MAV_MISSION_ERROR
    );
    c.vehicle.set_mission_fault(None);
    assert_eq!(
        download(&mut c, FENCE).await.len(),
        4,
        "every refusal left the plan as it was"
    );
    // A count of 0 clears it.
    assert_eq!(
        upload(&mut c, FENCE, &[]).await,
        MavMissionResult::MAV_MISSION_ACCEPTED
    );
    assert!(download(&mut c, FENCE).await.is_empty());
}

/// Flies to the middle of the square fence in OFFBOARD, then sets a setpoint 40 m north
/// (20 m outside) with `GF_ACTION` = `action`; returns the mode the breach switched to
/// and the furthest north the vehicle went.
async fn fly_across(action: i32) -> (Px4Mode, f64, u64) {
    let mut c = start_virtual(|_| {});
    c.wait_home().await;
    c.param_set_i32("GF_ACTION", action).await;
    assert_eq!(
        upload(&mut c, FENCE, &square()).await,
        MavMissionResult::MAV_MISSION_ACCEPTED
    );
    c.vehicle.take_off_offboard(5.0, 6.0);
    assert!(c.vehicle.armed());
    c.stream(position_setpoint(1, 40.0, 0.0, -5.0), 20.0);
    let mut furthest = 0.0f64;
    let mut mode = Px4Mode::Offboard;
    let deadline = c.now() + SECS(30);
    while c.now() < deadline {
        c.run_for(Duration::from_millis(100));
        furthest = furthest.max(c.vehicle.true_position_ned_m()[0]);
        mode = c.vehicle.truth().mode;
        if mode != Px4Mode::Offboard && c.vehicle.truth().velocity_ned_m_s.horizontal_norm() < 0.2 {
            break;
        }
    }
    (mode, furthest, c.vehicle.stats().geofence_breaches)
}

#[tokio::test]
async fn a_breach_takes_gf_action_hold_return_or_land() {
    let (mode, furthest, breaches) = fly_across(2).await;
    assert_eq!(mode, Px4Mode::Hold);
    assert_eq!(breaches, 1);
    // PX4's offboard position loop flies the 40 m step fast: past the fence at 20 m the
    // vehicle brakes at MPC_ACC_HOR and stops short of the setpoint.
    assert!(
        furthest > 20.0 && furthest < 38.0,
        "stopped at its braking point past the fence, short of the setpoint: {furthest:.1} m"
    );
    let (mode, _, _) = fly_across(3).await;
    assert_eq!(mode, Px4Mode::Rtl);
    let (mode, _, _) = fly_across(5).await;
    assert_eq!(mode, Px4Mode::Land);
}
