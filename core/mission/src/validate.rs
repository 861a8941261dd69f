//! Checking a plan before it is stored (`POST /api/v1/missions`): every point inside the
//! geofence with its margin, between floor and ceiling; speeds within the vehicles'
//! limits; formations, lanes, station points and patrol places far enough apart for the
//! separation the swarm keeps (separation by construction, as formation changes are);
//! groups that name something. A refusal names the step and field
//! (`steps[2].polygon[1]`) and says why. What depends on the swarm at the time (which
//! vehicles a group is, their energy) is checked at start ([`crate::resolve`],
//! [`crate::energy`]).

use crate::lanes;
use crate::plan::{IntruderReaction, MissionPlan, Point, Station, Step, StepKind, Survey};
use skein_model::geo::Ned;
use skein_model::geofence::{Geofence, polygon};

/// What a plan is checked against.
#[derive(Debug, Clone)]
pub struct Limits<'a> {
    /// The geofence in force.
    pub fence: &'a Geofence,
    /// How far inside the fence every point must be, metres.
    pub fence_margin_m: f64,
    /// The distance setpoints keep from each other (separation + tracking margin),
    /// metres: station points, patrol places and survey lanes at least this far apart.
    pub separation_m: f64,
    /// The smallest slot distance a formation may have, metres (`√2 ×` the above).
    pub min_slot_distance_m: f64,
    /// The slowest vehicle model's speed limit, m/s.
    pub max_speed_m_s: f64,
}

/// Why a plan was refused: the field's path and the reason.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlanError {
    /// `name`, `steps`, `steps[2].polygon[1]`, `groups.observers` ...
    pub field: String,
    /// What is wrong.
    pub error: String,
}

impl PlanError {
    /// A refusal of `field`.
    pub fn new(field: impl Into<String>, error: impl Into<String>) -> Self {
        PlanError {
            field: field.into(),
            error: error.into(),
        }
    }
}

impl std::fmt::Display for PlanError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.field, self.error)
    }
}

impl std::error::Error for PlanError {}

type Checked = Result<(), PlanError>;

/// Checks `plan` against `limits`.
///
/// # Errors
/// The first field found wrong, in plan order.
pub fn check(plan: &MissionPlan, limits: &Limits) -> Checked {
    let name = plan.name.trim();
    if name.is_empty() || plan.name.chars().count() > 64 {
        return Err(PlanError::new("name", "1 to 64 characters"));
    }
    if plan.steps.is_empty() {
        return Err(PlanError::new("steps", "a plan needs at least one step"));
    }
    for (g, spec) in &plan.groups {
        if spec.vehicles.is_empty() && spec.model.is_none() {
            return Err(PlanError::new(
                format!("groups.{g}"),
                "a group lists `vehicles` or names a `model`",
            ));
        }
    }
    for (i, step) in plan.steps.iter().enumerate() {
        check_step(plan, i, step, limits)?;
    }
    if let Some(low) = &plan.reactions.low_battery {
        in_range(
            "reactions.low_battery.below_percent",
            low.below_percent,
            crate::energy::RESERVE_PERCENT + 1.0,
            99.0,
        )?;
    }
    if let Some(r) = &plan.reactions.intruder {
        intruder(r)?;
    }
    Ok(())
}

fn intruder(r: &IntruderReaction) -> Checked {
    let at = "reactions.intruder";
    if !(1..=8).contains(&r.observers) {
        return Err(PlanError::new(
            format!("{at}.observers"),
            format!("{} outside 1 to 8", r.observers),
        ));
    }
    if let Some(s) = r.standoff_m {
        in_range(&format!("{at}.standoff_m"), s, 10.0, 60.0)?;
    }
    let Some(zone) = &r.zone else {
        return Ok(());
    };
    if zone.len() < 3 {
        return Err(PlanError::new(format!("{at}.zone"), "at least 3 points"));
    }
    if let Some(j) = zone
        .iter()
        .position(|p| !(p[0].is_finite() && p[1].is_finite()))
    {
        return Err(PlanError::new(format!("{at}.zone[{j}]"), "not a number"));
    }
    if let Some((a, b)) = polygon::self_intersection(zone) {
        return Err(PlanError::new(
            format!("{at}.zone"),
            format!("edges {a} and {b} cross: the zone must be a simple polygon"),
        ));
    }
    Ok(())
}

