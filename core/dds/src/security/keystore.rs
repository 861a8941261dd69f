//! SROS 2 keystores, made by skein: `skein dds keystore create DIR` and
//! `skein dds enclave create DIR --enclave NAME --role ROLE`, in the layout
//! `ros2 security create_keystore` / `create_enclave` write, so that ROS 2 users
//! recognise them and RustDDS reads an enclave by ROS 2's default file names:
//!
//! ```text
//! DIR/public/identity_ca.cert.pem      the identity CA (signs participants' certificates)
//! DIR/public/permissions_ca.cert.pem   the permissions CA (signs governance, permissions)
//! DIR/private/identity_ca.key.pem      their keys (mode 0600, directory 0700)
//! DIR/private/permissions_ca.key.pem
//! DIR/enclaves/governance.xml, governance.p7s
//! DIR/enclaves/skein/agent/a2/         one enclave: what one participant presents
//!     cert.pem key.pem identity_ca.cert.pem permissions_ca.cert.pem
//!     governance.p7s permissions.xml permissions.p7s
//! ```
//!
//! Unlike SROS 2, the two CAs are distinct keys, and an enclave holds copies of the CA
//! certificates and the governance rather than links, so that the enclave directory alone
//! can be mounted into a container. Keys are EC P-256 (prime256v1), certificates and
//! signatures SHA-256, documents signed as S/MIME (`openssl smime -sign -text`), all by
//! OpenSSL ([`openssl`]).

use super::policy::{self, Role};
use openssl::asn1::Asn1Time;
use openssl::bn::{BigNum, MsbOption};
use openssl::ec::{EcGroup, EcKey};
use openssl::hash::MessageDigest;
use openssl::nid::Nid;
use openssl::pkcs7::{Pkcs7, Pkcs7Flags};
use openssl::pkey::{PKey, Private};
use openssl::stack::Stack;
use openssl::x509::extension::{BasicConstraints, KeyUsage, SubjectKeyIdentifier};
use openssl::x509::{X509, X509NameBuilder};
use std::path::{Path, PathBuf};

/// The identity CA's certificate, under `public/`.
pub const IDENTITY_CA_CERT: &str = "identity_ca.cert.pem";
/// The permissions CA's certificate, under `public/`.
pub const PERMISSIONS_CA_CERT: &str = "permissions_ca.cert.pem";
/// The identity CA's key, under `private/`.
pub const IDENTITY_CA_KEY: &str = "identity_ca.key.pem";
/// The permissions CA's key, under `private/`.
pub const PERMISSIONS_CA_KEY: &str = "permissions_ca.key.pem";
/// The signed governance, under `enclaves/` and in every enclave.
pub const GOVERNANCE: &str = "governance.p7s";

/// How long certificates and permissions are valid: from now, in days.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Validity {
    /// Days before now the validity starts (0: now).
    pub from_days_ago: u32,
    /// Days from now it ends; 0 or less than `from_days_ago` makes an expired certificate
    /// (for tests of refusal).
    pub days: i64,
}

/// Makes a keystore in `dir` (created if missing): the two CAs, valid for `validity`, and
/// the signed governance ([`policy::governance_xml`]).
///
/// # Errors
/// `dir` already holds a keystore (`public/identity_ca.cert.pem`), a file cannot be
/// written, or OpenSSL failed; the text names the file or step.
pub fn create_keystore(dir: &Path, validity: Validity) -> Result<(), String> {
    let public = dir.join("public");
    let private = dir.join("private");
    let enclaves = dir.join("enclaves");
    if public.join(IDENTITY_CA_CERT).exists() {
        return Err(format!(
            "{}: already a keystore (it has public/{IDENTITY_CA_CERT})",
            dir.display()
        ));
    }
    for d in [&public, &private, &enclaves] {
        std::fs::create_dir_all(d).map_err(|e| format!("{}: {e}", d.display()))?;
    }
    set_mode(&private, 0o700)?;
    let (id_key, id_cert) = new_ca("skein identity CA", validity)?;
    let (perm_key, perm_cert) = new_ca("skein permissions CA", validity)?;
    write_key(&private.join(IDENTITY_CA_KEY), &id_key)?;
    write_key(&private.join(PERMISSIONS_CA_KEY), &perm_key)?;
    write(&public.join(IDENTITY_CA_CERT), &pem(&id_cert)?)?;
    write(&public.join(PERMISSIONS_CA_CERT), &pem(&perm_cert)?)?;
    let governance = policy::governance_xml();
    write(&enclaves.join("governance.xml"), governance.as_bytes())?;
    write(
        &enclaves.join(GOVERNANCE),
        &smime_sign(&perm_key, &perm_cert, governance.as_bytes())?,
    )?;
    Ok(())
}

