//! The fleet's pre-flight checks (`GET /api/v1/preflight`): for each vehicle, what a crew
//! looks at before the first takeoff, from its snapshot: the link, PX4's own arming
//! checks and what PX4 said, the home, GNSS, battery, the autopilot's geofence and
//! Remote ID. A vehicle is ready when no check fails (a warning does not stop it).

use crate::fsm::VehicleState;
use crate::geofence::FenceSyncState;
use crate::vehicle::VehicleSnapshot;
use serde::Serialize;

/// PX4's `BAT_LOW_THR` default (15 %): below it PX4 warns of a low battery, and a
/// vehicle should not take off.
pub const BATTERY_LOW_PERCENT: f64 = 15.0;

/// The `GPS_FIX_TYPE` a flight needs: 3 (3D fix).
pub const FIX_3D: u8 = 3;

/// The outcome of one check.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum CheckState {
    /// Passed.
    Ok,
    /// Worth a look; does not stop the vehicle.
    Warn,
    /// Stops the vehicle.
    Fail,
}

/// One check of one vehicle.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct PreflightCheck {
    /// `link`, `state`, `px4_arming_checks`, `home`, `gnss`, `battery`, `geofence`,
    /// `remote_id`.
    pub check: &'static str,
    /// The outcome.
    pub state: CheckState,
    /// What was seen (`"3D fix, 12 satellites, eph 0.80 m"`; PX4's own texts for its
    /// arming checks).
    pub detail: String,
}

/// One vehicle's checks.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct VehiclePreflight {
    /// Vehicle id.
    pub id: String,
    /// No check fails.
    pub ready: bool,
    /// The checks, in the order above.
    pub checks: Vec<PreflightCheck>,
}

/// The checks of vehicle `v`.
pub fn preflight(v: &VehicleSnapshot) -> VehiclePreflight {
    let checks: Vec<PreflightCheck> = [
        link(v),
        state(v),
        px4_arming(v),
        home(v),
        gnss(v),
        battery(v),
        geofence(v),
    ]
    .into_iter()
    .chain(remote_id(v))
    .collect();
    VehiclePreflight {
        id: v.id.clone(),
        ready: checks.iter().all(|c| c.state != CheckState::Fail),
        checks,
    }
}

fn check(check: &'static str, state: CheckState, detail: impl Into<String>) -> PreflightCheck {
    PreflightCheck {
        check,
        state,
        detail: detail.into(),
    }
}

fn pass_or(fail: bool, bad: CheckState) -> CheckState {
    if fail { bad } else { CheckState::Ok }
}

fn link(v: &VehicleSnapshot) -> PreflightCheck {
    let detail = format!(
        "{}, last message {} ms ago",
        if v.link.connected { "up" } else { "lost" },
        v.link.last_seen_ms
    );
    check("link", pass_or(!v.link.connected, CheckState::Fail), detail)
}

fn state(v: &VehicleSnapshot) -> PreflightCheck {
    let on_ground = matches!(v.state, VehicleState::Landed | VehicleState::Armed);
    check(
        "state",
        pass_or(!on_ground, CheckState::Warn),
        format!("{:?}", v.state),
    )
}

/// PX4's arming checks (`SYS_STATUS` `PREARM_CHECK`), with what PX4 last said.
fn px4_arming(v: &VehicleSnapshot) -> PreflightCheck {
    let said: Vec<&str> = v.px4_messages.iter().map(|m| m.text.as_str()).collect();
    let said = if said.is_empty() {
        String::new()
    } else {
        format!(": {}", said.join("; "))
    };
    match v.prearm_ok {
        Some(true) => check("px4_arming_checks", CheckState::Ok, format!("pass{said}")),
        Some(false) => check("px4_arming_checks", CheckState::Fail, format!("fail{said}")),
        None => check(
            "px4_arming_checks",
            CheckState::Warn,
            format!("not reported{said}"),
        ),
    }
}

fn home(v: &VehicleSnapshot) -> PreflightCheck {
    match &v.home {
        Some(h) => check(
            "home",
            CheckState::Ok,
            format!("{:.6} / {:.6}", h.lat_deg, h.lon_deg),
        ),
        None => check("home", CheckState::Fail, "no HOME_POSITION yet"),
    }
}

fn gnss(v: &VehicleSnapshot) -> PreflightCheck {
    let Some(g) = v.gps else {
        return check("gnss", CheckState::Fail, "no GPS_RAW_INT yet");
    };
    let fix = match g.fix_type {
        0 | 1 => "no fix",
        2 => "2D fix",
        3 => "3D fix",
        4 => "DGPS",
        5 => "RTK float",
        6 => "RTK fixed",
        _ => "other fix",
    };
    let eph = g
        .eph_m
        .map_or("eph unknown".into(), |e| format!("eph {e:.2} m"));
    check(
        "gnss",
        pass_or(g.fix_type < FIX_3D, CheckState::Fail),
        format!("{fix}, {} satellites, {eph}", g.satellites),
    )
}

fn battery(v: &VehicleSnapshot) -> PreflightCheck {
    match v.battery {
        Some(b) if b.percent.is_finite() => check(
            "battery",
            pass_or(b.percent < BATTERY_LOW_PERCENT, CheckState::Fail),
            format!("{:.0} %, {:.2} V", b.percent, b.voltage_v),
        ),
        _ => check("battery", CheckState::Warn, "not reported"),
    }
}