fn check_step(plan: &MissionPlan, i: usize, step: &Step, limits: &Limits) -> Checked {
    let at = |field: &str| format!("steps[{i}].{field}");
    if let Some(g) = &step.group
        && !plan.groups.contains_key(g)
    {
        let known: Vec<&str> = plan.groups.keys().map(String::as_str).collect();
        return Err(PlanError::new(
            at("group"),
            format!("no group `{g}` in `groups` (it has: {})", list(&known)),
        ));
    }
    let whole_swarm = step.group.is_none();
    match &step.kind {
        StepKind::Takeoff(t) => {
            above_zero(&at("altitude_m"), t.altitude_m, limits.fence.max_altitude_m)?;
            in_range(&at("interval_s"), t.interval_s, 0.0, 60.0)
        }
        StepKind::Transit(t) => {
            altitude(&at("altitude_m"), t.altitude_m, limits)?;
            speed(&at("speed_m_s"), t.speed_m_s, limits)?;
            points(&at("waypoints"), &t.waypoints, 1, t.altitude_m, limits)?;
            match &t.formation {
                Some(_) if !whole_swarm => Err(PlanError::new(
                    at("formation"),
                    "a formation flies every airborne vehicle: a group's transit flies without one",
                )),
                Some(f) if f.spacing_m < limits.min_slot_distance_m - 1e-9 => Err(PlanError::new(
                    at("formation.spacing_m"),
                    format!(
                        "{} m is below the {:.2} m formation changes need to keep the separation",
                        f.spacing_m, limits.min_slot_distance_m
                    ),
                )),
                _ => Ok(()),
            }
        }
        StepKind::Survey(s) => survey(&at(""), s, limits),
        StepKind::Patrol(p) => {
            altitude(&at("altitude_m"), p.altitude_m, limits)?;
            points(&at("route"), &p.route, 2, p.altitude_m, limits)?;
            if let Some(d) = p.duration_s {
                in_range(&at("duration_s"), d, 0.0, 86_400.0)?;
            }
            Ok(())
        }
        StepKind::Station(s) => station(&at(""), s, limits),
        StepKind::Return(t) | StepKind::Land(t) => {
            in_range(&at("interval_s"), t.interval_s, 0.0, 60.0)
        }
    }
}

fn survey(at: &str, s: &Survey, limits: &Limits) -> Checked {
    altitude(&format!("{at}altitude_m"), s.altitude_m, limits)?;
    points(&format!("{at}polygon"), &s.polygon, 3, s.altitude_m, limits)?;
    if let Some((a, b)) = polygon::self_intersection(&s.polygon) {
        return Err(PlanError::new(
            format!("{at}polygon"),
            format!("edges {a} and {b} cross: the area must be a simple polygon"),
        ));
    }
    let spacing = match (s.lane_spacing_m, s.camera) {
        (Some(l), _) => (l, format!("{at}lane_spacing_m")),
        (None, Some(c)) => {
            in_range(&format!("{at}camera.hfov_deg"), c.hfov_deg, 1.0, 170.0)?;
            in_range(&format!("{at}camera.overlap"), c.overlap, 0.0, 0.9)?;
            (c.lane_spacing_m(s.altitude_m), format!("{at}camera"))
        }
        (None, None) => {
            return Err(PlanError::new(
                format!("{at}lane_spacing_m"),
                "give `lane_spacing_m`, or a `camera` to space the lanes by its footprint",
            ));
        }
    };
    if !(spacing.0.is_finite() && spacing.0 >= limits.separation_m) {
        return Err(PlanError::new(
            spacing.1,
            format!(
                "lanes {:.2} m apart: two vehicles on neighbouring lanes need {:.2} m",
                spacing.0, limits.separation_m
            ),
        ));
    }
    // The lanes divide the width evenly, so they may come out closer than asked.
    if let Some((n, actual)) = lanes::lane_spacing(&s.polygon, spacing.0)
        && n > 1
        && actual < limits.separation_m
    {
        return Err(PlanError::new(
            spacing.1,
            format!(
                "the area's width divides into {n} lanes {actual:.2} m apart (at most {:.2} \
                 asked): two vehicles on neighbouring lanes need {:.2} m; widen the spacing \
                 to {:.2} m",
                spacing.0,
                limits.separation_m,
                actual * n as f64 / (n - 1) as f64
            ),
        ));
    }
    if lanes::lanes(&s.polygon, spacing.0).is_empty() {
        return Err(PlanError::new(
            format!("{at}polygon"),
            "the area has no lane",
        ));
    }
    Ok(())
}

