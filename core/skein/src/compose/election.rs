//! A coordinator candidate's side of the election (`skein_swarm::election`, on DDS): its
//! lease's settings, the API address it advertises there (where a standby's 409 sends
//! clients), and the host name that default ids are made from.

use super::role::Candidate;
use std::net::{IpAddr, SocketAddr};

/// The lease a coordinator candidate publishes: its id and priority, the API address it
/// advertises ([`advertised_url`]) and the election's timing (a `secured` participant
/// listens longer first: its peers' handshakes take time).
pub(super) fn lease_candidate(
    candidate: &Candidate,
    api_scheme: &str,
    api_local: SocketAddr,
    dds_networks: &[IpAddr],
    secured: bool,
) -> skein_dds::lease::Candidate {
    let timing = skein_swarm::election::ElectionConfig {
        first_listen: if secured {
            skein_dds::security::FIRST_LISTEN
        } else {
            skein_swarm::election::ElectionConfig::default().first_listen
        },
        ..Default::default()
    };
    skein_dds::lease::Candidate {
        coordinator_id: candidate.id.clone(),
        priority: candidate.priority,
        api_url: advertised_url(api_scheme, api_local, dds_networks),
        timing,
    }
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
fn advertised_url(scheme: &str, local: SocketAddr, dds_networks: &[IpAddr]) -> String {
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
