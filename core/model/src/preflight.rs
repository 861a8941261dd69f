//! The fleet's pre-flight checks (`GET /api/v1/preflight`): for each vehicle, what a crew
//! looks at before the first takeoff, from its snapshot: the link, PX4's own arming
//! checks and what PX4 said, the home, GNSS, battery, the autopilot's geofence and
//! Remote ID. A vehicle is ready when no check fails (a warning does not stop it).

use crate::fsm::VehicleState;
use crate::geofence::FenceSyncState;
use crate::vehicle::{OperatorLocationSource, RemoteIdStatus, VehicleSnapshot};
use serde::Serialize;

/// PX4's `BAT_LOW_THR` default (15 %): below it PX4 warns of a low battery, and a
/// vehicle should not take off.
pub const BATTERY_LOW_PERCENT: f64 = 15.0;

/// The `GPS_FIX_TYPE` a flight needs: 3 (3D fix).
pub const FIX_3D: u8 = 3;

/// RTK corrections older than this are stale (a receiver drops from RTK fixed to float
/// within seconds of losing them): the `gnss` check warns.
pub const CORRECTIONS_STALE_S: f64 = 10.0;

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

/// PX4's arming checks: each by name from its events' report where PX4 sends one
/// ([`px4_arming_by_name`]), else `SYS_STATUS`'s `PREARM_CHECK` with what PX4 last said.
fn px4_arming(v: &VehicleSnapshot) -> PreflightCheck {
    if !v.px4_arming_checks.is_empty() {
        return px4_arming_by_name(v);
    }
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

/// PX4's checks by name: those that prevent arming in the current mode fail
/// (`"fail: Open Drone ID system missing"`), the others are listed after them; only
/// warnings or worse that prevent nothing warn.
fn px4_arming_by_name(v: &VehicleSnapshot) -> PreflightCheck {
    let (failing, other): (Vec<_>, Vec<_>) =
        v.px4_arming_checks.iter().partition(|c| c.prevents_arming);
    let names = |cs: &[&crate::vehicle::Px4ArmingCheck]| {
        cs.iter()
            .map(|c| format!("{} ({})", c.message, c.severity))
            .collect::<Vec<_>>()
            .join("; ")
    };
    let serious = |c: &&crate::vehicle::Px4ArmingCheck| {
        matches!(
            c.severity.as_str(),
            "emergency" | "alert" | "critical" | "error" | "warning"
        )
    };
    if !failing.is_empty() {
        let mut detail = format!("fail: {}", names(&failing));
        if !other.is_empty() {
            detail.push_str(&format!("; also: {}", names(&other)));
        }
        return check("px4_arming_checks", CheckState::Fail, detail);
    }
    let state = if other.iter().any(serious) {
        CheckState::Warn
    } else {
        CheckState::Ok
    };
    check(
        "px4_arming_checks",
        state,
        format!("pass; reported: {}", names(&other)),
    )
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
    let eph = g
        .eph_m
        .map_or("eph unknown".into(), |e| format!("eph {e:.2} m"));
    let stale = g.correction_age_s.filter(|age| *age > CORRECTIONS_STALE_S);
    let corrections = match (g.correction_age_s, stale) {
        (_, Some(age)) => format!(", RTK corrections {age:.0} s old"),
        (Some(age), None) => format!(", RTK corrections {age:.1} s old"),
        (None, _) => String::new(),
    };
    let state = if g.fix_type < FIX_3D {
        CheckState::Fail
    } else if stale.is_some() {
        CheckState::Warn
    } else {
        CheckState::Ok
    };
    check(
        "gnss",
        state,
        format!(
            "{}, {} satellites, {eph}{corrections}",
            g.fix_name(),
            g.satellites
        ),
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

/// Remote ID, where skein sends it or a transmitter reported: the transmitter's
/// verdict, then where the operator location comes from; it warns when the ground
/// station's live GNSS is configured but another location is sent.
fn remote_id(v: &VehicleSnapshot) -> Option<PreflightCheck> {
    let r = v.remote_id.as_ref()?;
    let mut c = remote_id_transmitter(r);
    let source = match r.operator_location_source {
        Some(OperatorLocationSource::LiveGnss) => "live GNSS",
        Some(OperatorLocationSource::Fixed) => "the fixed location",
        Some(OperatorLocationSource::Takeoff) => "the takeoff point",
        None => return Some(c),
    };
    match (&r.operator_location_fallback, r.operator_location_age_s) {
        (Some(why), _) => {
            if c.state == CheckState::Ok {
                c.state = CheckState::Warn;
            }
            c.detail += &format!("; operator at {source}, not live GNSS: {why}");
        }
        (None, Some(age)) => c.detail += &format!("; operator at {source} ({age:.1} s old)"),
        (None, None) => c.detail += &format!("; operator at {source}"),
    }
    Some(c)
}

fn remote_id_transmitter(r: &RemoteIdStatus) -> PreflightCheck {
    match (&r.transmitter, r.operator_sent) {
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
    }
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
            correction_age_s: None,
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
    fn px4s_own_checks_are_named_and_fail_only_where_they_prevent_arming() {
        use crate::vehicle::Px4ArmingCheck;
        let odid = |prevents| Px4ArmingCheck {
            message: "Open Drone ID system missing".into(),
            description: String::new(),
            severity: "error".into(),
            prevents_arming: prevents,
        };
        let mut v = ready_vehicle();
        v.prearm_ok = Some(false);
        v.px4_arming_checks = vec![odid(true)];
        let c = preflight(&v)
            .checks
            .into_iter()
            .find(|c| c.check == "px4_arming_checks")
            .unwrap();
        assert_eq!(c.state, CheckState::Fail);
        assert_eq!(c.detail, "fail: Open Drone ID system missing (error)");
        // COM_ARM_ODID 1: PX4 reports it but arms.
        v.prearm_ok = Some(true);
        v.px4_arming_checks = vec![odid(false)];
        let c = preflight(&v)
            .checks
            .into_iter()
            .find(|c| c.check == "px4_arming_checks")
            .unwrap();
        assert_eq!(c.state, CheckState::Warn, "{c:?}");
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
                    ..RemoteIdStatus::default()
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
    fn live_gnss_configured_without_a_fix_warns_naming_the_location_sent() {
        let mut v = ready_vehicle();
        let ready = Some(RemoteIdArmStatus {
            good_to_arm: true,
            error: String::new(),
        });
        v.remote_id = Some(RemoteIdStatus {
            operator_sent: true,
            transmitter: ready.clone(),
            operator_location_source: Some(OperatorLocationSource::LiveGnss),
            operator_location_age_s: Some(0.42),
            ..RemoteIdStatus::default()
        });
        let p = preflight(&v);
        let c = p.checks.iter().find(|c| c.check == "remote_id").unwrap();
        assert_eq!(c.state, CheckState::Ok, "{c:?}");
        assert!(
            c.detail.ends_with("operator at live GNSS (0.4 s old)"),
            "{c:?}"
        );
        v.remote_id = Some(RemoteIdStatus {
            operator_sent: true,
            transmitter: ready,
            operator_location_source: Some(OperatorLocationSource::Fixed),
            operator_location_fallback: Some("no fix from gpsd://127.0.0.1:2947".into()),
            ..RemoteIdStatus::default()
        });
        let p = preflight(&v);
        assert!(p.ready, "a warning: {p:?}");
        let c = p.checks.iter().find(|c| c.check == "remote_id").unwrap();
        assert_eq!(c.state, CheckState::Warn, "{c:?}");
        assert!(
            c.detail
                .contains("operator at the fixed location, not live GNSS: no fix from gpsd://"),
            "{c:?}"
        );
    }

    #[test]
    fn stale_rtk_corrections_warn_and_fresh_ones_are_shown() {
        let mut v = ready_vehicle();
        let g = v.gps.as_mut().unwrap();
        g.fix_type = 6;
        g.correction_age_s = Some(0.4);
        let p = preflight(&v);
        let c = p.checks.iter().find(|c| c.check == "gnss").unwrap();
        assert_eq!(c.state, CheckState::Ok);
        assert!(c.detail.starts_with("RTK fixed, 12 satellites"), "{c:?}");
        assert!(c.detail.ends_with("RTK corrections 0.4 s old"), "{c:?}");
        v.gps.as_mut().unwrap().correction_age_s = Some(42.0);
        let p = preflight(&v);
        assert!(p.ready);
        assert_eq!(state_of(&p, "gnss"), Some(CheckState::Warn));
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
