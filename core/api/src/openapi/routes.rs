//! Every route of the API, declared once. Each handler states its path, method and
//! OpenAPI operation with `#[utoipa::path(...)]` next to its code; here it is registered
//! in the router of the role it needs. The axum router ([`crate::app`]: one
//! authentication `route_layer` per role), the role table ([`crate::openapi::route_access`]) and
//! the served contract ([`crate::openapi`], with each operation's role) are all built
//! from `by_role`, so they cannot disagree.
//!
//! Adding a route touches the handler (with its `#[utoipa::path]`), one line here in its
//! role's router, and its row in `docs/api.md` (a test holds the doc to the contract).

use crate::roles::{Access, Role};
use crate::{
    ApiState, auth, election, fault_injection, flight_logs, formation_control, geofence, map,
    missions, openapi, payloads, plugins, preflight, px4_params, recording, rehearsals, rtk,
    stream, swarm_status, swarms, tracks, vehicles, video,
};
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

/// The routes of each role: who may call them, and the handlers with their operations.
pub(crate) fn by_role() -> [(Access, OpenApiRouter<ApiState>); 4] {
    [
        (Access::Public, public()),
        (Access::Role(Role::Viewer), viewer()),
        (Access::Role(Role::Operator), operator()),
        (Access::Role(Role::Admin), admin()),
    ]
}

/// Anyone, without a token: health, and the contract (it holds no swarm data).
fn public() -> OpenApiRouter<ApiState> {
    OpenApiRouter::default()
        .routes(routes!(swarm_status::health))
        .routes(routes!(openapi::serve))
}

/// Reads (every GET) and the WebSocket stream.
fn viewer() -> OpenApiRouter<ApiState> {
    OpenApiRouter::default()
        .routes(routes!(auth::whoami))
        .routes(routes!(vehicles::list_vehicles))
        .routes(routes!(vehicles::get_vehicle))
        .routes(routes!(preflight::fleet_preflight))
        .routes(routes!(rtk::status))
        .routes(routes!(missions::list))
        .routes(routes!(missions::get))
        .routes(routes!(rehearsals::rehearsal))
        .routes(routes!(flight_logs::list_logs))
        .routes(routes!(flight_logs::log_file))
        .routes(routes!(flight_logs::downloads))
        .routes(routes!(px4_params::list_params))
        .routes(routes!(px4_params::get_param))
        .routes(routes!(formation_control::get_formation))
        .routes(routes!(formation_control::shapes))
        .routes(routes!(payloads::list_payloads))
        .routes(routes!(video::payload_snapshot))
        .routes(routes!(video::payload_stream))
        .routes(routes!(plugins::listing))
        .routes(routes!(swarm_status::supervision_tree))
        .routes(routes!(swarm_status::metrics))
        .routes(routes!(swarm_status::links))
        .routes(routes!(geofence::get_geofence))
        .routes(routes!(map::map_info))
        .routes(routes!(map::map_tile))
        .routes(routes!(election::status))
        .routes(routes!(tracks::list_tracks))
        .routes(routes!(swarms::list_swarms))
        .routes(routes!(tracks::sim_truth))
        .routes(routes!(recording::status))
        .routes(routes!(stream::stream))
}

/// Flying: commands, the formation and its leader, payloads, tracks, recordings, the
/// geofence, RTK corrections, missions.
fn operator() -> OpenApiRouter<ApiState> {
    OpenApiRouter::default()
        .routes(routes!(vehicles::vehicle_command))
        .routes(routes!(vehicles::swarm_command))
        .routes(routes!(flight_logs::download_log))
        .routes(routes!(flight_logs::fetch_latest))
        .routes(routes!(rtk::put, rtk::delete))
        .routes(routes!(missions::create))
        .routes(routes!(missions::control))
        .routes(routes!(rehearsals::rehearse))
        .routes(routes!(formation_control::put_formation))
        .routes(routes!(formation_control::delete_formation))
        .routes(routes!(formation_control::leader_goto))
        .routes(routes!(formation_control::leader_waypoints))
        .routes(routes!(formation_control::leader_orbit))
        .routes(routes!(formation_control::leader_hold))
        .routes(routes!(payloads::attach_payload))
        .routes(routes!(payloads::payload_command))
        .routes(routes!(payloads::detach_payload))
        .routes(routes!(tracks::observe))
        .routes(routes!(tracks::stop_observing))
        .routes(routes!(swarms::observe_swarm))
        .routes(routes!(swarms::stop_observing_swarm))
        .routes(routes!(recording::start))
        .routes(routes!(recording::stop))
        .routes(routes!(geofence::put_geofence))
}

/// Everything else: PX4 parameter writes, plugin libraries, fault injection.
fn admin() -> OpenApiRouter<ApiState> {
    OpenApiRouter::default()
        .routes(routes!(px4_params::put_param))
        .routes(routes!(plugins::load))
        .routes(routes!(plugins::unload))
        .routes(routes!(plugins::reload))
        .routes(routes!(fault_injection::inject_fault))
}
