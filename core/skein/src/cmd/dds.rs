//! DDS Security from the command line (see `skein_dds::security`):
//!
//! - `skein dds keystore create DIR`: a new SROS 2 keystore (identity and permissions CAs,
//!   signed governance);
//! - `skein dds enclave create DIR --enclave /skein/agent/a2 --role agent`: a participant's
//!   key, certificate and signed permissions for its role;
//! - [`DdsSecurityArgs`]: `--dds-keystore DIR --dds-enclave NAME`, which `skein up --dds`,
//!   `skein agent` and `skein coordinator` share, resolved with `[dds] keystore`/`enclave`
//!   and ROS 2's `ROS_SECURITY_*` environment into the DDS link's settings.

use crate::config::DdsSection;
use skein_dds::security::keystore::{self, Validity};
use skein_dds::security::{DdsSecurity, Role};
use std::path::PathBuf;
use std::process::ExitCode;

/// `--dds-keystore` and `--dds-enclave`.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct DdsSecurityArgs {
    /// DDS Security: the SROS 2 keystore (`skein dds keystore create`) whose enclave this
    /// participant presents (with --dds-enclave; as `[dds] keystore`; else
    /// `ROS_SECURITY_KEYSTORE` when `ROS_SECURITY_ENABLE=true`).
    #[arg(long, value_name = "DIR")]
    pub dds_keystore: Option<PathBuf>,
    /// DDS Security: the enclave (`/skein/agent/a2`, made by `skein dds enclave create`)
    /// this participant presents (as `[dds] enclave`; else `ROS_SECURITY_ENCLAVE_OVERRIDE`).
    #[arg(long, value_name = "NAME")]
    pub dds_enclave: Option<String>,
}

impl DdsSecurityArgs {
    /// Whether either flag was given (they go with DDS).
    pub fn given(&self) -> bool {
        self.dds_keystore.is_some() || self.dds_enclave.is_some()
    }

    /// The DDS link's security: the flags, else `[dds]`'s keys, else ROS 2's environment
    /// (`None`: unsecured).
    ///
    /// # Errors
    /// Only one of a pair, or an enclave that is incomplete (the text says which file and
    /// how to make it).
    pub fn resolve(&self, file: &DdsSection) -> Result<Option<DdsSecurity>, String> {
        let (keystore, enclave) = if self.given() {
            (self.dds_keystore.clone(), self.dds_enclave.clone())
        } else {
            (file.keystore.clone(), file.enclave.clone())
        };
        DdsSecurity::resolve(keystore.as_deref(), enclave.as_deref(), |k| {
            std::env::var(k).ok()
        })
    }
}

/// `skein dds ...`.
#[derive(clap::Subcommand, Debug)]
pub enum DdsCommand {
    /// SROS 2 keystores: `skein dds keystore create DIR`.
    #[command(subcommand)]
    Keystore(KeystoreCommand),
    /// Enclaves (one per participant): `skein dds enclave create DIR --enclave NAME --role ROLE`.
    #[command(subcommand)]
    Enclave(EnclaveCommand),
}

/// `skein dds keystore ...`.
#[derive(clap::Subcommand, Debug)]
pub enum KeystoreCommand {
    /// A new keystore: identity and permissions CAs (EC P-256), and the swarm's governance
    /// signed by the permissions CA. The CA keys stay in DIR/private: keep DIR off the
    /// aircraft, copy only enclaves there.
    Create(KeystoreCreateArgs),
}

/// `skein dds enclave ...`.
#[derive(clap::Subcommand, Debug)]
pub enum EnclaveCommand {
    /// A participant's enclave: key, certificate (subject `CN=<enclave>`) and the
    /// permissions of its role, signed by the keystore's CAs.
    Create(EnclaveCreateArgs),
}

/// Arguments of `skein dds keystore create`.
#[derive(clap::Args, Debug)]
pub struct KeystoreCreateArgs {
    /// The keystore's directory (created; refused if it already holds a keystore).
    pub dir: PathBuf,
    /// Days the CAs are valid.
    #[arg(long, default_value_t = 3650)]
    pub days: u32,
}

/// Arguments of `skein dds enclave create`.
#[derive(clap::Args, Debug)]
pub struct EnclaveCreateArgs {
    /// The keystore (`skein dds keystore create`).
    pub dir: PathBuf,
    /// The enclave's name, `/`-separated (`/skein/agent/a2`).
    #[arg(long)]
    pub enclave: String,
    /// What it may do: `agent`, `coordinator` or `viewer`.
    #[arg(long)]
    pub role: Role,
    /// Days its certificate and permissions are valid.
    #[arg(long, default_value_t = 3650)]
    pub days: u32,
}

/// Runs `skein dds ...`.
///
/// # Errors
/// What [`keystore::create_keystore`] or [`keystore::create_enclave`] refuse.
pub fn run(command: DdsCommand) -> Result<ExitCode, String> {
    match command {
        DdsCommand::Keystore(KeystoreCommand::Create(a)) => {
            keystore::create_keystore(&a.dir, Validity::days(a.days))?;
            println!("wrote a DDS Security keystore to {}", a.dir.display());
            println!(
                "# Enrol each participant: skein dds enclave create {} --enclave /skein/agent/a1 --role agent",
                a.dir.display()
            );
        }
        DdsCommand::Enclave(EnclaveCommand::Create(a)) => {
            let dir = keystore::create_enclave(&a.dir, &a.enclave, a.role, Validity::days(a.days))?;
            println!(
                "wrote enclave {} ({}) to {}",
                a.enclave,
                a.role,
                dir.display()
            );
            println!(
                "# Present it: --dds-keystore {} --dds-enclave {} (or in [dds]: keystore = {:?}, enclave = {:?})",
                a.dir.display(),
                a.enclave,
                a.dir.display().to_string(),
                a.enclave
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_win_over_the_config_and_the_config_is_read_without_them() {
        let dir = std::env::temp_dir().join(format!("skein-dds-args-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        keystore::create_keystore(&dir, Validity::days(1)).unwrap();
        keystore::create_enclave(&dir, "/skein/agent/a1", Role::Agent, Validity::days(1)).unwrap();
        let file = DdsSection {
            keystore: Some(dir.clone()),
            enclave: Some("/skein/agent/a1".into()),
            ..DdsSection::default()
        };
        let from_file = DdsSecurityArgs::default().resolve(&file).unwrap().unwrap();
        assert_eq!(from_file.enclave, "/skein/agent/a1");
        let flags = DdsSecurityArgs {
            dds_keystore: Some(dir.clone()),
            dds_enclave: Some("/skein/agent/a2".into()),
        };
        let e = flags.resolve(&file).unwrap_err();
        assert!(
            e.contains("/skein/agent/a2") && e.contains("enclave create"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
