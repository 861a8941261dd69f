//! API request parsing: arbitrary bytes as the body of every route that takes one
//! (`skein_api::requests`, the same functions the handlers call). Nothing may panic, a
//! refused body is a 4xx with a message (and the field's path when there is one), and an
//! accepted formation or leader motion holds only finite numbers within the contract's
//! ranges.
#![no_main]

use libfuzzer_sys::fuzz_target;
use skein_api::error::ApiError;
use skein_api::requests::{self, recording, tracks};

fn refused_cleanly(e: &ApiError) {
    assert!(e.status.is_client_error(), "{} for a body: {e:?}", e.status);
    assert!(!e.error.is_empty(), "an error without a message: {e:?}");
    if let Some(f) = &e.field {
        assert!(!f.is_empty(), "an empty field name: {e:?}");
    }
}

fn check<T>(r: Result<T, ApiError>, ok: impl FnOnce(&T)) {
    match r {
        Ok(v) => ok(&v),
        Err(e) => refused_cleanly(&e),
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&which, body)) = data.split_first() else {
        return;
    };
    match which % 13 {
        0 => check(requests::commands::vehicle_command(body), |_| {}),
        1 => check(requests::commands::swarm_command(body), |_| {}),
        2 => check(requests::formation::formation(body), |f| {
            // Custom formations take offsets instead of a spacing (0).
            let custom = f.shape == skein_model::formation::Shape::Custom;
            assert!(f.spacing_m.is_finite() && f.spacing_m <= 1000.0, "{f:?}");
            assert!(custom || f.spacing_m > 0.0, "{f:?}");
            assert!(f.heading_deg.is_finite(), "{f:?}");
            assert!(f.altitude_m.is_none_or(|a| a.is_finite() && a.abs() <= 10_000.0), "{f:?}");
            for o in &f.offsets {
                assert!(o.north_m.is_finite() && o.east_m.is_finite() && o.down_m.is_finite(), "{f:?}");
            }
        }),
        3 => check(requests::leader::goto(body), |_| {}),
        4 => check(requests::leader::waypoints(body), |_| {}),
        5 => check(requests::leader::orbit(body), |_| {}),
        6 => check(requests::leader::hold(body), |_| {}),
        7 => check(requests::px4_param_write::param_value(body), |v| assert!(v.is_finite())),
        8 => check(requests::payloads::parse_attach(body), |_| {}),
        9 => {
            check(requests::plugins::load(body), |_| {});
            check(requests::plugins::unload(body), |_| {});
            check(requests::plugins::reload(body), |_| {});
        }
        10 => check(requests::faults::fault(body), |_| {}),
        11 => check(requests::parse_or_empty::<tracks::ObserveRequest>(body), |_| {}),
        _ => check(
            requests::parse_or_empty::<recording::RecordingStartRequest>(body),
            |_| {},
        ),
    }
});
