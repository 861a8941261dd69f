//! The API contract: an OpenAPI 3.1 document served at `GET /api/v1/openapi.json`, built
//! from the same declarations as the router ([`routes`]): each handler's
//! `#[utoipa::path]` (path, method, parameters, body, answers), the `ToSchema` types it
//! names (collected with everything they refer to), and the role of the router it is
//! registered in. What every operation shares is added once, in [`finish`].
//!
//! Beyond the schemas, an operation may name the body fields the coordinator checks
//! against the running swarm (its vehicles, geofence, speed limits, loaded plugins), which
//! no static schema can state: `x-skein-swarm-checks`, `{field: what it must be}`. A
//! request valid by the schema may be refused with a 400 (or 422) naming one of those
//! fields, and only those.
//!
//! Every operation but the public ones needs a bearer token (security scheme `bearer`)
//! once tokens are configured.

pub mod finish;
pub mod routes;

use crate::responses::ErrorBody;
use crate::roles::{Access, Role, RouteAccess};
use std::sync::OnceLock;
use utoipa::OpenApi;
use utoipa::openapi::path::{Operation, PathItem};
use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};

/// The extension naming the fields the running swarm checks beyond the schema.
pub const SWARM_CHECKS_EXTENSION: &str = "x-skein-swarm-checks";

/// The document's title, description, and the schemas no operation names itself.
#[derive(OpenApi)]
#[openapi(
    info(
        title = "skein",
        description = "The HTTP API of skein, a PX4 swarm orchestrator. Errors are JSON \
                       `{\"error\", \"field\"}` with a 4xx status; `field` names the \
                       request field at fault by its path. See docs/api.md."
    ),
    components(schemas(ErrorBody))
)]
struct Base;

/// The operations of a path, with their methods (upper case).
fn operations_of(item: &PathItem) -> impl Iterator<Item = (&'static str, &Operation)> {
    [
        ("GET", &item.get),
        ("PUT", &item.put),
        ("POST", &item.post),
        ("DELETE", &item.delete),
        ("PATCH", &item.patch),
        ("HEAD", &item.head),
        ("OPTIONS", &item.options),
        ("TRACE", &item.trace),
    ]
    .into_iter()
    .filter_map(|(m, op)| op.as_ref().map(|op| (m, op)))
}

fn operations_of_mut(item: &mut PathItem) -> impl Iterator<Item = (&'static str, &mut Operation)> {
    [
        ("GET", &mut item.get),
        ("PUT", &mut item.put),
        ("POST", &mut item.post),
        ("DELETE", &mut item.delete),
        ("PATCH", &mut item.patch),
        ("HEAD", &mut item.head),
        ("OPTIONS", &mut item.options),
        ("TRACE", &mut item.trace),
    ]
    .into_iter()
    .filter_map(|(m, op)| op.as_mut().map(|op| (m, op)))
}

/// Every operation of `doc`: method (upper case), path, operation.
pub fn operations(
    doc: &utoipa::openapi::OpenApi,
) -> impl Iterator<Item = (&'static str, &str, &Operation)> {
    doc.paths
        .paths
        .iter()
        .flat_map(|(path, item)| operations_of(item).map(move |(m, op)| (m, path.as_str(), op)))
}

/// The access an operation of the contract states (`x-skein-role`).
pub fn access_of(op: &Operation) -> Option<Access> {
    op.extensions
        .as_ref()?
        .get(finish::ROLE_EXTENSION)?
        .as_str()?
        .parse()
        .ok()
}

fn build() -> utoipa::openapi::OpenApi {
    let mut doc = Base::openapi();
    doc.info.version = env!("CARGO_PKG_VERSION").to_string();
    doc.info.license = None;
    for (access, routes) in routes::by_role() {
        let mut part = routes.into_openapi();
        for (path, item) in &mut part.paths.paths {
            for (method, op) in operations_of_mut(item) {
                finish::operation(op, method, path, access);
            }
        }
        doc.merge(part);
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

/// Every operation of [`crate::app`] with its access (the role table the tests and
/// `docs/api.md` are checked against), read from the contract's
/// `x-skein-role` (an operation without one would need an admin: fail closed).
pub fn route_access() -> &'static [RouteAccess] {
    static TABLE: OnceLock<Vec<RouteAccess>> = OnceLock::new();
    TABLE.get_or_init(|| {
        operations(contract())
            .map(|(method, path, op)| RouteAccess {
                method: method.to_string(),
                path: path.to_string(),
                access: access_of(op).unwrap_or(Access::Role(Role::Admin)),
            })
            .collect()
    })
}

/// The contract (built once).
pub fn contract() -> &'static utoipa::openapi::OpenApi {
    static DOC: OnceLock<utoipa::openapi::OpenApi> = OnceLock::new();
    DOC.get_or_init(build)
}

/// The contract as JSON (built once).
pub fn document() -> &'static str {
    static JSON: OnceLock<String> = OnceLock::new();
    JSON.get_or_init(|| {
        contract()
            .to_json()
            .expect("the OpenAPI document serialises")
    })
}

/// This contract, OpenAPI 3.1 (never needs a token)
#[utoipa::path(get, path = "/api/v1/openapi.json",
    responses((status = 200, body = Object)))]
pub(crate) async fn serve() -> axum::response::Response {
    use axum::response::IntoResponse;
    (
        [(axum::http::header::CONTENT_TYPE, "application/json")],
        document(),
    )
        .into_response()
}

#[cfg(test)]
mod tests;
