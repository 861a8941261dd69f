//! `skein health`: is the skein process behind an API healthy? `GET /api/v1/health`
//! (public, no token) answered `200` with `"status": "ok"` exits 0 and prints one line;
//! anything else (no answer, a 503 from a coordinator that does not answer its API, a
//! timeout) exits 1 saying why. The container image's `HEALTHCHECK` runs it, so the image
//! needs neither a shell nor curl: a coordinator's API listens on 8080 in a container, an
//! agent's own (loopback) API on the port its `--http` gives it.
//!
//! Plain HTTP only (an API with `tls_cert` is checked through a plain-HTTP listener of its
//! own, or by an outside monitor).

use std::process::ExitCode;
use std::time::Duration;

/// `skein health`.
#[derive(clap::Args, Debug)]
pub struct HealthArgs {
    /// Base URL of the API to ask (plain HTTP).
    #[arg(
        long,
        value_name = "URL",
        env = "SKEIN_HEALTH_URL",
        default_value = "http://127.0.0.1:8080"
    )]
    pub url: String,
    /// How long to wait for the answer, seconds.
    #[arg(long, value_name = "S", default_value_t = 3.0)]
    pub timeout_s: f64,
}

/// Asks; prints one line; exit status 0 when healthy, 1 otherwise.
///
/// # Errors
/// A timeout that is not a positive number of seconds.
pub fn health(args: &HealthArgs) -> Result<ExitCode, String> {
    if !(args.timeout_s.is_finite() && args.timeout_s > 0.0 && args.timeout_s <= 3600.0) {
        return Err(format!(
            "--timeout-s {}: not a time in (0, 3600] seconds",
            args.timeout_s
        ));
    }
    let url = format!("{}/api/v1/health", args.url.trim_end_matches('/'));
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .timeout_global(Some(Duration::from_secs_f64(args.timeout_s)))
        .build()
        .into();
    let (status, body) = match agent.get(&url).call() {
        Ok(mut r) => (
            r.status().as_u16(),
            r.body_mut().read_to_string().unwrap_or_default(),
        ),
        Err(e) => {
            println!("skein health: unhealthy: {url}: {e}");
            return Ok(ExitCode::FAILURE);
        }
    };
    let health: serde_json::Value = serde_json::from_str(&body).unwrap_or_default();
    if status == 200 && health["status"] == "ok" {
        let role = health["coordinator_role"]
            .as_str()
            .map(|r| format!("{r} coordinator, "))
            .unwrap_or_default();
        println!(
            "skein health: ok ({role}{} vehicles, {} connected)",
            health["vehicles"], health["connected"]
        );
        Ok(ExitCode::SUCCESS)
    } else {
        println!("skein health: unhealthy: {url}: HTTP {status}: {body}");
        Ok(ExitCode::FAILURE)
    }
}
