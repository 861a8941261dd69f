//! skein's geofence as PX4 holds it: the mission items of `MAV_MISSION_TYPE_FENCE` and
//! `MAV_MISSION_TYPE_RALLY` (the items QGroundControl uploads), the breach action
//! (`GF_ACTION`) and the ceiling (`GF_MAX_VER_DIST`), built once per fence version from
//! the swarm-frame fence and the swarm origin, and the comparison of what a vehicle
//! returns with what was sent.
//!
//! Items (mavlink.io, "Mission Protocol: geofence and rally"):
//! - the inclusion area: the polygon if there is one (each vertex a
//!   `MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION`, param1 = the vertex count), otherwise
//!   the circle (`MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION` at the swarm origin, param1 = the
//!   radius). skein's polygon lies inside its circle (`Geofence::validate`), and PX4 keeps
//!   a vehicle inside *any* inclusion area, so one area is exactly skein's fence;
//! - each exclusion area, `..._POLYGON_VERTEX_EXCLUSION` or `..._CIRCLE_EXCLUSION`;
//! - `MAV_FRAME_GLOBAL`, latitude and longitude in degE7, altitude 0 (PX4 ignores it
//!   for fence items and takes the ceiling from `GF_MAX_VER_DIST`);
//! - rally points as `MAV_CMD_NAV_RALLY_POINT`, altitude above mean sea level.

use crate::mission::MissionItem;
use skein_mavlink::dialect::{MavCmd, MavFrame};
use skein_model::geo::{GeoPoint, Ned, NedFrame};
use skein_model::geofence::{FenceArea, Geofence};

/// What one fence version asks of every autopilot.
#[derive(Debug, Clone, PartialEq)]
pub struct FencePlan {
    /// skein's fence version (1 = the configured fence).
    pub version: u64,
    /// The `MAV_MISSION_TYPE_FENCE` items.
    pub fence: Vec<MissionItem>,
    /// The `MAV_MISSION_TYPE_RALLY` items.
    pub rally: Vec<MissionItem>,
    /// `GF_ACTION`.
    pub gf_action: i32,
    /// The fence's ceiling above mean sea level, metres: `GF_MAX_VER_DIST` is this less
    /// the vehicle's home altitude.
    pub ceiling_amsl_m: f64,
}

fn global_item(command: MavCmd, param1: f32, at: GeoPoint, z: f32) -> MissionItem {
    let (x, y, _) = at.to_mavlink();
    MissionItem {
        command,
        frame: MavFrame::MAV_FRAME_GLOBAL,
        params: [param1, 0.0, 0.0, 0.0],
        x,
        y,
        z,
    }
}

fn polygon_items(out: &mut Vec<MissionItem>, command: MavCmd, v: &[[f64; 2]], frame: &NedFrame) {
    for [n, e] in v {
        let at = frame.to_geo(Ned::new(*n, *e, 0.0));
        out.push(global_item(command, v.len() as f32, at, 0.0));
    }
}

impl FencePlan {
    /// The plan of `fence` (swarm frame) about the swarm `frame`'s origin.
    pub fn new(fence: &Geofence, frame: &NedFrame, version: u64) -> Self {
        let mut items = Vec::new();
        if fence.polygon.len() >= 3 {
            polygon_items(
                &mut items,
                MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                &fence.polygon,
                frame,
            );
        } else {
            items.push(global_item(
                MavCmd::MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION,
                fence.radius_m as f32,
                frame.origin,
                0.0,
            ));
        }
        for area in &fence.exclusions {
            match area {
                FenceArea::Polygon(v) => polygon_items(
                    &mut items,
                    MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
                    v,
                    frame,
                ),
                FenceArea::Circle {
                    north_m,
                    east_m,
                    radius_m,
                } => items.push(global_item(
                    MavCmd::MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION,
                    *radius_m as f32,
                    frame.to_geo(Ned::new(*north_m, *east_m, 0.0)),
                    0.0,
                )),
            }
        }
        let rally = fence
            .rally_points
            .iter()
            .map(|r| {
                let at = frame.to_geo(Ned::new(r.north_m, r.east_m, 0.0));
                let alt = frame.origin.alt_amsl_m + r.altitude_m;
                global_item(MavCmd::MAV_CMD_NAV_RALLY_POINT, 0.0, at, alt as f32)
            })
            .collect();
        FencePlan {
            version,
            fence: items,
            rally,
            gf_action: fence.breach_action.gf_action(),
            ceiling_amsl_m: frame.origin.alt_amsl_m + fence.max_altitude_m,
        }
    }
}

