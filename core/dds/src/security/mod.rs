//! DDS Security on the swarm's domain, as ROS 2's SROS 2 sets it up: a participant
//! presents an *enclave* of a *keystore* ([`keystore`]: certificates, keys, governance and
//! permissions in SROS 2's layout), and RustDDS's builtin plugins (PKI-DH authentication,
//! access control by the signed permissions, AES-GCM-GMAC) refuse every participant that
//! cannot prove an identity from the keystore's CA, and every write or read its
//! permissions ([`policy`], by role) do not grant.
//!
//! [`DdsSecurity`] is what `--dds-keystore DIR --dds-enclave NAME` (or `[dds]` keys, or
//! ROS 2's environment: `ROS_SECURITY_ENABLE`, `ROS_SECURITY_KEYSTORE`,
//! `ROS_SECURITY_ENCLAVE_OVERRIDE`, `ROS_SECURITY_STRATEGY`) resolve to;
//! [`crate::carrier::ros2::Ros2Carrier::join`] turns it on for the participant.

pub mod keystore;
pub mod policy;
pub mod refusals;
pub mod repeats;

use crate::carrier::WriterIdentity;
pub use policy::Role;
use ros2_client::dds::rustdds::DomainParticipantSecurityConfigFiles;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// How long a secured coordinator candidate listens after it starts before it may claim
/// the role ([`skein_swarm::election::ElectionConfig::first_listen`]; 1 s unsecured):
/// a new participant hears nothing before DDS Security's handshake, key exchange and
/// secure discovery are done, which took 1.8–2.5 s on loopback, and a restarted
/// coordinator that claimed before hearing the active one made two on the test WLAN.
pub const FIRST_LISTEN: std::time::Duration = std::time::Duration::from_secs(5);

/// The files of one enclave every secured participant reads (ROS 2's default names).
pub const ENCLAVE_FILES: [&str; 6] = [
    "identity_ca.cert.pem",
    "cert.pem",
    "key.pem",
    "permissions_ca.cert.pem",
    "governance.p7s",
    "permissions.p7s",
];

/// A participant's DDS Security: the enclave `enclave` of the keystore at `keystore`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DdsSecurity {
    /// The keystore's directory (`ROS_SECURITY_KEYSTORE`).
    pub keystore: PathBuf,
    /// The enclave's name (`/skein/agent/a2`).
    pub enclave: String,
    /// The enclave's directory, holding [`ENCLAVE_FILES`].
    pub dir: PathBuf,
}

impl DdsSecurity {
    /// The enclave `enclave` of the keystore at `keystore`, checked to hold every file of
    /// [`ENCLAVE_FILES`] and a certificate valid now.
    ///
    /// # Errors
    /// `enclave` is not an enclave name, a file is missing (the text names it and the
    /// command that makes it), or the certificate is unreadable, expired or not yet valid
    /// (RustDDS 0.15 checks no certificate's dates itself, only the permissions').
    pub fn new(keystore: impl Into<PathBuf>, enclave: &str) -> Result<Self, String> {
        let keystore = keystore.into();
        let dir = enclave_dir(&keystore, enclave)?;
        for f in ENCLAVE_FILES {
            if !dir.join(f).is_file() {
                return Err(format!(
                    "DDS Security: enclave {enclave} of keystore {} has no {f} \
                     (make it with `skein dds enclave create KEYSTORE --enclave {enclave} \
                     --role ROLE` where the keystore is, and copy its directory to {})",
                    keystore.display(),
                    dir.display()
                ));
            }
        }
        check_validity(&dir.join("cert.pem"))
            .map_err(|e| format!("DDS Security: enclave {enclave}: {e}"))?;
        Ok(DdsSecurity {
            keystore,
            enclave: enclave.to_string(),
            dir,
        })
    }

