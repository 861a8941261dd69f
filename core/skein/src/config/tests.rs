//! Tests of the config file: parsing, validation, errors naming the key and line.

use super::*;

#[test]
fn full_file_parses() {
    let c = ConfigFile::parse(
        r#"
[swarm]
origin = { lat_deg = 47.397742, lon_deg = 8.545594, alt_amsl_m = 488.0 }
stream_rate_hz = 30.0
geofence = { radius_m = 200.0, max_altitude_m = 60.0 }

[link]
mav_type = "onboard_controller"
telemetry = "swarm"
params = { COM_OF_LOSS_T = 1.0, COM_OBL_RC_ACT = 5 }

[[vehicles]]
connection = "udpin:0.0.0.0:14540"
id = "alpha"

[[vehicles]]
connection = "udpin:0.0.0.0:14549"
sysid = 11

[[vehicles]]
connection = "udpin:0.0.0.0:14549"
sysid = 12
model = "generic"
"#,
    )
    .unwrap();
    let s = c.swarm_config().unwrap();
    assert_eq!(s.stream_rate_hz, 30.0);
    assert_eq!(s.geofence.radius_m, 200.0);
    assert_eq!(c.identity().mav_type, MavType::MAV_TYPE_ONBOARD_CONTROLLER);
    assert_eq!(s.link_setup.telemetry, skein_link::TelemetryProfile::Swarm);
    assert_eq!(
        s.link_setup.params,
        vec![
            ("COM_OBL_RC_ACT".to_string(), 5.0),
            ("COM_OF_LOSS_T".to_string(), 1.0)
        ]
    );
    let eps = c.endpoints().unwrap();
    assert_eq!(eps.len(), 2, "the two 14549 entries share an endpoint");
    assert_eq!(eps[1].vehicles.len(), 2);
    assert_eq!(eps[0].vehicles[0].id.as_deref(), Some("alpha"));
}

#[test]
fn errors_name_the_key_and_line() {
    let e = ConfigFile::parse("[[vehicles]]\nconection = \"udpin:0.0.0.0:14540\"\n").unwrap_err();
    assert!(e.contains("line 2"), "{e}");
    assert!(e.contains("conection"), "{e}");

    let e = ConfigFile::parse("[[vehicles]]\nid = \"a\"\nconnection = \"udpn:1.2.3.4:5\"\n")
        .unwrap_err();
    assert!(e.contains("line 3"), "{e}");
    assert!(e.contains("unknown scheme `udpn`"), "{e}");

    let e = ConfigFile::parse("[swarm]\nstream_rate_hz = \"fast\"\n").unwrap_err();
    assert!(e.contains("line 2") && e.contains("stream_rate_hz"), "{e}");

    let e = ConfigFile::parse("[swarm]\nstream_rate_hz = 1.0\n").unwrap_err();
    assert!(e.contains("swarm.stream_rate_hz"), "{e}");

    let e = ConfigFile::parse(
        "[[vehicles]]\nconnection = \"udpin:0.0.0.0:1\"\nid = \"x\"\n[[vehicles]]\nconnection = \"udpin:0.0.0.0:2\"\nid = \"x\"\n",
    )
    .unwrap_err();
    assert!(e.contains("vehicles[1].id"), "{e}");
}

#[test]
fn supervision_and_models() {
    let c = ConfigFile::parse(
        r#"
[supervision]
vehicle_escalation = "land"
payload = { max_restarts = 2, window_s = 30.0 }

[models.tester]
payloads = [{ slot = "fixture", kind = "fault-fixture" }]
"#,
    )
    .unwrap();
    let s = c.swarm_config().unwrap();
    assert_eq!(
        s.supervision.vehicle_escalation,
        skein_swarm::supervision::VehicleEscalation::Land
    );
    assert_eq!(s.supervision.payload.max_restarts, 2);
    assert_eq!(
        s.supervision.payload.backoff_max_ms, 5000,
        "other fields default"
    );
    assert_eq!(s.models["tester"].payloads[0].kind, "fault-fixture");
    let e = ConfigFile::parse("[supervision]\npayload = { max_restart = 2 }\n").unwrap_err();
    assert!(e.contains("max_restart") && e.contains("line 2"), "{e}");
    let e = ConfigFile::parse(
        "[models.x]\npayloads = [{ slot = \"a\", kind = \"k\" }, { slot = \"a\", kind = \"k\" }]\n",
    )
    .unwrap_err();
    assert!(e.contains("models.x.payloads[1].slot"), "{e}");
    let e = ConfigFile::parse("[[vehicles]]\nconnection = \"udpin:0.0.0.0:1\"\nmodel = \"nope\"\n")
        .unwrap_err();
    assert!(e.contains("vehicles[0].model `nope`"), "{e}");
}