/// How `held` (what the vehicle returned) differs from `sent`, or `None` when they are
/// the same plan: same commands in the same order, positions within 1 degE7 (PX4 keeps
/// them as doubles and truncates on the way back), param1 (vertex count, radius) and
/// altitude within a millimetre.
pub fn difference(sent: &[MissionItem], held: &[MissionItem]) -> Option<String> {
    if sent.len() != held.len() {
        return Some(format!(
            "{} items sent, the vehicle holds {}",
            sent.len(),
            held.len()
        ));
    }
    for (i, (s, h)) in sent.iter().zip(held).enumerate() {
        let same = s.command == h.command
            && (s.x - h.x).abs() <= 1
            && (s.y - h.y).abs() <= 1
            && (s.params[0] - h.params[0]).abs() <= 1e-3
            && (s.z - h.z).abs() <= 1e-3;
        if !same {
            return Some(format!(
                "item {i}: sent {:?} at ({}, {}) param1 {}, the vehicle holds {:?} at ({}, {}) param1 {}",
                s.command, s.x, s.y, s.params[0], h.command, h.x, h.y, h.params[0]
            ));
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use skein_model::geofence::{BreachAction, RallyPoint};

    const ORIGIN: GeoPoint = GeoPoint::new(47.397_742, 8.545_594, 488.0);

    #[test]
    fn a_polygon_fence_uploads_its_vertices_exclusions_and_rally_points() {
        let fence = Geofence {
            polygon: vec![[-50.0, -50.0], [50.0, -50.0], [50.0, 50.0], [-50.0, 50.0]],
            exclusions: vec![FenceArea::Circle {
                north_m: 10.0,
                east_m: 0.0,
                radius_m: 5.0,
            }],
            rally_points: vec![RallyPoint {
                north_m: 0.0,
                east_m: 20.0,
                altitude_m: 15.0,
            }],
            breach_action: BreachAction::Rtl,
            ..Geofence::default()
        };
        let frame = NedFrame::new(ORIGIN);
        let plan = FencePlan::new(&fence, &frame, 7);
        assert_eq!(plan.fence.len(), 5);
        assert!(plan.fence[..4].iter().all(|i| i.command
            == MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
            && i.params[0] == 4.0));
        // Vertex 0 is 50 m south and west of the origin.
        let v0 = GeoPoint::from_mavlink(plan.fence[0].x, plan.fence[0].y, 0);
        let back = frame.to_ned(&GeoPoint::new(v0.lat_deg, v0.lon_deg, ORIGIN.alt_amsl_m));
        assert!(
            (back.north_m + 50.0).abs() < 0.02 && (back.east_m + 50.0).abs() < 0.02,
            "{back:?}"
        );
        assert_eq!(
            plan.fence[4].command,
            MavCmd::MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
        );
        assert_eq!(plan.fence[4].params[0], 5.0);
        assert_eq!(plan.rally.len(), 1);
        assert_eq!(plan.rally[0].z, 503.0);
        assert_eq!((plan.gf_action, plan.ceiling_amsl_m), (3, 608.0));
        assert_eq!(difference(&plan.fence, &plan.fence), None);
        let mut off = plan.fence.clone();
        off[2].x += 1;
        assert_eq!(difference(&plan.fence, &off), None, "PX4's truncation");
        off[2].x += 10;
        assert!(difference(&plan.fence, &off).unwrap().starts_with("item 2"));
        assert!(difference(&plan.fence, &off[..3]).is_some());
    }

    #[test]
    fn without_a_polygon_the_circle_is_the_inclusion_area() {
        let plan = FencePlan::new(&Geofence::default(), &NedFrame::new(ORIGIN), 1);
        assert_eq!(plan.fence.len(), 1);
        let c = plan.fence[0];
        assert_eq!(c.command, MavCmd::MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION);
        assert_eq!(c.params[0], 500.0);
        assert_eq!((c.x, c.y), (473_977_420, 85_455_940));
        assert_eq!(plan.gf_action, 2, "hold, PX4's default");
    }
}
