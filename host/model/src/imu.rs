//! Gravity, inertial quantities and the inertial sensor model (paper eq. (5),
//! (6); docs/model.md §2–3).
//!
//! ```text
//! g = [g_x, g_y, −sqrt(g0² − g_x² − g_y²)]      (base frame)
//! ω = Rᵀ ω_n,   s = Rᵀ (a_n − g)                 (IMU frame)
//! ω̃ = K_ω Γ_ω R_ω ω + b_ω,   s̃ = K_a Γ_a R_a s + b_a
//! Γ = [[1, 0, 0], [γ_yz, 1, 0], [−γ_zy, γ_zx, 1]],  R = Rz(r_z)·Ry(r_y)·Rx(r_x),  K = diag(k)
//! ```

use super::geom::{self, mul_mtv, mul_mv, sub, M3, V3};
use super::jet::Scalar;

/// The six IMU channels in z order: accelerometer x, y, z (m/s²), then
/// gyroscope x, y, z (rad/s) — the `imu.csv` value columns and the names of
/// per-channel parameters and statistics.
pub const IMU_CHANNELS: [&str; 6] = ["ax", "ay", "az", "gx", "gy", "gz"];

/// One value per IMU channel, in [`IMU_CHANNELS`] order; indexed by position
/// or by channel name, serialized as an object keyed by channel name
/// ([`PerChannel::serialize_present`] leaves out the `None` entries).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PerChannel<T>(pub [T; 6]);

impl<T> PerChannel<T> {
    /// (channel name, value) in channel order.
    pub fn iter(&self) -> impl Iterator<Item = (&'static str, &T)> {
        IMU_CHANNELS.iter().copied().zip(&self.0)
    }

    /// The value of `channel` (`ax` … `gz`), if it is one.
    pub fn get(&self, channel: &str) -> Option<&T> {
        IMU_CHANNELS
            .iter()
            .position(|c| *c == channel)
            .map(|k| &self.0[k])
    }
}

impl<T> std::ops::Index<usize> for PerChannel<T> {
    type Output = T;
    fn index(&self, k: usize) -> &T {
        &self.0[k]
    }
}

impl<T> std::ops::Index<&str> for PerChannel<T> {
    type Output = T;
    /// # Panics
    /// When `channel` is not one of [`IMU_CHANNELS`].
    #[track_caller]
    fn index(&self, channel: &str) -> &T {
        self.get(channel)
            .unwrap_or_else(|| panic!("`{channel}` is not an IMU channel"))
    }
}

impl<T: serde::Serialize> serde::Serialize for PerChannel<T> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut m = s.serialize_map(Some(6))?;
        for (c, v) in IMU_CHANNELS.iter().zip(&self.0) {
            m.serialize_entry(c, v)?;
        }
        m.end()
    }
}

impl<T: serde::Serialize> PerChannel<Option<T>> {
    /// Serializes the channels that have a value (`#[serde(serialize_with =
    /// "PerChannel::serialize_present")]`).
    pub fn serialize_present<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut m = s.serialize_map(None)?;
        for (c, v) in IMU_CHANNELS.iter().zip(&self.0) {
            if let Some(v) = v {
                m.serialize_entry(c, v)?;
            }
        }
        m.end()
    }
}

/// Why an inertial computation is undefined.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum ImuError {
    /// g_x² + g_y² ≥ g0²: no real vertical component (eq. (5)).
    #[error("gravity direction (g_x, g_y) = ({gx}, {gy}) has magnitude ≥ g0 = {g0}")]
    GravityOutOfRange {
        /// g_x.
        gx: f64,
        /// g_y.
        gy: f64,
        /// g0.
        g0: f64,
    },
    /// A sensor gain is zero, so the sensor model cannot be inverted.
    #[error("sensor gain k_{axis} is zero: the sensor model is not invertible")]
    ZeroGain {
        /// `x`, `y` or `z`.
        axis: char,
    },
}

/// Gravity in the base frame from (g_x, g_y) and the magnitude g0 (eq. (5)).
pub fn gravity<S: Scalar>(g_xy: [S; 2], g0: f64) -> Result<V3<S>, ImuError> {
    let z2 = S::cst(g0 * g0) - g_xy[0] * g_xy[0] - g_xy[1] * g_xy[1];
    if z2.value().partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
        return Err(ImuError::GravityOutOfRange {
            gx: g_xy[0].value(),
            gy: g_xy[1].value(),
            g0,
        });
    }
    Ok([g_xy[0], g_xy[1], -z2.sqrt()])
}