    /// What `--dds-keystore` and `--dds-enclave` (`keystore`, `enclave`; both or neither)
    /// or, when neither is given, ROS 2's environment (read through `env`) ask for:
    /// `None` for an unsecured participant. With `ROS_SECURITY_ENABLE=true`, the keystore
    /// is `ROS_SECURITY_KEYSTORE` and the enclave `ROS_SECURITY_ENCLAVE_OVERRIDE`; under
    /// `ROS_SECURITY_STRATEGY=Permissive` a missing enclave runs unsecured (with a
    /// warning), as ROS 2 does, otherwise (`Enforce`, the default here) it is an error.
    ///
    /// # Errors
    /// Only one of the two flags, a missing variable, or an enclave [`DdsSecurity::new`]
    /// refuses.
    pub fn resolve(
        keystore: Option<&Path>,
        enclave: Option<&str>,
        env: impl Fn(&str) -> Option<String>,
    ) -> Result<Option<Self>, String> {
        match (keystore, enclave) {
            (Some(k), Some(e)) => return Self::new(k, e).map(Some),
            (Some(_), None) => return Err("--dds-keystore needs --dds-enclave".into()),
            (None, Some(_)) => return Err("--dds-enclave needs --dds-keystore".into()),
            (None, None) => {}
        }
        if !env("ROS_SECURITY_ENABLE").is_some_and(|v| v.eq_ignore_ascii_case("true")) {
            return Ok(None);
        }
        let permissive = env("ROS_SECURITY_STRATEGY").is_some_and(|v| v == "Permissive");
        let found = match (
            env("ROS_SECURITY_KEYSTORE"),
            env("ROS_SECURITY_ENCLAVE_OVERRIDE"),
        ) {
            (Some(k), Some(e)) => Self::new(k, &e),
            (None, _) => Err("ROS_SECURITY_ENABLE=true needs ROS_SECURITY_KEYSTORE".into()),
            (_, None) => Err("ROS_SECURITY_ENABLE=true needs ROS_SECURITY_ENCLAVE_OVERRIDE".into()),
        };
        match found {
            Ok(s) => Ok(Some(s)),
            Err(e) if permissive => {
                tracing::warn!("{e}; ROS_SECURITY_STRATEGY=Permissive: DDS runs unsecured");
                Ok(None)
            }
            Err(e) => Err(e),
        }
    }

    /// The enclave's files as RustDDS's builtin plugins read them (no key password: SROS 2
    /// keys have none).
    pub(crate) fn config_files(&self) -> DomainParticipantSecurityConfigFiles {
        DomainParticipantSecurityConfigFiles::with_ros_default_names(&self.dir, String::new())
    }
}

/// The [`WriterIdentity`] a participant presenting enclave `name` (a certificate of
/// subject `CN=<name>`, as [`keystore::create_enclave`] makes it) writes with under DDS
/// Security: the subject's DER hashed with SHA-256, its first 64 bits shifted right by
/// one with the top bit set, truncated to 48 (DDS Security 1.1 §9.3.1.1, as RustDDS
/// computes it).
///
/// # Errors
/// OpenSSL could not encode the name.
pub fn identity_of(name: &str) -> Result<WriterIdentity, String> {
    let mut b = openssl::x509::X509NameBuilder::new().map_err(|e| e.to_string())?;
    b.append_entry_by_nid(openssl::nid::Nid::COMMONNAME, name)
        .map_err(|e| e.to_string())?;
    let der = b.build().to_der().map_err(|e| e.to_string())?;
    let hash = openssl::sha::sha256(&der);
    let mut first = [0; 8];
    first.copy_from_slice(&hash[..8]);
    let bits = (u64::from_be_bytes(first) >> 1) | (1 << 63);
    let mut id = [0; 6];
    id.copy_from_slice(&bits.to_be_bytes()[..6]);
    Ok(WriterIdentity(id))
}

