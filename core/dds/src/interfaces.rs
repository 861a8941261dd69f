//! The network interfaces of this host (of its network namespace), to notice that one
//! was removed or created: RustDDS joins its discovery multicast group, and sets the
//! interface of its multicast sends, per interface when the participant is created, so
//! a participant outlives neither. A container whose network is disconnected and
//! connected again (`docker network disconnect` / `connect`), a USB network adapter
//! plugged out and in, a VPN interface re-created: each gets a new interface (a new
//! index, often a new name and address), and the old participant hears no peer on it
//! again. [`crate::link`] then joins the domain again on a new participant.
//!
//! An interface that only goes down and up (a WLAN out of range, a cable pulled) keeps
//! its index and its multicast memberships: nothing changes here.
//!
//! A participant held to some local addresses (`--dds-network`, RustDDS
//! `with_only_networks`) uses only the interfaces that carry them: [`current_on`] lists
//! only those, so another interface that comes or goes on the same computer (a Docker
//! bridge, a VPN, a test's network namespace plumbing) costs it no rejoin.

use std::collections::BTreeSet;
use std::net::IpAddr;

/// The interfaces as (name, index), from `/sys/class/net` (sysfs shows the network
/// namespace it was mounted in: a container's own, or `ip netns exec`'s).
pub type Interfaces = BTreeSet<(String, u32)>;

/// The interfaces now; empty when `/sys/class/net` cannot be read (then no change is
/// ever seen).
pub fn current() -> Interfaces {
    let Ok(dir) = std::fs::read_dir("/sys/class/net") else {
        return Interfaces::new();
    };
    dir.filter_map(Result::ok)
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let index = std::fs::read_to_string(e.path().join("ifindex")).ok()?;
            Some((name, index.trim().parse().ok()?))
        })
        .collect()
}

/// The interfaces, of [`current`], that carry one of the local addresses `networks`
/// (every interface when `networks` is empty): the ones a participant created with
/// `with_only_networks(networks)` uses. An address no interface carries adds nothing;
/// when the addresses cannot be read (`getifaddrs` fails), every interface is listed, as
/// for no restriction.
pub fn current_on(networks: &[IpAddr]) -> Interfaces {
    let all = current();
    if networks.is_empty() {
        return all;
    }
    let Ok(addresses) = nix::ifaddrs::getifaddrs() else {
        return all;
    };
    let carriers: BTreeSet<String> = addresses
        .filter(|a| {
            a.address.as_ref().is_some_and(|s| {
                let ip = s
                    .as_sockaddr_in()
                    .map(|v4| IpAddr::V4(v4.ip()))
                    .or_else(|| s.as_sockaddr_in6().map(|v6| IpAddr::V6(v6.ip())));
                ip.is_some_and(|ip| networks.contains(&ip))
            })
        })
        .map(|a| a.interface_name)
        .collect();
    all.into_iter()
        .filter(|(name, _)| carriers.contains(name))
        .collect()
}

/// What changed from `before` to `now`, for the log (`+eth1#57 -eth0#55`); `None` when
/// nothing did.
pub fn changes(before: &Interfaces, now: &Interfaces) -> Option<String> {
    if before == now {
        return None;
    }
    let added = now.difference(before).map(|(n, i)| format!("+{n}#{i}"));
    let removed = before.difference(now).map(|(n, i)| format!("-{n}#{i}"));
    Some(added.chain(removed).collect::<Vec<_>>().join(" "))
}

/// A change from `seen` that held: `first` and `second`, read a moment apart, agree and
/// differ from `seen`. A listing read while sysfs changes under it, or a device that is
/// re-created within the moment, gives no change here until it is stable; the next poll
/// looks again.
pub fn settled(seen: &Interfaces, first: &Interfaces, second: &Interfaces) -> Option<String> {
    if first != second {
        return None;
    }
    changes(seen, second)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_loopback_interface_is_listed() {
        assert!(current().iter().any(|(n, _)| n == "lo"), "{:?}", current());
    }

    #[test]
    fn held_to_loopback_only_the_loopback_interface_counts() {
        let lo = current_on(&[IpAddr::from([127, 0, 0, 1])]);
        assert_eq!(
            lo.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>(),
            ["lo"],
            "{lo:?}"
        );
        // No interface carries a documentation address: nothing to watch.
        assert!(current_on(&[IpAddr::from([192, 0, 2, 77])]).is_empty());
        assert_eq!(current_on(&[]), current());
    }

    #[test]
    fn a_re_created_interface_is_a_change() {
        let before: Interfaces = [("lo".into(), 1), ("eth0".into(), 55)].into();
        assert_eq!(changes(&before, &before), None);
        let after: Interfaces = [("lo".into(), 1), ("eth1".into(), 57)].into();
        assert_eq!(
            changes(&before, &after).as_deref(),
            Some("+eth1#57 -eth0#55")
        );
        // A change counts once two readings agree on it.
        assert_eq!(settled(&before, &after, &before), None);
        assert_eq!(settled(&before, &before, &before), None);
        assert_eq!(
            settled(&before, &after, &after).as_deref(),
            Some("+eth1#57 -eth0#55")
        );
        // The same name with a new index: re-created, the old memberships gone.
        let same_name: Interfaces = [("lo".into(), 1), ("eth0".into(), 58)].into();
        assert_eq!(
            changes(&before, &same_name).as_deref(),
            Some("+eth0#58 -eth0#55")
        );
    }
}