/// Angular velocity ω and specific force s in the IMU frame from the base-frame
/// ω_n, a_n, the IMU rotation R and gravity g (eq. (5)). Returns `(ω, s)`.
pub fn inertial<S: Scalar>(r: &M3<S>, omega_n: V3<S>, a_n: V3<S>, g: V3<S>) -> (V3<S>, V3<S>) {
    (mul_mtv(r, omega_n), mul_mtv(r, sub(a_n, g)))
}

/// Intrinsics of one triaxial sensor (eq. (6)): misalignment γ = (γ_yz, γ_zy,
/// γ_zx) (rad), rotation r = (r_z, r_y, r_x) (rad), gains k = (k_x, k_y, k_z),
/// biases b (sensor units: m/s² or rad/s).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuIntrinsics<S = f64> {
    /// (γ_yz, γ_zy, γ_zx).
    pub gamma: [S; 3],
    /// (r_z, r_y, r_x).
    pub r: [S; 3],
    /// (k_x, k_y, k_z).
    pub k: [S; 3],
    /// (b_x, b_y, b_z).
    pub b: [S; 3],
}

impl ImuIntrinsics<f64> {
    /// An ideal sensor rotated by `r`: γ = 0, k = 1, b = 0.
    pub fn ideal(r: [f64; 3]) -> Self {
        Self {
            gamma: [0.0; 3],
            r,
            k: [1.0; 3],
            b: [0.0; 3],
        }
    }

    /// Inverse of [`ImuIntrinsics::apply`]: the physical vector (ω or s, IMU
    /// frame) from a raw sensor output, `Rᵀ Γ⁻¹ K⁻¹ (raw − b)`.
    pub fn invert(&self, raw: V3) -> Result<V3, ImuError> {
        let mut u = sub(raw, self.b);
        for (i, axis) in ['x', 'y', 'z'].into_iter().enumerate() {
            if self.k[i] == 0.0 {
                return Err(ImuError::ZeroGain { axis });
            }
            u[i] /= self.k[i];
        }
        // Γ is unit lower triangular: forward substitution.
        let [gyz, gzy, gzx] = self.gamma;
        let w0 = u[0];
        let w1 = u[1] - gyz * w0;
        let w2 = u[2] + gzy * w0 - gzx * w1;
        Ok(mul_mtv(&self.rotation(), [w0, w1, w2]))
    }
}

impl<S: Scalar> ImuIntrinsics<S> {
    /// Γ = [[1, 0, 0], [γ_yz, 1, 0], [−γ_zy, γ_zx, 1]].
    pub fn gamma_matrix(&self) -> M3<S> {
        let (o, z) = (S::cst(1.0), S::cst(0.0));
        let [gyz, gzy, gzx] = self.gamma;
        [[o, z, z], [gyz, o, z], [-gzy, gzx, o]]
    }

    /// R = Rz(r_z)·Ry(r_y)·Rx(r_x).
    pub fn rotation(&self) -> M3<S> {
        geom::rot_zyx(self.r)
    }

    /// K Γ R.
    pub fn matrix(&self) -> M3<S> {
        let mut m = geom::mul_mm(&self.gamma_matrix(), &self.rotation());
        for (row, &k) in m.iter_mut().zip(self.k.iter()) {
            for e in row.iter_mut() {
                *e *= k;
            }
        }
        m
    }

    /// Sensor output from the physical vector: K Γ R v + b (eq. (6)).
    pub fn apply(&self, v: V3<S>) -> V3<S> {
        geom::add(mul_mv(&self.matrix(), v), self.b)
    }
}

/// The predicted sensor output `[s̃; ω̃]` = `[ax, ay, az, gx, gy, gz]` from ω and s.
pub(crate) fn sensor_output<S: Scalar>(
    accel: &ImuIntrinsics<S>,
    gyro: &ImuIntrinsics<S>,
    omega: V3<S>,
    s: V3<S>,
) -> [S; 6] {
    let a = accel.apply(s);
    let w = gyro.apply(omega);
    [a[0], a[1], a[2], w[0], w[1], w[2]]
}

