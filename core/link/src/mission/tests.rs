//! The mission client against a scripted vehicle: uploads and downloads step by step,
//! errors, resends and time-outs, queueing, answers meant for another ground station.
#![allow(deprecated)] // MISSION_REQUEST, which PX4 may still send

use super::*;
use skein_mavlink::dialect::MISSION_REQUEST_DATA;
use tokio::sync::oneshot;

const T: (u8, u8) = (1, 1);
const US: (u8, u8) = (255, 190);
const FENCE: MavMissionType = MavMissionType::MAV_MISSION_TYPE_FENCE;

fn vertex(i: i32) -> MissionItem {
    MissionItem {
        command: MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
        frame: MavFrame::MAV_FRAME_GLOBAL,
        params: [3.0, 0.0, 0.0, 0.0],
        x: 473_977_420 + i,
        y: 85_455_940,
        z: 0.0,
    }
}

fn request_int(seq: u16) -> MavMessage {
    MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
        seq,
        target_system: US.0,
        target_component: US.1,
        mission_type: FENCE,
    })
}

fn vehicle_ack(result: MavMissionResult) -> MavMessage {
    MavMessage::MISSION_ACK(MISSION_ACK_DATA {
        target_system: US.0,
        target_component: US.1,
        mavtype: result,
        mission_type: FENCE,
        opaque_id: 0,
    })
}

fn only(out: &[MissionTransmit]) -> &MavMessage {
    assert_eq!(out.len(), 1, "{out:?}");
    &out[0].msg
}

#[test]
fn an_upload_answers_each_request_and_ends_on_the_vehicles_ack() {
    let mut c = MissionClient::default();
    let (tx, mut rx) = oneshot::channel();
    let items = vec![vertex(0), vertex(1), vertex(2)];
    let out = c.start(FENCE, MissionOp::Upload(items.clone(), Some(tx.into())), T);
    let MavMessage::MISSION_COUNT(count) = only(&out) else {
        panic!("{out:?}")
    };
    assert_eq!((count.count, count.mission_type), (3, FENCE));
    for seq in 0..3u16 {
        let out = c.on_message(&request_int(seq), US, T);
        let MavMessage::MISSION_ITEM_INT(item) = only(&out) else {
            panic!("{out:?}")
        };
        assert_eq!(item.seq, seq);
        assert_eq!(MissionItem::from_message(item), items[usize::from(seq)]);
    }
    // PX4 may ask with the float request too.
    let old = MavMessage::MISSION_REQUEST(MISSION_REQUEST_DATA {
        seq: 2,
        target_system: US.0,
        target_component: US.1,
        mission_type: FENCE,
    });
    assert_eq!(c.on_message(&old, US, T).len(), 1);
    assert!(rx.try_recv().is_err(), "not done before the ack");
    assert!(
        c.on_message(&vehicle_ack(MavMissionResult::MAV_MISSION_ACCEPTED), US, T)
            .is_empty()
    );
    assert_eq!(rx.try_recv().unwrap(), Ok(()));
    assert!(!c.busy(FENCE));
}

#[test]
fn an_error_ack_fails_the_upload_naming_the_result() {
    let mut c = MissionClient::default();
    let (tx, mut rx) = oneshot::channel();
    c.start(
        FENCE,
        MissionOp::Upload(vec![vertex(0)], Some(tx.into())),
        T,
    );
    c.on_message(&vehicle_ack(MavMissionResult::MAV_MISSION_NO_SPACE), US, T);
    assert_eq!(
        rx.try_recv().unwrap(),
        Err(LinkError::Rejected {
            command: "fence upload".into(),
            result: "MAV_MISSION_NO_SPACE".into(),
            statustexts: vec![],
        })
    );
}

#[test]
fn answers_for_another_ground_station_are_ignored() {
    let mut c = MissionClient::default();
    c.start(FENCE, MissionOp::Upload(vec![vertex(0)], None), T);
    let theirs = MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
        seq: 0,
        target_system: 42,
        target_component: 190,
        mission_type: FENCE,
    });
    assert!(c.on_message(&theirs, US, T).is_empty());
    // Another mission type's messages do not touch the fence transfer either.
    let rally = MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
        seq: 0,
        target_system: US.0,
        target_component: US.1,
        mission_type: MavMissionType::MAV_MISSION_TYPE_RALLY,
    });
    assert!(c.on_message(&rally, US, T).is_empty());
    assert!(c.busy(FENCE));
}

#[test]
fn a_download_requests_every_item_and_acknowledges_the_last() {
    let mut c = MissionClient::default();
    let (tx, mut rx) = oneshot::channel();
    let out = c.start(FENCE, MissionOp::Download(Some(tx.into())), T);
    assert!(matches!(only(&out), MavMessage::MISSION_REQUEST_LIST(_)));
    let count = MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count: 2,
        target_system: US.0,
        target_component: US.1,
        mission_type: FENCE,
        opaque_id: 0,
    });
    let out = c.on_message(&count, US, T);
    assert!(matches!(only(&out), MavMessage::MISSION_REQUEST_INT(r) if r.seq == 0));
    assert!(c.on_message(&count, US, T).is_empty(), "a repeated count");
    for seq in 0..2u16 {
        let item = vertex(i32::from(seq)).to_message(seq, US, FENCE);
        let out = c.on_message(&item, US, T);
        if seq == 0 {
            assert!(matches!(only(&out), MavMessage::MISSION_REQUEST_INT(r) if r.seq == 1));
            // The same item again (a duplicate) changes nothing.
            assert!(c.on_message(&item, US, T).is_empty());
        } else {
            let MavMessage::MISSION_ACK(a) = only(&out) else {
                panic!("{out:?}")
            };
            assert_eq!(a.mavtype, MavMissionResult::MAV_MISSION_ACCEPTED);
        }
    }
    assert_eq!(rx.try_recv().unwrap(), Ok(vec![vertex(0), vertex(1)]));
}

#[test]
fn silence_resends_the_last_message_then_times_out() {
    let mut c = MissionClient::default();
    let (tx, mut rx) = oneshot::channel();
    let out = c.start(
        FENCE,
        MissionOp::Upload(vec![vertex(0)], Some(tx.into())),
        T,
    );
    let (_, mut generation) = out[0].deadline.unwrap();
    let out = c.on_message(&request_int(0), US, T);
    generation = out[0].deadline.map_or(generation, |d| d.1);
    for _ in 1..MISSION_ATTEMPTS {
        let out = c.on_deadline(FENCE, generation, T);
        assert!(
            matches!(only(&out), MavMessage::MISSION_ITEM_INT(_)),
            "the item again"
        );
    }
    assert!(
        c.on_deadline(FENCE, generation - 1, T).is_empty(),
        "a stale deadline"
    );
    assert!(c.on_deadline(FENCE, generation, T).is_empty());
    assert_eq!(
        rx.try_recv().unwrap(),
        Err(LinkError::Timeout {
            command: "fence upload".into(),
            attempts: MISSION_ATTEMPTS
        })
    );
}

#[test]
fn operations_on_one_type_wait_their_turn() {
    let mut c = MissionClient::default();
    c.start(FENCE, MissionOp::Upload(vec![], None), T);
    assert!(
        c.start(FENCE, MissionOp::Download(None), T).is_empty(),
        "queued"
    );
    // The (empty) upload's ack starts the download.
    let out = c.on_message(&vehicle_ack(MavMissionResult::MAV_MISSION_ACCEPTED), US, T);
    assert!(matches!(only(&out), MavMessage::MISSION_REQUEST_LIST(_)));
}
