//! [`Ned`]: a vector in a north-east-down frame, and its arithmetic.

use serde::{Deserialize, Serialize};
use std::ops::{Add, Mul, Sub};

/// A vector in a north-east-down frame, metres (positions) or metres per second
/// (velocities, where the field names keep `_m` for brevity and the type says which).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct Ned {
    /// North component, metres.
    pub north_m: f64,
    /// East component, metres.
    pub east_m: f64,
    /// Down component, metres (negative is up).
    pub down_m: f64,
}

impl Ned {
    /// The zero vector.
    pub const ZERO: Ned = Ned::new(0.0, 0.0, 0.0);

    /// Builds a vector from its north, east and down components.
    pub const fn new(north_m: f64, east_m: f64, down_m: f64) -> Self {
        Self {
            north_m,
            east_m,
            down_m,
        }
    }

    /// Euclidean length.
    pub fn norm(&self) -> f64 {
        self.norm_squared().sqrt()
    }

    /// Squared Euclidean length (cheaper than [`Ned::norm`] for comparisons).
    pub fn norm_squared(&self) -> f64 {
        self.dot(self)
    }

    /// The same vector shortened to at most `max` (metres, or the vector's own unit).
    pub fn clamped_norm(self, max: f64) -> Ned {
        let n = self.norm();
        if n > max { self * (max / n) } else { self }
    }

    /// Length of the horizontal (north, east) part.
    pub fn horizontal_norm(&self) -> f64 {
        self.north_m.hypot(self.east_m)
    }

    /// Dot product.
    pub fn dot(&self, other: &Ned) -> f64 {
        self.north_m * other.north_m + self.east_m * other.east_m + self.down_m * other.down_m
    }

    /// Cross product (right-handed NED: north × east = down).
    pub fn cross(&self, o: &Ned) -> Ned {
        Ned::new(
            self.east_m * o.down_m - self.down_m * o.east_m,
            self.down_m * o.north_m - self.north_m * o.down_m,
            self.north_m * o.east_m - self.east_m * o.north_m,
        )
    }

    /// Rotates the horizontal part by `yaw_rad` about the down axis (clockwise seen from
    /// above, as headings turn): a vector `(1, 0, 0)` rotated by π/2 points east.
    pub fn rotated_yaw(&self, yaw_rad: f64) -> Ned {
        let (s, c) = yaw_rad.sin_cos();
        Ned::new(
            c * self.north_m - s * self.east_m,
            s * self.north_m + c * self.east_m,
            self.down_m,
        )
    }

    /// True when every component is finite.
    pub fn is_finite(&self) -> bool {
        self.north_m.is_finite() && self.east_m.is_finite() && self.down_m.is_finite()
    }
}

impl Add for Ned {
    type Output = Ned;
    fn add(self, o: Ned) -> Ned {
        Ned::new(
            self.north_m + o.north_m,
            self.east_m + o.east_m,
            self.down_m + o.down_m,
        )
    }
}

impl Sub for Ned {
    type Output = Ned;
    fn sub(self, o: Ned) -> Ned {
        Ned::new(
            self.north_m - o.north_m,
            self.east_m - o.east_m,
            self.down_m - o.down_m,
        )
    }
}

impl Mul<f64> for Ned {
    type Output = Ned;
    fn mul(self, k: f64) -> Ned {
        Ned::new(self.north_m * k, self.east_m * k, self.down_m * k)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yaw_rotation_turns_north_into_east() {
        let v = Ned::new(1.0, 0.0, 2.0).rotated_yaw(std::f64::consts::FRAC_PI_2);
        assert!((v.north_m).abs() < 1e-12 && (v.east_m - 1.0).abs() < 1e-12 && v.down_m == 2.0);
    }

    #[test]
    fn cross_product_is_right_handed() {
        let c = Ned::new(1.0, 0.0, 0.0).cross(&Ned::new(0.0, 1.0, 0.0));
        assert_eq!(c, Ned::new(0.0, 0.0, 1.0));
    }

    #[test]
    fn lengths_and_clamping() {
        let v = Ned::new(3.0, 4.0, 12.0);
        assert_eq!(
            (v.norm(), v.norm_squared(), v.horizontal_norm()),
            (13.0, 169.0, 5.0)
        );
        assert!((v.clamped_norm(6.5).norm() - 6.5).abs() < 1e-12);
        assert_eq!(v.clamped_norm(20.0), v);
    }
}
