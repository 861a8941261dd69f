//! MAVLink 2 signing in the simulator, as PX4 v1.16 does it (`MAV_SIGN_CFG`,
//! `SETUP_SIGNING`), over real UDP with skein's own encoder.

mod common;

use common::{GroundStation, start};
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::*;
use skein_mavlink::signing::{LinkSigning, SigningKey, timestamp_now};
use std::sync::Arc;
use std::time::Duration;

fn setup_signing(key: &SigningKey) -> MavMessage {
    MavMessage::SETUP_SIGNING(SETUP_SIGNING_DATA {
        initial_timestamp: timestamp_now(),
        target_system: 1,
        target_component: 1,
        secret_key: *key.as_bytes(),
    })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn setup_signing_replaces_the_key_only_when_signed_with_the_current_one() {
    let old = SigningKey::from_bytes([1; 32]);
    let new = SigningKey::from_bytes([2; 32]);
    let thief = SigningKey::from_bytes([3; 32]);
    let (sim, mut clients) = start(1, |c| {
        c.signing_key = Some(old.clone());
        c.params.push(("MAV_SIGN_CFG".into(), 2.0));
    })
    .await;
    let c = &mut clients[0];
    // The vehicle signs what it sends.
    let signed_hb = c
        .wait_for(Duration::from_secs(5), |f| {
            matches!(f.msg, MavMessage::HEARTBEAT(_)).then_some(())
        })
        .await;
    assert!(signed_hb.is_some(), "no heartbeat");
    assert!(sim.stats()[0].signing.frames_signed > 0);

    // Unsigned, then signed with a wrong key: SETUP_SIGNING is dropped like any frame.
    c.send(&setup_signing(&thief)).await;
    c.enc
        .set_signing(Some(Arc::new(LinkSigning::new(thief.clone(), 0))));
    c.send(&setup_signing(&thief)).await;
    assert!(
        common::eventually(Duration::from_secs(5), || {
            let s = sim.stats()[0].signing;
            s.unsigned >= 1 && s.bad_signature >= 1
        })
        .await
    );
    // Still the old key: a command signed with it is obeyed.
    c.enc
        .set_signing(Some(Arc::new(LinkSigning::new(old.clone(), 0))));
    c.wait_home().await;
    assert_eq!(c.arm(true).await, MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(c.arm(false).await, MavResult::MAV_RESULT_ACCEPTED);

    // Signed with the current key: the key is replaced.
    c.send(&setup_signing(&new)).await;
    // The key is installed once the vehicle's own frames verify with it.
    let installed = LinkSigning::new(new.clone(), 0);
    let deadline = std::time::Instant::now() + Duration::from_secs(5);
    loop {
        let datagram = c.next_raw(Duration::from_secs(5)).await.expect("a frame");
        let first = &datagram[..usize::from(datagram[1]) + 12 + 13];
        if installed.verify(first) == skein_mavlink::signing::Verdict::Valid {
            break;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "the vehicle never signed with the new key"
        );
    }
    let before = sim.stats()[0].signing.bad_signature;
    let old_cmd = c.command_long_msg(
        MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        0,
    );
    c.send(&old_cmd).await;
    assert!(
        common::eventually(Duration::from_secs(5), || {
            sim.stats()[0].signing.bad_signature > before
        })
        .await,
        "a frame signed with the replaced key was not refused"
    );
    assert!(!sim.truth(1).unwrap().armed);
    // With the new key: obeyed, and the vehicle's frames now verify with it.
    let new_signing = Arc::new(LinkSigning::new(new.clone(), 0));
    c.enc.set_signing(Some(new_signing));
    assert_eq!(c.arm(true).await, MavResult::MAV_RESULT_ACCEPTED);
    let check = LinkSigning::new(new, 0);
    c.clear();
    let datagram = c.next_raw(Duration::from_secs(5)).await.expect("a frame");
    // The first frame of the datagram: header, payload, CRC and the 13-byte signature.
    let first = &datagram[..usize::from(datagram[1]) + 12 + 13];
    assert_eq!(
        check.verify(first),
        skein_mavlink::signing::Verdict::Valid,
        "the vehicle does not sign with the new key"
    );
}
