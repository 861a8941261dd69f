//! The flying mission carried through a coordinator failover: the active coordinator
//! mirrors it whole ([`MissionMirror`], published on `/skein/mission` by the DDS carrier
//! beside the formation's mirror); a standby that takes the role flies it on from the
//! mirror, converted into its swarm frame and clock ([`MissionRun::take_over`]: the same
//! step, its lanes and laps as they were, every vehicle's current point commanded again
//! from where it is). One that steps down lets its own run go: the active one flies the
//! mission, and this one resumes the mirror should it claim the role again.

use super::super::CoordinatorState;
use crate::events::SwarmEvent;
use serde::{Deserialize, Serialize};
use skein_mission::MissionRun;

/// The flying mission as the active coordinator mirrors it (`/skein/mission`, JSON).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MissionMirror {
    /// The mission's id (`m-3`): the new active coordinator keeps it.
    pub id: String,
    /// Its run, whole: plan, step, routes, clocks, reactions (positions in the
    /// sender's swarm frame until the receiver converts them).
    pub run: MissionRun,
    /// When it was mirrored, µs on the sender's wall clock (the receiver's once
    /// converted).
    pub stamp_us: u64,
}

impl CoordinatorState {
    /// The flying mission to mirror (`None`: none flies).
    pub(in crate::coordinator) fn mission_mirror(&mut self) -> Option<MissionMirror> {
        let (id, m) = self.missions.flying()?;
        Some(MissionMirror {
            id: id.clone(),
            run: m.run.clone()?,
            stamp_us: crate::protocol::wall_us(),
        })
    }

    /// Flies on `mirror`, the mission of coordinator `from` (its positions and stamp in
    /// this process's frame and clock), unless one flies here.
    pub(in crate::coordinator) fn resume_mission(&mut self, mirror: MissionMirror, from: &str) {
        if let Some((flying, _)) = self.missions.flying() {
            tracing::warn!(
                "mission {} of `{from}` is not resumed: mission {flying} flies here",
                mirror.id
            );
            return;
        }
        let MissionMirror {
            id,
            mut run,
            stamp_us,
        } = mirror;
        let age_s = crate::protocol::wall_us().saturating_sub(stamp_us) as f64 / 1e6;
        let actions = run.take_over(age_s);
        let (state, step) = (run.status().state, run.status().step);
        tracing::warn!(
            "resuming mission {id} `{}` of `{from}` at step {step} ({state:?}), mirrored \
             {age_s:.1} s ago",
            run.plan().name
        );
        self.missions.adopt(&id, run);
        self.apply_mission(&id, actions);
        self.emit(SwarmEvent::MissionStep { id, state, step });
    }

    /// This coordinator stepped down: the active one flies its mission now.
    pub(in crate::coordinator) fn missions_stepped_down(&mut self, reason: &str) {
        if let Some(id) = self.missions.let_go() {
            tracing::warn!(
                "mission {id} is left to the active coordinator: this one stepped down \
                 ({reason})"
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::MissionMirror;
    use crate::coordinator::distributed::DistributedMsg;
    use crate::coordinator::missions::MissionMsg;
    use crate::coordinator::swarm::tests::swarm_on_udp;
    use std::time::Duration;

    /// A coordinator given another's mirror flies it on under the same id, at the same
    /// step; once it steps down it flies it no more (and mirrors nothing).
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_mirrored_mission_is_flown_on_and_let_go_at_a_step_down() {
        let swarm = swarm_on_udp().await;
        let plan: skein_mission::MissionPlan = serde_json::from_value(serde_json::json!({
            "name": "carried",
            "steps": [{"kind": "takeoff", "altitude_m": 10.0, "interval_s": 60.0},
                      {"kind": "land"}]
        }))
        .unwrap();
        let groups = vec![vec!["uav-9".to_string()], vec!["uav-9".to_string()]];
        let mut run = skein_mission::MissionRun::new(plan, groups);
        run.start();
        let mirror = MissionMirror {
            id: "m-7".into(),
            run,
            stamp_us: crate::protocol::wall_us(),
        };
        let cast = |m: DistributedMsg| swarm.coordinator.cast(m.into()).expect("cast");
        cast(DistributedMsg::ResumeMission(
            Box::new(mirror),
            "gcs-b".into(),
        ));
        let ask = || async {
            swarm
                .coordinator
                .call(
                    |r| MissionMsg::Get("m-7".into(), r).into(),
                    Some(Duration::from_secs(5)),
                )
                .await
                .expect("the coordinator answers")
                .success_or(())
                .expect("an answer")
        };
        let info = ask().await.expect("m-7 adopted");
        assert_eq!(info.status.state, skein_mission::RunState::Running);
        assert_eq!(info.name, "carried");
        let mirrored = || async {
            swarm
                .coordinator
                .call(
                    |r| DistributedMsg::GetMissionMirror(r).into(),
                    Some(Duration::from_secs(5)),
                )
                .await
                .expect("the coordinator answers")
                .success_or(())
                .expect("an answer")
        };
        assert_eq!(mirrored().await.map(|m| m.id), Some("m-7".to_string()));

        cast(DistributedMsg::SteppedDown("handed over to gcs-a".into()));
        assert!(mirrored().await.is_none(), "a standby flies no mission");
        assert_eq!(
            ask().await.unwrap().status.state,
            skein_mission::RunState::Ready
        );
        swarm.coordinator.stop(None);
    }
}
