//! What an agent does with its vehicles before it exits on SIGTERM (systemd's stop,
//! `docker stop`, `docker compose down`) or Ctrl-C: a process that simply ended would
//! stop every offboard setpoint stream, and each PX4 would fall into its offboard-loss
//! failsafe. Instead the agent puts every vehicle it has in the air into a PX4 mode that
//! needs no companion computer, waits until PX4 has it, and only then exits (0):
//!
//! - `land` (the default): `MAV_CMD_NAV_LAND` (PX4 AUTO.LAND) through the vehicle's own
//!   command path; done when the vehicle is on the ground and disarmed;
//! - `rtl`: `MAV_CMD_NAV_RETURN_TO_LAUNCH` (PX4 AUTO.RTL); done once the vehicle is
//!   returning (PX4 flies home and lands by itself);
//! - `hold`: PX4's Hold mode (AUTO.LOITER, `MAV_CMD_DO_SET_MODE`, confirmed from the
//!   `HEARTBEAT`) through the link, as a failing vehicle's escalation does; done once PX4
//!   reports the mode.
//!
//! `[agent] shutdown_action` / `--shutdown-action` choose, `shutdown_timeout_s` bounds the
//! wait (default 60 s: a landing from 10 m takes 15-25 s). Vehicles on the ground, or
//! whose link is already lost (nothing reaches them), are left as they are. Past the
//! timeout the agent exits with a failure naming the vehicles still in the air; a second
//! signal ends the wait at once.

use ractor::ActorRef;
use ractor::rpc::CallResult;
use skein_link::{LinkCommand, Px4LinkMsg};
use skein_model::fsm::VehicleState;
use skein_model::px4::Px4Mode;
use skein_model::vehicle::VehicleSnapshot;
use skein_swarm::{Command, CommandMsg, CoordinatorMsg, FleetMsg};
use std::collections::BTreeMap;
use std::str::FromStr;
use std::time::{Duration, Instant};

/// The PX4 mode an agent leaves its airborne vehicles in when it exits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ShutdownAction {
    /// PX4 Hold (AUTO.LOITER): stay where it is.
    Hold,
    /// PX4 AUTO.LAND: land where it is (the default).
    Land,
    /// PX4 AUTO.RTL: return to launch and land there.
    Rtl,
}

impl FromStr for ShutdownAction {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "hold" => Ok(ShutdownAction::Hold),
            "land" => Ok(ShutdownAction::Land),
            "rtl" => Ok(ShutdownAction::Rtl),
            _ => Err(format!("`{s}` is not a shutdown action (hold, land, rtl)")),
        }
    }
}

impl ShutdownAction {
    fn name(self) -> &'static str {
        match self {
            ShutdownAction::Hold => "hold",
            ShutdownAction::Land => "land",
            ShutdownAction::Rtl => "rtl",
        }
    }
}

/// What to do with the vehicles at shutdown, and how long to wait for it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ShutdownPlan {
    /// The mode the airborne vehicles are left in.
    pub action: ShutdownAction,
    /// The longest wait for every vehicle to be in it.
    pub timeout: Duration,
}

impl Default for ShutdownPlan {
    fn default() -> Self {
        ShutdownPlan {
            action: ShutdownAction::Land,
            timeout: Duration::from_secs(60),
        }
    }
}

/// How long one question to the coordinator may take.
const ASK: Duration = Duration::from_secs(5);

async fn vehicles(coordinator: &ActorRef<CoordinatorMsg>) -> Result<Vec<VehicleSnapshot>, String> {
    match coordinator
        .call(|r| FleetMsg::ListVehicles(r).into(), Some(ASK))
        .await
    {
        Ok(CallResult::Success(v)) => Ok(v),
        _ => Err("the coordinator did not list the vehicles".into()),
    }
}

/// Done with `v` under `action`: it is in the mode asked for (or on the ground).
fn secured(action: ShutdownAction, v: &VehicleSnapshot) -> bool {
    if !v.state.is_airborne() {
        return true;
    }
    match action {
        ShutdownAction::Land => false,
        ShutdownAction::Rtl => v.state == VehicleState::ReturnToLaunch,
        // Confirmed by the link's own command (see `hold`).
        ShutdownAction::Hold => false,
    }
}

/// Puts PX4 `id` into Hold through its link; `Ok` once its `HEARTBEAT` says so.
async fn hold(
    coordinator: &ActorRef<CoordinatorMsg>,
    id: &str,
    within: Duration,
) -> Result<(), String> {
    let name = id.to_string();
    let link = match coordinator
        .call(|r| FleetMsg::GetLink(name, r).into(), Some(ASK))
        .await
    {
        Ok(CallResult::Success(Ok(link))) => link,
        Ok(CallResult::Success(Err(e))) => return Err(format!("{id}: no link ({e:?})")),
        _ => return Err(format!("{id}: the coordinator did not answer")),
    };
    match link
        .call(
            |r| Px4LinkMsg::Command(LinkCommand::SetMode(Px4Mode::Hold), r),
            Some(within),
        )
        .await
    {
        Ok(CallResult::Success(Ok(()))) => Ok(()),
        Ok(CallResult::Success(Err(e))) => Err(format!("{id}: Hold not confirmed ({e})")),
        _ => Err(format!("{id}: Hold not confirmed in time")),
    }
}

