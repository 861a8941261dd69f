//! The API contract: an OpenAPI 3.1 document generated from the request and response
//! types, served at `GET /api/v1/openapi.json`.
//!
//! Schemas come from the types themselves (`utoipa::ToSchema` on the request types of
//! [`crate::requests`], on [`crate::responses`] and on the swarm's view types); the
//! operations from [`OPERATIONS`], one row per method and path, whose access is read
//! from [`auth::ROUTES`] (a test checks that both tables name the same routes, and that
//! `docs/api.md` lists every operation). Every operation but the public ones needs a
//! bearer token (security scheme `bearer`) once tokens are configured.

mod operations;

pub use operations::{Answer, Body, OPERATIONS, Operation, route_of};

use crate::auth::{self, Access};
use crate::requests::{
    commands::CommandRequest,
    faults::FaultRequest,
    formation::{FormationRequest, OffsetRequest},
    leader::{
        LeaderGoToRequest, LeaderHoldRequest, LeaderOrbitRequest, LeaderWaypointsRequest,
        PointRequest,
    },
    payloads::AttachRequest,
    plugins::{LoadRequest, ReloadRequest, UnloadRequest},
    px4_param_write::ParamValueRequest,
};
use crate::responses::{
    Cleared, Detached, ErrorBody, FaultInjected, ParamEntry, ParamValue, PayloadView,
    PluginsListing, Reloaded, ShapeInfo,
};
use std::sync::OnceLock;
use utoipa::OpenApi;
use utoipa::openapi::path::{HttpMethod, OperationBuilder, ParameterBuilder, ParameterIn};
use utoipa::openapi::request_body::RequestBodyBuilder;
use utoipa::openapi::schema::{ArrayBuilder, ObjectBuilder, Schema, Type};
use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityRequirement, SecurityScheme};
use utoipa::openapi::{Content, RefOr, Required, ResponseBuilder};

/// The schemas of the contract (utoipa collects the types they refer to).
#[derive(OpenApi)]
#[openapi(
    info(
        title = "skein",
        description = "The HTTP API of skein, a PX4 swarm orchestrator. Errors are JSON \
                       `{\"error\", \"field\"}` with a 4xx status; `field` names the \
                       request field at fault by its path. See docs/api.md."
    ),
    components(schemas(
        ErrorBody,
        skein_swarm::election::ElectionStatus,
        crate::requests::tracks::ObserveRequest,
        crate::requests::recording::RecordingStartRequest,
        crate::tracks::TracksListing,
        crate::tracks::Observing,
        crate::tracks::Released,
        crate::recording::RecordingStatus,
        crate::recording::RecordingFile,
        crate::recording::RecordingDone,
        CommandRequest,
        FormationRequest,
        OffsetRequest,
        PointRequest,
        LeaderGoToRequest,
        LeaderWaypointsRequest,
        LeaderOrbitRequest,
        LeaderHoldRequest,
        ParamValueRequest,
        AttachRequest,
        LoadRequest,
        UnloadRequest,
        ReloadRequest,
        FaultRequest,
        Cleared,
        FaultInjected,
        ShapeInfo,
        ParamEntry,
        ParamValue,
        PluginsListing,
        PayloadView,
        Detached,
        Reloaded,
        skein_plugin_host::LibraryInfo,
        auth::Identity,
        skein_model::vehicle::VehicleSnapshot,
        skein_model::safety::Geofence,
        skein_swarm::coordinator::messages::Health,
        skein_swarm::CommandOutcome,
        skein_swarm::FormationStatus,
        skein_swarm::coordinator::messages::EndpointStats,
        skein_swarm::supervision::TreeNode,
    ))
)]
struct Schemas;

fn method(m: &str) -> HttpMethod {
    match m {
        "GET" => HttpMethod::Get,
        "PUT" => HttpMethod::Put,
        "POST" => HttpMethod::Post,
        "DELETE" => HttpMethod::Delete,
        other => unreachable!("method {other} in OPERATIONS"),
    }
}

fn schema_ref(name: &str) -> RefOr<Schema> {
    RefOr::Ref(utoipa::openapi::Ref::from_schema_name(name))
}

fn object() -> Schema {
    Schema::Object(ObjectBuilder::new().schema_type(Type::Object).build())
}

fn json(schema: impl Into<RefOr<Schema>>) -> Content {
    Content::new(Some(schema))
}

