//! The rehearsal's picture: the paths flown over the plan, as SVG, north up, east to the
//! right, one SVG unit a metre. Drawn: the geofence (its circle, polygon and exclusion
//! areas), the plan (survey polygons filled, patrol routes dashed, transit waypoints,
//! station points), each vehicle's path in its own colour with its id at the end, the
//! intruders' paths in red, and a scale bar.

use crate::record::Record;
use skein_mission::MissionPlan;
use skein_mission::plan::StepKind;
use skein_model::geo::Ned;
use skein_model::geofence::{FenceArea, Geofence};
use std::fmt::Write;

/// Colours of the vehicles' paths, in turn.
const PALETTE: [&str; 8] = [
    "#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b", "#e377c2", "#7f7f7f",
];

/// SVG x, y of a swarm-frame horizontal point (`[north_m, east_m]`).
fn xy(p: [f64; 2]) -> (f64, f64) {
    (p[1], -p[0])
}

fn points(ps: impl Iterator<Item = [f64; 2]>) -> String {
    ps.map(|p| {
        let (x, y) = xy(p);
        format!("{x:.1},{y:.1}")
    })
    .collect::<Vec<_>>()
    .join(" ")
}

fn ned2(p: &Ned) -> [f64; 2] {
    [p.north_m, p.east_m]
}