/// The enclaves of the keystore at `keystore` (every directory under `enclaves/` that
/// holds a `cert.pem`), by the identity each writes with ([`identity_of`]): what names
/// an agent's enclave in `GET /api/v1/coordinator`. A keystore that holds only this
/// participant's enclave (as on an aircraft) names only that one.
pub fn known_enclaves(keystore: &Path) -> BTreeMap<WriterIdentity, String> {
    fn walk(dir: &Path, name: &str, out: &mut BTreeMap<WriterIdentity, String>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        if dir.join("cert.pem").is_file()
            && let Ok(id) = identity_of(name)
        {
            out.insert(id, name.to_string());
        }
        for e in entries.flatten() {
            if e.path().is_dir()
                && let Some(token) = e.file_name().to_str()
            {
                walk(
                    &e.path(),
                    &format!("{}/{token}", name.trim_end_matches('/')),
                    out,
                );
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(&keystore.join("enclaves"), "/", &mut out);
    out
}

/// Whether the X.509 certificate at `path` is valid now.
///
/// # Errors
/// Unreadable, expired or not yet valid, with its dates.
fn check_validity(path: &Path) -> Result<(), String> {
    let pem = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let cert = openssl::x509::X509::from_pem(&pem)
        .map_err(|e| format!("{}: not a PEM certificate: {e}", path.display()))?;
    // The clock the keystore dated the certificate with (`clock_gettime(CLOCK_REALTIME)`),
    // not OpenSSL's `time()`, which on Linux reads the coarse clock, up to a tick behind: a
    // certificate made in the same second was "valid only from" the next second.
    let now_s = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_err(|e| e.to_string())?
        .as_secs();
    let now = openssl::asn1::Asn1Time::from_unix(i64::try_from(now_s).map_err(|e| e.to_string())?)
        .map_err(|e| e.to_string())?;
    if cert.not_after() < now {
        return Err(format!(
            "its certificate expired on {} ({})",
            cert.not_after(),
            path.display()
        ));
    }
    if cert.not_before() > now {
        return Err(format!(
            "its certificate is valid only from {} ({})",
            cert.not_before(),
            path.display()
        ));
    }
    Ok(())
}

/// The directory of enclave `name` in the keystore at `keystore`:
/// `keystore/enclaves/<name without its leading />`.
///
/// # Errors
/// `name` does not start with `/`, or a token between `/`s is empty or holds anything but
/// ASCII letters, digits and `_` (SROS 2's enclave names).
pub fn enclave_dir(keystore: &Path, name: &str) -> Result<PathBuf, String> {
    let bad = || {
        format!(
            "enclave `{name}`: `/`-separated names of letters, digits and `_`, starting \
             with `/` (e.g. /skein/agent/a2)"
        )
    };
    let rest = name.strip_prefix('/').ok_or_else(bad)?;
    let mut dir = keystore.join("enclaves");
    for token in rest.split('/') {
        if token.is_empty() || !token.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return Err(bad());
        }
        dir.push(token);
    }
    Ok(dir)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    #[test]
    fn enclave_names_map_to_directories_and_bad_ones_are_refused() {
        let k = Path::new("/ks");
        assert_eq!(
            enclave_dir(k, "/skein/agent/a2").unwrap(),
            Path::new("/ks/enclaves/skein/agent/a2")
        );
        for bad in ["skein/a", "/", "/skein//a", "/skein/../x", "/a b"] {
            let e = enclave_dir(k, bad).unwrap_err();
            assert!(e.contains(bad), "{e}");
        }
    }

    #[test]
    fn ros_environment_turns_security_on_and_permissive_runs_without_an_enclave() {
        let env = |pairs: &[(&str, &str)]| {
            let m: HashMap<String, String> = pairs
                .iter()
                .map(|(k, v)| ((*k).to_string(), (*v).to_string()))
                .collect();
            move |k: &str| m.get(k).cloned()
        };
        assert_eq!(DdsSecurity::resolve(None, None, env(&[])), Ok(None));
        let missing = [
            ("ROS_SECURITY_ENABLE", "true"),
            ("ROS_SECURITY_KEYSTORE", "/nonexistent"),
            ("ROS_SECURITY_ENCLAVE_OVERRIDE", "/skein/agent/a1"),
        ];
        let e = DdsSecurity::resolve(None, None, env(&missing)).unwrap_err();
        assert!(e.contains("has no identity_ca.cert.pem"), "{e}");
        let mut permissive = missing.to_vec();
        permissive.push(("ROS_SECURITY_STRATEGY", "Permissive"));
        assert_eq!(DdsSecurity::resolve(None, None, env(&permissive)), Ok(None));
        let e = DdsSecurity::resolve(Some(Path::new("/k")), None, env(&[])).unwrap_err();
        assert!(e.contains("--dds-enclave"), "{e}");
    }
}
