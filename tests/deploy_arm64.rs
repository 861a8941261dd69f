//! The arm64 image for the companions (Raspberry Pi 4, Jetson Orin NX), made on this
//! amd64 machine: skein and its plugins cross-compiled by `deploy/docker/cross-build.sh`
//! (aarch64-unknown-linux-gnu, Debian's cross gcc; the root `Cargo.toml`'s `arm64-test`
//! profile, in `target/arm64`), the image built by `build-image.sh --arch arm64` on the
//! arm64 base `make-base.sh` makes from Debian's arm64 packages (kept for the next run),
//! under 75 MB, labelled arm64.
//! Its files are then run under qemu-user (Debian's `qemu-aarch64`, the image's own
//! loader and libraries by `-L`):
//!
//! - `skein --version` answers;
//! - `skein sim --vehicles 1` answers a ground station: heartbeats to it, and a
//!   `COMMAND_ACK` and the `AUTOPILOT_VERSION` to its `MAV_CMD_REQUEST_MESSAGE`;
//! - `skein up --sim 1` loads the image's plugins by `dlopen` from its plugin directory,
//!   and a gimbal attached to uav-1 runs and answers a command through the plugin ABI.
//!
//! In `tests/run.sh` the cross-build runs beside the test lanes at idle priority
//! (`tests/lanes.sh`), and this target after them: its own build is then up to date.

mod support;

use serde_json::{Value, json};
use skein_mavlink::dialect::{
    HEARTBEAT_DATA, MavAutopilot, MavCmd, MavModeFlag, MavState, MavType,
};
use skein_mavlink::{CommandTarget, Decoder, Encoder, MavMessage, command_long};
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;
use std::time::{Duration, Instant};
use support::docker::{Image, docker};
use support::{Skein, eventually};

/// The image's files, exported (its root) once for every test of this process.
struct Rootfs {
    root: PathBuf,
}

fn rootfs() -> &'static Rootfs {
    static ROOTFS: OnceLock<Rootfs> = OnceLock::new();
    ROOTFS.get_or_init(|| {
        let ws = support::workspace();
        let started = Instant::now();
        let out = Command::new(ws.join("deploy/docker/cross-build.sh"))
            .args(["--profile", "arm64-test", "--target-dir"])
            .arg(ws.join("target/arm64"))
            .output()
            .expect("run cross-build.sh");
        let build_s = started.elapsed().as_secs_f64();
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "cross-build.sh failed:\n{stdout}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let bin_dir = PathBuf::from(stdout.trim().lines().last().expect("the output directory"));
        let image = Image::build(
            "arm64",
            &format!("skein:test-{}-arm64", std::process::id()),
            &bin_dir,
            &[],
        );
        assert_eq!(image.architecture(), "arm64");
        // 69.6 MB since DDS Security (OpenSSL 3's arm64 libraries and RustDDS's security
        // code in skein and the camera plugin, 2026-11-25); under 60 MB before.
        assert!(image.size < 75_000_000, "the image is {} bytes", image.size);
        // The image's files as a directory (then the image goes: `image` drops).
        let root = support::plugins::scratch("arm64-rootfs");
        let id = docker(&["create", "--platform", "linux/arm64", &image.tag]);
        let export = Command::new("sh")
            .arg("-c")
            .arg(format!(
                "docker export {id} | tar -x -C '{}'",
                root.display()
            ))
            .status()
            .unwrap();
        docker(&["rm", &id]);
        assert!(export.success(), "docker export");
        eprintln!(
            "{}",
            json!({"cross_build_s": build_s, "image_bytes": image.size,
                   "image_build_s": image.build_s})
        );
        Rootfs { root }
    })
}

impl Rootfs {
    /// `qemu-aarch64 -L ROOT ROOT/usr/local/bin/skein <args>`.
    fn command<'a>(&'a self, args: &[&'a str]) -> Vec<String> {
        let root = self.root.to_string_lossy().into_owned();
        let mut c = vec![
            "qemu-aarch64".to_string(),
            "-L".into(),
            root.clone(),
            format!("{root}/usr/local/bin/skein"),
        ];
        c.extend(args.iter().map(|a| a.to_string()));
        c
    }

    fn path(&self, inside: &str) -> String {
        Path::new(&self.root)
            .join(inside.trim_start_matches('/'))
            .to_string_lossy()
            .into_owned()
    }
}

#[test]
fn arm64_skein_reports_its_version_under_qemu() {
    let r = rootfs();
    let c = r.command(&["--version"]);
    let out = Command::new(&c[0])
        .args(&c[1..])
        .output()
        .expect("qemu-aarch64");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(text.trim(), format!("skein {}", env!("CARGO_PKG_VERSION")));
}

