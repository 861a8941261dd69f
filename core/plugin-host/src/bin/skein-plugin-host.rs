//! A standalone `plugin-host` child: the same as `skein plugin-host`, for tests and for
//! deployments that keep the child executable separate from `skein`.
//!
//! Usage: `skein-plugin-host --socket PATH --library PATH` (started by the plugin manager,
//! not by hand).

use std::process::ExitCode;

fn main() -> ExitCode {
    match skein_plugin_host::PluginHostArgs::parse(std::env::args_os().skip(1)) {
        Ok(args) => skein_plugin_host::plugin_host_main(args),
        Err(e) => {
            eprintln!("{e}");
            ExitCode::from(2)
        }
    }
}
