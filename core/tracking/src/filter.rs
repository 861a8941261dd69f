//! A constant-velocity Kalman filter over a 3D position (`nalgebra`): state
//! `[north, east, down, v_north, v_east, v_down]` (swarm frame, metres and m/s), position
//! measurements with a full covariance, white-acceleration process noise.

use nalgebra::{Matrix3, Matrix6, SMatrix, Vector3, Vector6};

/// One track's filter.
#[derive(Debug, Clone, PartialEq)]
pub struct ConstantVelocity {
    /// State: position (m) then velocity (m/s), NED.
    pub x: Vector6<f64>,
    /// State covariance.
    pub p: Matrix6<f64>,
    /// Standard deviation of the unmodelled acceleration, m/s².
    pub accel_sigma_m_s2: f64,
}

type H = SMatrix<f64, 3, 6>;

fn h() -> H {
    let mut h = H::zeros();
    h.fixed_view_mut::<3, 3>(0, 0).fill_with_identity();
    h
}

impl ConstantVelocity {
    /// A filter at `position` with covariance `position_cov`, unknown velocity (standard
    /// deviation `velocity_sigma_m_s` per axis).
    pub fn new(
        position: Vector3<f64>,
        position_cov: Matrix3<f64>,
        velocity_sigma_m_s: f64,
        accel_sigma_m_s2: f64,
    ) -> Self {
        let mut x = Vector6::zeros();
        x.fixed_rows_mut::<3>(0).copy_from(&position);
        let mut p = Matrix6::zeros();
        p.fixed_view_mut::<3, 3>(0, 0).copy_from(&position_cov);
        let v2 = velocity_sigma_m_s * velocity_sigma_m_s;
        p.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(Matrix3::identity() * v2));
        ConstantVelocity {
            x,
            p,
            accel_sigma_m_s2,
        }
    }

    /// Position estimate.
    pub fn position(&self) -> Vector3<f64> {
        self.x.fixed_rows::<3>(0).into()
    }

    /// Velocity estimate.
    pub fn velocity(&self) -> Vector3<f64> {
        self.x.fixed_rows::<3>(3).into()
    }

    /// Position covariance, m².
    pub fn position_cov(&self) -> Matrix3<f64> {
        self.p.fixed_view::<3, 3>(0, 0).into()
    }

    /// The state `dt_s` later (no change for `dt_s <= 0`).
    pub fn predict(&mut self, dt_s: f64) {
        if dt_s <= 0.0 {
            return;
        }
        let mut f = Matrix6::identity();
        f.fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&(Matrix3::identity() * dt_s));
        let q2 = self.accel_sigma_m_s2 * self.accel_sigma_m_s2;
        let (t2, t3, t4) = (dt_s * dt_s, dt_s.powi(3), dt_s.powi(4));
        let mut q = Matrix6::zeros();
        let i = Matrix3::identity() * q2;
        q.fixed_view_mut::<3, 3>(0, 0).copy_from(&(i * (t4 / 4.0)));
        q.fixed_view_mut::<3, 3>(0, 3).copy_from(&(i * (t3 / 2.0)));
        q.fixed_view_mut::<3, 3>(3, 0).copy_from(&(i * (t3 / 2.0)));
        q.fixed_view_mut::<3, 3>(3, 3).copy_from(&(i * t2));
        self.x = f * self.x;
        self.p = f * self.p * f.transpose() + q;
    }

    /// Mahalanobis distance² of a position measurement `z` with covariance `r`.
    pub fn distance2(&self, z: &Vector3<f64>, r: &Matrix3<f64>) -> Option<f64> {
        let s = self.position_cov() + r;
        let e = z - self.position();
        s.try_inverse().map(|si| (e.transpose() * si * e)[0])
    }

    /// Updates with a position measurement `z` (covariance `r`). Returns false (and
    /// leaves the state alone) when the innovation covariance is singular.
    pub fn update(&mut self, z: &Vector3<f64>, r: &Matrix3<f64>) -> bool {
        let h = h();
        let s = h * self.p * h.transpose() + r;
        let Some(si) = s.try_inverse() else {
            return false;
        };
        let k = self.p * h.transpose() * si;
        let innovation = z - h * self.x;
        self.x += k * innovation;
        // Joseph form: stays symmetric and positive definite.
        let ikh = Matrix6::identity() - k * h;
        self.p = ikh * self.p * ikh.transpose() + k * r * k.transpose();
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn learns_a_constant_velocity_from_positions() {
        let r = Matrix3::identity() * 0.25;
        let start = Vector3::new(0.0, -50.0, -20.0);
        let v = Vector3::new(0.0, 5.0, 0.0);
        let mut f = ConstantVelocity::new(start, r, 10.0, 1.0);
        for k in 1..=50 {
            f.predict(0.2);
            let t = k as f64 * 0.2;
            // ±0.3 m alternating measurement error.
            let noise = Vector3::new(0.3, -0.3, 0.1) * if k % 2 == 0 { 1.0 } else { -1.0 };
            assert!(f.update(&(start + v * t + noise), &r));
        }
        assert!((f.velocity() - v).norm() < 0.3, "{}", f.velocity());
        assert!((f.position() - (start + v * 10.0)).norm() < 0.5);
        let before = f.position_cov().trace();
        f.predict(2.0);
        assert!(f.position_cov().trace() > before);
        assert!((f.position() - (start + v * 12.0)).norm() < 1.0);
    }
}
