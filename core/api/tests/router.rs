//! The router without a socket or a swarm (`tower::ServiceExt::oneshot` on
//! [`skein_api::app`], a coordinator stand-in that answers nothing): routing, the 404 of
//! paths that are no route, bodies refused naming the field, the contract and the
//! dashboard. The roles are `tests/api_auth.rs`'.

mod support;

use axum::http::StatusCode;
use skein_api::auth::Auth;
use skein_api::openapi::route_access;
use support::{TOKENS, call, concrete, configured, request, request_with, router};

#[tokio::test]
async fn every_operation_of_the_contract_is_a_route() {
    let app = router(Auth::disabled()).await;
    let mut missing = Vec::new();
    for route in route_access() {
        let uri = concrete(&route.path);
        let (status, body) = call(&app, request(&route.method, &uri, None, [127, 0, 0, 1])).await;
        let unrouted = body["error"]
            .as_str()
            .is_some_and(|e| e.starts_with("no such endpoint"));
        if unrouted || status == StatusCode::METHOD_NOT_ALLOWED {
            missing.push(format!("{} {uri}: {status} {body}", route.method));
        }
    }
    assert!(missing.is_empty(), "{}", missing.join("\n"));
    assert!(route_access().len() > 40);
}

#[tokio::test]
async fn a_path_that_is_no_route_answers_404_json_naming_it() {
    let app = router(Auth::disabled()).await;
    for (method, path) in [
        ("GET", "/api/v1/nothing"),
        ("POST", "/api/v1/plugins/frobnicate"),
        ("POST", "/api/v1/formation/leader/spin"),
    ] {
        let (status, body) = call(&app, request(method, path, None, [127, 0, 0, 1])).await;
        assert_eq!(status, StatusCode::NOT_FOUND, "{method} {path}: {body}");
        assert_eq!(body["error"], format!("no such endpoint: {path}"), "{body}");
    }
}

#[tokio::test]
async fn a_method_the_route_has_not_answers_405() {
    let app = router(Auth::disabled()).await;
    let (status, _) = call(
        &app,
        request("PATCH", "/api/v1/formation", None, [127, 0, 0, 1]),
    )
    .await;
    assert_eq!(status, StatusCode::METHOD_NOT_ALLOWED);
}

#[tokio::test]
async fn a_refused_body_names_the_field_at_fault() {
    let app = router(Auth::disabled()).await;
    for (method, path, body, field) in [
        (
            "PUT",
            "/api/v1/formation",
            r#"{"shape":"line","spacing_m":"x"}"#,
            "spacing_m",
        ),
        (
            "PUT",
            "/api/v1/formation",
            r#"{"shape":"custom","offsets":[{"forward_m":1,"right_m":2e9}]}"#,
            "offsets[0].right_m",
        ),
        (
            "POST",
            "/api/v1/formation/leader/orbit",
            r#"{"north_m":0,"east_m":0}"#,
            "radius_m",
        ),
        (
            "POST",
            "/api/v1/vehicles/uav-1/commands",
            r#"{"command":"force_disarm"}"#,
            "confirm",
        ),
        (
            "POST",
            "/api/v1/swarm/commands",
            r#"{"command":"clear_hazard"}"#,
            "command",
        ),
        (
            "POST",
            "/api/v1/vehicles/uav-1/payloads",
            r#"{"slot":" ","kind":"lamp"}"#,
            "slot",
        ),
    ] {
        let (status, answer) = call(
            &app,
            request_with(method, path, None, [127, 0, 0, 1], Some(body)),
        )
        .await;
        assert_eq!(
            (status, answer["field"].as_str()),
            (StatusCode::BAD_REQUEST, Some(field)),
            "{method} {path} {body}: {answer}"
        );
    }
}

#[tokio::test]
async fn the_contract_is_served_without_a_token() {
    let app = router(configured()).await;
    let (status, body) = call(
        &app,
        request("GET", "/api/v1/openapi.json", None, [10, 0, 0, 3]),
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    let served: serde_json::Value = serde_json::from_str(skein_api::openapi::document()).unwrap();
    assert_eq!(body, served);
}

#[tokio::test]
async fn the_dashboard_is_served_for_every_other_path_without_a_token() {
    let app = router(configured()).await;
    let res = tower::ServiceExt::oneshot(app.clone(), request("GET", "/", None, [10, 0, 0, 4]))
        .await
        .unwrap();
    assert_eq!(res.status(), StatusCode::OK);
    assert!(
        res.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("text/html")
    );
    let (status, body) = call(
        &app,
        request("GET", "/no-such-file.js", None, [10, 0, 0, 4]),
    )
    .await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    assert_eq!(body["error"], "no such file: /no-such-file.js");
    // An API path, though, needs a token even to learn it is none.
    let (status, _) = call(&app, request("GET", "/api/v1/nothing", None, [10, 0, 0, 4])).await;
    assert_eq!(status, StatusCode::UNAUTHORIZED);
    let (status, _) = call(
        &app,
        request("GET", "/api/v1/nothing", Some(TOKENS[0].2), [10, 0, 0, 4]),
    )
    .await;
    assert_eq!(status, StatusCode::NOT_FOUND);
}

/// The pure reads answer from the coordinator's published state, not its mailbox: with a
/// coordinator that answers nothing, the vehicles, the formation, the supervision tree
/// and the tracks are still read (a swarm with nothing in it), while the health check,
/// which asks the coordinator, says it is unavailable.
#[tokio::test]
async fn reads_answer_without_the_coordinator_and_health_asks_it() {
    let app = router(Auth::disabled()).await;
    for path in [
        "/api/v1/vehicles",
        "/api/v1/formation",
        "/api/v1/supervision",
        "/api/v1/tracks",
        "/api/v1/swarms",
    ] {
        let (status, body) = call(&app, request("GET", path, None, [127, 0, 0, 1])).await;
        assert_eq!(status, StatusCode::OK, "{path}: {body}");
    }
    let (status, body) = call(
        &app,
        request("GET", "/api/v1/vehicles/uav-1", None, [127, 0, 0, 1]),
    )
    .await;
    assert_eq!(status, StatusCode::NOT_FOUND, "{body}");
    let (status, body) = call(&app, request("GET", "/api/v1/health", None, [127, 0, 0, 1])).await;
    assert_eq!(status, StatusCode::SERVICE_UNAVAILABLE, "{body}");
}
