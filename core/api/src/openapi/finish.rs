//! What every operation of the contract shares, added once to each: its role
//! (`x-skein-role`, the `bearer` security requirement or none, and a "Role: …" line), an
//! operation id from its method and path, a description of each of its statuses, the
//! `ErrorBody` of its 4xx / 5xx answers, and the statuses the gates add: 401 / 403 / 429
//! where a token is needed, 409 for a write (a standby coordinator refuses them). A body
//! the handler declares as `Option<T>` (read with [`crate::requests::parse_or_empty`]) is
//! a `T` that may be left out, not a JSON `null`.

use crate::roles::Access;
use utoipa::openapi::path::Operation;
use utoipa::openapi::schema::{Schema, SchemaType, Type};
use utoipa::openapi::security::SecurityRequirement;
use utoipa::openapi::{Content, Ref, RefOr, Required, Response};

/// The extension naming an operation's role.
pub const ROLE_EXTENSION: &str = "x-skein-role";

/// What a status means in this API (the description of a response that has none).
pub fn status_text(status: &str) -> &'static str {
    match status {
        "101" => "Switching to the WebSocket",
        "200" => "OK",
        "201" => "Created",
        "202" => "Accepted: the outcome follows on the stream",
        "400" => "Invalid request: `field` names the field at fault by its path",
        "401" => "No or invalid token (`field`: authorization)",
        "403" => {
            "Forbidden: the token's role is too low (`required_role`), or the operation is refused"
        }
        "404" => "No such vehicle, slot, plugin, track, target or parameter",
        "409" => {
            "The swarm's or the vehicle's state forbids it, or this coordinator is a standby \
             (the error says why, naming the active coordinator)"
        }
        "422" => "Not a loadable plugin (the error names the file and what differs)",
        "429" => "Too many failed token attempts from this address (Retry-After)",
        "500" => "The recording's file could not be written",
        "502" => "The vehicle sent a value JSON cannot carry",
        "503" => "The coordinator, the vehicle's link or the payload is not available",
        _ => "",
    }
}

fn is_error(status: &str) -> bool {
    status.starts_with('4') || status.starts_with('5')
}

fn error_body() -> Content {
    Content::new(Some(RefOr::<Schema>::Ref(Ref::from_schema_name(
        "ErrorBody",
    ))))
}

/// `oneOf: [null, T]` → `T`.
fn without_null(schema: &mut RefOr<Schema>) -> bool {
    let RefOr::T(Schema::OneOf(one_of)) = schema else {
        return false;
    };
    let is_null = |s: &RefOr<Schema>| matches!(s, RefOr::T(Schema::Object(o)) if o.schema_type == SchemaType::Type(Type::Null));
    if one_of.items.len() != 2 || !one_of.items.iter().any(is_null) {
        return false;
    }
    let Some(t) = one_of.items.iter().find(|s| !is_null(s)).cloned() else {
        return false;
    };
    *schema = t;
    true
}

/// An optional body is one that may be left out: its schema without `null`, not required.
fn optional_body(op: &mut Operation) {
    let Some(body) = &mut op.request_body else {
        return;
    };
    let mut optional = false;
    for content in body.content.values_mut() {
        if let Some(schema) = &mut content.schema {
            optional |= without_null(schema);
        }
    }
    if optional {
        body.required = Some(Required::False);
    }
}

/// Completes `op`, the operation `method` (upper case) `path` of a router of `access`.
pub fn operation(op: &mut Operation, method: &str, path: &str, access: Access) {
    optional_body(op);
    op.operation_id = Some(format!(
        "{}{}",
        method.to_lowercase(),
        path.replace(['/', '.', '-'], "_").replace(['{', '}'], "")
    ));
    let role = match access {
        Access::Public => "none (public)".to_string(),
        Access::Role(r) => r.as_str().to_string(),
    };
    op.description = Some(match op.description.take() {
        Some(d) if !d.is_empty() => format!("{d}\n\nRole: {role}."),
        _ => format!("Role: {role}."),
    });
    op.extensions
        .get_or_insert_with(Default::default)
        .insert(ROLE_EXTENSION.to_string(), access.as_str().into());
    let mut added: Vec<&str> = Vec::new();
    if method != "GET" {
        // A standby coordinator refuses every write (crate::election).
        added.push("409");
    }
    match access {
        Access::Public => op.security = Some(vec![SecurityRequirement::default()]),
        Access::Role(_) => {
            added.extend(["401", "403", "429"]);
            op.security = Some(vec![SecurityRequirement::new(
                "bearer",
                Vec::<String>::new(),
            )]);
        }
    }
    for status in added {
        op.responses
            .responses
            .entry(status.to_string())
            .or_insert_with(|| RefOr::T(Response::new("")));
    }
    for (status, response) in &mut op.responses.responses {
        let RefOr::T(response) = response else {
            continue;
        };
        if response.description.is_empty() {
            response.description = status_text(status).to_string();
        }
        if is_error(status) && response.content.is_empty() {
            response
                .content
                .insert("application/json".to_string(), error_body());
        }
    }
}
