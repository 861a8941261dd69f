//! The simulated camera's renderer: a pinhole projection of the swarm (and the simulator's
//! intruders, drawn as the different airframe they are, without any label) from one
//! vehicle's pose and gimbal angles, drawn over a sky/ground background split by the
//! horizon. An aircraft's drawn size follows its span and range.
//!
//! Frames: the camera looks along the optical axis given by an azimuth (degrees clockwise
//! from north) and an elevation (degrees above the horizontal), without roll (a stabilised
//! gimbal). Image axes: `u` to the right, `v` down, origin at the top-left pixel corner;
//! the principal point is the image centre; pixels are square.

use skein_plugin_sdk::geometry::{Ned, direction};

/// Intrinsics of a pinhole camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pinhole {
    /// Image width, pixels.
    pub width_px: u32,
    /// Image height, pixels.
    pub height_px: u32,
    /// Focal length, millimetres (the zoom).
    pub focal_length_mm: f64,
    /// Sensor width, millimetres (1/2.3" sensor: 6.17 mm).
    pub sensor_width_mm: f64,
}

impl Pinhole {
    /// Focal length in pixels: `focal_length_mm / sensor_width_mm * width_px`.
    pub fn focal_px(&self) -> f64 {
        self.focal_length_mm / self.sensor_width_mm * f64::from(self.width_px)
    }

    /// Horizontal field of view, degrees.
    pub fn horizontal_fov_deg(&self) -> f64 {
        2.0 * (f64::from(self.width_px) / 2.0 / self.focal_px())
            .atan()
            .to_degrees()
    }

    /// Vertical field of view, degrees.
    pub fn vertical_fov_deg(&self) -> f64 {
        2.0 * (f64::from(self.height_px) / 2.0 / self.focal_px())
            .atan()
            .to_degrees()
    }
}

/// Where the camera is and where it looks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraPose {
    /// Camera position, swarm-frame NED, metres.
    pub position: Ned,
    /// Optical axis azimuth, degrees clockwise from north.
    pub azimuth_deg: f64,
    /// Optical axis elevation, degrees above the horizontal (negative looks down).
    pub elevation_deg: f64,
}

impl CameraPose {
    /// The camera's axes in NED: forward (optical axis), right, and image-down.
    pub fn basis(&self) -> (Ned, Ned, Ned) {
        let forward = direction(self.azimuth_deg, self.elevation_deg);
        let (s, c) = self.azimuth_deg.to_radians().sin_cos();
        let right = Ned::new(-s, c, 0.0);
        let down = forward.cross(&right);
        (forward, right, down)
    }
}

/// Nearest depth rendered, metres.
const NEAR_M: f64 = 0.5;

/// Projects a world point: `(u, v, depth_m)` in pixels, `None` when it is behind the camera
/// (or nearer than 0.5 m). The pixel may be outside the image.
pub fn project(cam: &Pinhole, pose: &CameraPose, point: Ned) -> Option<(f64, f64, f64)> {
    let (f, r, d) = pose.basis();
    let rel = point - pose.position;
    let z = rel.dot(&f);
    if z < NEAR_M {
        return None;
    }
    let fpx = cam.focal_px();
    Some((
        f64::from(cam.width_px) / 2.0 + fpx * rel.dot(&r) / z,
        f64::from(cam.height_px) / 2.0 + fpx * rel.dot(&d) / z,
        z,
    ))
}

/// Another aircraft to draw.
#[derive(Debug, Clone, PartialEq)]
pub struct Aircraft {
    /// Its vehicle id (or, for an intruder, its truth id: never drawn).
    pub id: String,
    /// Its position, swarm-frame NED, metres.
    pub position: Ned,
    /// Its span, metres (`None`: the scene's `aircraft_span_m`).
    pub span_m: Option<f64>,
    /// A non-cooperative aircraft (an intruder): drawn as the different airframe it is.
    pub intruder: bool,
}

/// An aircraft that appears in the frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Visible {
    /// Its vehicle id (an intruder's truth id).
    pub id: String,
    /// An intruder.
    pub intruder: bool,
    /// Projected centre, pixels from the left edge.
    pub x_px: f64,
    /// Projected centre, pixels from the top edge.
    pub y_px: f64,
    /// Distance along the optical axis, metres.
    pub depth_m: f64,
    /// Drawn radius, pixels.
    pub radius_px: f64,
}

/// What to render.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// The camera's pose.
    pub pose: CameraPose,
    /// The ground plane's `down`, swarm frame, metres (0: the swarm origin's altitude).
    pub ground_down_m: f64,
    /// Other aircraft.
    pub aircraft: Vec<Aircraft>,
    /// Rotor-tip to rotor-tip span of an aircraft, metres (sets its drawn size).
    pub aircraft_span_m: f64,
}