fn geofence(v: &VehicleSnapshot) -> PreflightCheck {
    let Some(f) = &v.fence else {
        return check("geofence", CheckState::Warn, "not kept here");
    };
    let state = match f.state {
        FenceSyncState::Synced => CheckState::Ok,
        FenceSyncState::Pending => CheckState::Warn,
        FenceSyncState::Differs | FenceSyncState::Failed => CheckState::Fail,
    };
    let why = f
        .reason
        .as_deref()
        .map_or(String::new(), |r| format!(": {r}"));
    check(
        "geofence",
        state,
        format!("autopilot {} (version {}){why}", f.state.name(), f.version),
    )
}

/// Remote ID, where skein sends it or a transmitter reported.
fn remote_id(v: &VehicleSnapshot) -> Option<PreflightCheck> {
    let r = v.remote_id.as_ref()?;
    Some(match (&r.transmitter, r.operator_sent) {
        (Some(t), _) if !t.good_to_arm => check(
            "remote_id",
            CheckState::Fail,
            format!("transmitter not ready: {}", t.error),
        ),
        (Some(_), true) => check(
            "remote_id",
            CheckState::Ok,
            "operator sent, transmitter ready",
        ),
        (Some(_), false) => check(
            "remote_id",
            CheckState::Warn,
            "transmitter ready, no operator configured ([remote_id])",
        ),
        (None, _) => check(
            "remote_id",
            CheckState::Warn,
            "operator sent, no transmitter heard",
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::{Ned, NedFrame};
    use crate::geofence::FenceStatus;
    use crate::vehicle::{Battery, GpsStatus, Px4Message, RemoteIdArmStatus, RemoteIdStatus};

    fn ready_vehicle() -> VehicleSnapshot {
        let frame = NedFrame::new(crate::geo::GeoPoint::new(47.0, 8.0, 500.0));
        let mut v = VehicleSnapshot::hovering_at("uav-1", 1, &frame, Ned::ZERO);
        v.state = VehicleState::Landed;
        v.prearm_ok = Some(true);
        v.gps = Some(GpsStatus {
            fix_type: 3,
            satellites: 12,
            eph_m: Some(0.8),
            epv_m: Some(1.2),
        });
        v.battery = Some(Battery {
            percent: 90.0,
            voltage_v: 16.2,
        });
        v.fence = Some(FenceStatus {
            state: FenceSyncState::Synced,
            reason: None,
            ..FenceStatus::pending(1, "")
        });
        v
    }

    fn state_of(p: &VehiclePreflight, name: &str) -> Option<CheckState> {
        p.checks.iter().find(|c| c.check == name).map(|c| c.state)
    }

    #[test]
    fn a_vehicle_on_the_ground_with_everything_in_order_is_ready() {
        let p = preflight(&ready_vehicle());
        assert!(p.ready, "{p:?}");
        assert!(p.checks.iter().all(|c| c.state == CheckState::Ok), "{p:?}");
        assert_eq!(
            state_of(&p, "remote_id"),
            None,
            "not configured, none heard"
        );
    }

    #[test]
    fn px4_refusing_to_arm_fails_with_what_it_said() {
        let mut v = ready_vehicle();
        v.prearm_ok = Some(false);
        v.px4_messages.push(Px4Message {
            severity: 2,
            text: "Preflight Fail: Open Drone ID system missing".into(),
            unix_ms: 0,
        });
        let p = preflight(&v);
        assert!(!p.ready);
        let c = p
            .checks
            .iter()
            .find(|c| c.check == "px4_arming_checks")
            .unwrap();
        assert_eq!(c.state, CheckState::Fail);
        assert!(c.detail.contains("Open Drone ID system missing"), "{c:?}");
    }

    #[test]
    fn no_fix_a_low_battery_a_failed_fence_or_a_transmitter_not_ready_fail() {
        type Spoil = fn(&mut VehicleSnapshot);
        let cases: [(&str, Spoil); 4] = [
            ("gnss", |v| v.gps.as_mut().unwrap().fix_type = 2),
            ("battery", |v| v.battery.as_mut().unwrap().percent = 10.0),
            ("geofence", |v| {
                v.fence.as_mut().unwrap().state = FenceSyncState::Failed
            }),
            ("remote_id", |v| {
                v.remote_id = Some(RemoteIdStatus {
                    operator_sent: true,
                    transmitter: Some(RemoteIdArmStatus {
                        good_to_arm: false,
                        error: "operator ID missing".into(),
                    }),
                })
            }),
        ];
        for (name, spoil) in cases {
            let mut v = ready_vehicle();
            spoil(&mut v);
            let p = preflight(&v);
            assert!(!p.ready, "{name}: {p:?}");
            assert_eq!(state_of(&p, name), Some(CheckState::Fail), "{name}: {p:?}");
        }
    }

    #[test]
    fn in_the_air_or_a_fence_pending_only_warns() {
        let mut v = ready_vehicle();
        v.state = VehicleState::Hovering;
        v.fence.as_mut().unwrap().state = FenceSyncState::Pending;
        let p = preflight(&v);
        assert!(p.ready, "{p:?}");
        assert_eq!(state_of(&p, "state"), Some(CheckState::Warn));
        assert_eq!(state_of(&p, "geofence"), Some(CheckState::Warn));
    }
}
