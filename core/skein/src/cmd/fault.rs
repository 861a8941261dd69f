//! `skein fault --target PATH --kind panic|hang|stop|error`: injects a fault into an actor
//! of a running skein through its API (`POST /api/v1/faults`, which answers only with
//! `--enable-fault-injection` and an admin token).

use std::process::ExitCode;
use std::time::Duration;

/// `skein fault`.
#[derive(clap::Args, Debug)]
pub struct FaultArgs {
    /// Base URL of the running skein's API.
    #[arg(long, default_value = "http://127.0.0.1:8080")]
    pub url: String,
    /// API token (admin); default: the SKEIN_TOKEN environment variable.
    #[arg(long)]
    pub token: Option<String>,
    /// Actor path, e.g. coordinator/uav-1/px4link (see GET /api/v1/supervision).
    #[arg(long)]
    pub target: String,
    /// What to do to it: panic, hang, stop or error.
    #[arg(long)]
    pub kind: String,
}

/// Sends the fault; prints the API's answer.
///
/// # Errors
/// The API could not be reached, or it refused (the error holds its status and body).
pub fn fault(args: FaultArgs) -> Result<ExitCode, String> {
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .timeout_global(Some(Duration::from_secs(10)))
        .build()
        .into();
    let url = format!("{}/api/v1/faults", args.url.trim_end_matches('/'));
    let mut req = agent.post(&url);
    if let Some(t) = args
        .token
        .clone()
        .or_else(|| std::env::var("SKEIN_TOKEN").ok())
    {
        req = req.header("Authorization", format!("Bearer {t}"));
    }
    let mut resp = req
        .send_json(serde_json::json!({"target": args.target, "kind": args.kind}))
        .map_err(|e| format!("{url}: {e}"))?;
    let status = resp.status().as_u16();
    let body = resp.body_mut().read_to_string().unwrap_or_default();
    if status == 202 {
        println!("{body}");
        Ok(ExitCode::SUCCESS)
    } else {
        Err(format!("{url}: HTTP {status}: {body}"))
    }
}
