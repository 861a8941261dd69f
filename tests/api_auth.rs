//! Roles on every route, over the router without a socket: each operation of the
//! contract (`skein_api::openapi::route_access`, the role table read from it) × {no token, viewer,
//! operator, admin} → 401 / 403 / through, and the failed-attempt lockout (429). The
//! coordinator is a stand-in that drops every request (handlers answer 503 at once): only
//! the gates' verdict is under test.

#[path = "../core/api/tests/support/mod.rs"]
mod support;

use axum::http::StatusCode;
use skein_api::auth::{self, Auth};
use skein_api::openapi::route_access;
use skein_api::roles::Access;
use support::{TOKENS, call, concrete, configured, request, router, router_of};

#[derive(Debug, PartialEq)]
enum Verdict {
    Unauthorized,
    Forbidden,
    Through,
}

#[tokio::test]
async fn every_route_enforces_its_role() {
    let app = router(configured()).await;
    let mut failures = Vec::new();
    for route in route_access() {
        let (method, access) = (route.method.as_str(), route.access);
        let uri = concrete(&route.path);
        for caller in [None, Some(0usize), Some(1), Some(2)] {
            let token = caller.map(|i| TOKENS[i].2);
            let role = caller.map(|i| TOKENS[i].1);
            let expected = match (access, role) {
                (Access::Public, _) => Verdict::Through,
                (Access::Role(_), None) => Verdict::Unauthorized,
                (Access::Role(need), Some(r)) if r < need => Verdict::Forbidden,
                _ => Verdict::Through,
            };
            let (status, body) = call(&app, request(method, &uri, token, [10, 0, 0, 1])).await;
            let got = match status {
                StatusCode::UNAUTHORIZED => {
                    assert_eq!(body["field"], "authorization", "{method} {uri}: {body}");
                    Verdict::Unauthorized
                }
                // A 403 of the middleware names the role; a handler's own 403 does not.
                StatusCode::FORBIDDEN if body.get("required_role").is_some() => {
                    assert_eq!(body["field"], "authorization");
                    let Access::Role(need) = access else {
                        unreachable!()
                    };
                    assert_eq!(body["required_role"], need.as_str());
                    Verdict::Forbidden
                }
                _ => Verdict::Through,
            };
            // The table names real routes: none falls through to the 404 catch-all or 405.
            if caller == Some(2) {
                let e = body["error"].as_str().unwrap_or("");
                if e.starts_with("no such endpoint") || status == StatusCode::METHOD_NOT_ALLOWED {
                    failures.push(format!("{method} {uri}: not a route of the router"));
                }
            }
            if got != expected {
                failures.push(format!(
                    "{method} {uri} as {:?}: expected {expected:?}, got {status} {body}",
                    caller.map(|i| TOKENS[i].0)
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[tokio::test]
async fn without_tokens_everything_is_open_and_whoami_says_so() {
    let app = router(Auth::disabled()).await;
    for route in route_access() {
        let (method, path) = (route.method.as_str(), &route.path);
        let (status, body) =
            call(&app, request(method, &concrete(path), None, [127, 0, 0, 1])).await;
        assert!(
            status != StatusCode::UNAUTHORIZED && body.get("required_role").is_none(),
            "{method} {path}: {status} {body}"
        );
    }
    let (status, body) = call(
        &app,
        request("GET", "/api/v1/auth/whoami", None, [127, 0, 0, 1]),
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(
        body,
        serde_json::json!({"auth": false, "name": null, "role": "admin"})
    );
}

#[tokio::test]
async fn whoami_names_the_token_and_the_query_token_works_for_gets_only() {
    let app = router(configured()).await;
    let (status, body) = call(
        &app,
        request(
            "GET",
            "/api/v1/auth/whoami",
            Some(TOKENS[1].2),
            [10, 0, 0, 2],
        ),
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(
        body,
        serde_json::json!({"auth": true, "name": "ops", "role": "operator"})
    );
    let q = format!("/api/v1/auth/whoami?token={}", TOKENS[0].2);
    let (status, body) = call(&app, request("GET", &q, None, [10, 0, 0, 2])).await;
    assert_eq!(status, StatusCode::OK, "{body}");
    assert_eq!(body["name"], "watch");
    let q = format!("/api/v1/swarm/commands?token={}", TOKENS[2].2);
    let (status, _) = call(&app, request("POST", &q, None, [10, 0, 0, 2])).await;
    assert_eq!(status, StatusCode::UNAUTHORIZED);
    // Unknown API paths need a token too (no probing), the dashboard's files do not.
    let (status, _) = call(&app, request("GET", "/api/v1/nothing", None, [10, 0, 0, 2])).await;
    assert_eq!(status, StatusCode::UNAUTHORIZED);
    let (status, _) = call(&app, request("GET", "/", None, [10, 0, 0, 2])).await;
    assert_eq!(status, StatusCode::OK);
}

#[tokio::test]
async fn repeated_bad_tokens_are_answered_429_per_ip() {
    let app = router(configured()).await;
    let bad = [10, 0, 0, 66];
    for i in 0..auth::MAX_FAILURES {
        let (status, _) = call(
            &app,
            request("GET", "/api/v1/vehicles", Some(&format!("guess-{i}")), bad),
        )
        .await;
        assert_eq!(status, StatusCode::UNAUTHORIZED, "attempt {i}");
    }
    // Locked out: even the right token is refused for now.
    let (status, body) = call(
        &app,
        request("GET", "/api/v1/vehicles", Some(TOKENS[2].2), bad),
    )
    .await;
    assert_eq!(status, StatusCode::TOO_MANY_REQUESTS, "{body}");
    assert_eq!(body["field"], "authorization");
    // Another client is not affected, nor is the public health route.
    let (status, body) = call(
        &app,
        request(
            "GET",
            "/api/v1/auth/whoami",
            Some(TOKENS[0].2),
            [10, 0, 0, 67],
        ),
    )
    .await;
    assert_eq!(status, StatusCode::OK, "{body}");
    let (status, _) = call(&app, request("GET", "/api/v1/health", None, bad)).await;
    assert_ne!(status, StatusCode::TOO_MANY_REQUESTS);
}

/// An election status of candidate `gcs-b`, standby under `gcs-a`, or active itself.
fn election(role: skein_swarm::election::CoordinatorRole) -> skein_swarm::election::ElectionStatus {
    use skein_swarm::election::{CoordinatorRole, ElectionStatus, Lease};
    let a = Lease {
        coordinator_id: "gcs-a".into(),
        priority: 2,
        epoch: 3,
        active: true,
        api_url: "http://10.0.0.2:8080".into(),
    };
    let mut b = Lease {
        coordinator_id: "gcs-b".into(),
        priority: 1,
        epoch: 3,
        active: role == CoordinatorRole::Active,
        api_url: "http://10.0.0.3:8080".into(),
    };
    if role == CoordinatorRole::Active {
        b.epoch = 4;
    }
    ElectionStatus {
        active: Some(if role == CoordinatorRole::Active {
            b.clone()
        } else {
            a
        }),
        this: b,
        role,
        peers: Vec::new(),
    }
}

#[tokio::test]
async fn a_standby_refuses_every_write_after_authentication_and_answers_reads() {
    use skein_swarm::election::CoordinatorRole;
    let (tx, rx) = tokio::sync::watch::channel(election(CoordinatorRole::Standby));
    let app = router_of(configured(), Some(rx)).await;
    let admin = Some(TOKENS[2].2);
    for route in route_access() {
        let (method, access) = (route.method.as_str(), route.access);
        let uri = concrete(&route.path);
        let (status, body) = call(&app, request(method, &uri, admin, [10, 0, 0, 7])).await;
        if method == "GET" {
            assert_ne!(status, StatusCode::CONFLICT, "{method} {uri}: {body}");
            continue;
        }
        assert_eq!(status, StatusCode::CONFLICT, "{method} {uri}: {body}");
        let e = body["error"].as_str().unwrap();
        assert!(
            e.contains("`gcs-b` is a standby") && e.contains("`gcs-a`") && e.contains("epoch 3"),
            "{e}"
        );
        assert!(e.contains("http://10.0.0.2:8080"), "{e}");
        // Authentication comes first: no token is a 401, not a 409.
        if access != Access::Public {
            let (status, _) = call(&app, request(method, &uri, None, [10, 0, 0, 8])).await;
            assert_eq!(status, StatusCode::UNAUTHORIZED, "{method} {uri}");
        }
    }
    let (status, body) = call(
        &app,
        request("GET", "/api/v1/coordinator", admin, [10, 0, 0, 7]),
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(body["role"], "standby");
    assert_eq!(body["active"]["coordinator_id"], "gcs-a");
    // Once active, writes pass to their handlers (the mute coordinator: 503).
    tx.send_replace(election(CoordinatorRole::Active));
    let (status, body) = call(
        &app,
        request("POST", "/api/v1/swarm/commands", admin, [10, 0, 0, 7]),
    )
    .await;
    assert_ne!(status, StatusCode::CONFLICT, "{body}");
}

#[tokio::test]
async fn skein_up_is_no_candidate_and_says_so() {
    let app = router(configured()).await;
    let (status, body) = call(
        &app,
        request(
            "GET",
            "/api/v1/coordinator",
            Some(TOKENS[0].2),
            [10, 0, 0, 9],
        ),
    )
    .await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    assert!(
        body["error"]
            .as_str()
            .unwrap()
            .contains("not a coordinator candidate"),
        "{body}"
    );
}
