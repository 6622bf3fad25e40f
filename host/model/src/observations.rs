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
}
