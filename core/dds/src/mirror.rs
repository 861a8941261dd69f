//! The formation mirror on `/skein/formation`: the active coordinator publishes its
//! formation ([`FormationMirror`]) at 5 Hz, `null` when it flies none; every standby
//! keeps the latest one of the highest epoch, converted into its own swarm frame. When a
//! standby takes the role, it flies that formation on from where it was (its reference
//! moved on by the mirror's age), so a failover costs the formation no more than the
//! lease timeout of stale targets: the agents move their last targets on by their age
//! meanwhile, and hold only after `coordinator_timeout_s`.
//!
//! The topic is transient-local: a standby that starts late gets the last formation at
//! once.

use crate::envelope::{Envelope, body_or_drop};
use crate::link::DdsShared;
use crate::reframe::{into_view, reframed};
use skein_swarm::election::CoordinatorRole;
use skein_swarm::formation::FormationMirror;
use skein_swarm::{CoordinatorMsg, DistributedMsg};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

/// How often the active coordinator publishes its formation.
pub const MIRROR_PERIOD: Duration = Duration::from_millis(200);

/// The latest formation heard from another coordinator.
struct Heard {
    from: String,
    epoch: u64,
    mirror: Option<FormationMirror>,
}

/// Runs the mirror until the task is aborted (see the module docs).
pub(crate) async fn run(shared: Arc<DdsShared>) {
    let (Some(topics), Some(election)) = (shared.protocol(), shared.election()) else {
        return;
    };
    let Some(view) = shared.view().await else {
        tracing::error!("dds: the coordinator did not answer: no formation mirror");
        return;
    };
    let me = election.borrow().this.coordinator_id.clone();
    let mut was_active = election.borrow().role == CoordinatorRole::Active;
    let mut heard: Option<Heard> = None;
    let mut tick = tokio::time::interval(MIRROR_PERIOD);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tick.tick().await;
        loop {
            let env = match topics.formation.reader.take() {
                Ok(Some((m, _))) => Envelope::from_msg(m),
                Ok(None) => break,
                Err(e) => {
                    shared.counters.malformed.fetch_add(1, Ordering::Relaxed);
                    tracing::warn!("dds: a formation sample was dropped: {e:?}");
                    continue;
                }
            };
            if env.sender_id == me || heard.as_ref().is_some_and(|h| h.epoch > env.epoch) {
                continue;
            }
            let Some(mirror) = body_or_drop::<Option<FormationMirror>>(&shared, &env, "formation")
            else {
                continue;
            };
            let reframe = into_view(&view, env.origin);
            heard = Some(Heard {
                from: env.sender_id,
                epoch: env.epoch,
                mirror: mirror.map(|m| reframed(m, reframe.as_ref(), |r, x| r.mirror(x))),
            });
        }
        let (active, epoch) = {
            let s = election.borrow();
            (s.role == CoordinatorRole::Active, s.this.epoch)
        };
        if active
            && !was_active
            && let Some(h) = heard.take()
            && h.epoch < epoch
            && let Some(mirror) = h.mirror
        {
            let _ = shared.coordinator().cast(CoordinatorMsg::Distributed(
                DistributedMsg::ResumeFormation(mirror, h.from),
            ));
        }
        was_active = active;
        if active
            && let Some(mirror) = shared.formation_mirror().await
            && let Ok(m) = Envelope::message("", &me, epoch, view.frame(), &mirror)
        {
            shared.count(topics.formation.writer.publish(m));
        }
    }
}
