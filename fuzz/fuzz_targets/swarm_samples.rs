//! Swarm protocol samples: arbitrary bytes as the payload of a `skein_msgs/SwarmMessage`
//! on `/skein/swarm/*` or `/skein/formation`, decoded as RustDDS decodes a sample for
//! skein's readers (`skein_dds::msgs::from_cdr`), unwrapped (`Envelope::from_msg`), its
//! body read as every protocol type the agent and the coordinator read (`Envelope::body`:
//! targets and commands, reports, answers, events, the formation mirror), and its
//! positions converted into a receiver's swarm frame as they do (`reframe::reframed`,
//! which refuses a body whose positions are no points there). Nothing may panic, and
//! every position of a body that is read and converted is finite.
#![no_main]

use libfuzzer_sys::fuzz_target;
use skein_dds::envelope::{Envelope, ReportBody};
use skein_dds::msgs::{SwarmMessage, from_cdr};
use skein_dds::reframe::{Reframe, reframed};
use skein_model::geo::{GeoPoint, Ned, NedFrame};
use skein_swarm::formation::{FormationMirror, LeaderMotion};
use skein_swarm::protocol::{FromVehicle, ToVehicle};
use skein_swarm::{Command, SwarmEvent};

fn finite(what: &str, p: Ned) {
    assert!(
        p.north_m.is_finite() && p.east_m.is_finite() && p.down_m.is_finite(),
        "{what} not finite after the conversion: {p:?}"
    );
}

fuzz_target!(|data: &[u8]| {
    let Ok(m) = from_cdr::<SwarmMessage>(data) else {
        return;
    };
    let env = Envelope::from_msg(m);
    // The receiver: a frame of its own (Zurich), as an agent or a coordinator has.
    let frame = NedFrame::new(GeoPoint::new(47.397, 8.545, 488.0));
    let reframe = Reframe::new(env.origin, frame);
    let r = reframe.as_ref();
    if let Ok(msg) = env.body::<ToVehicle>() {
        match reframed(msg, r, |r, m| r.to_vehicle(m)) {
            Some(ToVehicle::Slot {
                target: Some(target),
            }) => {
                finite("a slot target", target.position);
                finite("a slot goal", target.goal);
            }
            Some(ToVehicle::Command {
                command: Command::GoTo(goto),
                ..
            }) => finite("a go-to point", goto.target()),
            _ => {}
        }
    }
    if let Ok(body) = env.body::<ReportBody>() {
        if let Some(report) = reframed(body.report, r, |r, x| r.report(x)) {
            report
                .position
                .into_iter()
                .for_each(|p| finite("a report's position", p));
            report
                .target
                .into_iter()
                .for_each(|p| finite("a report's target", p));
        }
        if let Some(snapshot) = reframed(body.snapshot, r, |r, x| r.snapshot(x))
            && let Some(f) = snapshot.formation
        {
            finite("a snapshot's formation target", f.target);
        }
    }
    if let Ok(Some(mirror)) = env.body::<Option<FormationMirror>>()
        && let Some(mirror) = reframed(mirror, r, |r, m| r.mirror(m))
    {
        finite("a mirror's reference", mirror.reference.position);
        match mirror.reference.motion {
            LeaderMotion::Hold => {}
            LeaderMotion::GoTo { target, .. } => finite("a mirror's go-to", target),
            LeaderMotion::Waypoints { points, .. } => {
                points
                    .into_iter()
                    .for_each(|p| finite("a mirror's waypoint", p));
            }
            LeaderMotion::Orbit { centre, .. } => finite("a mirror's orbit centre", centre),
        }
    }
    let _ = env.body::<FromVehicle>();
    let _ = env.body::<SwarmEvent>();
});
