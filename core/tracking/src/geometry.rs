//! Bearings in the swarm frame and their fusion into a 3D point: least-squares
//! triangulation of rays from several observers, weakly completed along each ray by the
//! range the target's apparent size gives.
//!
//! Vectors are swarm-frame NED, metres (`nalgebra::Vector3` as north, east, down).

use nalgebra::{Matrix3, Vector3};

/// One bearing: a ray from an observer toward a detected aircraft.
#[derive(Debug, Clone, PartialEq)]
pub struct Ray {
    /// Observer (camera) position, swarm-frame NED, metres.
    pub origin: Vector3<f64>,
    /// Unit direction toward the target, NED.
    pub dir: Vector3<f64>,
    /// Range from the target's apparent size, metres (assuming the nominal span), if known.
    pub range_from_size_m: Option<f64>,
    /// Capture time, wall-clock microseconds.
    pub stamp_us: u64,
    /// Observer vehicle id (bearings of one observer are associated one-to-one).
    pub observer: String,
    /// Detector confidence, 0..1.
    pub confidence: f64,
}

/// Unit vector of a bearing: azimuth clockwise from north, elevation above the horizontal
/// (both degrees), in NED.
pub fn bearing_dir(azimuth_deg: f64, elevation_deg: f64) -> Vector3<f64> {
    let (sa, ca) = azimuth_deg.to_radians().sin_cos();
    let (se, ce) = elevation_deg.to_radians().sin_cos();
    Vector3::new(ce * ca, ce * sa, -se)
}

/// `I − d dᵀ`: projects onto the plane perpendicular to the unit vector `d`.
pub fn perp(d: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::identity() - d * d.transpose()
}

/// How the fusion weighs a ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayNoise {
    /// Bearing standard deviation, radians (a ray is `σ · range` wide).
    pub bearing_sigma_rad: f64,
    /// Relative standard deviation of a range from apparent size (0.3 = 30 %).
    pub size_range_rel_sigma: f64,
}

/// Fuses rays into the point that best explains them, with its covariance (m²).
///
/// Each ray contributes information `P⊥/σ⊥² + d dᵀ/σ∥²` about the pseudo-point
/// `origin + dir · ρ`: across the ray with `σ⊥ = σ_bearing · range`, along it (only when
/// `ρ`, the range from size, is known) with `σ∥ = rel · ρ`. Across-ray terms alone are
/// the least-squares triangulation of the rays (minimum of the summed squared,
/// range-normalised distances to the rays); the along-ray terms only matter where the rays
/// are nearly parallel or alone. Two passes: the second recomputes each ray's width at the
/// first estimate's range.
///
/// `None` when the rays do not fix a point (one ray without a range, parallel rays without
/// ranges) or the point lies behind an observer.
pub fn fuse_rays(
    rays: &[(Vector3<f64>, Vector3<f64>, Option<f64>)],
    noise: RayNoise,
) -> Option<(Vector3<f64>, Matrix3<f64>)> {
    if rays.is_empty() {
        return None;
    }
    let solve = |range_of: &dyn Fn(usize) -> f64| -> Option<(Vector3<f64>, Matrix3<f64>)> {
        let mut info = Matrix3::zeros();
        let mut b = Vector3::zeros();
        for (i, (o, d, size_range)) in rays.iter().enumerate() {
            let r = range_of(i).max(1.0);
            let s_perp = noise.bearing_sigma_rad * r;
            let mut w = perp(d) / (s_perp * s_perp);
            let mut q = *o;
            if let Some(rho) = size_range.filter(|r| r.is_finite() && *r > 0.0) {
                let s_along = noise.size_range_rel_sigma * rho;
                w += d * d.transpose() / (s_along * s_along);
                q = o + d * rho;
            }
            b += w * q;
            info += w;
        }
        let cov = info.try_inverse()?;
        // Ill-conditioned (nearly parallel rays without ranges): refuse.
        if !cov.iter().all(|v| v.is_finite()) || cov.trace() > 1e8 {
            return None;
        }
        Some((cov * b, cov))
    };
    let first = solve(&|i| rays[i].2.unwrap_or(50.0))?;
    let (p, cov) = solve(&|i| (first.0 - rays[i].0).norm())?;
    let in_front = rays.iter().all(|(o, d, _)| (p - o).dot(d) > 0.0);
    in_front.then_some((p, cov))
}

