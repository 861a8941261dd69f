//! Counter-UAS scenes: a swarm of four with an intruder passing east of it, and the
//! observation UAVs' cameras pointed at its pass.

use super::{Skein, eventually};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The observation UAVs of `skein up --sim 4` (gimbal, camera, detector).
pub const OBSERVERS: [&str; 2] = ["uav-2", "uav-4"];

/// Builds the counter-UAS plugins (gimbal, camera, detector) into a fresh scratch
/// directory `name` of this test process; returns it.
pub fn build_plugins(name: &str) -> PathBuf {
    let dir = super::plugins::scratch(name);
    super::plugins::build_into(
        &[
            "skein-plugin-gimbal",
            "skein-plugin-camera",
            "skein-plugin-detector",
        ],
        &[],
        &dir,
    );
    dir
}

/// `skein up --sim 4` with the plugins of `plugin_dir` and one intruder flying straight
/// passes southward (and back) along a line 60 m east of home, 14 m up, at
/// `speed_m_s`: 90 m either side of its closest point of approach.
pub fn up_with_intruder_pass(plugin_dir: &Path, speed_m_s: f64) -> Skein {
    up_with_intruder_pass_and(plugin_dir, speed_m_s, &[])
}

/// [`up_with_intruder_pass`] with `extra` arguments for `skein up`.
pub fn up_with_intruder_pass_and(plugin_dir: &Path, speed_m_s: f64, extra: &[&str]) -> Skein {
    up_with_pass(plugin_dir, "straight", 1, speed_m_s, extra)
}

/// `skein up --sim 4` with the plugins of `plugin_dir` and `n` intruders flying a V on the
/// pass of [`up_with_intruder_pass`] (south along a line 60 m east of home, 14 m up, at
/// `speed_m_s`), the leader ahead and pairs 6 m behind it and 6 m to either side.
pub fn up_with_formation_pass(plugin_dir: &Path, speed_m_s: f64, n: usize) -> Skein {
    up_with_pass(plugin_dir, "formation", n, speed_m_s, &[])
}

/// `skein up --sim 4` with `n` intruders in `pattern` on the pass southward (and back)
/// 60 m east of home, 14 m up, at `speed_m_s`, plus `extra` arguments.
fn up_with_pass(
    plugin_dir: &Path,
    pattern: &str,
    n: usize,
    speed_m_s: f64,
    extra: &[&str],
) -> Skein {
    let mut args = vec![
        "--plugin-dir".to_string(),
        plugin_dir.to_str().unwrap().to_string(),
    ];
    args.extend(pass_args(pattern, n, speed_m_s));
    args.extend(extra.iter().map(|a| a.to_string()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    Skein::up_sim(4, &args)
}

/// The `skein up` arguments of `n` intruders in `pattern` on the pass southward (and
/// back) 60 m east of home, 14 m up, at `speed_m_s`, starting 90 m north of the closest
/// point of approach.
pub fn pass_args(pattern: &str, n: usize, speed_m_s: f64) -> Vec<String> {
    [
        "--intruders",
        &n.to_string(),
        "--intruder-pattern",
        pattern,
        "--intruder-heading-deg",
        "180",
        "--intruder-cpa-m",
        "60",
        "--intruder-range-m",
        "90",
        "--intruder-altitude-m",
        "14",
        "--intruder-speed-m-s",
        &speed_m_s.to_string(),
    ]
    .map(str::to_string)
    .to_vec()
}

impl Skein {
    /// Flies the two observers `baseline_m` apart north–south (uav-2 north, uav-4 south of
    /// the origin, each keeping its east, 10 m up) and waits until both are within 1 m of
    /// there. Two cameras range an aircraft by the angle between their rays: from the
    /// spawn grid's 5 m at 60 m that angle is under 5°, and the rays of two aircraft of a
    /// formation run nearly parallel and meet at ghosts hundreds of metres out.
    pub fn spread_observers(&self, baseline_m: f64) {
        let half = baseline_m / 2.0;
        let east_of = |id: &str| {
            super::distributed::vehicle(self, id)["position"]["east_m"]
                .as_f64()
                .expect("the observer's position")
        };
        // Each along its own column of the spawn grid, clear of the others'.
        let spots = [
            (OBSERVERS[0], half, east_of(OBSERVERS[0])),
            (OBSERVERS[1], -half, east_of(OBSERVERS[1])),
        ];
        for (id, north_m, east_m) in spots {
            let (status, body) = self.post(
                &format!("/api/v1/vehicles/{id}/commands"),
                json!({"command": "goto", "north_m": north_m, "east_m": east_m, "down_m": -10.0}),
            );
            assert_eq!(status, 202, "{body}");
        }
        eventually("the observers spread", Duration::from_secs(30), || {
            let vs = self.vehicles();
            let off: Vec<String> = spots
                .iter()
                .filter_map(|(id, north_m, east_m)| {
                    let Some(v) = vs.iter().find(|v| v["id"] == *id) else {
                        return Some(format!("{id} not listed"));
                    };
                    let p = &v["position"];
                    let n = p["north_m"].as_f64().unwrap_or(f64::NAN);
                    let e = p["east_m"].as_f64().unwrap_or(f64::NAN);
                    let d = (n - north_m).hypot(e - east_m);
                    (d.is_nan() || d > 1.0).then(|| format!("{id} {d:.1} m off"))
                })
                .collect();
            if off.is_empty() {
                Ok(())
            } else {
                Err(off.join(", "))
            }
        });
    }

    /// Starts the intruders' passes again from their beginning (90 m before the closest
    /// point of approach, out of the cameras' view), through the simulator's stats socket:
    /// a test that waits for them from here does not depend on how long its set-up took.
    pub fn restart_intruders(&self) {
        let answer = super::sim_stats(&self.sim_stats_addr(), "intruders restart");
        assert_eq!(answer["ok"], true, "intruders restart: {answer}");
    }

    /// Every intruder leaves the simulated world (no camera sees one) until the next
    /// [`Skein::restart_intruders`], through the simulator's stats socket.
    pub fn intruders_leave(&self) {
        let answer = super::sim_stats(&self.sim_stats_addr(), "intruders leave");
        assert_eq!(answer["ok"], true, "intruders leave: {answer}");
    }

    /// Points the gimbals of `ids` at `yaw_deg` (earth frame), `pitch_deg` up, and waits
    /// until their cameras report that azimuth.
    pub fn point_gimbals(&self, ids: &[&str], yaw_deg: f64, pitch_deg: f64) {
        for v in ids {
            let (status, body) = self.post(
                &format!("/api/v1/vehicles/{v}/payloads/gimbal"),
                json!({"command": "set_angles", "pitch_deg": pitch_deg, "yaw_deg": yaw_deg, "yaw_frame": "earth"}),
            );
            assert_eq!(status, 200, "{body}");
        }
        eventually("the gimbals pointed", Duration::from_secs(20), || {
            let vs = self.vehicles();
            let ok = ids.iter().all(|id| {
                vs.iter()
                    .find(|v| v["id"] == *id)
                    .and_then(|v| v["payloads"].as_array())
                    .and_then(|ps| ps.iter().find(|p| p["slot"] == "camera"))
                    .and_then(|p| p["state"]["pointing"]["azimuth_deg"].as_f64())
                    .is_some_and(|az| (az - yaw_deg).abs() < 2.0)
            });
            if ok {
                Ok(())
            } else {
                Err("cameras not pointed yet".to_string())
            }
        });
    }
}