#[test]
fn plugins_section() {
    let c = ConfigFile::parse("[plugins]\ndir = \"/opt/skein/plugins\"\n").unwrap();
    assert_eq!(
        c.plugins.dir.as_deref(),
        Some(Path::new("/opt/skein/plugins"))
    );
    let e = ConfigFile::parse("[plugins]\ndirectory = \"x\"\n").unwrap_err();
    assert!(e.contains("directory") && e.contains("line 2"), "{e}");
}

#[test]
fn empty_file_is_fine() {
    let c = ConfigFile::parse("").unwrap();
    assert!(c.vehicles.is_empty());
    assert_eq!(c.swarm_config().unwrap().stream_rate_hz, 50.0);
}

#[test]
fn signing_keys_and_the_gcs_forward() {
    let dir = std::env::temp_dir().join(format!("skein-cfg-keys-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("good.key"), format!("{}\n", "0f".repeat(32))).unwrap();
    std::fs::write(dir.join("bad.key"), "not a key").unwrap();
    let file = |text: &str| {
        let p = dir.join("skein.toml");
        std::fs::write(&p, text).unwrap();
        ConfigFile::load(&p)
    };
    let c = file(
        r#"
[gcs]
forward = "udpout:127.0.0.1:14550"

[[vehicles]]
connection = "udpin:0.0.0.0:14540"
signing_key_file = "good.key"
signing_link_id = 4

[[vehicles]]
connection = "udpin:0.0.0.0:14541"
"#,
    )
    .unwrap();
    assert_eq!(
        c.gcs.forward.as_ref().map(|f| f.0.to_string()).as_deref(),
        Some("udpout:127.0.0.1:14550")
    );
    let eps = c.endpoints().unwrap();
    let s = eps[0].vehicles[0].signing.as_ref().expect("signing");
    assert_eq!((s.key.as_bytes()[0], s.link_id), (0x0f, 4));
    assert!(eps[1].vehicles[0].signing.is_none());

    let e = file(
        "[[vehicles]]\nconnection = \"udpin:0.0.0.0:14540\"\nsigning_key_file = \"bad.key\"\n",
    )
    .unwrap_err();
    assert!(
        e.contains("bad.key") && e.contains("64 hex characters"),
        "{e}"
    );
    let e = file(
        "[[vehicles]]\nconnection = \"udpin:0.0.0.0:14540\"\nsigning_key_file = \"none.key\"\n",
    )
    .unwrap_err();
    assert!(e.contains("none.key") && e.contains("cannot read"), "{e}");
    let e = ConfigFile::parse(
        "[[vehicles]]\nconnection = \"udpin:0.0.0.0:14540\"\nsigning_link_id = 1\n",
    )
    .unwrap_err();
    assert!(e.contains("vehicles[0].signing_link_id needs"), "{e}");
    let e = ConfigFile::parse("[gcs]\nforwrd = \"udpout:127.0.0.1:14550\"\n").unwrap_err();
    assert!(e.contains("forwrd"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn map_and_geofence_sections() {
    let c = ConfigFile::parse(
        r#"
[swarm]
geofence = { radius_m = 300.0, max_altitude_m = 60.0, polygon = [[-50.0, -50.0], [80.0, -50.0], [80.0, 50.0], [-50.0, 50.0]], exclusions = [{ circle = { north_m = 20.0, east_m = 0.0, radius_m = 5.0 } }], rally_points = [{ north_m = -40.0, east_m = 0.0, altitude_m = 15.0 }], breach_action = "rtl" }

[map]
tiles = "field.mbtiles"
online_url = "https://tiles.example/{z}/{x}/{y}.png"
online_attribution = "example"
"#,
    )
    .unwrap();
    let g = c.swarm_config().unwrap().geofence;
    assert_eq!(g.polygon.len(), 4);
    assert_eq!(g.breach_action, skein_model::geofence::BreachAction::Rtl);
    assert_eq!(c.map.tiles.as_deref(), Some(Path::new("field.mbtiles")));
    let e = ConfigFile::parse("[map]\ntile = \"x\"\n").unwrap_err();
    assert!(e.contains("tile"), "{e}");
    let e = ConfigFile::parse(
        "[swarm]\ngeofence = { radius_m = 100.0, max_altitude_m = 60.0, polygon = [[0.0, 0.0], [5.0, 5.0], [5.0, 0.0], [0.0, 5.0]] }\n",
    )
    .unwrap_err();
    assert!(
        e.contains("swarm.geofence.polygon") && e.contains("self-intersecting"),
        "{e}"
    );
}