/// Makes enclave `name` (`/skein/agent/a2`: `/`-separated tokens of letters, digits and
/// `_`) in the keystore at `keystore` for `role`: a new key, a certificate whose subject
/// is `CN=<name>` signed by the identity CA, and permissions for that subject signed by
/// the permissions CA, all valid for `validity`. Returns the enclave's directory
/// (`keystore/enclaves/skein/agent/a2`).
///
/// # Errors
/// `name` is not an enclave name, the keystore is incomplete, the enclave exists, a file
/// cannot be read or written, or OpenSSL failed; the text names which.
pub fn create_enclave(
    keystore: &Path,
    name: &str,
    role: Role,
    validity: Validity,
) -> Result<PathBuf, String> {
    let dir = super::enclave_dir(keystore, name)?;
    if dir.join("cert.pem").exists() {
        return Err(format!("enclave {name}: exists ({})", dir.display()));
    }
    let public = keystore.join("public");
    let private = keystore.join("private");
    let read = |p: PathBuf| {
        std::fs::read(&p).map_err(|e| format!("{}: {e} (is it a keystore?)", p.display()))
    };
    let id_cert =
        X509::from_pem(&read(public.join(IDENTITY_CA_CERT))?).map_err(ssl("identity CA"))?;
    let id_key = PKey::private_key_from_pem(&read(private.join(IDENTITY_CA_KEY))?)
        .map_err(ssl("identity CA key"))?;
    let perm_cert =
        X509::from_pem(&read(public.join(PERMISSIONS_CA_CERT))?).map_err(ssl("permissions CA"))?;
    let perm_key = PKey::private_key_from_pem(&read(private.join(PERMISSIONS_CA_KEY))?)
        .map_err(ssl("permissions CA key"))?;
    let governance = read(keystore.join("enclaves").join(GOVERNANCE))?;

    let key = new_key()?;
    let subject = format!("CN={name}");
    let dates = validity.dates();
    let cert = certificate(name, &key, Some((&id_key, &id_cert)), dates)?;
    let (not_before, not_after) = xml_dates(dates);
    let permissions = policy::permissions_xml(&subject, role, &not_before, &not_after);

    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    write_key(&dir.join("key.pem"), &key)?;
    write(&dir.join("cert.pem"), &pem(&cert)?)?;
    write(&dir.join(IDENTITY_CA_CERT), &pem(&id_cert)?)?;
    write(&dir.join(PERMISSIONS_CA_CERT), &pem(&perm_cert)?)?;
    write(&dir.join(GOVERNANCE), &governance)?;
    write(&dir.join("permissions.xml"), permissions.as_bytes())?;
    write(
        &dir.join("permissions.p7s"),
        &smime_sign(&perm_key, &perm_cert, permissions.as_bytes())?,
    )?;
    Ok(dir)
}

impl Validity {
    /// `days` from now.
    pub fn days(days: u32) -> Self {
        Validity {
            from_days_ago: 0,
            days: i64::from(days),
        }
    }

    /// Its start and end, from one reading of the clock.
    fn dates(self) -> Dates {
        let now = chrono::Utc::now();
        let at = |d: i64| now + chrono::Duration::days(d);
        (at(-i64::from(self.from_days_ago)), at(self.days))
    }
}

/// `dates` as the permissions document writes them (UTC, `%FT%T`).
fn xml_dates((from, to): Dates) -> (String, String) {
    let f = |t: chrono::DateTime<chrono::Utc>| t.format("%FT%T").to_string();
    (f(from), f(to))
}

/// `dates` as a certificate's validity.
fn asn1_dates((from, to): Dates) -> Result<(Asn1Time, Asn1Time), String> {
    let f = |t: chrono::DateTime<chrono::Utc>| {
        Asn1Time::from_unix(t.timestamp()).map_err(ssl("validity"))
    };
    Ok((f(from)?, f(to)?))
}

/// A validity's start and end (UTC).
type Dates = (chrono::DateTime<chrono::Utc>, chrono::DateTime<chrono::Utc>);

/// A new EC P-256 key.
fn new_key() -> Result<PKey<Private>, String> {
    let group = EcGroup::from_curve_name(Nid::X9_62_PRIME256V1).map_err(ssl("P-256"))?;
    let ec = EcKey::generate(&group).map_err(ssl("EC key"))?;
    PKey::from_ec_key(ec).map_err(ssl("EC key"))
}

/// A new self-signed CA named `CN=<cn>`.
fn new_ca(cn: &str, validity: Validity) -> Result<(PKey<Private>, X509), String> {
    let key = new_key()?;
    let cert = certificate(cn, &key, None, validity.dates())?;
    Ok((key, cert))
}

