//! A private LAN of network namespaces for multi-host tests: a bridge in a namespace of
//! its own (the switch), one namespace per host joined to it by a veth pair (host `i` at
//! `.2 + i`), and this namespace joined too (at `.1`, so the test reaches the hosts'
//! APIs), on a /24 of 10.0.0.0/8 chosen from this test process's pid.
//!
//! The bridge is not in this namespace because Docker's `FORWARD DROP` policy applies to
//! bridged frames here (`br_netfilter`): it would drop the hosts' DDS traffic to each
//! other. The switch namespace has no firewall rules.
//!
//! [`Lan::wlan`] makes the switch a WLAN instead (`tests/peers/wlan_relay.py`, a hub in
//! user space, since this kernel has no netem): each host's link gets a profile (good or
//! bad WLAN, bursts of interference, 5G-like latency, down) and may flap
//! ([`Lan::profile`], [`Lan::flap`]).
//!
//! Needs root (`ip netns`, `ip link`). Everything is removed on drop, and namespaces left
//! by a killed earlier run (whose process is gone) are removed on creation.

use std::io::{BufRead, BufReader, Write};
use std::net::Ipv4Addr;
use std::os::unix::net::UnixStream;
use std::process::{Child, Command, Stdio};

/// One host of the LAN.
pub struct Host {
    /// Its namespace (`skein-<pid>-<tag>-<i>`).
    pub ns: String,
    /// Its address on the LAN.
    pub addr: Ipv4Addr,
    /// The switch side of its veth pair (down cuts the host off the LAN), or on a WLAN
    /// its TAP device, by which the relay names its port.
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
    /// The WLAN relay, when the switch is one ([`Lan::wlan`]).
    relay: Option<Relay>,
}

/// A network namespace of this test process's own with only its loopback (up), for a
/// process that must not see this namespace's interfaces, nor change them for the
/// others; removed on drop.
pub struct Namespace {
    /// Its name (`skein-<pid>-<tag>-ns`).
    pub name: String,
}

impl Namespace {
    /// Creates `skein-<pid>-<tag>-ns` with its loopback up.
    pub fn new(tag: char) -> Namespace {
        remove_stale();
        let name = format!("skein-{}-{tag}-ns", std::process::id());
        ip(&["netns", "add", &name]);
        let ns = Namespace { name };
        ns.ip(&["link", "set", "lo", "up"]);
        ns
    }

    /// `ip <args>` inside it.
    pub fn ip(&self, args: &[&str]) {
        ip_in(&self.name, args);
    }
}

impl Drop for Namespace {
    fn drop(&mut self) {
        let _ = Command::new("ip")
            .args(["netns", "del", &self.name])
            .status();
    }
}

/// The user-space WLAN switch: its process and its control socket.
struct Relay {
    child: Child,
    control: std::path::PathBuf,
}

