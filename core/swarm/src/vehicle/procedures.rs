//! Procedures: the multi-step operations behind a command (arm, land, RTL, entering
//! OFFBOARD for a takeoff, hold or go-to), run as tasks against the link actor that post
//! their outcome back as [`VehicleMsg::ProcedureDone`], so the actor never blocks. A
//! newer command supersedes a running procedure by generation.

use super::VehicleActorState;
use super::control::Target;
use super::messages::{Child, ProcedureStep, VehicleMsg};
use super::shared::Memory;
use ractor::ActorRef;
use skein_link::{LinkCommand, Px4LinkMsg, VehicleLink};
use skein_model::fsm::{Event, VehicleState};
use skein_model::px4::Px4Mode;
use std::time::{Duration, Instant};

/// How long PX4 must have seen setpoints before OFFBOARD is requested (PX4 needs > 1 s).
pub const OFFBOARD_PRESTREAM: Duration = Duration::from_millis(1100);

impl VehicleActorState {
    pub(super) fn start_procedure(
        &self,
        myself: &ActorRef<VehicleMsg>,
        mem: &mut Memory,
        command_id: u64,
        command: &'static str,
        work: Procedure,
    ) {
        mem.procedure += 1;
        let generation = mem.procedure;
        mem.entering_offboard = (matches!(work, Procedure::EnterOffboard { .. })
            && mem.state != VehicleState::TakingOff)
            .then_some(generation);
        let link = self.shared.link.clone();
        let Some(actor) = self.children.actor::<Px4LinkMsg>(&Child::Link) else {
            let _ = myself.cast(VehicleMsg::ProcedureDone {
                generation,
                command_id,
                command,
                result: Err("link actor not running".into()),
            });
            return;
        };
        let me = myself.clone();
        tokio::spawn(async move {
            let result = work.run(&link, &actor).await;
            let _ = me.cast(VehicleMsg::ProcedureDone {
                generation,
                command_id,
                command,
                result,
            });
        });
    }

    pub(super) fn procedure_done(
        &self,
        generation: u64,
        command_id: u64,
        command: &'static str,
        result: Result<ProcedureStep, String>,
    ) {
        let mut mem = self.shared.memory();
        if mem.entering_offboard == Some(generation) {
            mem.entering_offboard = None;
        }
        if generation != mem.procedure {
            // A later command took over the vehicle: report what this one achieved, but
            // don't act on it (e.g. no climb from a takeoff that was cancelled).
            drop(mem);
            self.emit_result(command_id, command, result.map(|_| ()));
            return;
        }
        match &result {
            Ok(ProcedureStep::OffboardEngaged) if mem.state == VehicleState::TakingOff => {
                // Climb from where the vehicle is to the takeoff altitude above home.
                let frame = self.swarm_frame();
                let home_down = self.shared.link.with_telemetry(|t| {
                    let home = t.home?;
                    Some(frame?.to_ned(&home.geo).down_m)
                });
                if let (Some(home_down), Some(target)) = (home_down, mem.target) {
                    let mut p = target.position();
                    p.down_m = home_down - mem.takeoff_altitude_m;
                    mem.target = Some(Target::Hold(p));
                    mem.offboard_engaged = true;
                } else {
                    drop(mem);
                    self.fail_procedure(command_id, command, "home position lost".into());
                    return;
                }
            }
            Ok(_) => {}
            Err(e) => {
                let e = e.clone();
                drop(mem);
                self.fail_procedure(command_id, command, e);
                return;
            }
        }
        drop(mem);
        self.emit_result(command_id, command, result.map(|_| ()));
    }

    pub(super) fn fail_procedure(&self, command_id: u64, command: &'static str, error: String) {
        let mut mem = self.shared.memory();
        if let Some(o) = self.observed() {
            let _ = self.apply(&mut mem, Event::ProcedureFailed(o));
        }
        drop(mem);
        tracing::warn!(id = %self.shared.id, "{command} failed: {error}");
        self.emit_result(command_id, command, Err(error));
    }
}

/// A multi-step operation run as a task against the link actor.
pub(super) enum Procedure {
    /// One command, acknowledged.
    Link(LinkCommand),
    /// Wait until the stream has run long enough, arm if asked, switch to OFFBOARD and
    /// see it confirmed.
    EnterOffboard {
        /// Arm first.
        arm: bool,
    },
}

/// Longest wait for one link command (ACK retries plus mode confirmation).
const LINK_CALL_TIMEOUT: Duration = Duration::from_secs(10);

async fn link_call(actor: &ActorRef<Px4LinkMsg>, cmd: LinkCommand) -> Result<(), String> {
    match ractor::call_t!(
        actor,
        Px4LinkMsg::Command,
        LINK_CALL_TIMEOUT.as_millis() as u64,
        cmd
    ) {
        Ok(Ok(())) => Ok(()),
        Ok(Err(e)) => Err(e.to_string()),
        Err(e) => Err(format!("link actor unavailable: {e}")),
    }
}

/// PX4 stays in LAND (or RTL) after touching down and refuses to arm there: on the
/// ground, switch to HOLD first.
async fn leave_landing_modes(
    link: &VehicleLink,
    actor: &ActorRef<Px4LinkMsg>,
) -> Result<(), String> {
    let on_ground_in_landing_mode = link.with_telemetry(|t| {
        t.observed().is_some_and(|o| {
            !o.airborne() && matches!(o.mode, Px4Mode::Land | Px4Mode::Rtl | Px4Mode::Precland)
        })
    });
    if on_ground_in_landing_mode {
        link_call(actor, LinkCommand::SetMode(Px4Mode::Hold)).await?;
    }
    Ok(())
}

impl Procedure {
    async fn run(
        self,
        link: &VehicleLink,
        actor: &ActorRef<Px4LinkMsg>,
    ) -> Result<ProcedureStep, String> {
        match self {
            Procedure::Link(cmd) => {
                if cmd == LinkCommand::Arm {
                    leave_landing_modes(link, actor).await?;
                }
                link_call(actor, cmd).await?;
                Ok(ProcedureStep::Acknowledged)
            }
            Procedure::EnterOffboard { arm } => {
                let deadline = Instant::now() + Duration::from_secs(5);
                loop {
                    let since = link.stream().streaming_since();
                    if since.is_some_and(|s| s.elapsed() >= OFFBOARD_PRESTREAM) {
                        break;
                    }
                    if Instant::now() > deadline {
                        return Err("setpoint stream did not start".into());
                    }
                    tokio::time::sleep(Duration::from_millis(20)).await;
                }
                if arm {
                    leave_landing_modes(link, actor).await?;
                    link_call(actor, LinkCommand::Arm).await?;
                }
                link_call(actor, LinkCommand::SetMode(Px4Mode::Offboard)).await?;
                Ok(ProcedureStep::OffboardEngaged)
            }
        }
    }
}
