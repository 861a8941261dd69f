//! A private LAN of network namespaces for multi-host tests: a bridge in a namespace of
//! its own (the switch), one namespace per host joined to it by a veth pair (host `i` at
//! `.2 + i`), and this namespace joined too (at `.1`, so the test reaches the hosts'
//! APIs), on a /24 of 10.0.0.0/8 chosen from this test process's pid.
//!
//! The bridge is not in this namespace because Docker's `FORWARD DROP` policy applies to
//! bridged frames here (`br_netfilter`): it would drop the hosts' DDS traffic to each
//! other. The switch namespace has no firewall rules.
//!
//! Needs root (`ip netns`, `ip link`). Everything is removed on drop, and namespaces left
//! by a killed earlier run (whose process is gone) are removed on creation.

use std::net::Ipv4Addr;
use std::process::Command;

/// One host of the LAN.
pub struct Host {
    /// Its namespace (`skein-<pid>-<tag>-<i>`).
    pub ns: String,
    /// Its address on the LAN.
    pub addr: Ipv4Addr,
    /// The switch side of its veth pair: down cuts the host off the LAN.
    veth: String,
}

/// The LAN (see the module docs).
pub struct Lan {
    /// The switch namespace (holds the bridge `br0`).
    switch: String,
    /// This namespace's side of its link to the switch.
    uplink: String,
    /// The hosts, in order.
    pub hosts: Vec<Host>,
}

fn ip(args: &[&str]) {
    let out = Command::new("ip").args(args).output().expect("run ip");
    assert!(
        out.status.success(),
        "ip {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `ip <args>` inside namespace `ns`.
fn ip_in(ns: &str, args: &[&str]) {
    let mut all = vec!["netns", "exec", ns, "ip"];
    all.extend_from_slice(args);
    ip(&all);
}

/// Removes namespaces `skein-<pid>-…` of processes that are gone.
fn remove_stale() {
    let Ok(out) = Command::new("ip").args(["netns", "list"]).output() else {
        return;
    };
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let name = line.split_whitespace().next().unwrap_or("");
        if let Some(pid) = name
            .strip_prefix("skein-")
            .and_then(|r| r.split('-').next())
            && !std::path::Path::new(&format!("/proc/{pid}")).exists()
        {
            let _ = Command::new("ip").args(["netns", "del", name]).status();
        }
    }
}

impl Lan {
    /// A bridge and `n` host namespaces; `tag` (a digit or letter) tells two LANs of one
    /// test process apart.
    pub fn new(tag: char, n: usize) -> Lan {
        remove_stale();
        let pid = std::process::id();
        let short = pid % 100_000;
        // 10.A.B.0/24 from the pid and the tag, so parallel test processes differ.
        let (a, b) = (
            100 + (pid % 100) as u8,
            ((pid / 100) % 200) as u8 + tag as u8 % 50,
        );
        let switch = format!("skein-{pid}-{tag}-sw");
        ip(&["netns", "add", &switch]);
        let mut lan = Lan {
            switch: switch.clone(),
            uplink: format!("skr{short}{tag}"),
            hosts: Vec::new(),
        };
        let in_switch = |args: &[&str]| ip_in(&switch, args);
        in_switch(&["link", "add", "br0", "type", "bridge"]);
        in_switch(&["link", "set", "br0", "up"]);
        // `port` (created here with its peer `other`) goes into the switch, on the bridge.
        let plug = |port: &str, other: &str| {
            ip(&["link", "add", port, "type", "veth", "peer", "name", other]);
            ip(&["link", "set", port, "netns", &switch]);
            in_switch(&["link", "set", port, "master", "br0"]);
            in_switch(&["link", "set", port, "up"]);
        };
        let uplink = lan.uplink.clone();
        plug(&format!("{uplink}p"), &uplink);
        ip(&["addr", "add", &format!("10.{a}.{b}.1/24"), "dev", &uplink]);
        ip(&["link", "set", &uplink, "up"]);
        for i in 0..n {
            let ns = format!("skein-{pid}-{tag}-{i}");
            let veth = format!("skv{short}{tag}{i}");
            let inner = format!("skp{short}{tag}{i}");
            let addr = Ipv4Addr::new(10, a, b, 2 + i as u8);
            ip(&["netns", "add", &ns]);
            lan.hosts.push(Host {
                ns: ns.clone(),
                addr,
                veth: veth.clone(),
            });
            plug(&veth, &inner);
            ip(&["link", "set", &inner, "netns", &ns]);
            let exec = |args: &[&str]| ip_in(&ns, args);
            exec(&["link", "set", "lo", "up"]);
            exec(&["addr", "add", &format!("{addr}/24"), "dev", &inner]);
            exec(&["link", "set", &inner, "up"]);
            // DDS discovery is multicast (239.255.0.1): route it out of the LAN side.
            exec(&["route", "add", "224.0.0.0/4", "dev", &inner]);
        }
        lan
    }

    /// Cuts host `i` off the LAN (its switch-side link down).
    pub fn cut(&self, i: usize) {
        ip_in(&self.switch, &["link", "set", &self.hosts[i].veth, "down"]);
    }

    /// Joins host `i` to the LAN again.
    pub fn heal(&self, i: usize) {
        ip_in(&self.switch, &["link", "set", &self.hosts[i].veth, "up"]);
    }
}

impl Drop for Lan {
    fn drop(&mut self) {
        // Deleting a namespace destroys the veths in it, and so their peers.
        for h in &self.hosts {
            let _ = Command::new("ip").args(["netns", "del", &h.ns]).status();
        }
        let _ = Command::new("ip")
            .args(["netns", "del", &self.switch])
            .status();
        let _ = Command::new("ip")
            .args(["link", "del", &self.uplink])
            .status();
    }
}
