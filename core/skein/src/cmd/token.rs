//! `skein token create --role viewer|operator|admin [--name NAME]`: a new API token and
//! the `[[http.tokens]]` lines (name, role, salted hash) to add to the config; the token
//! itself is stored nowhere (see `skein_api::auth`).

use std::process::ExitCode;

/// `skein token create`.
#[derive(clap::Args, Debug)]
pub struct TokenCreateArgs {
    /// viewer (reads, the stream), operator (flies: commands, formation, payloads) or
    /// admin (plugins, parameter writes, faults, and everything else).
    #[arg(long)]
    pub role: skein_api::roles::Role,
    /// Who holds it (shown in the dashboard); default: the role.
    #[arg(long)]
    pub name: Option<String>,
}

/// Prints a new token and its config lines.
///
/// # Errors
/// The OS's random generator failed, or `--name` holds a quote, backslash or newline.
pub fn token_create(args: &TokenCreateArgs) -> Result<ExitCode, String> {
    let token = skein_api::auth::new_token()?;
    let hash = skein_api::auth::hash_token(&token)?;
    let name = args.name.clone().unwrap_or_else(|| args.role.to_string());
    if name.contains(['"', '\\', '\n']) {
        return Err(format!(
            "--name {name:?}: no quotes, backslashes or newlines"
        ));
    }
    println!("token: {token}");
    println!();
    println!("# Add to the [http] part of the config file (the token itself is not stored):");
    println!("[[http.tokens]]");
    println!("name = \"{name}\"");
    println!("role = \"{}\"", args.role);
    println!("hash = \"{hash}\"");
    Ok(ExitCode::SUCCESS)
}
