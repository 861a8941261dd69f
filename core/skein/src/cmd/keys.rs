//! `skein key create [--out FILE]`: a fresh random MAVLink 2 signing key (32 bytes from the
//! operating system's generator) written as 64 hex characters to a file only its owner
//! can read (mode 0600), and the config line that uses it.

use rand::TryRngCore;
use skein_mavlink::signing::{KEY_LEN, SigningKey};
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `skein key create`.
#[derive(clap::Args, Debug)]
pub struct KeyCreateArgs {
    /// Key file to write (refused if it exists, unless --force).
    #[arg(long, default_value = "mavlink-signing.key")]
    pub out: PathBuf,
    /// Replace an existing file.
    #[arg(long)]
    pub force: bool,
}

/// A new random key.
///
/// # Errors
/// The operating system's random generator failed.
pub fn new_key() -> Result<SigningKey, String> {
    let mut bytes = [0u8; KEY_LEN];
    rand::rngs::OsRng
        .try_fill_bytes(&mut bytes)
        .map_err(|e| format!("no randomness from the operating system: {e}"))?;
    Ok(SigningKey::from_bytes(bytes))
}

/// Runs `skein key create`.
///
/// # Errors
/// The file exists (without `--force`) or cannot be written.
pub fn key_create(args: &KeyCreateArgs) -> Result<ExitCode, String> {
    use std::os::unix::fs::{OpenOptionsExt, PermissionsExt};
    let key = new_key()?;
    let mut opts = std::fs::OpenOptions::new();
    opts.write(true).mode(0o600);
    if args.force {
        opts.create(true).truncate(true);
    } else {
        opts.create_new(true);
    }
    let path = &args.out;
    let mut f = opts.open(path).map_err(|e| {
        if e.kind() == std::io::ErrorKind::AlreadyExists {
            format!("{}: exists (give --force to replace it)", path.display())
        } else {
            format!("{}: {e}", path.display())
        }
    })?;
    // An existing file keeps its mode through `truncate`: make it 0600 either way.
    f.set_permissions(std::fs::Permissions::from_mode(0o600))
        .and_then(|()| writeln!(f, "{}", key.to_hex()))
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let shown = std::fs::canonicalize(path).unwrap_or_else(|_| path.clone());
    println!(
        "wrote a MAVLink 2 signing key to {} (mode 0600)",
        shown.display()
    );
    println!();
    println!("# In the [[vehicles]] table of every vehicle that holds this key:");
    println!("signing_key_file = {:?}", shown.display().to_string());
    println!();
    println!(
        "# The simulator: skein sim --signing-key-file {0} (or skein up --sim N --sim-signing-key-file {0})",
        shown.display()
    );
    Ok(ExitCode::SUCCESS)
}
