//! The observations of one session, as the estimator takes them: joint
//! samples and IMU samples on the session clock, in SI units
//! (docs/model.md §4, §7).

/// Observations, on the session clock (s), in SI units.
#[derive(Debug, Clone, Default)]
pub struct Measurements {
    /// Joint sample times, non-decreasing.
    pub joint_t: Vec<f64>,
    /// Joint positions, row-major `[s·n + j]`.
    pub joint_q: Vec<f64>,
    /// IMU sample times, non-decreasing.
    pub imu_t: Vec<f64>,
    /// IMU samples `[ax, ay, az, gx, gy, gz]`.
    pub imu_z: Vec<[f64; 6]>,
    /// Sensor temperature at each IMU sample, °C, when recorded (not used
    /// by the model; a regressor of `robimu_workflows::diagnose`).
    pub imu_temp: Option<Vec<f64>>,
    /// The further IMUs of a multi-IMU session (docs/model.md §9):
    /// `extra_imus[j - 1]` is IMU j ≥ 1; empty for one IMU. IMU 0 is
    /// `imu_t`/`imu_z`/`imu_temp` above.
    pub extra_imus: Vec<ImuSamples>,
}

/// The observations of a pose session (MODEL.md §10), on the session clock
/// (s), SI units: pose samples of B in W and IMU samples.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PoseMeasurements {
    /// Pose sample times.
    pub pose_t: Vec<f64>,
    /// Positions p̃ of B's origin in W (m).
    pub pose_p: Vec<[f64; 3]>,
    /// Unit quaternions q̃ = [w, x, y, z] (Hamilton) of B in W.
    pub pose_q: Vec<[f64; 4]>,
    /// IMU sample times, non-decreasing.
    pub imu_t: Vec<f64>,
    /// IMU samples `[ax, ay, az, gx, gy, gz]`.
    pub imu_z: Vec<[f64; 6]>,
}

/// One IMU's samples on the session clock (docs/model.md §7.4, §9).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ImuSamples {
    /// Sample times, non-decreasing.
    pub t: Vec<f64>,
    /// Samples `[ax, ay, az, gx, gy, gz]`.
    pub z: Vec<[f64; 6]>,
    /// Sensor temperature at each sample, °C, when recorded.
    pub temp: Option<Vec<f64>>,
}

/// A borrowed view of one IMU's samples ([`Measurements::imu`]).
#[derive(Debug, Clone, Copy)]
pub struct ImuView<'a> {
    /// Sample times.
    pub t: &'a [f64],
    /// Samples `[ax, ay, az, gx, gy, gz]`.
    pub z: &'a [[f64; 6]],
    /// Temperatures, °C, when recorded.
    pub temp: Option<&'a [f64]>,
}

impl Measurements {
    /// Number of IMUs K (≥ 1; docs/model.md §9).
    pub fn n_imus(&self) -> usize {
        1 + self.extra_imus.len()
    }

    /// IMU `j`'s samples (0 ≤ j < [`Self::n_imus`]).
    ///
    /// # Panics
    /// If `j ≥ self.n_imus()`.
    pub fn imu(&self, j: usize) -> ImuView<'_> {
        if j == 0 {
            ImuView {
                t: &self.imu_t,
                z: &self.imu_z,
                temp: self.imu_temp.as_deref(),
            }
        } else {
            let s = &self.extra_imus[j - 1];
            ImuView {
                t: &s.t,
                z: &s.z,
                temp: s.temp.as_deref(),
            }
        }
    }

    /// The joint samples with IMU `j` alone, as IMU 0 of a one-IMU set
    /// (`robimu calibrate --imu j`).
    ///
    /// # Panics
    /// If `j ≥ self.n_imus()`.
    pub fn only_imu(&self, j: usize) -> Measurements {
        let v = self.imu(j);
        Measurements {
            joint_t: self.joint_t.clone(),
            joint_q: self.joint_q.clone(),
            imu_t: v.t.to_vec(),
            imu_z: v.z.to_vec(),
            imu_temp: v.temp.map(<[f64]>::to_vec),
            extra_imus: Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn imu_views_and_one_imu_alone() {
        let m = Measurements {
            joint_t: vec![0.0, 1.0],
            joint_q: vec![0.1, 0.2],
            imu_t: vec![0.5],
            imu_z: vec![[1.0; 6]],
            imu_temp: None,
            extra_imus: vec![ImuSamples {
                t: vec![0.25, 0.75],
                z: vec![[2.0; 6], [3.0; 6]],
                temp: Some(vec![20.0, 21.0]),
            }],
        };
        assert_eq!(m.n_imus(), 2);
        assert_eq!(m.imu(0).t, &[0.5]);
        assert_eq!(m.imu(1).z[1], [3.0; 6]);
        let one = m.only_imu(1);
        assert_eq!(one.n_imus(), 1);
        assert_eq!(one.imu_t, vec![0.25, 0.75]);
        assert_eq!(one.imu_temp, Some(vec![20.0, 21.0]));
        assert_eq!(one.joint_q, m.joint_q);
        assert_eq!(Measurements::default().n_imus(), 1);
    }
}