/// The picture of `plan` flown as `record` saw it, inside `fence`.
pub(crate) fn svg(plan: &MissionPlan, fence: &Geofence, record: &Record) -> String {
    let mut all: Vec<[f64; 2]> = Vec::new();
    for s in &plan.steps {
        all.extend(step_points(&s.kind));
    }
    for t in record.trails.values() {
        all.extend(t.iter().map(ned2));
    }
    let (mut lo, mut hi) = ([-20.0f64, -20.0f64], [20.0f64, 20.0f64]);
    for p in &all {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let pad = 0.08 * (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let (x0, y0) = (lo[1] - pad, -hi[0] - pad);
    let (w, h) = (hi[1] - lo[1] + 2.0 * pad, hi[0] - lo[0] + 2.0 * pad);
    let stroke = (w.max(h) / 400.0).max(0.2);
    let mut out = String::new();
    let _ = write!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="{x0:.1} {y0:.1} {w:.1} {h:.1}" width="800" height="{:.0}" font-family="sans-serif" font-size="{:.1}">"#,
        800.0 * h / w,
        4.0 * stroke * 3.0
    );
    let _ = write!(
        out,
        r##"<rect x="{x0:.1}" y="{y0:.1}" width="{w:.1}" height="{h:.1}" fill="#fbfbf8"/>"##
    );
    draw_fence(&mut out, fence, stroke);
    for s in &plan.steps {
        draw_step(&mut out, &s.kind, stroke);
    }
    for (i, (id, trail)) in record.trails.iter().enumerate() {
        let colour = PALETTE[i % PALETTE.len()];
        let _ = write!(
            out,
            r#"<polyline points="{}" fill="none" stroke="{colour}" stroke-width="{:.2}"/>"#,
            points(trail.iter().map(ned2)),
            stroke * 1.5
        );
        if let Some(last) = trail.last() {
            let (x, y) = xy(ned2(last));
            let _ = write!(
                out,
                r#"<text x="{x:.1}" y="{y:.1}" fill="{colour}">{id}</text>"#
            );
        }
    }
    for trail in record.intruder_trails.values() {
        let _ = write!(
            out,
            r##"<polyline points="{}" fill="none" stroke="#d62728" stroke-width="{:.2}" stroke-dasharray="{:.1}"/>"##,
            points(trail.iter().map(ned2)),
            stroke * 1.5,
            stroke * 6.0
        );
    }
    scale_bar(&mut out, x0, y0 + h, w, stroke);
    out.push_str("</svg>");
    out
}

/// The horizontal points a step names.
fn step_points(kind: &StepKind) -> Vec<[f64; 2]> {
    match kind {
        StepKind::Transit(t) => t.waypoints.clone(),
        StepKind::Survey(s) => s.polygon.clone(),
        StepKind::Patrol(p) => p.route.clone(),
        StepKind::Station(s) => s.points.clone(),
        StepKind::Takeoff(_) | StepKind::Return(_) | StepKind::Land(_) => Vec::new(),
    }
}

fn draw_step(out: &mut String, kind: &StepKind, stroke: f64) {
    match kind {
        StepKind::Survey(s) => {
            let _ = write!(
                out,
                r##"<polygon points="{}" fill="#cfe3f5" fill-opacity="0.6" stroke="#6a9ec9" stroke-width="{stroke:.2}"/>"##,
                points(s.polygon.iter().copied())
            );
        }
        StepKind::Patrol(p) => {
            let _ = write!(
                out,
                r##"<polygon points="{}" fill="none" stroke="#b07aa1" stroke-width="{stroke:.2}" stroke-dasharray="{:.1}"/>"##,
                points(p.route.iter().copied()),
                stroke * 4.0
            );
        }
        StepKind::Transit(t) => {
            let _ = write!(
                out,
                r##"<polyline points="{}" fill="none" stroke="#999" stroke-width="{stroke:.2}" stroke-dasharray="{:.1}"/>"##,
                points(t.waypoints.iter().copied()),
                stroke * 2.0
            );
        }
        StepKind::Station(s) => {
            for p in &s.points {
                let (x, y) = xy(*p);
                let r = stroke * 4.0;
                let _ = write!(
                    out,
                    r##"<rect x="{:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="none" stroke="#555" stroke-width="{stroke:.2}"/>"##,
                    x - r,
                    y - r,
                    2.0 * r,
                    2.0 * r
                );
            }
        }
        StepKind::Takeoff(_) | StepKind::Return(_) | StepKind::Land(_) => {}
    }
}

fn draw_fence(out: &mut String, fence: &Geofence, stroke: f64) {
    let _ = write!(
        out,
        r##"<circle cx="0" cy="0" r="{:.1}" fill="none" stroke="#c44" stroke-width="{stroke:.2}"/>"##,
        fence.radius_m
    );
    if fence.polygon.len() >= 3 {
        let _ = write!(
            out,
            r##"<polygon points="{}" fill="none" stroke="#c44" stroke-width="{stroke:.2}"/>"##,
            points(fence.polygon.iter().copied())
        );
    }
    for area in &fence.exclusions {
        match area {
            FenceArea::Polygon(v) => {
                let _ = write!(
                    out,
                    r##"<polygon points="{}" fill="#f4caca" stroke="#c44" stroke-width="{stroke:.2}"/>"##,
                    points(v.iter().copied())
                );
            }
            FenceArea::Circle {
                north_m,
                east_m,
                radius_m,
            } => {
                let (x, y) = xy([*north_m, *east_m]);
                let _ = write!(
                    out,
                    r##"<circle cx="{x:.1}" cy="{y:.1}" r="{radius_m:.1}" fill="#f4caca" stroke="#c44" stroke-width="{stroke:.2}"/>"##
                );
            }
        }
    }
}

/// A scale bar of a round length near a fifth of the width, bottom left.
fn scale_bar(out: &mut String, x0: f64, bottom: f64, w: f64, stroke: f64) {
    let target = w / 5.0;
    let unit = 10f64.powf(target.log10().floor());
    let len = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|k| k * unit)
        .rfind(|l| *l <= target)
        .unwrap_or(unit);
    let (x, y) = (x0 + w * 0.04, bottom - w * 0.04);
    let _ = write!(
        out,
        r##"<line x1="{x:.1}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#333" stroke-width="{:.2}"/><text x="{x:.1}" y="{:.1}" fill="#333">{len:.0} m</text>"##,
        x + len,
        stroke * 2.0,
        y - stroke * 3.0
    );
}
