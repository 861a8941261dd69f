//! What the endpoint's route does with a frame from the vehicle: the autopilot's messages
//! that carry its boot clock are applied to the telemetry on the receive task, the rest
//! go to the [`super::Px4Link`] actor.

use super::{FrameSink, Px4LinkMsg, VehicleLink};
use crate::endpoint::FrameHandler;
use crate::telemetry::{Change, boot_time_ms};
use ractor::ActorRef;
use skein_mavlink::Frame;
use std::sync::Arc;

/// The route of one vehicle (see the module docs): `link` is its shared state,
/// `components` where its component traffic goes, `actor` its link actor.
///
/// The route holds `link` weakly. The endpoint keeps a route for its whole life and the
/// link holds the endpoint, so a strong reference here would keep both alive, and with
/// them the setpoint stream, after everything else had let go: a stopped swarm went on
/// streaming its last setpoints to every vehicle, unsupervised, for the life of the
/// process. The vehicle's state holds the link while its actors restart, so a restart
/// does not drop it.
pub(super) fn handler(
    link: &Arc<VehicleLink>,
    components: Option<FrameSink>,
    actor: ActorRef<Px4LinkMsg>,
) -> FrameHandler {
    let compid = link.compid;
    let link = Arc::downgrade(link);
    Arc::new(move |f| {
        let Some(link) = link.upgrade() else {
            return; // the vehicle is gone: nobody to tell
        };
        if applies_on_route(&f, compid) {
            // Position, attitude and the boot clock change nothing but the telemetry:
            // applied here, on the receive task, they cost no actor message (they are most
            // of the traffic of a large swarm).
            if let Some(sink) = &components {
                sink(&f);
            }
            let change = link.apply(&f.msg);
            if change != Change::None {
                let _ = actor.cast(Px4LinkMsg::Applied(change));
            }
        } else {
            let _ = actor.cast(Px4LinkMsg::Frame(f));
        }
    })
}

/// Whether the route applies `frame` to the telemetry itself instead of handing it to the
/// actor: the autopilot's messages that carry its boot clock ([`boot_time_ms`]:
/// `LOCAL_POSITION_NED`, `GLOBAL_POSITION_INT`, `ATTITUDE`, `SYSTEM_TIME`), which no
/// command, parameter or mission exchange waits for. What they change that matters (a
/// reboot seen in their `time_boot_ms`) still reaches the actor as
/// [`Px4LinkMsg::Applied`].
///
/// All of them or none: the reboot check compares the boot clock across these messages,
/// and one applied by the actor, behind its mailbox, after a later one the route applied
/// would look like the clock going back. With `SYSTEM_TIME` left to the actor, an actor
/// 200 ms behind on a busy machine saw reboots that never happened (the vehicle's home
/// forgotten, its procedure failed, a formation leader dropped out).
pub(super) fn applies_on_route(frame: &Frame, autopilot_compid: u8) -> bool {
    frame.compid == autopilot_compid && boot_time_ms(&frame.msg).is_some()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::telemetry::Telemetry;
    use skein_mavlink::MavMessage;
    use skein_mavlink::dialect::{
        ATTITUDE_DATA, GLOBAL_POSITION_INT_DATA, HEARTBEAT_DATA, LOCAL_POSITION_NED_DATA,
        SYSTEM_TIME_DATA,
    };
    use std::time::Instant;

    fn frame(compid: u8, msg: MavMessage) -> Frame {
        Frame {
            sysid: 1,
            compid,
            seq: 0,
            version: 2,
            msg,
        }
    }

    fn clocked(ms: u32) -> [MavMessage; 4] {
        [
            MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
                time_boot_ms: ms,
                ..Default::default()
            }),
            MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
                time_boot_ms: ms,
                ..Default::default()
            }),
            MavMessage::ATTITUDE(ATTITUDE_DATA {
                time_boot_ms: ms,
                ..Default::default()
            }),
            MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA {
                time_boot_ms: ms,
                ..Default::default()
            }),
        ]
    }

    #[test]
    fn every_message_with_the_boot_clock_is_applied_on_the_route_and_nothing_else() {
        for msg in clocked(1000) {
            assert!(applies_on_route(&frame(1, msg.clone()), 1), "{msg:?}");
            // Another component's (a camera's) goes to the actor, which hands it on.
            assert!(!applies_on_route(&frame(100, msg.clone()), 1), "{msg:?}");
        }
        let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
        assert!(!applies_on_route(&frame(1, hb), 1));
    }

    #[test]
    fn messages_applied_in_arrival_order_see_no_reboot_however_late_the_actor_is() {
        // The autopilot's stream over 2 s: every kind of clocked message each 50 ms. Applied
        // in the order they arrive (all on the route), the clock never goes back.
        let mut t = Telemetry::default();
        for ms in (0..2000).step_by(50) {
            for msg in clocked(ms) {
                assert_eq!(t.apply(&msg, Instant::now()), Change::None, "{ms} ms");
            }
        }
        // What the split between route and actor did: a SYSTEM_TIME 300 ms old, applied
        // after the positions that followed it, reads as a reboot.
        let late = &clocked(1650)[3];
        assert_eq!(t.apply(late, Instant::now()), Change::Rebooted);
    }
}
