//! The operations of the contract: one row per method and path, with the request
//! body, the success answers and the error statuses each may give.

/// What an operation answers on success.
#[derive(Debug, Clone, Copy)]
pub enum Answer {
    /// JSON of the named schema.
    Json(&'static str),
    /// A JSON array of the named schema.
    JsonArray(&'static str),
    /// Any JSON (the OpenAPI document itself).
    AnyJson,
    /// Text of this media type.
    Text(&'static str),
    /// Bytes of this media type.
    Binary(&'static str),
    /// `101 Switching Protocols` to a WebSocket.
    WebSocket,
}

/// A request body.
#[derive(Debug, Clone, Copy)]
pub enum Body {
    /// None.
    None,
    /// JSON of the named schema.
    Json(&'static str),
    /// JSON of the named schema, or no body at all.
    OptionalJson(&'static str),
    /// A JSON object of no fixed shape (a payload's own command).
    JsonObject,
}

/// One operation of the contract.
#[derive(Debug, Clone, Copy)]
pub struct Operation {
    /// HTTP method.
    pub method: &'static str,
    /// Path as the contract (and docs/api.md) write it.
    pub path: &'static str,
    /// One line on what it does.
    pub summary: &'static str,
    /// Its request body.
    pub body: Body,
    /// Success answers: status and body.
    pub ok: &'static [(u16, Answer)],
    /// Error statuses it may answer (401 / 403 / 429 of the authentication are added to
    /// every operation that needs a token).
    pub errors: &'static [u16],
}

const fn op(
    method: &'static str,
    path: &'static str,
    summary: &'static str,
    body: Body,
    ok: &'static [(u16, Answer)],
    errors: &'static [u16],
) -> Operation {
    Operation {
        method,
        path,
        summary,
        body,
        ok,
        errors,
    }
}

use Answer::{Json, JsonArray};

/// Every operation of the API.
pub const OPERATIONS: &[Operation] = &[
    op(
        "GET",
        "/api/v1/health",
        "Swarm health (never needs a token)",
        Body::None,
        &[(200, Json("Health"))],
        &[503],
    ),
    op(
        "GET",
        "/api/v1/openapi.json",
        "This contract, OpenAPI 3.1 (never needs a token)",
        Body::None,
        &[(200, Answer::AnyJson)],
        &[],
    ),
    op(
        "GET",
        "/api/v1/auth/whoami",
        "The caller's token: name and role",
        Body::None,
        &[(200, Json("Identity"))],
        &[],
    ),
    op(
        "GET",
        "/api/v1/vehicles",
        "Every vehicle, sorted by id",
        Body::None,
        &[(200, JsonArray("VehicleSnapshot"))],
        &[503],
    ),
    op(
        "GET",
        "/api/v1/vehicles/{id}",
        "One vehicle",
        Body::None,
        &[(200, Json("VehicleSnapshot"))],
        &[404, 503],
    ),
    op(
        "POST",
        "/api/v1/vehicles/{id}/commands",
        "A command for one vehicle: 202 once its state machine accepted it (the outcome follows on the stream); clear_hazard answers 200",
        Body::Json("CommandRequest"),
        &[(202, Json("CommandOutcome")), (200, Json("Cleared"))],
        &[400, 404, 409, 503],
    ),
    op(
        "GET",
        "/api/v1/vehicles/{id}/params",
        "The PX4 parameters seen so far",
        Body::None,
        &[(200, JsonArray("ParamEntry"))],
        &[404, 503],
    ),
    op(
        "GET",
        "/api/v1/vehicles/{id}/params/{name}",
        "Read a PX4 parameter (PARAM_REQUEST_READ)",
        Body::None,
        &[(200, Json("ParamValue"))],
        &[400, 404, 409, 503],
    ),
    op(
        "PUT",
        "/api/v1/vehicles/{id}/params/{name}",
        "Write a PX4 parameter (PARAM_SET), answered with the value PX4 confirms",
        Body::Json("ParamValueRequest"),
        &[(200, Json("ParamValue"))],
        &[400, 404, 409, 503],
    ),
    op(
        "POST",
        "/api/v1/swarm/commands",
        "A command for every vehicle (409 when every vehicle refused)",
        Body::Json("CommandRequest"),
        &[(202, Json("CommandOutcome"))],
        &[400, 409, 503],
    ),
    op(
        "GET",
        "/api/v1/formation",
        "The formation status",
        Body::None,
        &[(200, Json("FormationStatus"))],
        &[503],
    ),
    op(
        "PUT",
        "/api/v1/formation",
        "Fly a formation",
        Body::Json("FormationRequest"),
        &[(200, Json("FormationStatus"))],
        &[400, 503],
    ),
    op(
        "DELETE",
        "/api/v1/formation",
        "Stop flying the formation (members hold where they are)",
        Body::None,
        &[(200, Json("FormationStatus"))],
        &[503],
    ),
    op(
        "POST",
        "/api/v1/formation/leader/goto",
        "Move the formation's reference to a point",
        Body::Json("LeaderGoToRequest"),
        &[(200, Json("FormationStatus"))],
        &[400, 409, 503],
    ),
    op(
        "POST",
        "/api/v1/formation/leader/waypoints",
        "Move the formation's reference along waypoints",
        Body::Json("LeaderWaypointsRequest"),
        &[(200, Json("FormationStatus"))],
        &[400, 409, 503],
    ),
    op(
        "POST",
        "/api/v1/formation/leader/orbit",
        "Orbit the formation's reference around a centre",
        Body::Json("LeaderOrbitRequest"),
        &[(200, Json("FormationStatus"))],
        &[400, 409, 503],
    ),
    op(
        "POST",
        "/api/v1/formation/leader/hold",
        "Stop the formation's reference",
        Body::OptionalJson("LeaderHoldRequest"),
        &[(200, Json("FormationStatus"))],
        &[400, 409, 503],
    ),
    op(
        "GET",
        "/api/v1/formation/shapes",
        "The shapes, with the fewest vehicles each needs",
        Body::None,
        &[(200, JsonArray("ShapeInfo"))],
        &[],
    ),
    op(
        "GET",
        "/api/v1/vehicles/{id}/payloads",
        "The vehicle's payload slots",
        Body::None,
        &[(200, Answer::JsonArray("PayloadView"))],
        &[404, 503],
    ),
    op(
        "POST",
        "/api/v1/vehicles/{id}/payloads",
        "Attach a payload (until restart): 201 with the payload as listed, once its driver exists",
        Body::Json("AttachRequest"),
        &[(201, Json("PayloadView"))],
        &[400, 404, 409, 503],
    ),
    op(
        "POST",
        "/api/v1/vehicles/{id}/payloads/{slot}",
        "A payload's own JSON command; answered with its answer",
        Body::JsonObject,
        &[(200, Answer::AnyJson)],
        &[400, 404, 409, 503],
    ),
    op(
        "DELETE",
        "/api/v1/vehicles/{id}/payloads/{slot}",
        "Detach a payload (until restart), after its driver's shutdown ran",
        Body::None,
        &[(200, Json("Detached"))],
        &[404, 409, 503],
    ),
    op(
        "GET",
        "/api/v1/vehicles/{id}/payloads/{slot}/snapshot",
        "The camera's last frame",
        Body::None,
        &[(200, Answer::Binary("image/jpeg"))],
        &[404, 503],
    ),
    op(
        "GET",
        "/api/v1/vehicles/{id}/payloads/{slot}/stream",
        "The camera's frames as MJPEG, every new one",
        Body::None,
        &[(200, Answer::Binary("multipart/x-mixed-replace"))],
        &[404, 503],
    ),
    op(
        "GET",
        "/api/v1/plugins",
        "Plugin libraries, their instances, payload providers and refused files",
        Body::None,
        &[(200, Json("PluginsListing"))],
        &[],
    ),
    op(
        "POST",
        "/api/v1/plugins/load",
        "Load a plugin library from the plugin directory",
        Body::Json("LoadRequest"),
        &[(200, Json("LibraryInfo"))],
        &[400, 403, 409, 422, 503],
    ),
    op(
        "POST",
        "/api/v1/plugins/unload",
        "Unload a plugin library (force: stop its instances first)",
        Body::Json("UnloadRequest"),
        &[(200, Json("LibraryInfo"))],
        &[400, 404, 409, 503],
    ),
    op(
        "POST",
        "/api/v1/plugins/reload",
        "Reload a plugin library from its file; its instances move to the new build",
        Body::Json("ReloadRequest"),
        &[(200, Json("Reloaded"))],
        &[400, 404, 409, 422, 503],
    ),
    op(
        "GET",
        "/api/v1/supervision",
        "The actor tree: status, restarts, failures",
        Body::None,
        &[(200, Json("TreeNode"))],
        &[503],
    ),
    op(
        "POST",
        "/api/v1/faults",
        "Inject a fault into an actor (only with --enable-fault-injection)",
        Body::Json("FaultRequest"),
        &[(202, Json("FaultInjected"))],
        &[400, 403, 404, 503],
    ),
    op(
        "GET",
        "/metrics",
        "Prometheus / OpenMetrics counters",
        Body::None,
        &[(200, Answer::Text("application/openmetrics-text"))],
        &[503],
    ),
    op(
        "GET",
        "/api/v1/links",
        "MAVLink counters per endpoint",
        Body::None,
        &[(200, JsonArray("EndpointStats"))],
        &[503],
    ),
    op(
        "GET",
        "/api/v1/geofence",
        "The geofence every setpoint is clamped into",
        Body::None,
        &[(200, Json("Geofence"))],
        &[404],
    ),
    op(
        "GET",
        "/api/v1/coordinator",
        "The coordinator election as this candidate sees it (skein coordinator only)",
        Body::None,
        &[(200, Json("ElectionStatus"))],
        &[404],
    ),
    op(
        "GET",
        "/api/v1/tracks",
        "The counter-UAS tracks (swarm frame) and who observes each",
        Body::None,
        &[(200, Json("TracksListing"))],
        &[503],
    ),
    op(
        "POST",
        "/api/v1/tracks/{id}/observe",
        "Point the gimbals of the given (default: every) observation UAV at the track and keep them on it",
        Body::OptionalJson("ObserveRequest"),
        &[(200, Json("Observing"))],
        &[400, 404, 409, 503],
    ),
    op(
        "DELETE",
        "/api/v1/tracks/{id}/observe",
        "Stop observing the track; the gimbals hold their angles",
        Body::None,
        &[(200, Json("Released"))],
        &[503],
    ),
    op(
        "GET",
        "/api/v1/sim/truth",
        "The embedded simulator's ground truth (vehicles and intruders), for evaluation only",
        Body::None,
        &[(200, Answer::AnyJson)],
        &[404, 503],
    ),
    op(
        "GET",
        "/api/v1/recording",
        "The running recording, or null",
        Body::None,
        &[(200, Json("RecordingStatus"))],
        &[503],
    ),
    op(
        "POST",
        "/api/v1/recording/start",
        "Start recording to MCAP in the recordings directory",
        Body::OptionalJson("RecordingStartRequest"),
        &[(201, Json("RecordingFile"))],
        &[400, 409, 500, 503],
    ),
    op(
        "POST",
        "/api/v1/recording/stop",
        "Stop the recording and finish its file",
        Body::None,
        &[(200, Json("RecordingDone"))],
        &[409, 500, 503],
    ),
    op(
        "GET",
        "/api/v1/stream",
        "WebSocket of vehicle states (10 Hz) and events",
        Body::None,
        &[(101, Answer::WebSocket)],
        &[],
    ),
];

/// The route of [`crate::auth::ROUTES`] (and of the router) that serves `path`: the leader
/// commands and plugin operations are one route each with a path parameter.
pub fn route_of(path: &str) -> &str {
    if path.starts_with("/api/v1/formation/leader/") {
        "/api/v1/formation/leader/{command}"
    } else if path.starts_with("/api/v1/plugins/") {
        "/api/v1/plugins/{op}"
    } else {
        path
    }
}