const SKY_HORIZON: [f64; 3] = [205.0, 222.0, 238.0];
const SKY_ZENITH: [f64; 3] = [60.0, 115.0, 190.0];
const GROUND_NEAR: [f64; 3] = [96.0, 140.0, 72.0];
const GROUND_ALT: [f64; 3] = [110.0, 150.0, 80.0];
const GRID: [f64; 3] = [70.0, 100.0, 55.0];
const HAZE: [f64; 3] = [180.0, 190.0, 195.0];
const AIRFRAME: [u8; 3] = [35, 35, 40];
const ROTOR: [u8; 3] = [220, 50, 30];
/// Intruders: a dark grey airframe with black rotors (no swarm livery).
const INTRUDER_AIRFRAME: [u8; 3] = [70, 70, 75];
const INTRUDER_ROTOR: [u8; 3] = [20, 20, 22];

fn mix(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
    let t = t.clamp(0.0, 1.0);
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

/// The background colour seen along the (not necessarily unit) ray `ray` from `origin`.
fn background(ray: Ned, origin: Ned, ground_down_m: f64) -> [f64; 3] {
    let len = ray.norm();
    let up = -ray.down_m / len;
    let height = ground_down_m - origin.down_m;
    if up >= 0.0 || height <= 0.0 {
        return mix(SKY_HORIZON, SKY_ZENITH, up.max(0.0).sqrt());
    }
    // Ground: intersect the ground plane; a 10 m grid with 50 m checks, hazing with range.
    let t = height / ray.down_m;
    let hit = origin + ray * t;
    let range = (ray * t).norm();
    let check = ((hit.north_m / 50.0).floor() + (hit.east_m / 50.0).floor()) as i64 % 2 == 0;
    let mut c = if check { GROUND_NEAR } else { GROUND_ALT };
    let on_line = |x: f64| {
        let f = (x / 10.0).rem_euclid(1.0);
        !(0.04..=0.96).contains(&f)
    };
    // Grid lines fade out by 250 m, before they get thinner than a pixel and alias.
    if range < 250.0 && (on_line(hit.north_m) || on_line(hit.east_m)) {
        c = mix(GRID, c, range / 250.0);
    }
    mix(c, HAZE, range / 2500.0)
}

fn fill_disc(px: &mut [u8], w: u32, h: u32, cx: f64, cy: f64, r: f64, color: [u8; 3]) {
    let (x0, x1) = (
        (cx - r).floor().max(0.0),
        (cx + r).ceil().min(f64::from(w) - 1.0),
    );
    let (y0, y1) = (
        (cy - r).floor().max(0.0),
        (cy + r).ceil().min(f64::from(h) - 1.0),
    );
    if x0 > x1 || y0 > y1 {
        return;
    }
    for y in y0 as u32..=y1 as u32 {
        for x in x0 as u32..=x1 as u32 {
            let (dx, dy) = (f64::from(x) + 0.5 - cx, f64::from(y) + 0.5 - cy);
            if dx * dx + dy * dy <= r * r {
                let i = ((y * w + x) * 3) as usize;
                px[i..i + 3].copy_from_slice(&color);
            }
        }
    }
}

/// Renders the scene: RGB8 pixels (row-major, `width_px * height_px * 3` bytes) and the
/// aircraft that appear, nearest last.
pub fn render(cam: &Pinhole, scene: &Scene) -> (Vec<u8>, Vec<Visible>) {
    let (w, h) = (cam.width_px, cam.height_px);
    let mut px = vec![0u8; (w as usize) * (h as usize) * 3];
    let (f, r, d) = scene.pose.basis();
    let fpx = cam.focal_px();
    let (cx, cy) = (f64::from(w) / 2.0, f64::from(h) / 2.0);
    for y in 0..h {
        let dv = (f64::from(y) + 0.5 - cy) / fpx;
        let row = f + d * dv;
        for x in 0..w {
            let du = (f64::from(x) + 0.5 - cx) / fpx;
            let c = background(row + r * du, scene.pose.position, scene.ground_down_m);
            let i = ((y * w + x) * 3) as usize;
            px[i] = c[0].round() as u8;
            px[i + 1] = c[1].round() as u8;
            px[i + 2] = c[2].round() as u8;
        }
    }
    let mut visible: Vec<Visible> = scene
        .aircraft
        .iter()
        .filter_map(|a| {
            let (u, v, z) = project(cam, &scene.pose, a.position)?;
            // At least 3 px, so a distant aircraft stays a visible dot.
            let span = a.span_m.unwrap_or(scene.aircraft_span_m);
            let radius = (span / 2.0 * fpx / z).max(3.0);
            let inside = u + radius >= 0.0
                && u - radius < f64::from(w)
                && v + radius >= 0.0
                && v - radius < f64::from(h);
            inside.then(|| Visible {
                id: a.id.clone(),
                intruder: a.intruder,
                x_px: u,
                y_px: v,
                depth_m: z,
                radius_px: radius,
            })
        })
        .collect();
    // Painter's order: far first.
    visible.sort_by(|a, b| b.depth_m.total_cmp(&a.depth_m));
    for a in &visible {
        let rr = a.radius_px;
        let (rotor, airframe) = if a.intruder {
            (INTRUDER_ROTOR, INTRUDER_AIRFRAME)
        } else {
            (ROTOR, AIRFRAME)
        };
        if rr < 6.0 {
            fill_disc(&mut px, w, h, a.x_px, a.y_px, rr, rotor);
            fill_disc(&mut px, w, h, a.x_px, a.y_px, rr * 0.5, airframe);
        } else {
            // A quadcopter seen from its side or above: four rotors around a body.
            for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
                let off = rr * 0.55;
                fill_disc(
                    &mut px,
                    w,
                    h,
                    a.x_px + sx * off,
                    a.y_px + sy * off * 0.5,
                    rr * 0.4,
                    rotor,
                );
            }
            fill_disc(&mut px, w, h, a.x_px, a.y_px, rr * 0.38, airframe);
        }
    }
    (px, visible)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> Pinhole {
        Pinhole {
            width_px: 320,
            height_px: 240,
            focal_length_mm: 4.0,
            sensor_width_mm: 6.4,
        }
    }

    #[test]
    fn point_on_the_axis_projects_to_the_centre() {
        let pose = CameraPose {
            position: Ned::new(0.0, 0.0, -20.0),
            azimuth_deg: 90.0,
            elevation_deg: -30.0,
        };
        let p = pose.position + direction(90.0, -30.0) * 50.0;
        let (u, v, z) = project(&cam(), &pose, p).unwrap();
        assert!((u - 160.0).abs() < 1e-9 && (v - 120.0).abs() < 1e-9 && (z - 50.0).abs() < 1e-9);
    }

    #[test]
    fn right_and_up_map_to_image_right_and_up() {
        let pose = CameraPose {
            position: Ned::default(),
            azimuth_deg: 0.0,
            elevation_deg: 0.0,
        };
        // 40 m north, 5 m east, 2 m up.
        let (u, v, _) = project(&cam(), &pose, Ned::new(40.0, 5.0, -2.0)).unwrap();
        let f = cam().focal_px();
        assert_eq!(f, 200.0);
        assert!((u - (160.0 + f * 5.0 / 40.0)).abs() < 1e-9);
        assert!((v - (120.0 - f * 2.0 / 40.0)).abs() < 1e-9);
        assert!(project(&cam(), &pose, Ned::new(-10.0, 0.0, 0.0)).is_none());
    }

    #[test]
    fn looking_down_keeps_north_at_the_top() {
        let pose = CameraPose {
            position: Ned::new(0.0, 0.0, -50.0),
            azimuth_deg: 0.0,
            elevation_deg: -90.0,
        };
        let (_, v, _) = project(&cam(), &pose, Ned::new(10.0, 0.0, 0.0)).unwrap();
        assert!(v < 120.0);
    }

    #[test]
    fn horizon_splits_sky_and_ground() {
        let pose = CameraPose {
            position: Ned::new(0.0, 0.0, -20.0),
            azimuth_deg: 0.0,
            elevation_deg: 0.0,
        };
        let scene = Scene {
            pose,
            ground_down_m: 0.0,
            aircraft: vec![],
            aircraft_span_m: 1.0,
        };
        let (px, vis) = render(&cam(), &scene);
        assert!(vis.is_empty());
        let at = |x: usize, y: usize| {
            let i = (y * 320 + x) * 3;
            [px[i], px[i + 1], px[i + 2]]
        };
        // Top row: sky (blue dominant); bottom row: ground (green dominant).
        let top = at(160, 0);
        let bottom = at(160, 239);
        assert!(top[2] > top[1] && top[2] > top[0], "{top:?}");
        assert!(bottom[1] > bottom[2] && bottom[1] > bottom[0], "{bottom:?}");
    }

    #[test]
    fn fov_matches_focal_length() {
        let c = cam();
        // 320 px wide, f = 200 px: 2 atan(0.8) = 77.3°.
        assert!((c.horizontal_fov_deg() - 77.3196).abs() < 1e-3);
        let zoomed = Pinhole {
            focal_length_mm: 8.0,
            ..c
        };
        assert!((zoomed.horizontal_fov_deg() - 2.0 * 0.4f64.atan().to_degrees()).abs() < 1e-9);
    }
}