/// Puts every airborne vehicle of this process into the PX4 mode of `plan` and waits
/// until each is in it (see the module docs). Prints what it does on stdout.
///
/// # Errors
/// The vehicles still airborne (with their states) at the timeout, or a coordinator that
/// does not answer.
pub(crate) async fn secure_vehicles(
    coordinator: &ActorRef<CoordinatorMsg>,
    plan: ShutdownPlan,
) -> Result<(), String> {
    let started = Instant::now();
    let deadline = started + plan.timeout;
    let action = plan.action;
    let mut pending = airborne(coordinator).await?;
    if pending.is_empty() {
        println!("skein: shutdown: no vehicle in the air");
        return Ok(());
    }
    let list = listing(&pending);
    println!("skein: shutdown: {} first: {list}", action.name());
    crate::service::stopping(&format!("{}: {list}", action.name()));
    let command = match action {
        ShutdownAction::Hold => return hold_all(coordinator, &pending, started, deadline).await,
        ShutdownAction::Land => Command::Land,
        ShutdownAction::Rtl => Command::Rtl,
    };
    for id in pending.keys() {
        command_vehicle(coordinator, id, command.clone()).await;
    }
    loop {
        let now = vehicles(coordinator).await?;
        settle(action, &now, &mut pending, started);
        if pending.is_empty() {
            return Ok(());
        }
        if Instant::now() >= deadline {
            return Err(format!(
                "still in the air after {:.0} s: {}",
                plan.timeout.as_secs_f64(),
                listing(&pending)
            ));
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}

/// The connected airborne vehicles and their states; those whose link is lost are left
/// as they are (said on stdout).
async fn airborne(
    coordinator: &ActorRef<CoordinatorMsg>,
) -> Result<BTreeMap<String, VehicleState>, String> {
    let mut pending = BTreeMap::new();
    for v in vehicles(coordinator).await? {
        if !v.state.is_airborne() {
            continue;
        }
        if !v.state.is_connected() {
            println!(
                "skein: shutdown: {} is {}: nothing reaches it, left as it is",
                v.id, v.state
            );
            continue;
        }
        pending.insert(v.id, v.state);
    }
    Ok(pending)
}

/// `id (state), …` of `pending`.
fn listing(pending: &BTreeMap<String, VehicleState>) -> String {
    pending
        .iter()
        .map(|(id, s)| format!("{id} ({s})"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Puts every vehicle of `pending` in PX4 Hold, each confirmed by its link from PX4's
/// HEARTBEAT or failed, before `deadline`.
async fn hold_all(
    coordinator: &ActorRef<CoordinatorMsg>,
    pending: &BTreeMap<String, VehicleState>,
    started: Instant,
    deadline: Instant,
) -> Result<(), String> {
    let mut failed = Vec::new();
    for id in pending.keys() {
        let left = deadline.saturating_duration_since(Instant::now());
        match hold(coordinator, id, left).await {
            Ok(()) => println!(
                "skein: shutdown: {id} holds (PX4 Hold) after {:.1} s",
                started.elapsed().as_secs_f64()
            ),
            Err(e) => {
                eprintln!("skein: shutdown: {e}");
                failed.push(e);
            }
        }
    }
    if failed.is_empty() {
        Ok(())
    } else {
        Err(format!("not holding: {}", failed.join("; ")))
    }
}

/// Gives vehicle `id` `command` through the coordinator; a refusal or a lost command is
/// said on stderr (the wait that follows tells the outcome).
async fn command_vehicle(coordinator: &ActorRef<CoordinatorMsg>, id: &str, command: Command) {
    let name = id.to_string();
    match coordinator
        .call(
            |r| CommandMsg::VehicleCommand(name, command, r).into(),
            Some(ASK),
        )
        .await
    {
        Ok(CallResult::Success(Ok(outcome))) if outcome.refused.is_empty() => {}
        Ok(CallResult::Success(Ok(outcome))) => {
            for r in outcome.refused {
                eprintln!("skein: shutdown: {}: {}", r.id, r.reason);
            }
        }
        _ => eprintln!("skein: shutdown: {id}: the command was not delivered"),
    }
}

/// Takes out of `pending` the vehicles of `now` that are done under `action` (or whose
/// link is lost), saying so on stdout and to systemd.
fn settle(
    action: ShutdownAction,
    now: &[VehicleSnapshot],
    pending: &mut BTreeMap<String, VehicleState>,
    started: Instant,
) {
    for v in now {
        let Some(state) = pending.get_mut(&v.id) else {
            continue;
        };
        *state = v.state;
        if !secured(action, v) && v.state.is_connected() {
            continue;
        }
        let what = if !v.state.is_connected() {
            format!("is {} (nothing reaches it)", v.state)
        } else if v.state.is_airborne() {
            format!("is {}", v.state)
        } else {
            "landed".to_string()
        };
        let line = format!(
            "shutdown: {} {what} after {:.1} s",
            v.id,
            started.elapsed().as_secs_f64()
        );
        println!("skein: {line}");
        crate::service::status(&line);
        pending.remove(&v.id);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn actions_parse_by_name_and_refuse_others() {
        assert_eq!("land".parse(), Ok(ShutdownAction::Land));
        assert_eq!("hold".parse(), Ok(ShutdownAction::Hold));
        assert_eq!("rtl".parse(), Ok(ShutdownAction::Rtl));
        let e = "stay".parse::<ShutdownAction>().unwrap_err();
        assert!(e.contains("hold, land, rtl"), "{e}");
    }
}