impl Relay {
    /// Starts `tests/peers/wlan_relay.py` in namespace `switch` with TAP devices `taps`,
    /// and waits until they exist.
    fn start(switch: &str, taps: &[String]) -> Relay {
        let control = std::env::temp_dir().join(format!("{switch}-relay.sock"));
        let script = super::workspace().join("tests/peers/wlan_relay.py");
        let mut cmd = Command::new("ip");
        cmd.args(["netns", "exec", switch, "python3"])
            .arg(&script)
            .arg("--control")
            .arg(&control);
        for t in taps {
            cmd.args(["--tap", t]);
        }
        let mut child = cmd
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start tests/peers/wlan_relay.py");
        let mut ready = String::new();
        BufReader::new(child.stdout.take().expect("stdout"))
            .read_line(&mut ready)
            .expect("the relay's first line");
        assert_eq!(ready.trim(), "ready", "wlan_relay.py did not start");
        Relay { child, control }
    }
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
        Lan::make(tag, n, false)
    }

    /// [`Lan::new`] with a WLAN for a switch: every host's link `clean` until
    /// [`Lan::profile`] says otherwise.
    pub fn wlan(tag: char, n: usize) -> Lan {
        Lan::make(tag, n, true)
    }

    fn make(tag: char, n: usize, wlan: bool) -> Lan {
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
            relay: None,
        };
        let in_switch = |args: &[&str]| ip_in(&switch, args);
        let uplink = lan.uplink.clone();
        let hosts: Vec<(String, String, String)> = (0..n)
            .map(|i| {
                (
                    format!("skein-{pid}-{tag}-{i}"),
                    format!("skv{short}{tag}{i}"),
                    format!("skp{short}{tag}{i}"),
                )
            })
            .collect();
        for (ns, _, _) in &hosts {
            ip(&["netns", "add", ns]);
        }
        if wlan {
            // The relay makes one TAP per link in the switch namespace; each goes to its
            // side (the uplink to this namespace, a host's link into the host's).
            let mut taps = vec![uplink.clone()];
            taps.extend(hosts.iter().map(|(_, _, inner)| inner.clone()));
            lan.relay = Some(Relay::start(&switch, &taps));
            in_switch(&[
                "link",
                "set",
                &uplink,
                "netns",
                &std::process::id().to_string(),
            ]);
        } else {
            in_switch(&["link", "add", "br0", "type", "bridge"]);
            in_switch(&["link", "set", "br0", "up"]);
        }
        // A veth pair `port` / `other` whose `port` joins the bridge.
        let plug = |port: &str, other: &str| {
            ip(&["link", "add", port, "type", "veth", "peer", "name", other]);
            ip(&["link", "set", port, "netns", &switch]);
            in_switch(&["link", "set", port, "master", "br0"]);
            in_switch(&["link", "set", port, "up"]);
        };
        if !wlan {
            plug(&format!("{uplink}p"), &uplink);
        }
        ip(&["addr", "add", &format!("10.{a}.{b}.1/24"), "dev", &uplink]);
        ip(&["link", "set", &uplink, "up"]);
        for (i, (ns, veth, inner)) in hosts.into_iter().enumerate() {
            let addr = Ipv4Addr::new(10, a, b, 2 + i as u8);
            if wlan {
                in_switch(&["link", "set", &inner, "netns", &ns]);
            } else {
                plug(&veth, &inner);
                ip(&["link", "set", &inner, "netns", &ns]);
            }
            let exec = |args: &[&str]| ip_in(&ns, args);
            exec(&["link", "set", "lo", "up"]);
            exec(&["addr", "add", &format!("{addr}/24"), "dev", &inner]);
            exec(&["link", "set", &inner, "up"]);
            // DDS discovery is multicast (239.255.0.1): route it out of the LAN side.
            exec(&["route", "add", "224.0.0.0/4", "dev", &inner]);
            lan.hosts.push(Host {
                ns,
                addr,
                veth: if wlan { inner } else { veth },
            });
        }
        lan
    }

    /// Sends `line` to the relay; its answer, which must say ok.
    fn relay(&self, line: &str) -> serde_json::Value {
        let r = self.relay.as_ref().expect("Lan::wlan has a relay");
        let mut s = UnixStream::connect(&r.control).expect("the relay's control socket");
        writeln!(s, "{line}").expect("a relay command");
        let mut answer = String::new();
        BufReader::new(&s)
            .read_line(&mut answer)
            .expect("the relay's answer");
        let v: serde_json::Value = serde_json::from_str(&answer).expect("JSON from the relay");
        assert_eq!(v["ok"], true, "relay `{line}`: {v}");
        v
    }

    /// Gives host `i`'s link the WLAN profile `name` (`clean`, `wlan_good`, `wlan_bad`,
    /// `wlan_poor`, `bursts`, `5g`, `down`: see `tests/peers/wlan_relay.py`).
    pub fn profile(&self, i: usize, name: &str) {
        self.relay(&format!("profile {} {name}", self.hosts[i].veth));
    }

    /// Cuts host `i`'s link for `down_s` every `every_s` seconds from now (0, 0: no more).
    pub fn flap(&self, i: usize, down_s: f64, every_s: f64) {
        self.relay(&format!("flap {} {down_s} {every_s}", self.hosts[i].veth));
    }

    /// The relay's frame counts per port (`seen`, `passed`, `lost`), by host index.
    pub fn relay_stats(&self) -> Vec<serde_json::Value> {
        let v = self.relay("stats");
        self.hosts
            .iter()
            .map(|h| v["ports"][&h.veth].clone())
            .collect()
    }

    /// Cuts host `i` off the LAN (its switch-side link down, or cut in the relay).
    pub fn cut(&self, i: usize) {
        if self.relay.is_some() {
            self.relay(&format!("cut {} 1", self.hosts[i].veth));
        } else {
            ip_in(&self.switch, &["link", "set", &self.hosts[i].veth, "down"]);
        }
    }

    /// Joins host `i` to the LAN again.
    pub fn heal(&self, i: usize) {
        if self.relay.is_some() {
            self.relay(&format!("cut {} 0", self.hosts[i].veth));
        } else {
            ip_in(&self.switch, &["link", "set", &self.hosts[i].veth, "up"]);
        }
    }
}

impl Drop for Lan {
    fn drop(&mut self) {
        if let Some(r) = &mut self.relay {
            let _ = r.child.kill();
            let _ = r.child.wait();
            let _ = std::fs::remove_file(&r.control);
        }
        // Deleting a namespace destroys the veths in it, and so their peers.
        for h in &self.hosts {
            let _ = Command::new("ip").args(["netns", "del", &h.ns]).status();
        }
        let _ = Command::new("ip")
            .args(["netns", "del", &self.switch])
            .status();
        // The uplink: a veth of this namespace, or on a WLAN the relay's TAP, gone with it.
        if self.relay.is_none() {
            let _ = Command::new("ip")
                .args(["link", "del", &self.uplink])
                .status();
        }
    }
}
