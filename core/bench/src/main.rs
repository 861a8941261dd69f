//! `skein-bench`: skein's benchmarks, each printing one JSON object on stdout (progress on
//! stderr). `skein bench <what>` runs this executable (it lives beside `skein`); see the
//! crate docs of `skein_bench` for every benchmark.

use clap::Parser;
use std::process::ExitCode;

/// Command line.
#[derive(Parser, Debug)]
#[command(
    name = "skein bench",
    bin_name = "skein bench",
    version,
    about = "skein's benchmarks: each prints one JSON object on stdout."
)]
struct Cli {
    #[command(subcommand)]
    what: skein_bench::BenchWhat,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("SKEIN_LOG")
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
    {
        Ok(r) => r,
        Err(e) => {
            eprintln!("skein bench: cannot start the runtime: {e}");
            return ExitCode::FAILURE;
        }
    };
    skein_swarm::supervision::install_panic_hook();
    match runtime.block_on(skein_bench::run(skein_bench::BenchArgs { what: cli.what })) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("skein bench: {e}");
            ExitCode::FAILURE
        }
    }
}
