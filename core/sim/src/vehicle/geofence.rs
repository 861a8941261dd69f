//! The geofence as PX4 enforces it (`navigator` `Geofence` and the commander's failsafe
//! on a breach): the uploaded fence plan ([`super::mission`]) read into areas of the
//! vehicle's local frame, checked at every step against the estimated position of an
//! armed vehicle in the air, with PX4's rules (`Geofence::isInsidePolygonOrCircle`):
//! inside *any* inclusion area if there is one, outside *every* exclusion area, below
//! `GF_MAX_VER_DIST` above home and within `GF_MAX_HOR_DIST` of it (0 = off). On the
//! step the vehicle crosses out, `GF_ACTION` is taken: 0 nothing, 1 a critical status
//! text, 2 Hold (stop at the braking point), 3 Return, 4 flight termination (disarm),
//! 5 Land. It is taken again only after the vehicle has come back inside.

use super::*;

/// One area of the fence in the vehicle's local frame (north, east metres).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Area {
    Polygon {
        inclusion: bool,
        vertices: Vec<[f64; 2]>,
    },
    Circle {
        inclusion: bool,
        centre: [f64; 2],
        radius_m: f64,
    },
}

/// PNPOLY, as PX4's `insidePolygon`.
fn inside_polygon(v: &[[f64; 2]], p: [f64; 2]) -> bool {
    let mut c = false;
    let mut j = v.len() - 1;
    for i in 0..v.len() {
        if (v[i][1] >= p[1]) != (v[j][1] >= p[1])
            && p[0] <= (v[j][0] - v[i][0]) * (p[1] - v[i][1]) / (v[j][1] - v[i][1]) + v[i][0]
        {
            c = !c;
        }
        j = i;
    }
    c
}

impl Area {
    fn inclusion(&self) -> bool {
        match self {
            Area::Polygon { inclusion, .. } | Area::Circle { inclusion, .. } => *inclusion,
        }
    }

    fn contains(&self, p: [f64; 2]) -> bool {
        match self {
            Area::Polygon { vertices, .. } => inside_polygon(vertices, p),
            Area::Circle {
                centre, radius_m, ..
            } => (p[0] - centre[0]).hypot(p[1] - centre[1]) < *radius_m,
        }
    }
}

impl Vehicle {
    /// Reads the stored fence plan into areas of the local frame (the plan was checked
    /// when it was accepted).
    pub(super) fn load_fence(&mut self) {
        use MavCmd::*;
        let local = |it: &MISSION_ITEM_INT_DATA| {
            let g = GeoPoint::from_mavlink(it.x, it.y, 0);
            let p = self.origin.to_ned(&GeoPoint::new(
                g.lat_deg,
                g.lon_deg,
                self.origin.origin.alt_amsl_m,
            ));
            [p.north_m, p.east_m]
        };
        let items = &self.missions.fence;
        let mut areas = Vec::new();
        let mut i = 0;
        while i < items.len() {
            let it = &items[i];
            match it.command {
                MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION | MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION => {
                    areas.push(Area::Circle {
                        inclusion: it.command == MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION,
                        centre: local(it),
                        radius_m: f64::from(it.param1),
                    });
                    i += 1;
                }
                _ => {
                    let n = (it.param1 as usize).max(1).min(items.len() - i);
                    areas.push(Area::Polygon {
                        inclusion: it.command == MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                        vertices: items[i..i + n].iter().map(local).collect(),
                    });
                    i += n;
                }
            }
        }
        self.fence_areas = areas;
    }

    /// Why the estimated position is outside the fence, if it is.
    pub fn outside_fence(&self) -> Option<&'static str> {
        let p = self.est_pos();
        let max_ver = self.params.get(Param::GF_MAX_VER_DIST);
        if max_ver > 0.0 && self.home_local.down_m - p.down_m > max_ver {
            return Some("maximum altitude above home");
        }
        let max_hor = self.params.get(Param::GF_MAX_HOR_DIST);
        let from_home = (p - self.home_local).horizontal_norm();
        if max_hor > 0.0 && from_home > max_hor {
            return Some("maximum distance from home");
        }
        let here = [p.north_m, p.east_m];
        let mut has_inclusion = false;
        let mut inside_inclusion = false;
        for a in &self.fence_areas {
            let inside = a.contains(here);
            if a.inclusion() {
                has_inclusion = true;
                inside_inclusion |= inside;
            } else if inside {
                return Some("exclusion area");
            }
        }
        (has_inclusion && !inside_inclusion).then_some("inclusion area")
    }

    /// Every step: a breach by an armed vehicle in the air takes `GF_ACTION`, once per
    /// excursion.
    pub(super) fn check_geofence(&mut self, now: Instant, out: &mut Outbox) {
        if !self.armed || self.landed || !self.has_fix {
            self.fence_breached = false;
            return;
        }
        let Some(why) = self.outside_fence() else {
            self.fence_breached = false;
            return;
        };
        if self.fence_breached {
            return;
        }
        self.fence_breached = true;
        self.counters.geofence_breaches += 1;
        let action = match self.params.get(Param::GF_ACTION) as i32 {
            0 => return,
            1 => None,
            2 => Some((Px4Mode::Hold, "holding")),
            3 => Some((Px4Mode::Rtl, "returning")),
            4 => {
                self.disarm(now, "Failsafe: geofence breached, terminating", out);
                return;
            }
            _ => Some((Px4Mode::Land, "landing")),
        };
        let text = match action {
            Some((mode, doing)) => {
                self.failsafe_to(mode);
                format!("Failsafe: geofence breached ({why}), {doing}")
            }
            None => format!("Geofence breached ({why})"),
        };
        self.statustext(now, MavSeverity::MAV_SEVERITY_CRITICAL, &text, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pnpoly_as_px4() {
        let sq = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];
        assert!(inside_polygon(&sq, [5.0, 5.0]));
        assert!(!inside_polygon(&sq, [5.0, 15.0]));
        let c = Area::Circle {
            inclusion: false,
            centre: [0.0, 0.0],
            radius_m: 2.0,
        };
        assert!(c.contains([1.0, 1.0]) && !c.contains([2.0, 0.0]));
    }
}