/// A certificate for `key` with subject `CN=<cn>`, signed by `issuer` (key, certificate),
/// or self-signed as a CA when `None`.
fn certificate(
    cn: &str,
    key: &PKey<Private>,
    issuer: Option<(&PKey<Private>, &X509)>,
    dates: Dates,
) -> Result<X509, String> {
    let mut name = X509NameBuilder::new().map_err(ssl("name"))?;
    name.append_entry_by_nid(Nid::COMMONNAME, cn)
        .map_err(ssl("common name"))?;
    let name = name.build();
    let mut b = X509::builder().map_err(ssl("certificate"))?;
    b.set_version(2).map_err(ssl("version"))?;
    let mut serial = BigNum::new().map_err(ssl("serial"))?;
    serial
        .rand(127, MsbOption::MAYBE_ZERO, false)
        .map_err(ssl("serial"))?;
    let serial = serial.to_asn1_integer().map_err(ssl("serial"))?;
    b.set_serial_number(&serial).map_err(ssl("serial"))?;
    b.set_subject_name(&name).map_err(ssl("subject"))?;
    b.set_pubkey(key).map_err(ssl("public key"))?;
    let (not_before, not_after) = asn1_dates(dates)?;
    b.set_not_before(&not_before).map_err(ssl("not before"))?;
    b.set_not_after(&not_after).map_err(ssl("not after"))?;
    let (sign_key, issuer_name) = match issuer {
        Some((k, c)) => (k, c.subject_name()),
        None => (key, name.as_ref()),
    };
    b.set_issuer_name(issuer_name).map_err(ssl("issuer"))?;
    let (constraints, usage) = if issuer.is_none() {
        (
            BasicConstraints::new().critical().ca().build(),
            // digitalSignature too: the permissions CA signs the documents itself
            // (S/MIME verifiers check the signer's key usage).
            KeyUsage::new()
                .critical()
                .key_cert_sign()
                .crl_sign()
                .digital_signature()
                .build(),
        )
    } else {
        (
            BasicConstraints::new().critical().build(),
            KeyUsage::new()
                .critical()
                .digital_signature()
                .key_agreement()
                .build(),
        )
    };
    b.append_extension(constraints.map_err(ssl("basic constraints"))?)
        .map_err(ssl("basic constraints"))?;
    b.append_extension(usage.map_err(ssl("key usage"))?)
        .map_err(ssl("key usage"))?;
    let ski = SubjectKeyIdentifier::new()
        .build(&b.x509v3_context(issuer.map(|(_, c)| c.as_ref()), None))
        .map_err(ssl("subject key identifier"))?;
    b.append_extension(ski)
        .map_err(ssl("subject key identifier"))?;
    b.sign(sign_key, MessageDigest::sha256())
        .map_err(ssl("signature"))?;
    Ok(b.build())
}

/// `doc` signed by `key`/`cert` as clear-signed S/MIME, as `openssl smime -sign -text`
/// writes it (what DDS Security's builtin access control reads).
fn smime_sign(key: &PKey<Private>, cert: &X509, doc: &[u8]) -> Result<Vec<u8>, String> {
    let flags = Pkcs7Flags::DETACHED | Pkcs7Flags::TEXT;
    let certs = Stack::new().map_err(ssl("S/MIME"))?;
    let p7 = Pkcs7::sign(cert, key, &certs, doc, flags).map_err(ssl("S/MIME signature"))?;
    p7.to_smime(doc, flags).map_err(ssl("S/MIME"))
}

fn pem(cert: &X509) -> Result<Vec<u8>, String> {
    cert.to_pem().map_err(ssl("PEM"))
}

fn write(path: &Path, bytes: &[u8]) -> Result<(), String> {
    std::fs::write(path, bytes).map_err(|e| format!("{}: {e}", path.display()))
}

/// `key` as PKCS#8 PEM (unencrypted, as SROS 2 writes it), readable by its owner only.
fn write_key(path: &Path, key: &PKey<Private>) -> Result<(), String> {
    use std::io::Write as _;
    use std::os::unix::fs::OpenOptionsExt;
    let bytes = key.private_key_to_pem_pkcs8().map_err(ssl("private key"))?;
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(path)
        .and_then(|mut f| f.write_all(&bytes))
        .map_err(|e| format!("{}: {e}", path.display()))
}

fn set_mode(path: &Path, mode: u32) -> Result<(), String> {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode))
        .map_err(|e| format!("{}: {e}", path.display()))
}

/// A `map_err` naming the OpenSSL step that failed.
fn ssl(what: &'static str) -> impl FnOnce(openssl::error::ErrorStack) -> String {
    move |e| format!("OpenSSL, {what}: {e}")
}