fn status_text(status: u16) -> &'static str {
    match status {
        101 => "Switching to the WebSocket",
        200 => "OK",
        201 => "Created",
        202 => "Accepted: the outcome follows on the stream",
        400 => "Invalid request: `field` names the field at fault by its path",
        401 => "No or invalid token (`field`: authorization)",
        403 => {
            "Forbidden: the token's role is too low (`required_role`), or the operation is refused"
        }
        404 => "No such vehicle, slot, plugin, target or parameter",
        409 => {
            "The swarm's or the vehicle's state forbids it, or this coordinator is a standby \
             (the error says why, naming the active coordinator)"
        }
        422 => "Not a loadable plugin (the error names the file and what differs)",
        429 => "Too many failed token attempts from this address (Retry-After)",
        503 => "The coordinator, the vehicle's link or the payload is not available",
        _ => "",
    }
}

/// The description and an example of a path parameter (the examples name what a
/// `skein up --sim 3` has: uav-2 is an observation vehicle with a gimbal).
fn parameter_description(name: &str) -> (&'static str, &'static str) {
    match name {
        "id" => ("Vehicle id (`uav-1`)", "uav-2"),
        "name" => (
            "PX4 parameter name, 1 to 16 ASCII characters (`MPC_XY_VEL_MAX`)",
            "MPC_XY_VEL_MAX",
        ),
        "slot" => ("Payload slot (`camera`)", "gimbal"),
        _ => ("", ""),
    }
}

fn operation(o: &Operation) -> utoipa::openapi::path::Operation {
    let http_method = axum::http::Method::from_bytes(o.method.as_bytes()).expect("a method");
    let access = auth::required(&http_method, route_of(o.path));
    let role = match access {
        Access::Public => "none (public)".to_string(),
        Access::Role(r) => r.as_str().to_string(),
    };
    let mut b = OperationBuilder::new()
        .summary(Some(o.summary))
        .description(Some(format!("Role: {role}.")))
        .operation_id(Some(format!(
            "{}{}",
            o.method.to_lowercase(),
            o.path.replace(['/', '.', '-'], "_").replace(['{', '}'], "")
        )));
    for name in o
        .path
        .split('/')
        .filter_map(|s| s.strip_prefix('{').and_then(|s| s.strip_suffix('}')))
    {
        let (description, example) = parameter_description(name);
        let mut schema = ObjectBuilder::new()
            .schema_type(Type::String)
            .min_length(Some(1))
            .examples([example]);
        if name == "name" {
            schema = schema.max_length(Some(16));
        }
        b = b.parameter(
            ParameterBuilder::new()
                .name(name)
                .parameter_in(ParameterIn::Path)
                .required(Required::True)
                .description(Some(description))
                .schema(Some(schema)),
        );
    }
    let body = match o.body {
        Body::None => None,
        Body::Json(s) => Some((schema_ref(s), Required::True)),
        Body::OptionalJson(s) => Some((schema_ref(s), Required::False)),
        Body::JsonObject => Some((object().into(), Required::True)),
    };
    if let Some((schema, required)) = body {
        b = b.request_body(Some(
            RequestBodyBuilder::new()
                .content("application/json", json(schema))
                .required(Some(required))
                .build(),
        ));
    }
    for (status, answer) in o.ok {
        let r = ResponseBuilder::new().description(status_text(*status));
        let r = match answer {
            Answer::Json(s) => r.content("application/json", json(schema_ref(s))),
            Answer::JsonArray(s) => r.content(
                "application/json",
                json(ArrayBuilder::new().items(schema_ref(s)).build()),
            ),
            Answer::AnyJson => r.content(
                "application/json",
                json(Schema::Object(ObjectBuilder::new().build())),
            ),
            Answer::Text(mime) => r.content(
                *mime,
                json(ObjectBuilder::new().schema_type(Type::String).build()),
            ),
            Answer::Binary(mime) => r.content(
                *mime,
                json(
                    ObjectBuilder::new()
                        .schema_type(Type::String)
                        .content_media_type(*mime)
                        .build(),
                ),
            ),
            Answer::WebSocket => r,
        };
        b = b.response(status.to_string(), r.build());
    }
    let mut errors: Vec<u16> = o.errors.to_vec();
    if o.method != "GET" {
        // A standby coordinator refuses every write (skein_api::election).
        errors.push(409);
    }
    if access != Access::Public {
        errors.extend([401, 403, 429]);
        b = b.security(SecurityRequirement::new("bearer", Vec::<String>::new()));
    } else {
        b = b.security(SecurityRequirement::default());
    }
    errors.sort_unstable();
    errors.dedup();
    for status in errors {
        b = b.response(
            status.to_string(),
            ResponseBuilder::new()
                .description(status_text(status))
                .content("application/json", json(schema_ref("ErrorBody")))
                .build(),
        );
    }
    b.build()
}

