//! Where a reserve meets the vehicle it replaces on a patrol (a cyclic route), so that the
//! route is not left unflown while the reserve flies to it. Once up, the reserve flies to
//! the first point ahead of the low vehicle on its route that it reaches first (its
//! straight way shorter by [`MEET_MARGIN_M`] than the low vehicle's way along the route,
//! both at the route's speed), within two laps; the low vehicle flies on meanwhile. The
//! handover comes when the low vehicle, heading for that point, is within
//! [`HANDOVER_M`] of it with the reserve there: the reserve joins the route where the low
//! vehicle left it, a few metres back, and flies on, so the route went unflown only for
//! those metres. Should the low vehicle pass the point first (the reserve delayed), the
//! handover is at once, the reserve joining from where it is.

use super::route::Route;
use serde::{Deserialize, Serialize};
use skein_model::geo::Ned;

/// The low vehicle within this of the meeting point, metres, hands over: more than the
/// setpoint separation (3.5 m by default), so it is not braked short of it by the
/// reserve waiting there.
pub const HANDOVER_M: f64 = 8.0;

/// The reserve's way to a meeting point must be this much shorter than the low
/// vehicle's, metres (the reserve waits there rather than the other way round).
pub const MEET_MARGIN_M: f64 = 10.0;

/// The reserve within this of the meeting point, metres, is there.
const THERE_M: f64 = 3.0;

/// A meeting on the low vehicle's route.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) struct Meet {
    /// The point, swarm-frame NED.
    pub(super) point: Ned,
    /// The low vehicle's count of points reached while it heads for the point.
    pub(super) low_reached: usize,
}

/// What a pending swap does this tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Verdict {
    /// The reserve flies to the meeting point; the low vehicle flies on.
    Wait,
    /// The reserve takes the route now.
    HandOver,
}

/// The meeting point on `route` (cyclic, the low vehicle's, at `low`) for a reserve at
/// `reserve` (see the module docs); `None` when no point within two laps suits.
pub(super) fn plan(route: &Route, low: Ned, reserve: Ned) -> Option<Meet> {
    route
        .ahead(low, 2)
        .into_iter()
        .find(|(_, point, along_m)| (*point - reserve).norm() + MEET_MARGIN_M <= *along_m)
        .map(|(i, point, _)| Meet {
            point,
            low_reached: route.reached() + i,
        })
}

/// Whether the handover of `meet` is due, the low vehicle's route `route` and the two
/// vehicles where they are (`None`: not known).
pub(super) fn verdict(
    meet: &Meet,
    route: &Route,
    low: Option<Ned>,
    reserve: Option<Ned>,
) -> Verdict {
    let reached = route.reached();
    if reached > meet.low_reached {
        return Verdict::HandOver;
    }
    let near = |p: Option<Ned>, m: f64| p.is_some_and(|p| (p - meet.point).norm() < m);
    if reached == meet.low_reached && near(low, HANDOVER_M) && near(reserve, THERE_M) {
        Verdict::HandOver
    } else {
        Verdict::Wait
    }
}
