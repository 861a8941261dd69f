//! `skein mission rehearse PLAN`: a mission plan (JSON, or TOML by its `.toml` name)
//! rehearsed in virtual time on the swarm `skein up --sim N` would fly, without starting
//! anything: the configuration's settings (separation, loop rates, geofence, models), and
//! `N` simulated vehicles laid out as the simulator lays them (their models as `--sim`
//! gives them). It prints the rehearsal's figures as JSON (those of `POST
//! /api/v1/missions/{id}/rehearse`, the picture written to `--svg` instead) and exits 0
//! when the mission ended `done`, 1 when it did not, 2 on bad input.

use crate::config::ConfigFile;
use skein_mission::MissionPlan;
use skein_mission::resolve;
use skein_mission::swarm::VehicleSetup;
use skein_model::geo::NedFrame;
use skein_rehearse::Scenario;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// `skein mission`.
#[derive(clap::Subcommand, Debug)]
pub enum MissionCommand {
    /// Rehearse a plan in virtual time and print its figures (JSON).
    Rehearse(RehearseArgs),
}

/// `skein mission rehearse`.
#[derive(clap::Args, Debug)]
pub struct RehearseArgs {
    /// The plan: JSON (`POST /api/v1/missions`'s body), or TOML when its name ends in
    /// `.toml` (the same fields).
    pub plan: PathBuf,
    /// The configuration `skein up` would run with (its `[swarm]` settings, geofence and
    /// models); default: the built-in settings.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// How many simulated vehicles fly it (uav-1 … uav-N, as `skein up --sim N`).
    #[arg(long, default_value_t = 4)]
    pub sim: usize,
    /// Every vehicle's model (default: as `skein up --sim`, the even ones `observation`,
    /// the others `generic`).
    #[arg(long, value_name = "MODEL")]
    pub sim_model: Option<String>,
    /// The scenario: a JSON file with `POST /api/v1/missions/{id}/rehearse`'s body
    /// (intruders, seed, max_duration_s).
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Where to write the picture (SVG); default: not written.
    #[arg(long)]
    pub svg: Option<PathBuf>,
}

/// Runs `skein mission`.
pub fn run(command: MissionCommand) -> ExitCode {
    match command {
        MissionCommand::Rehearse(args) => match rehearse(&args) {
            Ok(report) => {
                let done = report.state == skein_mission::RunState::Done;
                if let Err(e) = print(report, args.svg.as_deref()) {
                    eprintln!("skein mission rehearse: {e}");
                    return ExitCode::from(2);
                }
                if done {
                    ExitCode::SUCCESS
                } else {
                    ExitCode::FAILURE
                }
            }
            Err(e) => {
                eprintln!("skein mission rehearse: {e}");
                ExitCode::from(2)
            }
        },
    }
}

/// The rehearsal of `args` (see the module docs).
///
/// # Errors
/// An unreadable or invalid plan, configuration or scenario (the field named), no
/// vehicle, an unknown model, a plan group the fleet cannot fill.
fn rehearse(args: &RehearseArgs) -> Result<skein_rehearse::RehearsalReport, String> {
    let file = match &args.config {
        Some(path) => ConfigFile::load(path)?,
        None => ConfigFile::default(),
    };
    let config = file.swarm_config()?;
    let origin = config.swarm_origin.unwrap_or(skein_sim::PX4_SITL_HOME);
    let plan = read_plan(&args.plan, &NedFrame::new(origin))?;
    if !(1..=255).contains(&args.sim) {
        return Err(format!("--sim {}: 1 to 255 vehicles", args.sim));
    }
    if let Some(m) = &args.sim_model
        && !config.models.contains_key(m)
    {
        return Err(format!("--sim-model {m}: no such vehicle model"));
    }
    skein_swarm::coordinator::missions::check_plan(&plan, &config, &config.geofence)
        .map_err(|e| format!("{}: {}: {}", args.plan.display(), e.field, e.error))?;
    let scenario = read_scenario(args.scenario.as_deref())?;
    let spacing_m = crate::compose::spawn_spacing_m(config.setpoint_separation_m());
    let cols = (args.sim as f64).sqrt().ceil() as usize;
    let vehicles: Vec<VehicleSetup> = (1..=args.sim)
        .map(|sysid| {
            let model = args
                .sim_model
                .clone()
                .unwrap_or_else(|| crate::compose::sim_mix_model(sysid).to_string());
            let m = config.model(&model);
            VehicleSetup {
                id: format!("uav-{sysid}"),
                home: skein_sim::spawn_offset(sysid - 1, cols, spacing_m),
                limits: m.limits,
                observer: m.payloads.iter().any(|p| p.kind == "gimbal"),
                model,
                battery_percent: None,
                battery_capacity_mah: None,
            }
        })
        .collect();
    let members = skein_mission::swarm::members(&vehicles);
    let groups =
        resolve::groups(&plan, &members).map_err(|e| format!("{}: {}", e.field, e.error))?;
    let swarm = skein_swarm::coordinator::missions::rehearsal_swarm(
        &config,
        config.geofence.clone(),
        origin,
        vehicles,
    );
    skein_rehearse::rehearse(&plan, groups, &swarm, &scenario)
        .map_err(|e| format!("scenario: {}: {}", e.field, e.error))
}

/// The plan in `path` (TOML by a `.toml` name, else JSON), its latitude/longitude points
/// put into `frame`, the swarm frame of the rehearsal.
fn read_plan(path: &Path, frame: &NedFrame) -> Result<MissionPlan, String> {
    let at = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let text = std::fs::read_to_string(path).map_err(|e| at(&e))?;
    let mut plan: serde_json::Map<String, serde_json::Value> =
        if path.extension().is_some_and(|e| e == "toml") {
            toml::from_str(&text).map_err(|e| at(&e))?
        } else {
            serde_json::from_str(&text).map_err(|e| at(&e))?
        };
    skein_mission::geodetic::points_to_swarm_frame(&mut plan, Some(frame))
        .map_err(|e| at(&format!("{}: {}", e.field, e.error)))?;
    serde_json::from_value(serde_json::Value::Object(plan)).map_err(|e| at(&e))
}

/// The scenario in `path` (JSON), checked; none: the default.
fn read_scenario(path: Option<&Path>) -> Result<Scenario, String> {
    let Some(path) = path else {
        return Ok(Scenario::default());
    };
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let scenario: Scenario =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    scenario
        .check()
        .map_err(|e| format!("{}: {}: {}", path.display(), e.field, e.error))?;
    Ok(scenario)
}

/// Prints `report` as JSON, its picture written to `svg` (and left out of the JSON).
fn print(mut report: skein_rehearse::RehearsalReport, svg: Option<&Path>) -> Result<(), String> {
    if let Some(path) = svg {
        std::fs::write(path, &report.picture_svg)
            .map_err(|e| format!("{}: {e}", path.display()))?;
    }
    report.picture_svg = svg.map_or_else(String::new, |p| p.display().to_string());
    let json = serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?;
    println!("{json}");
    Ok(())
}