/// Inverse of [`sensor_output`]: corrected `(ω, s)` from a raw `[ax, ay, az, gx, gy, gz]`.
pub fn correct(
    accel: &ImuIntrinsics,
    gyro: &ImuIntrinsics,
    z: [f64; 6],
) -> Result<(V3, V3), ImuError> {
    let s = accel.invert([z[0], z[1], z[2]])?;
    let w = gyro.invert([z[3], z[4], z[5]])?;
    Ok((w, s))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::rot_zyx;
    use std::f64::consts::PI;

    #[test]
    fn at_rest_z_up_gives_plus_g0() {
        // IMU z up: R = identity; at rest a_n = 0, ω_n = 0.
        let g = gravity([0.0, 0.0], 9.81).unwrap();
        let (w, s) = inertial(&geom::identity(), [0.0; 3], [0.0; 3], g);
        assert_eq!(w, [0.0; 3]);
        assert_eq!(s, [0.0, 0.0, 9.81]);
        // Tilted base: |s| still g0, and s = Rᵀ(−g).
        let g = gravity([0.3, -0.4], 9.81).unwrap();
        let r = rot_zyx([0.2, -0.1, 0.05]);
        let (_, s) = inertial(&r, [0.0; 3], [0.0; 3], g);
        assert!((geom::dot(s, s).sqrt() - 9.81).abs() < 1e-12);
        // IMU z down (flipped about x): s = (0, 0, −g0).
        let (_, s) = inertial(
            &geom::rot_x(PI),
            [0.0; 3],
            [0.0; 3],
            gravity([0.0, 0.0], 9.81).unwrap(),
        );
        assert!((s[2] + 9.81).abs() < 1e-12 && s[0].abs() < 1e-12 && s[1].abs() < 1e-12);
    }

    #[test]
    fn gravity_out_of_range_is_an_error() {
        assert!(matches!(
            gravity([7.0, 7.0], 9.81),
            Err(ImuError::GravityOutOfRange { .. })
        ));
    }

    #[test]
    fn matrix_is_k_gamma_r_written_out() {
        let m = ImuIntrinsics {
            gamma: [0.01, -0.02, 0.03],
            r: [3.0, 0.1, -0.2],
            k: [0.98, 1.02, 1.05],
            b: [0.1, -0.2, 0.3],
        };
        // Independent: entries of Γ by hand, rotations via explicit products.
        let gam = [[1.0, 0.0, 0.0], [0.01, 1.0, 0.0], [0.02, 0.03, 1.0]];
        let (cz, sz) = (3.0f64.cos(), 3.0f64.sin());
        let (cy, sy) = (0.1f64.cos(), 0.1f64.sin());
        let (cx, sx) = ((-0.2f64).cos(), (-0.2f64).sin());
        let rz = [[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]];
        let ry = [[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]];
        let rx = [[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]];
        let r = geom::mul_mm(&geom::mul_mm(&rz, &ry), &rx);
        let kg = geom::mul_mm(&gam, &r);
        let mm = m.matrix();
        for i in 0..3 {
            for j in 0..3 {
                assert!((mm[i][j] - m.k[i] * kg[i][j]).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn inverse_of_forward_is_identity() {
        let accel = ImuIntrinsics {
            gamma: [0.012, 0.03, -0.004],
            r: [PI + 0.004, 0.036, 0.019],
            k: [0.993, 0.977, 0.982],
            b: [-0.12, 0.30, -0.15],
        };
        let gyro = ImuIntrinsics {
            gamma: [0.0008, -0.0028, -0.0016],
            r: [PI + 0.02, 0.029, 0.015],
            k: [1.021, 1.027, 1.022],
            b: [-0.0023, -0.0026, -0.001],
        };
        let w = [0.3, -0.7, 1.1];
        let s = [1.5, -9.0, 3.2];
        let z = sensor_output(&accel, &gyro, w, s);
        let (w2, s2) = correct(&accel, &gyro, z).unwrap();
        for i in 0..3 {
            assert!((w2[i] - w[i]).abs() < 1e-14, "{w2:?} vs {w:?}");
            assert!((s2[i] - s[i]).abs() < 1e-13, "{s2:?} vs {s:?}");
        }
        let zero = ImuIntrinsics {
            k: [1.0, 0.0, 1.0],
            ..accel
        };
        assert_eq!(zero.invert([0.0; 3]), Err(ImuError::ZeroGain { axis: 'y' }));
    }
}
