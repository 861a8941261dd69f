//! `skein replay FILE.mcap`: plays a recording back into the dashboard (read-only API,
//! see `skein_api::replay_server`).

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;

/// `skein replay`.
#[derive(clap::Args, Debug)]
pub struct ReplayArgs {
    /// The MCAP file (`skein up --record`, `POST /api/v1/recording/start`).
    pub file: PathBuf,
    /// Playback speed, times real time (> 0).
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// Address of the dashboard and the read-only API.
    #[arg(long, default_value = "127.0.0.1:8080")]
    pub http: SocketAddr,
}

/// Serves the replay until Ctrl-C (or SIGTERM).
///
/// # Errors
/// A file that cannot be read or is not a recording, a speed that is not positive, or
/// an address that cannot be bound.
pub async fn run(args: ReplayArgs) -> Result<ExitCode, String> {
    if !(args.speed.is_finite() && args.speed > 0.0) {
        return Err(format!(
            "--speed must be a positive number, got {}",
            args.speed
        ));
    }
    let timeline = skein_record::Timeline::load(&args.file)
        .map_err(|e| format!("{}: {e}", args.file.display()))?;
    let duration_s = timeline.duration_s();
    let messages = timeline.messages.len();
    let state = skein_api::replay_server::ReplayState::new(&args.file, timeline, args.speed);
    let player = state.spawn_player();
    let listener = tokio::net::TcpListener::bind(args.http)
        .await
        .map_err(|e| format!("cannot listen on {}: {e}", args.http))?;
    let local = listener.local_addr().map_err(|e| e.to_string())?;
    println!(
        "skein: replaying {} ({messages} messages, {duration_s:.1} s at {}x): http://{local}/",
        args.file.display(),
        args.speed
    );
    let result =
        skein_api::replay_server::serve(listener, state, crate::process::shutdown_signal())
            .await
            .map_err(|e| e.to_string());
    player.abort();
    result.map(|()| ExitCode::SUCCESS)
}
