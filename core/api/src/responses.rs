//! Response bodies the handlers build themselves (the others are the swarm's view types:
//! [`skein_model::vehicle::VehicleSnapshot`], [`skein_swarm::FormationStatus`] …), typed
//! for the OpenAPI contract ([`crate::openapi`]).

use serde::Serialize;
use utoipa::openapi::RefOr;
use utoipa::openapi::schema::{KnownFormat, ObjectBuilder, Schema, SchemaFormat, Type};
use utoipa::{PartialSchema, ToSchema};

/// A binary answer (a JPEG frame, the MJPEG stream): bytes of the answer's media type, not
/// JSON (the contract's schema only).
pub struct Binary;

impl PartialSchema for Binary {
    fn schema() -> RefOr<Schema> {
        ObjectBuilder::new()
            .schema_type(Type::String)
            .format(Some(SchemaFormat::KnownFormat(KnownFormat::Binary)))
            .into()
    }
}

impl ToSchema for Binary {}

/// Every 4xx / 5xx answer.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct ErrorBody {
    /// What went wrong, for a human.
    pub error: String,
    /// The request field at fault (a path such as `offsets[2].right_m`), when there is
    /// one; `authorization` for 401 / 403 / 429.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub field: Option<String>,
    /// The role a 403 needed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub required_role: Option<String>,
}

/// `clear_hazard` done.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct Cleared {
    /// The vehicle no longer planned around.
    pub cleared: String,
}

/// A fault injected (`POST /api/v1/faults`, 202).
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct FaultInjected {
    /// The actor's path.
    pub target: String,
    /// The fault.
    pub kind: skein_model::supervision::FaultKind,
}

/// One entry of `GET /api/v1/formation/shapes`.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct ShapeInfo {
    /// The shape.
    pub shape: skein_model::formation::Shape,
    /// The fewest vehicles it needs.
    pub min_vehicles: usize,
}

/// A PX4 parameter as read or written.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct ParamValue {
    /// Parameter name.
    pub name: String,
    /// Its value (an integer for `int32`).
    #[schema(value_type = f64)]
    pub value: serde_json::Number,
    /// `int32` or `real32` (MAV_PARAM_TYPE).
    #[serde(rename = "type")]
    #[schema(pattern = "^(int32|real32)$")]
    pub param_type: &'static str,
}

/// A PX4 parameter of the listing (`GET …/params`).
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct ParamEntry {
    /// Parameter name.
    pub name: String,
    /// Its value.
    pub value: f64,
}

/// A payload provider: a plugin library or the built-in one.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct ProviderEntry {
    /// Plugin (or built-in) name.
    pub name: String,
    /// Its version.
    pub version: String,
    /// Payload kinds it provides.
    pub kinds: Vec<String>,
    /// `plugin` or `builtin`.
    pub source: &'static str,
}

/// A file the plugin host refused.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct RefusedFile {
    /// The file.
    #[schema(value_type = String)]
    pub file: std::path::PathBuf,
    /// Why (for an ABI mismatch: what differs).
    pub reason: String,
}

/// `GET /api/v1/plugins`.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct PluginsListing {
    /// The plugin directory; null without a plugin host.
    #[schema(value_type = Option<String>)]
    pub plugin_dir: Option<std::path::PathBuf>,
    /// Loaded libraries; each instance also has a `status`: `running`, or `stale` while
    /// it runs a replaced generation.
    #[schema(value_type = Vec<skein_plugin_host::LibraryInfo>)]
    pub libraries: Vec<serde_json::Value>,
    /// Every payload provider the vehicles use.
    pub providers: Vec<ProviderEntry>,
    /// Files refused, with the reason.
    pub refused: Vec<RefusedFile>,
}

/// One payload slot as a vehicle lists it (`GET …/payloads`, the vehicle's `payloads`).
/// The body is built by `skein_swarm`'s vehicle (`payload_json`); this type documents it
/// for the contract, which the contract test checks against a live swarm.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct PayloadView {
    /// Slot name.
    pub slot: String,
    /// Payload kind.
    pub kind: String,
    /// The plugin the slot asks for, if any.
    pub requested_plugin: Option<String>,
    /// The library serving it now; null while none does.
    pub plugin: Option<String>,
    /// Its version.
    pub plugin_version: Option<String>,
    /// Its build generation (0: built-in).
    pub generation: Option<u64>,
    /// `in_process` or `process`.
    pub isolation: skein_payload::Isolation,
    /// Supervision status (`running`, `restarting`, `failed`, `stopped`,
    /// `waiting_for_plugin`); null before the first report.
    pub status: Option<skein_model::supervision::ChildStatus>,
    /// The kind it waits for a provider of, while it waits.
    pub waiting_for: Option<String>,
    /// The payload's own published state; null while no driver runs.
    #[schema(value_type = Option<Object>)]
    pub state: serde_json::Value,
    /// Frames published so far.
    pub frames: u64,
}

/// Adds what the derives cannot say to the contract's schemas.
///
/// `FormationStatus` flattens an `Option<FormationSpec>` (`#[serde(flatten)]`): the
/// spec's fields are there while a formation is set and absent otherwise, which the
/// derived `allOf` (requiring them) does not allow. They become optional properties.
pub fn add_schemas(components: &mut utoipa::openapi::Components) {
    use utoipa::openapi::RefOr;
    use utoipa::openapi::schema::Schema;
    let Some(RefOr::T(Schema::Object(spec))) = components.schemas.get("FormationSpec").cloned()
    else {
        return;
    };
    let mut optional = spec;
    optional.required.clear();
    let flattened = "#/components/schemas/FormationSpec";
    let is_flattened = |item: &RefOr<Schema>| match item {
        RefOr::Ref(r) => r.ref_location == flattened,
        RefOr::T(Schema::OneOf(one)) => one
            .items
            .iter()
            .any(|i| matches!(i, RefOr::Ref(r) if r.ref_location == flattened)),
        RefOr::T(_) => false,
    };
    if let Some(RefOr::T(Schema::AllOf(all))) = components.schemas.get_mut("FormationStatus") {
        for item in all.items.iter_mut().filter(|i| is_flattened(i)) {
            *item = RefOr::T(Schema::Object(optional.clone()));
        }
    }
}

/// A payload detached (`DELETE …/payloads/{slot}`). Built by `skein_swarm`'s vehicle;
/// documented here for the contract.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct Detached {
    /// The slot that is gone.
    pub detached: String,
    /// Its payload kind.
    pub kind: Option<String>,
}

/// `POST /api/v1/plugins/reload`.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct Reloaded {
    /// The library, on its new build (instances as in the listing).
    #[schema(value_type = skein_plugin_host::LibraryInfo)]
    pub library: serde_json::Value,
    /// The replaced version.
    pub previous_version: String,
    /// The replaced generation.
    pub previous_generation: u64,
    /// Instances still running the replaced generation (the vehicles re-create them).
    pub stale_instances: Vec<skein_plugin_host::InstanceRecord>,
}