fn build() -> utoipa::openapi::OpenApi {
    let mut doc = Schemas::openapi();
    doc.info.version = env!("CARGO_PKG_VERSION").to_string();
    doc.info.license = None;
    for o in OPERATIONS {
        doc.paths
            .add_path_operation(o.path, vec![method(o.method)], operation(o));
    }
    let components = doc.components.get_or_insert_with(Default::default);
    components.add_security_scheme(
        "bearer",
        SecurityScheme::Http(
            HttpBuilder::new()
                .scheme(HttpAuthScheme::Bearer)
                .description(Some(
                    "A token of `skein token create`; GET requests may give it as the \
                     `token` query parameter instead",
                ))
                .build(),
        ),
    );
    crate::responses::add_schemas(components);
    doc
}

/// The contract as JSON (built once).
pub fn document() -> &'static str {
    static DOC: OnceLock<String> = OnceLock::new();
    DOC.get_or_init(|| build().to_json().expect("the OpenAPI document serialises"))
}

/// `GET /api/v1/openapi.json`.
pub async fn serve() -> axum::response::Response {
    use axum::response::IntoResponse;
    (
        [(axum::http::header::CONTENT_TYPE, "application/json")],
        document(),
    )
        .into_response()
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::Value;

    fn spec() -> Value {
        serde_json::from_str(document()).unwrap()
    }

    #[test]
    fn the_document_is_openapi_3_1_with_every_operation() {
        let v = spec();
        assert!(
            v["openapi"].as_str().unwrap().starts_with("3.1"),
            "{}",
            v["openapi"]
        );
        for o in OPERATIONS {
            let op = &v["paths"][o.path][o.method.to_lowercase()];
            assert!(op.is_object(), "{} {} missing", o.method, o.path);
            for (status, _) in o.ok {
                assert!(op["responses"][status.to_string()].is_object());
            }
        }
        // Every schema referred to exists.
        let text = document();
        for part in text.split("\"$ref\":\"#/components/schemas/").skip(1) {
            let name = part.split('"').next().unwrap();
            assert!(
                v["components"]["schemas"][name].is_object(),
                "schema {name} referred to but missing"
            );
        }
        assert_eq!(
            v["components"]["securitySchemes"]["bearer"]["scheme"],
            "bearer"
        );
        assert_eq!(
            v["paths"]["/api/v1/vehicles/{id}/commands"]["post"]["responses"]["401"]["content"]["application/json"]
                ["schema"]["$ref"],
            "#/components/schemas/ErrorBody"
        );
    }

    #[test]
    fn operations_and_the_auth_table_name_the_same_routes() {
        for o in OPERATIONS {
            let route = route_of(o.path);
            assert!(
                auth::ROUTES
                    .iter()
                    .any(|(m, p, _)| *m == o.method && *p == route),
                "{} {} is not in auth::ROUTES",
                o.method,
                o.path
            );
        }
        for (m, p, _) in auth::ROUTES {
            assert!(
                OPERATIONS
                    .iter()
                    .any(|o| o.method == *m && route_of(o.path) == *p),
                "{m} {p} of auth::ROUTES is not in the contract"
            );
        }
    }

    /// The method + path pairs of the first table of docs/api.md.
    fn documented() -> Vec<(String, String)> {
        let text =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/api.md"))
                .unwrap();
        let mut rows = Vec::new();
        let table = text
            .lines()
            .skip_while(|l| !l.starts_with("| method | path |"))
            .skip(2)
            .take_while(|l| l.starts_with('|'));
        for line in table {
            let cells: Vec<&str> = line.split('|').map(str::trim).collect();
            let path = cells[2].trim_matches('`');
            for m in cells[1].split('/').map(str::trim) {
                rows.push((m.to_string(), path.to_string()));
            }
        }
        rows
    }

    #[test]
    fn docs_api_md_lists_every_operation_and_nothing_else() {
        let docs = documented();
        assert!(docs.len() > 20, "{docs:?}");
        let spec = spec();
        for (m, p) in &docs {
            assert!(
                spec["paths"][p.as_str()][m.to_lowercase()].is_object(),
                "docs/api.md lists {m} {p}, which the contract has not"
            );
        }
        let paths = spec["paths"].as_object().unwrap();
        for (p, item) in paths {
            for m in item.as_object().unwrap().keys() {
                let m = m.to_uppercase();
                assert!(
                    docs.iter().any(|(dm, dp)| *dm == m && dp == p),
                    "the contract has {m} {p}, which docs/api.md does not list"
                );
            }
        }
    }
}