/// The closest approach of two rays: the parameters along each (metres from its origin)
/// and the miss distance; `None` for parallel rays.
pub fn closest_approach(
    o1: &Vector3<f64>,
    d1: &Vector3<f64>,
    o2: &Vector3<f64>,
    d2: &Vector3<f64>,
) -> Option<(f64, f64, f64)> {
    let w = o1 - o2;
    let b = d1.dot(d2);
    let denom = 1.0 - b * b;
    if denom < 1e-9 {
        return None;
    }
    let (d, e) = (d1.dot(&w), d2.dot(&w));
    let t1 = (b * e - d) / denom;
    let t2 = (e - b * d) / denom;
    let miss = ((o1 + d1 * t1) - (o2 + d2 * t2)).norm();
    Some((t1, t2, miss))
}

#[cfg(test)]
mod tests {
    use super::*;

    const NOISE: RayNoise = RayNoise {
        bearing_sigma_rad: 0.005,
        size_range_rel_sigma: 0.3,
    };

    fn ray_to(o: Vector3<f64>, target: Vector3<f64>) -> (Vector3<f64>, Vector3<f64>, Option<f64>) {
        (o, (target - o).normalize(), None)
    }

    #[test]
    fn two_bearings_triangulate_the_target() {
        let target = Vector3::new(60.0, 5.0, -20.0);
        let a = ray_to(Vector3::new(0.0, 0.0, -10.0), target);
        let b = ray_to(Vector3::new(0.0, 8.0, -10.0), target);
        let (p, cov) = fuse_rays(&[a, b], NOISE).expect("fixes a point");
        assert!((p - target).norm() < 1e-6, "{p}");
        // Uncertain mostly along the line of sight (8 m baseline at 60 m).
        assert!(
            cov.trace().sqrt() > 1.0 && cov.trace().sqrt() < 10.0,
            "{cov}"
        );
        // Bearings through an azimuth/elevation pair describe the same rays.
        let az = 5.0f64.atan2(60.0).to_degrees();
        let el = (10.0f64)
            .atan2((60.0f64.powi(2) + 25.0).sqrt())
            .to_degrees();
        assert!((bearing_dir(az, el) - a.1).norm() < 1e-9);
        // Closest approach agrees.
        let (t1, t2, miss) = closest_approach(&a.0, &a.1, &b.0, &b.1).unwrap();
        assert!(miss < 1e-9 && t1 > 0.0 && t2 > 0.0);
    }

    #[test]
    fn noisy_bearings_land_near_the_target() {
        let target = Vector3::new(80.0, -20.0, -15.0);
        let obs = [
            Vector3::new(0.0, 0.0, -10.0),
            Vector3::new(0.0, 10.0, -10.0),
            Vector3::new(8.0, 4.0, -12.0),
        ];
        // Rotate each ray by ~0.1° about the down axis, alternately.
        let rays: Vec<_> = obs
            .iter()
            .enumerate()
            .map(|(i, o)| {
                let (o, d, r) = ray_to(*o, target);
                let a = if i % 2 == 0 { 0.002 } else { -0.002 };
                let rot = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), a);
                (o, rot * d, r)
            })
            .collect();
        let (p, _) = fuse_rays(&rays, NOISE).unwrap();
        assert!((p - target).norm() < 3.0, "{p}");
    }

    #[test]
    fn one_ray_needs_a_range_and_parallel_rays_are_refused() {
        let o = Vector3::new(0.0, 0.0, -10.0);
        let d = Vector3::new(1.0, 0.0, 0.0);
        assert!(fuse_rays(&[(o, d, None)], NOISE).is_none());
        let (p, cov) = fuse_rays(&[(o, d, Some(40.0))], NOISE).unwrap();
        assert!((p - Vector3::new(40.0, 0.0, -10.0)).norm() < 1e-6);
        // Along the ray: 30 % of 40 m.
        assert!((cov[(0, 0)].sqrt() - 12.0).abs() < 1e-6);
        let o2 = Vector3::new(0.0, 5.0, -10.0);
        assert!(fuse_rays(&[(o, d, None), (o2, d, None)], NOISE).is_none());
        // Behind the observers: refused.
        let back = Vector3::new(-50.0, 2.5, -10.0);
        let r1 = ray_to(o, back);
        let r2 = ray_to(o2, back);
        let (r1, r2) = ((r1.0, -r1.1, None), (r2.0, -r2.1, None));
        assert!(fuse_rays(&[r1, r2], NOISE).is_none());
    }
}