fn station(at: &str, s: &Station, limits: &Limits) -> Checked {
    altitude(&format!("{at}altitude_m"), s.altitude_m, limits)?;
    in_range(&format!("{at}duration_s"), s.duration_s, 0.0, 86_400.0)?;
    points(&format!("{at}points"), &s.points, 1, s.altitude_m, limits)?;
    for (i, a) in s.points.iter().enumerate() {
        for (j, b) in s.points.iter().enumerate().skip(i + 1) {
            let d = polygon::distance(*a, *b);
            if d < limits.separation_m {
                return Err(PlanError::new(
                    format!("{at}points[{j}]"),
                    format!(
                        "{d:.2} m from points[{i}]: stations keep {:.2} m apart",
                        limits.separation_m
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// At least `min` points, each inside the fence (with its margin) at `altitude_m`.
fn points(at: &str, pts: &[Point], min: usize, altitude_m: f64, limits: &Limits) -> Checked {
    if pts.len() < min {
        return Err(PlanError::new(at, format!("at least {min} point(s)")));
    }
    let fence = limits.fence.shrunk(limits.fence_margin_m);
    for (j, p) in pts.iter().enumerate() {
        let ned = Ned::new(p[0], p[1], -altitude_m);
        if !(p[0].is_finite() && p[1].is_finite() && fence.contains(ned)) {
            let (_, why) = fence.clamp(ned, true);
            return Err(PlanError::new(
                format!("{at}[{j}]"),
                format!(
                    "({:.1}, {:.1}) at {altitude_m} m is outside the geofence{} with its {} m margin",
                    p[0],
                    p[1],
                    why.map(|v| format!(" ({})", v.name())).unwrap_or_default(),
                    limits.fence_margin_m
                ),
            ));
        }
    }
    Ok(())
}

fn altitude(at: &str, a: f64, limits: &Limits) -> Checked {
    let (lo, hi) = (
        limits.fence.min_altitude_m + limits.fence_margin_m,
        limits.fence.max_altitude_m - limits.fence_margin_m,
    );
    if a.is_finite() && a > 0.0 && a >= lo && a <= hi {
        Ok(())
    } else {
        Err(PlanError::new(
            at,
            format!(
                "{a} m outside the geofence's floor and ceiling with its margin: {lo} to {hi} m"
            ),
        ))
    }
}

fn speed(at: &str, v: f64, limits: &Limits) -> Checked {
    if v.is_finite() && v > 0.0 && v <= limits.max_speed_m_s {
        Ok(())
    } else {
        Err(PlanError::new(
            at,
            format!(
                "{v} m/s outside (0, {}] m/s (the slowest vehicle model's limit)",
                limits.max_speed_m_s
            ),
        ))
    }
}

fn in_range(at: &str, v: f64, lo: f64, hi: f64) -> Checked {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(PlanError::new(at, format!("{v} outside {lo} to {hi}")))
    }
}

/// Above 0 and at most `hi` (an altitude above home).
fn above_zero(at: &str, v: f64, hi: f64) -> Checked {
    if v.is_finite() && v > 0.0 && v <= hi {
        Ok(())
    } else {
        Err(PlanError::new(at, format!("{v} outside (0, {hi}]")))
    }
}

fn list(names: &[&str]) -> String {
    if names.is_empty() {
        "none".into()
    } else {
        names.join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits(fence: &Geofence) -> Limits<'_> {
        Limits {
            fence,
            fence_margin_m: 5.0,
            separation_m: 3.5,
            min_slot_distance_m: 4.95,
            max_speed_m_s: 12.0,
        }
    }

    fn plan(steps: &str) -> MissionPlan {
        serde_json::from_str(&format!(
            r#"{{"name": "t", "groups": {{"obs": {{"model": "observation"}}}}, "steps": {steps}}}"#
        ))
        .unwrap()
    }

    fn refused(steps: &str) -> PlanError {
        let fence = Geofence::default();
        check(&plan(steps), &limits(&fence)).expect_err("refused")
    }

    #[test]
    fn a_sound_plan_passes() {
        let fence = Geofence::default();
        let p = plan(
            r#"[{"kind": "takeoff", "altitude_m": 10},
                {"kind": "transit", "waypoints": [[50, 0]], "altitude_m": 15, "speed_m_s": 5,
                 "formation": {"shape": "wedge", "spacing_m": 7}},
                {"kind": "survey", "group": "obs", "polygon": [[0,0],[0,60],[40,60],[40,0]],
                 "altitude_m": 20, "camera": {"hfov_deg": 60, "overlap": 0.2}},
                {"kind": "patrol", "route": [[0,0],[0,80],[80,80]], "altitude_m": 20, "duration_s": 60},
                {"kind": "station", "points": [[10,10],[10,20]], "altitude_m": 20, "duration_s": 5},
                {"kind": "return"}, {"kind": "land"}]"#,
        );
        assert_eq!(check(&p, &limits(&fence)), Ok(()));
    }

    #[test]
    fn each_refusal_names_its_step_and_field() {
        for (steps, field, says) in [
            (
                r#"[{"kind": "takeoff", "altitude_m": 0}]"#,
                "steps[0].altitude_m",
                "outside",
            ),
            (
                r#"[{"kind": "transit", "waypoints": [[900, 0]], "altitude_m": 15, "speed_m_s": 5}]"#,
                "steps[0].waypoints[0]",
                "geofence (radius)",
            ),
            (
                r#"[{"kind": "transit", "waypoints": [[9, 0]], "altitude_m": 15, "speed_m_s": 50}]"#,
                "steps[0].speed_m_s",
                "limit",
            ),
            (
                r#"[{"kind": "transit", "group": "obs", "waypoints": [[9, 0]], "altitude_m": 15,
                    "speed_m_s": 5, "formation": {"shape": "line", "spacing_m": 7}}]"#,
                "steps[0].formation",
                "every airborne",
            ),
            (
                r#"[{"kind": "survey", "polygon": [[0,0],[0,60],[40,0],[40,60]], "altitude_m": 20,
                    "lane_spacing_m": 8}]"#,
                "steps[0].polygon",
                "cross",
            ),
            (
                r#"[{"kind": "survey", "polygon": [[0,0],[0,60],[40,60]], "altitude_m": 20,
                    "lane_spacing_m": 2}]"#,
                "steps[0].lane_spacing_m",
                "neighbouring lanes",
            ),
            (
                // 16 m across in lanes of at most 3.5 m: 5 lanes 3.2 m apart.
                r#"[{"kind": "survey", "polygon": [[0,0],[0,60],[16,60],[16,0]],
                    "altitude_m": 20, "lane_spacing_m": 3.5}]"#,
                "steps[0].lane_spacing_m",
                "5 lanes 3.20 m apart (at most 3.50 asked): two vehicles on neighbouring lanes \
                 need 3.50 m; widen the spacing to 4.00 m",
            ),
            (
                r#"[{"kind": "survey", "polygon": [[0,0],[0,60],[40,60]], "altitude_m": 20}]"#,
                "steps[0].lane_spacing_m",
                "camera",
            ),
            (
                r#"[{"kind": "station", "points": [[0,0],[1,1]], "altitude_m": 20, "duration_s": 5}]"#,
                "steps[0].points[1]",
                "apart",
            ),
            (
                r#"[{"kind": "patrol", "route": [[0,0]], "altitude_m": 200}]"#,
                "steps[0].altitude_m",
                "ceiling",
            ),
            (
                r#"[{"kind": "land", "group": "nobody"}]"#,
                "steps[0].group",
                "has: obs",
            ),
        ] {
            let e = refused(steps);
            assert_eq!(e.field, field, "{steps}: {e}");
            assert!(e.error.contains(says), "{steps}: {e}");
        }
        let fence = Geofence::default();
        let mut p = plan(r#"[{"kind": "land"}]"#);
        p.name = " ".into();
        assert_eq!(check(&p, &limits(&fence)).unwrap_err().field, "name");
        p = plan("[]");
        assert_eq!(check(&p, &limits(&fence)).unwrap_err().field, "steps");
    }

    #[test]
    fn an_intruder_reaction_is_checked() {
        let fence = Geofence::default();
        let with = |reaction: &str| {
            let mut p = plan(r#"[{"kind": "land"}]"#);
            p.reactions.intruder = Some(serde_json::from_str(reaction).unwrap());
            check(&p, &limits(&fence))
        };
        assert_eq!(with(r#"{"zone": [[0,0],[0,50],[50,50]]}"#), Ok(()));
        for (reaction, field) in [
            (r#"{"observers": 0}"#, "reactions.intruder.observers"),
            (r#"{"standoff_m": 5}"#, "reactions.intruder.standoff_m"),
            (r#"{"zone": [[0,0],[0,50]]}"#, "reactions.intruder.zone"),
            (
                r#"{"zone": [[0,0],[0,60],[40,0],[40,60]]}"#,
                "reactions.intruder.zone",
            ),
        ] {
            assert_eq!(with(reaction).unwrap_err().field, field, "{reaction}");
        }
    }
}