#[test]
fn arm64_sim_answers_a_ground_station_under_qemu() {
    let r = rootfs();
    let gcs = UdpSocket::bind("127.0.0.1:0").unwrap();
    gcs.set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    let gcs_port = gcs.local_addr().unwrap().port().to_string();
    let sim_port = support::free_udp_range(1);
    let sim_port_s = sim_port.to_string();
    let c = r.command(&[
        "sim",
        "--vehicles",
        "1",
        "--listen-base-port",
        &sim_port_s,
        "--target-base-port",
        &gcs_port,
    ]);
    let cmd: Vec<&str> = c.iter().map(String::as_str).collect();
    let _sim = support::Process::start_command(&cmd, &[]);
    let mut decoder = Decoder::new(Default::default());
    let mut encoder = Encoder::new(255, 190);
    let mut buf = [0u8; 2048];
    let mut receive = |until: &mut dyn FnMut(&MavMessage) -> bool, what: &str| {
        eventually(what, Duration::from_secs(30), || {
            let mut hit = false;
            if let Ok(n) = gcs.recv(&mut buf) {
                decoder.decode_datagram(&buf[..n], |f| {
                    if f.sysid == 1 && until(&f.msg) {
                        hit = true;
                    }
                });
            }
            if hit { Ok(()) } else { Err(what.to_string()) }
        });
    };
    receive(
        &mut |m| matches!(m, MavMessage::HEARTBEAT(h) if h.autopilot == MavAutopilot::MAV_AUTOPILOT_PX4),
        "a PX4 heartbeat from the arm64 simulator",
    );
    let heartbeat = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_GCS,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    });
    // MAV_CMD_REQUEST_MESSAGE for AUTOPILOT_VERSION (148).
    let request = command_long(
        CommandTarget::new(1, 1),
        MavCmd::MAV_CMD_REQUEST_MESSAGE,
        [148.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        0,
    );
    let to = format!("127.0.0.1:{sim_port}");
    let (mut acked, mut version) = (false, false);
    eventually(
        "COMMAND_ACK and AUTOPILOT_VERSION",
        Duration::from_secs(30),
        || {
            for m in [&heartbeat, &request] {
                gcs.send_to(encoder.encode(m).as_bytes(), &to).unwrap();
            }
            let deadline = Instant::now() + Duration::from_millis(500);
            while Instant::now() < deadline && !(acked && version) {
                if let Ok(n) = gcs.recv(&mut buf) {
                    decoder.decode_datagram(&buf[..n], |f| match f.msg {
                        MavMessage::COMMAND_ACK(a)
                            if a.command == MavCmd::MAV_CMD_REQUEST_MESSAGE =>
                        {
                            acked = true;
                        }
                        MavMessage::AUTOPILOT_VERSION(_) => version = true,
                        _ => {}
                    });
                }
            }
            if acked && version {
                Ok(())
            } else {
                Err(format!("ack {acked}, version {version}"))
            }
        },
    );
}

#[test]
fn arm64_skein_loads_a_plugin_by_dlopen_under_qemu() {
    let r = rootfs();
    let plugins = r.path("/usr/local/lib/skein/plugins");
    let c = r.command(&[
        "up",
        "--sim",
        "1",
        "--sim-base-port",
        "0",
        "--http",
        "127.0.0.1:0",
        "--plugin-dir",
        &plugins,
    ]);
    let cmd: Vec<&str> = c.iter().map(String::as_str).collect();
    let s = Skein::launch_command(&cmd);
    let (status, listing) = s.get("/api/v1/plugins");
    assert_eq!(status, 200, "{listing}");
    let loaded: Vec<&str> = listing["libraries"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|l| l["status"] == "loaded")
        .filter_map(|l| l["name"].as_str())
        .collect();
    for name in ["gimbal", "camera", "detector", "radio", "example"] {
        assert!(loaded.contains(&name), "{name} not loaded: {listing}");
    }
    assert_eq!(listing["refused"], json!([]), "{listing}");
    // The plugin's code runs: an instance created and commanded through its vtable.
    s.wait_all("uav-1 connected", 1, Duration::from_secs(60), |v| {
        v["link"]["connected"] == true
    });
    let (status, body) = s.post(
        "/api/v1/vehicles/uav-1/payloads",
        json!({"slot": "gimbal", "kind": "gimbal"}),
    );
    assert_eq!(status, 201, "{body}");
    assert_eq!(body["plugin"], "gimbal", "{body}");
    let answer: Value = eventually("the gimbal's answer", Duration::from_secs(30), || {
        let (status, a) = s.post(
            "/api/v1/vehicles/uav-1/payloads/gimbal",
            json!({"command": "set_angles", "pitch_deg": -30.0}),
        );
        if status == 200 {
            Ok(a)
        } else {
            Err(format!("{status}: {a}"))
        }
    });
    eprintln!("{}", json!({"gimbal_answer": answer}));
}
