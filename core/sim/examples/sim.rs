//! The simulator alone, as `skein sim` runs it: `cargo run -p skein-sim --example sim --
//! --vehicles 3 --stats 127.0.0.1:0`.

use clap::Parser;

/// `skein sim` without the rest of skein.
#[derive(Parser, Debug)]
#[command(
    name = "sim",
    about = "PX4 SITL-like multicopter simulator (MAVLink 2 over UDP)"
)]
struct Cli {
    #[command(flatten)]
    sim: skein_sim::cli::SimArgs,
}

#[tokio::main]
async fn main() -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    skein_sim::cli::run(Cli::parse().sim).await
}
