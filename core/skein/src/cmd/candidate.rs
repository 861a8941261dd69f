//! `skein coordinator`: a coordinator candidate with no vehicles of its own. It runs the
//! coordinator actor, the API and dashboard, and the DDS link, and takes part in the
//! coordinator election on `/skein/coordinator` (`skein_swarm::election`): the live
//! candidate of highest priority is active; a standby's API answers reads and refuses
//! writes with a 409 naming the active one.

use super::up::{UpArgs, up};
use clap::Args;
use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;
use std::process::ExitCode;

/// Command line of `skein coordinator`.
#[derive(Args, Debug)]
pub struct CoordinatorArgs {
    /// Election priority: the live candidate with the highest is active (equal: the
    /// smaller id).
    #[arg(long, value_name = "P", default_value_t = 1, env = "SKEIN_PRIORITY")]
    priority: u32,
    /// Id on `/skein/coordinator` (default `<hostname>-<pid>`).
    #[arg(long, value_name = "ID", env = "SKEIN_ID")]
    id: Option<String>,
    /// Configuration file (TOML): `[http]` tokens and TLS, `[dds]`, swarm settings.
    #[arg(long, value_name = "FILE", env = "SKEIN_CONFIG")]
    config: Option<PathBuf>,
    /// Listen address of the HTTP API and dashboard (port 0 picks a free port).
    #[arg(long, value_name = "ADDR:PORT", env = "SKEIN_HTTP")]
    http: Option<SocketAddr>,
    /// The DDS domain, 0 to 232 (default `[dds] domain_id`, else `ROS_DOMAIN_ID`, else 0).
    #[arg(long, value_name = "D", value_parser = skein_dds::parse_domain_id)]
    domain_id: Option<u16>,
    /// Use only the interface with this local address for DDS (repeatable).
    #[arg(long, value_name = "ADDR")]
    dds_network: Vec<IpAddr>,
    #[command(flatten)]
    dds_security: super::dds::DdsSecurityArgs,
    /// Listen on a non-loopback address without any `[[http.tokens]]` (refused without
    /// this flag).
    #[arg(long)]
    insecure_no_auth: bool,
}

/// This candidate's identity in the election.
#[derive(Debug, Clone, PartialEq)]
pub struct CandidateArgs {
    /// Id on the lease topic.
    pub id: String,
    /// Priority.
    pub priority: u32,
}

/// Runs a coordinator candidate until a signal or the coordinator's failure.
///
/// # Errors
/// As `skein up`: a bad config, a port in use, DDS that cannot start.
pub async fn coordinator(args: CoordinatorArgs) -> Result<ExitCode, String> {
    let id = match args.id {
        Some(id) if id.trim().is_empty() => return Err("--id: empty".into()),
        Some(id) => id,
        None => format!("{}-{}", hostname(), std::process::id()),
    };
    // `skein up`'s options at their defaults, then this role's.
    let mut up_args = UpArgs::defaults()?;
    up_args.config = args.config;
    up_args.http = args.http;
    up_args.domain_id = args.domain_id;
    up_args.dds_network = args.dds_network;
    up_args.dds_security = args.dds_security;
    up_args.insecure_no_auth = args.insecure_no_auth;
    up_args.candidate = Some(CandidateArgs {
        id,
        priority: args.priority,
    });
    up(up_args).await
}

/// The host's name (`/proc/sys/kernel/hostname`), `skein` if unreadable.
pub(crate) fn hostname() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|s| s.trim().to_string())
        .ok()
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "skein".into())
}

/// The API address a candidate advertises in its lease (`api_url`, where a standby's 409
/// sends clients): `scheme://local` when the API listens on one address; when it listens
/// on every address (`0.0.0.0`, `::`), one a peer can reach instead: the first
/// `--dds-network` address of the same family (peers already reach that interface for
/// DDS), else the address the host routes from ([`route_source`]), else the unspecified
/// address as it is (a client then has to know the host).
pub(crate) fn advertised_url(scheme: &str, local: SocketAddr, dds_networks: &[IpAddr]) -> String {
    let host = if local.ip().is_unspecified() {
        dds_networks
            .iter()
            .copied()
            .find(|a| a.is_ipv4() == local.is_ipv4() && !a.is_unspecified())
            .or_else(|| route_source(local.is_ipv4()))
            .unwrap_or(local.ip())
    } else {
        local.ip()
    };
    format!("{scheme}://{}", SocketAddr::new(host, local.port()))
}

/// The local address the host would send from towards a public address (a UDP socket's
/// `connect` only picks the route: nothing is sent); `None` without such a route.
fn route_source(ipv4: bool) -> Option<IpAddr> {
    let (bind, towards): (SocketAddr, SocketAddr) = if ipv4 {
        // TEST-NET-1 (RFC 5737): routed like any public address, never answered.
        (([0, 0, 0, 0], 0).into(), ([192, 0, 2, 1], 9).into())
    } else {
        // The documentation prefix (RFC 3849).
        (
            (std::net::Ipv6Addr::UNSPECIFIED, 0).into(),
            ("2001:db8::1".parse::<std::net::Ipv6Addr>().ok()?, 9).into(),
        )
    };
    let socket = std::net::UdpSocket::bind(bind).ok()?;
    socket.connect(towards).ok()?;
    let ip = socket.local_addr().ok()?.ip();
    (!ip.is_unspecified()).then_some(ip)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_listen_address_is_advertised_as_it_is() {
        let local: SocketAddr = "127.0.0.1:8080".parse().unwrap();
        assert_eq!(
            advertised_url("http", local, &["10.0.0.2".parse().unwrap()]),
            "http://127.0.0.1:8080"
        );
    }

    #[test]
    fn every_address_is_advertised_as_the_dds_network_or_the_routed_one() {
        let any: SocketAddr = "0.0.0.0:8443".parse().unwrap();
        let nets = ["fe80::1".parse().unwrap(), "10.0.0.2".parse().unwrap()];
        assert_eq!(advertised_url("https", any, &nets), "https://10.0.0.2:8443");
        let url = advertised_url("http", any, &[]);
        assert!(
            !url.contains("0.0.0.0") || route_source(true).is_none(),
            "{url}"
        );
        assert!(url.ends_with(":8443"), "{url}");
    }
}
